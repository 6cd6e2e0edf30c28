//! Running a learned method on one scenario (feature `nets`; without it,
//! a clear error says how to rebuild).
//!
//! What each scenario gives a learned method:
//! * MST-S / MST-L: the measurement fitted to 256 + 2·27 columns and Phi
//!   from the nominal mask moved to the scenario's pose — none (I, II), the
//!   calibrated dx, dy, θ (III), the true ones (IV). The networks keep their
//!   trained step-2 dispersion: a1 and α are not inputs of theirs.
//! * HDNet: the same, but it never sees the mask, so II–IV coincide.
//! * PnP-HSICNN: a model-based solver, so it gets the whole model (pose, a1,
//!   α, dispersion model) exactly as the TV solvers do.
//!
//! Weights are loaded for each reconstruction: milliseconds, against a
//! second or more for a forward pass and minutes for PnP-HSICNN.

use cassi_core::optics::DispersionModel;
use cassi_core::{Cube, Mask, Measurement, Mismatch};

use crate::method::LearnedMethod;

/// Bands of the networks' training data (MST toolbox).
pub const NETWORK_BANDS: usize = 28;
/// MST's fixed spatial size.
pub const MST_SIZE: usize = 256;
/// Detector columns per band the networks were trained with.
pub const TRAINED_STRIDE: f64 = 2.0;

/// Checks a study's nominal stride against what `method` was trained for.
pub fn check_stride(method: &LearnedMethod, stride: f64) -> anyhow::Result<()> {
    let m = method.method.as_str();
    if m != "pnp-hsicnn" && stride != TRAINED_STRIDE {
        anyhow::bail!(
            "{m} was trained for stride {TRAINED_STRIDE} (px per band); the study's stride is {stride}"
        );
    }
    Ok(())
}

/// Checks a scene shape against what `method` can take (a study checks
/// its mask first, so it fails before its first calibration).
pub fn check_shape(
    method: &LearnedMethod,
    bands: usize,
    rows: usize,
    cols: usize,
) -> anyhow::Result<()> {
    let m = method.method.as_str();
    if m == "pnp-hsicnn" {
        return Ok(());
    }
    if bands != NETWORK_BANDS {
        anyhow::bail!(
            "{m} reconstructs {NETWORK_BANDS} bands; the scene has {bands} (shape {bands}×{rows}×{cols})"
        );
    }
    if m.starts_with("mst") && (rows, cols) != (MST_SIZE, MST_SIZE) {
        anyhow::bail!(
            "{m} takes {MST_SIZE}×{MST_SIZE} scenes and masks; got {rows}×{cols} \
             (crop the scenes and the mask to {MST_SIZE}×{MST_SIZE})"
        );
    }
    Ok(())
}

/// Loads the weights once (strictly), so a wrong or mismatched file is an
/// error before the study starts.
pub fn check_weights(method: &LearnedMethod) -> anyhow::Result<()> {
    run::load_check(method)
}

/// The reconstruction of `y` by `method`, the instrument assumed to be
/// `nominal_mask` placed and dispersed as `params` / `model` say (see the
/// module notes for what each method uses of it).
pub fn reconstruct(
    method: &LearnedMethod,
    y: &Measurement,
    nominal_mask: &Mask,
    bands: usize,
    params: &Mismatch,
    model: DispersionModel,
) -> anyhow::Result<Cube> {
    let (rows, cols) = nominal_mask.shape();
    check_shape(method, bands, rows, cols)?;
    run::reconstruct(method, y, nominal_mask, bands, params, model)
}

#[cfg(feature = "nets")]
mod run {
    use anyhow::Context;
    use cassi_core::optics::DispersionModel;
    use cassi_core::solvers::Silent;
    use cassi_core::{Cube, Mask, Measurement, Mismatch};
    use cassi_nets::{PnpHsicnn, PnpHsicnnParams, Reconstructor};

    use crate::method::LearnedMethod;

    fn pnp(method: &LearnedMethod) -> anyhow::Result<PnpHsicnn> {
        let params = PnpHsicnnParams::default().with_overrides(method.iterations, None);
        PnpHsicnn::load(&method.weights, params).context("pnp-hsicnn weights")
    }

    fn network(method: &LearnedMethod) -> anyhow::Result<Reconstructor> {
        Reconstructor::load(&method.method, &method.weights)
            .with_context(|| format!("{} weights", method.method))
    }

    pub(super) fn load_check(method: &LearnedMethod) -> anyhow::Result<()> {
        if method.method == "pnp-hsicnn" {
            pnp(method).map(drop)
        } else {
            network(method).map(drop)
        }
    }

    pub(super) fn reconstruct(
        method: &LearnedMethod,
        y: &Measurement,
        nominal_mask: &Mask,
        bands: usize,
        params: &Mismatch,
        model: DispersionModel,
    ) -> anyhow::Result<Cube> {
        if method.method == "pnp-hsicnn" {
            let r = pnp(method)?.reconstruct(y, nominal_mask, bands, params, model, &mut Silent)?;
            return Ok(r.reconstruction.cube);
        }
        Ok(network(method)?
            .reconstruct(y, nominal_mask, &params.pose())?
            .cube)
    }
}

#[cfg(not(feature = "nets"))]
mod run {
    use cassi_core::optics::DispersionModel;
    use cassi_core::{Cube, Mask, Measurement, Mismatch};

    use crate::method::LearnedMethod;

    fn unavailable(method: &LearnedMethod) -> anyhow::Error {
        anyhow::anyhow!(
            "{}: this build has no deep networks; rebuild with `--features nets` \
             (cargo build --release -p cassi-cli --features nets)",
            method.method
        )
    }

    pub(super) fn load_check(method: &LearnedMethod) -> anyhow::Result<()> {
        Err(unavailable(method))
    }

    pub(super) fn reconstruct(
        method: &LearnedMethod,
        _y: &Measurement,
        _nominal_mask: &Mask,
        _bands: usize,
        _params: &Mismatch,
        _model: DispersionModel,
    ) -> anyhow::Result<Cube> {
        Err(unavailable(method))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn learned(name: &str) -> LearnedMethod {
        LearnedMethod {
            method: name.into(),
            weights: "w.pth".into(),
            iterations: None,
        }
    }

    #[test]
    fn shapes_the_networks_cannot_take_are_refused_with_both_shapes() {
        let e = check_shape(&learned("mst-s"), 28, 128, 128)
            .unwrap_err()
            .to_string();
        assert!(e.contains("256×256") && e.contains("128×128"), "{e}");
        let e = check_shape(&learned("hdnet"), 31, 64, 64)
            .unwrap_err()
            .to_string();
        assert!(e.contains("28 bands") && e.contains("31"), "{e}");
        let e = check_stride(&learned("mst-l"), 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("stride 2") && e.contains("1"), "{e}");
        assert!(check_stride(&learned("pnp-hsicnn"), 1.5).is_ok());
        assert!(check_shape(&learned("hdnet"), 28, 64, 96).is_ok());
        assert!(check_shape(&learned("mst-s"), 28, 256, 256).is_ok());
        assert!(check_shape(&learned("pnp-hsicnn"), 9, 20, 30).is_ok());
    }

    #[cfg(not(feature = "nets"))]
    #[test]
    fn without_the_feature_learned_methods_say_how_to_rebuild() {
        let e = check_weights(&learned("mst-s")).unwrap_err().to_string();
        assert!(e.contains("--features nets"), "{e}");
    }
}
