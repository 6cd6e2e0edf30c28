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
//! (`LearnedMethod::load`, in the study's methods): every reconstruction after that — each
//! scenario of each scene, the sweeps' too — runs with that one
//! [`LearnedModel`], which the study's clones share (`Arc`). Networks run
//! through `&self`; PnP-HSICNN's denoiser (a `cassi_core::Denoiser`) needs
//! `&mut self`, so its model runs one reconstruction at a time.

use cassi_core::recon::MethodId;

pub use run::{LearnedModel, not_loaded};

/// Checks a study's nominal stride against what `method` was trained for
/// (its registry shape rules).
pub fn check_stride(method: MethodId, stride: f64) -> anyhow::Result<()> {
    if let Some(trained) = method.spec().shape.stride
        && stride != trained as f64
    {
        anyhow::bail!(
            "{method} was trained for stride {trained} (px per band); the study's stride is {stride}"
        );
    }
    Ok(())
}

/// Checks a scene shape against what `method` can take (its registry shape
/// rules; a study checks its mask first, so it fails before its first
/// calibration).
pub fn check_shape(method: MethodId, bands: usize, rows: usize, cols: usize) -> anyhow::Result<()> {
    let rules = method.spec().shape;
    if let Some(trained) = rules.bands
        && bands != trained
    {
        anyhow::bail!(
            "{method} reconstructs {trained} bands; the scene has {bands} (shape {bands}×{rows}×{cols})"
        );
    }
    if let Some((r, c)) = rules.size
        && (rows, cols) != (r, c)
    {
        anyhow::bail!(
            "{method} takes {r}×{c} scenes and masks; got {rows}×{cols} \
             (crop the scenes and the mask to {r}×{c})"
        );
    }
    Ok(())
}

#[cfg(feature = "nets")]
mod run {
    use std::sync::{Mutex, PoisonError};

    use std::path::Path;

    use anyhow::Context;
    use cassi_core::recon::{MethodId, MethodKind, Model};
    use cassi_core::solvers::Silent;
    use cassi_core::{Cube, Measurement};
    use cassi_nets::{Network, PnpHsicnn, PnpHsicnnParams};

    /// A learned method's weights, loaded.
    // one per method, held once behind an Arc: the variants' sizes don't matter
    #[allow(clippy::large_enum_variant)]
    pub enum LearnedModel {
        /// A pretrained network (MST-S, MST-L, HDNet, …).
        Network(Network),
        /// PnP-HSICNN, locked while it reconstructs (it needs `&mut self`).
        PnpHsicnn(Mutex<PnpHsicnn>),
    }

    impl LearnedModel {
        /// `method`'s `weights`, loaded strictly; `iterations` overrides a
        /// learned PnP method's count.
        pub fn load(
            method: MethodId,
            weights: &Path,
            iterations: Option<usize>,
        ) -> anyhow::Result<Self> {
            let context = || format!("{method} weights");
            match method.kind() {
                MethodKind::LearnedPnp => {
                    let params = PnpHsicnnParams::default().with_overrides(iterations, None);
                    let pnp = PnpHsicnn::load(weights, params).with_context(context)?;
                    Ok(Self::PnpHsicnn(Mutex::new(pnp)))
                }
                MethodKind::Network => Ok(Self::Network(
                    Network::load(method, weights).with_context(context)?,
                )),
                MethodKind::Iterative => anyhow::bail!("{method} is not a learned method"),
            }
        }

        /// The cube from `y`, the instrument taken to be `model` (see the
        /// module notes for what each method uses of it).
        pub fn reconstruct(&self, y: &Measurement, model: &Model) -> anyhow::Result<Cube> {
            match self {
                // the network's own `&self` path: studies share one network
                // across threads without a lock
                Self::Network(network) => Ok(network
                    .reconstruct(y, model.nominal_mask(), &model.mismatch().pose())?
                    .cube),
                Self::PnpHsicnn(pnp) => {
                    // a reconstruction keeps no state in the model, so one
                    // that panicked leaves nothing to distrust
                    let mut pnp = pnp.lock().unwrap_or_else(PoisonError::into_inner);
                    Ok(pnp.solve(y, model, &mut Silent)?.reconstruction.cube)
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

    /// The error of running `method` before loading it.
    pub fn not_loaded(method: MethodId) -> anyhow::Error {
        anyhow::anyhow!("{method}: weights not loaded (LearnedMethod::load, before the study runs)")
    }
}

#[cfg(not(feature = "nets"))]
mod run {
    use std::path::Path;

    use cassi_core::recon::{MethodId, Model};
    use cassi_core::{Cube, Measurement};

    /// Has no values: this build has no deep networks, so nothing loads.
    #[derive(Debug)]
    pub enum LearnedModel {}

    impl LearnedModel {
        pub fn load(
            method: MethodId,
            _weights: &Path,
            _iterations: Option<usize>,
        ) -> anyhow::Result<Self> {
            Err(unavailable(method))
        }

        pub fn reconstruct(&self, _y: &Measurement, _model: &Model) -> anyhow::Result<Cube> {
            match *self {}
        }
    }

    fn unavailable(method: MethodId) -> anyhow::Error {
        anyhow::anyhow!(
            "{method}: this build has no deep networks; rebuild with `--features nets` \
             (cargo build --release -p cassi-cli --features nets)"
        )
    }

    /// The error of running `method` before loading it: here, that it
    /// cannot load at all.
    pub fn not_loaded(method: MethodId) -> anyhow::Error {
        unavailable(method)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_the_networks_cannot_take_are_refused_with_both_shapes() {
        let e = check_shape(MethodId::MstS, 28, 128, 128)
            .unwrap_err()
            .to_string();
        assert!(e.contains("256×256") && e.contains("128×128"), "{e}");
        let e = check_shape(MethodId::HdNet, 31, 64, 64)
            .unwrap_err()
            .to_string();
        assert!(e.contains("28 bands") && e.contains("31"), "{e}");
        let e = check_stride(MethodId::MstL, 1.0).unwrap_err().to_string();
        assert!(e.contains("stride 2") && e.contains("1"), "{e}");
        assert!(check_stride(MethodId::PnpHsicnn, 1.5).is_ok());
        assert!(check_shape(MethodId::HdNet, 28, 64, 96).is_ok());
        assert!(check_shape(MethodId::MstS, 28, 256, 256).is_ok());
        assert!(check_shape(MethodId::PnpHsicnn, 9, 20, 30).is_ok());
    }

    #[cfg(not(feature = "nets"))]
    #[test]
    fn without_the_feature_learned_methods_say_how_to_rebuild() {
        let e = LearnedModel::load(MethodId::MstS, std::path::Path::new("w.pth"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--features nets"), "{e}");
    }
}
