//! The PnP-HSICNN recipe: accelerated GAP on the assumed instrument's
//! operator, with TV warm-up then scheduled HSI-SDeCNN / TV prior steps.

use std::path::Path;

use cassi_core::recon::registry::MethodId;
use cassi_core::recon::{Model, ModelProblem, Reconstruction, Reconstructor};
use cassi_core::solvers::{Gap, GapParams, Observer, Strength};
use cassi_core::{Cube, Measurement};
use serde::{Deserialize, Serialize};

use super::schedule::{DenoiserSchedule, Stage};
use super::scheduled_denoiser::ScheduledDenoiser;
use crate::denoiser::HsiSdecnnDenoiser;
use crate::error::{NetError, Result};
use crate::hsi_sdecnn::HsiSdecnn;

/// Every setting of PnP-HSICNN.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PnpHsicnnParams {
    /// The GAP solver; its strength is the TV weight λ of the TV stages.
    pub gap: GapParams,
    /// Chambolle iterations per TV stage.
    pub tv_iterations: usize,
    /// Noise level given to HSI-SDeCNN, on the cube's [0, 1] scale.
    pub sigma: f32,
    pub schedule: DenoiserSchedule,
}

impl Default for PnpHsicnnParams {
    /// The paper's §5.1: accelerated GAP, 124 iterations (83 TV-only + 41
    /// alternating 3 network + 1 TV), TV λ = 0.05 with 5 inner iterations,
    /// σ = 10/255 (PnP-CASSI's TV weight 12.75/255 = 0.05).
    fn default() -> Self {
        Self {
            gap: GapParams {
                iterations: 124,
                accelerate: true,
                strength: Strength::Constant { value: 0.05 },
                nonnegative: true,
                tolerance: 0.0,
            },
            tv_iterations: 5,
            sigma: 10.0 / 255.0,
            schedule: DenoiserSchedule::PAPER,
        }
    }
}

impl PnpHsicnnParams {
    /// Overrides the iteration count (the schedule is cut or extended with
    /// it: fewer than its warm-up means TV only) and, if given, the TV weight.
    pub fn with_overrides(mut self, iterations: Option<usize>, tv_weight: Option<f32>) -> Self {
        if let Some(n) = iterations {
            self.gap.iterations = n;
        }
        if let Some(v) = tv_weight {
            self.gap.strength = Strength::Constant { value: v };
        }
        self
    }

    pub fn validate(&self) -> Result<()> {
        self.schedule.validate()?;
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(NetError::Input {
                what: "PnP-HSICNN sigma".into(),
                got: format!("{}", self.sigma),
                expected: "a finite noise level > 0".into(),
            });
        }
        Ok(())
    }
}

/// A PnP-HSICNN reconstruction and the stage each iteration ran.
#[derive(Debug, Clone)]
pub struct PnpReconstruction {
    pub reconstruction: Reconstruction,
    pub stages: Vec<Stage>,
}

/// HSI-SDeCNN weights with the PnP-HSICNN settings.
pub struct PnpHsicnn {
    pub params: PnpHsicnnParams,
    denoiser: HsiSdecnnDenoiser,
}

impl PnpHsicnn {
    pub fn new(net: HsiSdecnn, params: PnpHsicnnParams) -> Self {
        Self {
            params,
            denoiser: HsiSdecnnDenoiser::new(net),
        }
    }

    /// Loads the HSI-SDeCNN weights (PnP-CASSI's `deep_denoiser.pth`, or a
    /// `.safetensors` copy) strictly.
    pub fn load(weights: impl AsRef<Path>, params: PnpHsicnnParams) -> Result<Self> {
        Ok(Self::new(HsiSdecnn::load(weights)?, params))
    }

    /// Reconstructs a cube from `measurement`, the instrument taken to be
    /// `model` (nominal, calibrated or true), as cassi-core's TV recipes
    /// do. Any number of bands and any size: the denoiser slides its 7-band
    /// window with the band index clamped at the spectral edges.
    pub fn solve(
        &mut self,
        measurement: &Measurement,
        model: &Model,
        observer: &mut dyn Observer,
    ) -> Result<PnpReconstruction> {
        let p = self.params;
        p.validate()?;
        let problem = ModelProblem::new(measurement, model)?;
        let mut prior =
            ScheduledDenoiser::new(p.schedule, p.tv_iterations, &mut self.denoiser, p.sigma);
        let solution = Gap::new(p.gap).solve(
            &problem.op,
            problem.y.as_slice(),
            problem.cube_shape(),
            &mut prior,
            observer,
        )?;
        let stages = prior.applied().to_vec();
        Ok(PnpReconstruction {
            reconstruction: problem.finish(solution),
            stages,
        })
    }
}

impl Reconstructor for PnpHsicnn {
    fn name(&self) -> &str {
        MethodId::PnpHsicnn.name()
    }

    fn reconstruct(
        &mut self,
        y: &Measurement,
        model: &Model,
        observer: &mut dyn Observer,
    ) -> cassi_core::Result<Cube> {
        Ok(self.solve(y, model, observer)?.reconstruction.cube)
    }
}
