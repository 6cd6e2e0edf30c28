//! A denoiser that switches between TV and a learned denoiser per iteration,
//! following a [`DenoiserSchedule`].

use cassi_core::denoise::{TvChambolle2d, TvChambolleParams};
use cassi_core::{Cube, Denoiser};

use super::schedule::{DenoiserSchedule, Stage};

/// The prior step of PnP-HSICNN. The solvers call a denoiser exactly once
/// per iteration (cassi-core's GAP and ADMM do; `applied` records what ran,
/// and the recipe's test checks it against the schedule), so the n-th call
/// is iteration n. TV stages use the strength the solver passes (its TV
/// weight λ); learned stages use the fixed noise level `sigma`.
pub struct ScheduledDenoiser<'a> {
    schedule: DenoiserSchedule,
    tv: TvChambolle2d,
    learned: &'a mut dyn Denoiser,
    sigma: f32,
    applied: Vec<Stage>,
}

impl<'a> ScheduledDenoiser<'a> {
    pub fn new(
        schedule: DenoiserSchedule,
        tv_iterations: usize,
        learned: &'a mut dyn Denoiser,
        sigma: f32,
    ) -> Self {
        Self {
            schedule,
            tv: TvChambolle2d::new(TvChambolleParams {
                max_iter: tv_iterations,
                ..Default::default()
            }),
            learned,
            sigma,
            applied: Vec::new(),
        }
    }

    /// The stage of every call so far, in order.
    pub fn applied(&self) -> &[Stage] {
        &self.applied
    }
}

impl Denoiser for ScheduledDenoiser<'_> {
    fn denoise(&mut self, cube: &mut Cube, strength: f32) {
        let stage = self.schedule.stage(self.applied.len());
        match stage {
            Stage::Tv => self.tv.denoise(cube, strength),
            Stage::Dnn => self.learned.denoise(cube, self.sigma),
        }
        self.applied.push(stage);
    }

    fn name(&self) -> String {
        format!("tv-chambolle-2d / {} (scheduled)", self.learned.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sets every voxel to the strength it was called with.
    struct Marker;
    impl Denoiser for Marker {
        fn denoise(&mut self, cube: &mut Cube, strength: f32) {
            cube.as_mut_slice().fill(strength);
        }
        fn name(&self) -> String {
            "marker".into()
        }
    }

    #[test]
    fn calls_follow_the_schedule_with_each_stage_strength() {
        let schedule = DenoiserSchedule {
            warmup: 1,
            dnn_per_cycle: 1,
            tv_per_cycle: 1,
        };
        let mut marker = Marker;
        let mut d = ScheduledDenoiser::new(schedule, 5, &mut marker, 0.25);
        let mut cube = Cube::zeros(2, 4, 4);
        // TV of a constant cube leaves it constant: 0 stays 0
        d.denoise(&mut cube, 0.1);
        assert!(cube.as_slice().iter().all(|&v| v == 0.0));
        // the learned stage gets sigma, not the solver's strength
        d.denoise(&mut cube, 0.1);
        assert!(cube.as_slice().iter().all(|&v| v == 0.25));
        d.denoise(&mut cube, 0.1);
        assert!(cube.as_slice().iter().all(|&v| (v - 0.25).abs() < 1e-6));
        assert_eq!(d.applied(), [Stage::Tv, Stage::Dnn, Stage::Tv]);
    }
}
