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
//! A study loads each learned method once, before its first scene
//! ([`LearnedMethod::load`]): every reconstruction after that — each
//! scenario of each scene, the sweeps' too — runs with that one
//! [`LearnedModel`], which the study's clones share (`Arc`). Networks run
//! through `&self`; PnP-HSICNN's denoiser (a `cassi_core::Denoiser`) needs
//! `&mut self`, so its model runs one reconstruction at a time.

use cassi_core::optics::DispersionModel;
use cassi_core::{Cube, Mask, Measurement, Mismatch};

use crate::method::LearnedMethod;

pub use run::LearnedModel;

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

/// The reconstruction of `y` by `method`, the instrument assumed to be
/// `nominal_mask` placed and dispersed as `params` / `model` say (see the
/// module notes for what each method uses of it), with the model `method`
/// was loaded with.
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
    let loaded = method.model().ok_or_else(|| run::not_loaded(method))?;
    loaded.reconstruct(y, nominal_mask, bands, params, model)
}

#[cfg(feature = "nets")]
mod run {
    use std::sync::{Mutex, PoisonError};

    use anyhow::Context;
    use cassi_core::optics::DispersionModel;
    use cassi_core::solvers::Silent;
    use cassi_core::{Cube, Mask, Measurement, Mismatch};
    use cassi_nets::{PnpHsicnn, PnpHsicnnParams, Reconstructor};

    use crate::method::LearnedMethod;

    /// A learned method's weights, loaded.
    // one per method, held once behind an Arc: the variants' sizes don't matter
    #[allow(clippy::large_enum_variant)]
    pub enum LearnedModel {
        /// MST-S, MST-L or HDNet.
        Network(Reconstructor),
        /// PnP-HSICNN, locked while it reconstructs (it needs `&mut self`).
        PnpHsicnn(Mutex<PnpHsicnn>),
    }

    impl LearnedModel {
        /// `method`'s weights, loaded strictly.
        pub(crate) fn load(method: &LearnedMethod) -> anyhow::Result<Self> {
            if method.method == "pnp-hsicnn" {
                let params = PnpHsicnnParams::default().with_overrides(method.iterations, None);
                let pnp = PnpHsicnn::load(&method.weights, params).context("pnp-hsicnn weights")?;
                return Ok(Self::PnpHsicnn(Mutex::new(pnp)));
            }
            let network = Reconstructor::load(&method.method, &method.weights)
                .with_context(|| format!("{} weights", method.method))?;
            Ok(Self::Network(network))
        }

        pub(super) fn reconstruct(
            &self,
            y: &Measurement,
            nominal_mask: &Mask,
            bands: usize,
            params: &Mismatch,
            model: DispersionModel,
        ) -> anyhow::Result<Cube> {
            match self {
                Self::Network(network) => {
                    Ok(network.reconstruct(y, nominal_mask, &params.pose())?.cube)
                }
                Self::PnpHsicnn(pnp) => {
                    // a reconstruction keeps no state in the model, so one
                    // that panicked leaves nothing to distrust
                    let mut pnp = pnp.lock().unwrap_or_else(PoisonError::into_inner);
                    let r = pnp.reconstruct(y, nominal_mask, bands, params, model, &mut Silent)?;
                    Ok(r.reconstruction.cube)
                }
            }
        }
    }

    impl std::fmt::Debug for LearnedModel {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(match self {
                Self::Network(_) => "LearnedModel::Network",
                Self::PnpHsicnn(_) => "LearnedModel::PnpHsicnn",
            })
        }
    }

    pub(super) fn not_loaded(method: &LearnedMethod) -> anyhow::Error {
        anyhow::anyhow!(
            "{}: weights not loaded (LearnedMethod::load, before the study runs)",
            method.method
        )
    }
}

#[cfg(not(feature = "nets"))]
mod run {
    use cassi_core::optics::DispersionModel;
    use cassi_core::{Cube, Mask, Measurement, Mismatch};

    use crate::method::LearnedMethod;

    /// Has no values: this build has no deep networks, so nothing loads.
    #[derive(Debug)]
    pub enum LearnedModel {}

    impl LearnedModel {
        pub(crate) fn load(method: &LearnedMethod) -> anyhow::Result<Self> {
            Err(unavailable(method))
        }

        pub(super) fn reconstruct(
            &self,
            _y: &Measurement,
            _nominal_mask: &Mask,
            _bands: usize,
            _params: &Mismatch,
            _model: DispersionModel,
        ) -> anyhow::Result<Cube> {
            match *self {}
        }
    }

    fn unavailable(method: &LearnedMethod) -> anyhow::Error {
        anyhow::anyhow!(
            "{}: this build has no deep networks; rebuild with `--features nets` \
             (cargo build --release -p cassi-cli --features nets)",
            method.method
        )
    }

    pub(super) fn not_loaded(method: &LearnedMethod) -> anyhow::Error {
        unavailable(method)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn learned(name: &str) -> LearnedMethod {
        LearnedMethod::new(name, "w.pth", None)
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
        let e = learned("mst-s").load().unwrap_err().to_string();
        assert!(e.contains("--features nets"), "{e}");
    }

    /// A study runs only loaded methods: the load that checked the weights
    /// is the one every reconstruction uses.
    #[test]
    fn a_method_that_was_not_loaded_does_not_run() {
        let (y, mask) = (Measurement::zeros(8, 16), Mask::zeros(8, 8));
        let nominal = Mismatch::nominal(TRAINED_STRIDE);
        let e = reconstruct(
            &learned("pnp-hsicnn"),
            &y,
            &mask,
            4,
            &nominal,
            DispersionModel::Rounded,
        )
        .unwrap_err()
        .to_string();
        let expected = if cfg!(feature = "nets") {
            "not loaded"
        } else {
            "--features nets"
        };
        assert!(e.contains(expected), "{e}");
    }

    /// The study shares its models by reference (`Arc`), across threads too.
    #[test]
    fn models_and_studies_can_be_shared_across_threads() {
        fn shareable<T: Send + Sync>() {}
        shareable::<LearnedModel>();
        shareable::<crate::protocol::Study>();
    }
}
