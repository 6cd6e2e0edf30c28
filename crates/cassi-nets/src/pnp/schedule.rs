//! Which denoiser each PnP iteration applies.

use serde::{Deserialize, Serialize};

use crate::error::{NetError, Result};

/// The prior step of one iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// Chambolle TV with the solver's strength (the TV weight λ).
    Tv,
    /// The learned denoiser with its fixed noise level σ.
    Dnn,
}

/// TV for the first `warmup` iterations, then repeating cycles of
/// `dnn_per_cycle` learned-denoiser iterations followed by `tv_per_cycle`
/// TV iterations. TV early is cheap and robust while the estimate is far
/// from a clean cube (the network was trained on mild noise); the TV steps
/// between network steps keep it from drifting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct DenoiserSchedule {
    pub warmup: usize,
    pub dnn_per_cycle: usize,
    pub tv_per_cycle: usize,
}

impl DenoiserSchedule {
    /// The paper's (§5.1) and PnP-CASSI's: 83 TV iterations, then cycles of
    /// 3 network + 1 TV (with 124 iterations: 41 alternating ones, 31 of
    /// them the network's).
    pub const PAPER: Self = Self {
        warmup: 83,
        dnn_per_cycle: 3,
        tv_per_cycle: 1,
    };

    /// The stage of 0-based iteration `iteration`.
    pub fn stage(&self, iteration: usize) -> Stage {
        if iteration < self.warmup {
            return Stage::Tv;
        }
        let cycle = self.dnn_per_cycle + self.tv_per_cycle;
        if cycle == 0 || (iteration - self.warmup) % cycle < self.dnn_per_cycle {
            // cycle == 0 is refused by validate; read it as "network only"
            Stage::Dnn
        } else {
            Stage::Tv
        }
    }

    /// The stages of iterations 0 … iterations−1.
    pub fn stages(&self, iterations: usize) -> Vec<Stage> {
        (0..iterations).map(|i| self.stage(i)).collect()
    }

    /// How many of the first `iterations` iterations use `stage`.
    pub fn count(&self, iterations: usize, stage: Stage) -> usize {
        (0..iterations).filter(|&i| self.stage(i) == stage).count()
    }

    pub fn validate(&self) -> Result<()> {
        if self.dnn_per_cycle + self.tv_per_cycle == 0 {
            return Err(NetError::Input {
                what: "PnP denoiser schedule".into(),
                got: format!("{self:?}"),
                expected: "a cycle of at least one iteration (dnn_per_cycle + tv_per_cycle ≥ 1)"
                    .into(),
            });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_papers_schedule_is_83_tv_then_3_dnn_1_tv() {
        let s = DenoiserSchedule::PAPER;
        let stages = s.stages(124);
        assert!(stages[..83].iter().all(|&st| st == Stage::Tv));
        use Stage::{Dnn, Tv};
        assert_eq!(stages[83..91], [Dnn, Dnn, Dnn, Tv, Dnn, Dnn, Dnn, Tv]);
        // PnP-CASSI: from k = 83, the network iff (k − 83) mod 4 < 3
        for (k, &st) in stages.iter().enumerate().skip(83) {
            assert_eq!(st == Dnn, (k - 83) % 4 < 3, "iteration {k}");
        }
        assert_eq!(stages[123], Dnn);
        assert_eq!(s.count(124, Dnn), 31);
        assert_eq!(s.count(124, Tv), 93);
        // fewer iterations than the warm-up: TV only
        assert_eq!(s.count(80, Dnn), 0);
    }

    #[test]
    fn an_empty_cycle_is_refused() {
        let s = DenoiserSchedule {
            warmup: 2,
            dnn_per_cycle: 0,
            tv_per_cycle: 0,
        };
        assert!(s.validate().unwrap_err().to_string().contains("cycle"));
        assert!(DenoiserSchedule::PAPER.validate().is_ok());
        let tv_then_dnn = DenoiserSchedule {
            warmup: 2,
            dnn_per_cycle: 1,
            tv_per_cycle: 0,
        };
        assert_eq!(
            tv_then_dnn.stages(4),
            [Stage::Tv, Stage::Tv, Stage::Dnn, Stage::Dnn]
        );
    }
}
