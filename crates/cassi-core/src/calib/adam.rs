//! Adam with a cosine-annealed learning rate and gradient-norm clipping,
//! as the paper's Stage 2 uses it (PyTorch semantics: `Adam` defaults,
//! `CosineAnnealingLR` stepped after every update, `clip_grad_norm_`).

use serde::{Deserialize, Serialize};

use super::objective::Objective;
use super::stages::Scored;

/// One Adam run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AdamSettings {
    pub steps: usize,
    /// Initial learning rate per coordinate.
    pub lr: Vec<f64>,
    /// Learning rate the cosine schedule ends at.
    pub lr_min: f64,
    /// Largest joint L2 norm of the gradient; larger ones are scaled down.
    pub clip_norm: f64,
    pub beta1: f64,
    pub beta2: f64,
    pub eps: f64,
}

impl AdamSettings {
    /// PyTorch's defaults (β = (0.9, 0.999), ε = 1e-8) with the paper's
    /// clipping at 0.5.
    pub fn new(steps: usize, lr: Vec<f64>, lr_min: f64) -> Self {
        Self {
            steps,
            lr,
            lr_min,
            clip_norm: 0.5,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
        }
    }

    /// Learning rate at step i (0-based): η_min + (η₀ − η_min)(1 + cos(πi/T))/2.
    pub fn lr_at(&self, lr0: f64, i: usize) -> f64 {
        let t = i as f64 / self.steps.max(1) as f64;
        self.lr_min + (lr0 - self.lr_min) * 0.5 * (1.0 + (std::f64::consts::PI * t).cos())
    }
}

/// Minimises with `value_and_gradient`, projecting onto the feasible set with
/// `project` after every step. Returns the **last** iterate (as the paper
/// does, not the best seen) and the value at the last evaluated point.
pub fn adam(
    x0: &[f64],
    settings: &AdamSettings,
    mut value_and_gradient: impl FnMut(&[f64]) -> (f64, Vec<f64>),
    project: impl Fn(&mut [f64]),
) -> (Vec<f64>, f64) {
    let n = x0.len();
    assert_eq!(settings.lr.len(), n, "one learning rate per coordinate");
    let mut x = x0.to_vec();
    let (mut m, mut v) = (vec![0.0; n], vec![0.0; n]);
    let mut last = f64::NAN;
    for i in 0..settings.steps {
        let (f, mut g) = value_and_gradient(&x);
        last = f;
        let norm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm > settings.clip_norm {
            let c = settings.clip_norm / (norm + 1e-6);
            g.iter_mut().for_each(|v| *v *= c);
        }
        let t = (i + 1) as i32;
        let (b1t, b2t) = (1.0 - settings.beta1.powi(t), 1.0 - settings.beta2.powi(t));
        for j in 0..n {
            m[j] = settings.beta1 * m[j] + (1.0 - settings.beta1) * g[j];
            v[j] = settings.beta2 * v[j] + (1.0 - settings.beta2) * g[j] * g[j];
            let lr = settings.lr_at(settings.lr[j], i);
            x[j] -= lr * (m[j] / b1t) / ((v[j] / b2t).sqrt() + settings.eps);
        }
        project(&mut x);
    }
    (x, last)
}

/// [`adam`] over a differentiable `objective`'s free parameters from its
/// base, projected onto its bounds after every step: the last iterate's ψ
/// and the score at the last evaluated point.
pub(crate) fn minimise(objective: &Objective, settings: &AdamSettings) -> Scored {
    let (x, score) = adam(
        &objective.start(),
        settings,
        |v| objective.value_and_gradient(v),
        |v| objective.project(v),
    );
    Scored {
        parameters: objective.psi(&x),
        score,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_schedule_runs_from_lr0_to_lr_min() {
        let s = AdamSettings::new(50, vec![0.05], 0.002);
        assert_eq!(s.lr_at(0.05, 0), 0.05);
        assert!((s.lr_at(0.05, 25) - 0.026).abs() < 1e-12);
        assert!((s.lr_at(0.05, 50) - 0.002).abs() < 1e-12);
    }

    #[test]
    fn adam_reaches_the_minimum_of_an_ill_scaled_quadratic_within_the_box() {
        // f = 1e4 (x − 1)² + (y + 0.5)²: gradients up to 2e4, clipped to 0.5
        let s = AdamSettings::new(80, vec![0.05, 0.05], 0.001);
        let (x, _) = adam(
            &[0.0, 0.0],
            &s,
            |x| {
                let f = 1e4 * (x[0] - 1.0).powi(2) + (x[1] + 0.5).powi(2);
                (f, vec![2e4 * (x[0] - 1.0), 2.0 * (x[1] + 0.5)])
            },
            |x| x[1] = x[1].max(-0.3),
        );
        assert!((x[0] - 1.0).abs() < 0.01, "{x:?}");
        assert_eq!(x[1], -0.3, "projected onto the box");
    }
}
