//! A method of a study: an iterative solver of cassi-core, or a learned
//! method (pretrained network, or PnP with a learned denoiser) with its
//! weights file and, once loaded, its model.

use std::path::PathBuf;
use std::sync::Arc;

use cassi_core::Cube;
use cassi_core::Measurement;
use cassi_core::recon::{Method, MethodId, Model};
use serde::{Deserialize, Serialize};

use crate::learned::{LearnedModel, check_shape, not_loaded};

/// Serialised untagged: a solver is written exactly as before learned
/// methods existed (so earlier study records still resume), a learned
/// method as `{"method": "mst-s", "weights": "…"}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum StudyMethod {
    Solver(Method),
    Learned(LearnedMethod),
}

/// A learned method and the weights it runs with. A study runs it only
/// once [`load`](Self::load)ed: the model is kept here, and the study's
/// clones (the sweeps') share it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LearnedMethod {
    /// A learned method of the registry (network or learned PnP).
    pub method: MethodId,
    /// A PyTorch state-dict `.pth` or a `.safetensors` file.
    pub weights: PathBuf,
    /// PnP-HSICNN only: an iteration count other than the paper's 124.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// The weights, loaded; not part of a record (one read back has none).
    #[serde(skip)]
    loaded: Option<Arc<LearnedModel>>,
}

impl LearnedMethod {
    /// `method` with `weights`, not loaded yet.
    pub fn new(method: MethodId, weights: impl Into<PathBuf>, iterations: Option<usize>) -> Self {
        Self {
            method,
            weights: weights.into(),
            iterations,
            loaded: None,
        }
    }

    /// This method with its weights loaded, strictly, so a wrong or
    /// mismatched file is an error before a study starts; every
    /// reconstruction of the study then runs with this one model.
    pub fn load(self) -> anyhow::Result<Self> {
        let model = LearnedModel::load(self.method, &self.weights, self.iterations)?;
        Ok(Self {
            loaded: Some(Arc::new(model)),
            ..self
        })
    }

    /// The model [`load`](Self::load) made, if it ran.
    pub fn model(&self) -> Option<&LearnedModel> {
        self.loaded.as_deref()
    }

    /// The reconstruction of `y`, the instrument taken to be `model` (see
    /// [`crate::learned`] for what each method uses of it), with the model
    /// this method was loaded with.
    pub fn reconstruct(&self, y: &Measurement, model: &Model) -> anyhow::Result<Cube> {
        let (rows, cols) = model.nominal_mask().shape();
        check_shape(self.method, model.bands(), rows, cols)?;
        let loaded = self.model().ok_or_else(|| not_loaded(self.method))?;
        loaded.reconstruct(y, model)
    }
}

/// The same method, weights file and iterations, loaded or not (a record
/// read back equals the study that wrote it).
impl PartialEq for LearnedMethod {
    fn eq(&self, other: &Self) -> bool {
        (&self.method, &self.weights, self.iterations)
            == (&other.method, &other.weights, other.iterations)
    }
}

impl StudyMethod {
    pub fn name(&self) -> &str {
        match self {
            Self::Solver(m) => m.name(),
            Self::Learned(l) => l.method.name(),
        }
    }
}

impl From<Method> for StudyMethod {
    fn from(m: Method) -> Self {
        Self::Solver(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A solver serialises as a bare `Method` (old records compare equal);
    /// both kinds read back as themselves.
    #[test]
    fn solvers_keep_their_old_form_and_both_kinds_round_trip() {
        let gap = Method::by_name("gap-tv").unwrap();
        let solver = StudyMethod::from(gap);
        assert_eq!(
            serde_json::to_value(&solver).unwrap(),
            serde_json::to_value(gap).unwrap()
        );
        let learned = StudyMethod::Learned(LearnedMethod::new(MethodId::MstS, "w/mst_s.pth", None));
        let v = serde_json::to_value(&learned).unwrap();
        assert_eq!(
            v,
            serde_json::json!({"method": "mst-s", "weights": "w/mst_s.pth"})
        );
        for m in [solver, learned] {
            let back: StudyMethod =
                serde_json::from_value(serde_json::to_value(&m).unwrap()).unwrap();
            assert_eq!(back, m);
        }
        assert_eq!(
            StudyMethod::from(Method::by_name("pnp-tv").unwrap()).name(),
            "pnp-tv"
        );
    }

    /// A study runs only loaded methods: the load that checked the weights
    /// is the one every reconstruction uses.
    #[test]
    fn a_method_that_was_not_loaded_does_not_run() {
        let (y, mask) = (Measurement::zeros(8, 16), cassi_core::Mask::zeros(8, 8));
        let model = Model::nominal(&mask, 4, 2.0, cassi_core::optics::DispersionModel::Rounded);
        let e = LearnedMethod::new(MethodId::PnpHsicnn, "w.pth", None)
            .reconstruct(&y, &model.unwrap())
            .unwrap_err()
            .to_string();
        let expected = if cfg!(feature = "nets") {
            "not loaded"
        } else {
            "--features nets"
        };
        assert!(e.contains(expected), "{e}");
    }

    /// The study shares its models by reference (`Arc`), across threads too
    /// (the study itself: protocol's test).
    #[test]
    fn models_can_be_shared_across_threads() {
        fn shareable<T: Send + Sync>() {}
        shareable::<LearnedModel>();
        shareable::<StudyMethod>();
    }
}
