//! Linear operators as values with `apply` and `adjoint` (BART/SigPy style):
//! solvers are written against this trait, never against CASSI.

use crate::rng::Rng;

/// A real linear map A: R^n → R^m on flat f32 slices.
pub trait LinearOperator: Sync {
    /// n, the length of x.
    fn domain_len(&self) -> usize;
    /// m, the length of y.
    fn range_len(&self) -> usize;
    /// y ← A x (overwrites y).
    fn apply(&self, x: &[f32], y: &mut [f32]);
    /// x ← Aᵀ y (overwrites x).
    fn adjoint(&self, y: &[f32], x: &mut [f32]);
    /// diag(A Aᵀ), length m, where it is cheap to compute.
    fn diag_aat(&self) -> Option<Vec<f32>> {
        None
    }
    /// The diagonal normaliser Φ of the GAP and ADMM data steps
    /// x ← x + τ Aᵀ Φ⁻¹ r (see [`AatNormaliser`]). The default takes
    /// diag(A Aᵀ) as [`NormaliserKind::Approximate`], so the solvers
    /// line-search τ: safe for any A. An operator that knows A Aᵀ is
    /// diagonal says [`NormaliserKind::Exact`]; one with non-negative
    /// entries can return the row sums A Aᵀ 𝟙, a [`NormaliserKind::Majoriser`].
    fn aat_normaliser(&self) -> Option<AatNormaliser> {
        self.diag_aat().map(|phi| AatNormaliser {
            phi,
            kind: NormaliserKind::Approximate,
        })
    }
}

/// An operator whose matrix has no negative entry (light is only moved and
/// attenuated): its row sums A Aᵀ 𝟙 majorise A Aᵀ (Gershgorin), so any
/// composition of such operators has a valid normaliser.
pub trait NonNegativeOperator: LinearOperator {}

/// Φ = A Aᵀ 𝟙 for a non-negative `op`: one adjoint and one apply.
pub fn row_sum_majoriser(op: &dyn LinearOperator) -> AatNormaliser {
    let ones = vec![1.0f32; op.range_len()];
    let mut at1 = vec![0.0f32; op.domain_len()];
    op.adjoint(&ones, &mut at1);
    let mut phi = vec![0.0f32; op.range_len()];
    op.apply(&at1, &mut phi);
    AatNormaliser {
        phi,
        kind: NormaliserKind::Majoriser,
    }
}

/// A diagonal Φ (length m) standing in for A Aᵀ in the data step of GAP and
/// ADMM, and what it is known to be.
#[derive(Debug, Clone, PartialEq)]
pub struct AatNormaliser {
    /// Φ; entries ≤ 0 mark detector pixels no light reaches (GAP ignores
    /// their residual).
    pub phi: Vec<f32>,
    pub kind: NormaliserKind,
}

/// How a normaliser Φ relates to A Aᵀ; it decides the step length τ.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NormaliserKind {
    /// Φ = A Aᵀ (A Aᵀ is diagonal): τ = 1 is GAP's exact projection and
    /// ADMM's exact x-update.
    Exact,
    /// Φ ⪰ A Aᵀ (e.g. the row sums A Aᵀ 𝟙 of a non-negative A, by
    /// Gershgorin): τ = 1 is a stable relaxed step that never overshoots.
    Majoriser,
    /// Neither is known (e.g. diag(A Aᵀ) of a general A): the solvers
    /// line-search τ.
    Approximate,
}

/// The adjoint dot-product test: returns |⟨Ax, y⟩ − ⟨x, Aᵀy⟩| / (‖Ax‖‖y‖)
/// for uniform random x, y drawn from `seed`. An exact adjoint gives ~1e-7
/// (f32 rounding); a wrong one gives O(1).
pub fn adjoint_mismatch(op: &dyn LinearOperator, seed: u64) -> f64 {
    let mut rng = Rng::new(seed);
    let x: Vec<f32> = (0..op.domain_len()).map(|_| rng.uniform() as f32).collect();
    let y: Vec<f32> = (0..op.range_len()).map(|_| rng.uniform() as f32).collect();
    let mut ax = vec![0.0f32; op.range_len()];
    let mut aty = vec![0.0f32; op.domain_len()];
    op.apply(&x, &mut ax);
    op.adjoint(&y, &mut aty);
    let dot = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .map(|(&p, &q)| p as f64 * q as f64)
            .sum::<f64>()
    };
    let lhs = dot(&ax, &y);
    let rhs = dot(&x, &aty);
    let scale = dot(&ax, &ax).sqrt() * dot(&y, &y).sqrt();
    (lhs - rhs).abs() / scale.max(f64::MIN_POSITIVE)
}
