//! GAP and ADMM on the true (mismatched) instrument model, for every
//! dispersion model (issue #13): the adjoint holds, the data step converges
//! to data consistency when A Aᵀ is not diagonal, and reconstructing with the
//! true parameters never loses to the nominal ones on a measurement the
//! fitted operator did not make (2× oversampled simulation, binned: no
//! inverse crime).

use cassi_core::denoise::{NoPrior, TvChambolle2d, TvChambolleParams};
use cassi_core::linop::{AatNormaliser, LinearOperator, NormaliserKind, adjoint_mismatch};
use cassi_core::metrics::psnr;
use cassi_core::optics::{
    BandSpread, CassiOperator, DispersionModel, ModelOperator, NoiseModel, PhysicalSpec,
    SimulationSpec, simulate_oversampled, simulate_physical,
};
use cassi_core::recon::{Model, ModelProblem};
use cassi_core::solvers::{Admm, AdmmParams, Gap, GapParams, History, Silent, Strength};
use cassi_core::synth::{SceneSpec, random_binary_mask, synthetic_scene};
use cassi_core::{Cube, Denoiser, Mask, Mismatch, STANDARD_WAVELENGTHS_NM};

const MODELS: [DispersionModel; 4] = DispersionModel::ALL;

/// The operator of `model` for ψ = `m`.
fn operator(mask: &Mask, bands: usize, m: &Mismatch, model: DispersionModel) -> ModelOperator {
    ModelOperator::new(mask, bands, m, model).unwrap()
}

/// Mismatches with split taps under the subpixel model: the paper's, a
/// non-integer a1 alone (column split only), a tilt alone (row split), a
/// larger mix and a curved dispersion (band 7 of 8 1.5 px off the line).
fn mismatches() -> Vec<(&'static str, Mismatch)> {
    vec![
        ("paper", Mismatch::paper()),
        (
            "a1 2.3",
            Mismatch {
                dx: 0.5,
                a1: 2.3,
                ..Mismatch::nominal(2.0)
            },
        ),
        (
            "alpha 2",
            Mismatch {
                dy: -0.7,
                alpha_deg: 2.0,
                ..Mismatch::nominal(2.0)
            },
        ),
        (
            "mix",
            Mismatch {
                dx: -1.2,
                dy: 0.4,
                theta_deg: -0.5,
                a1: 1.85,
                alpha_deg: -1.5,
                ..Mismatch::nominal(2.0)
            },
        ),
        (
            "curved",
            Mismatch {
                dx: 0.3,
                a1: 2.2,
                alpha_deg: 0.8,
                a2: -0.03,
                ..Mismatch::nominal(2.0)
            },
        ),
    ]
}

fn scene_and_mask(size: usize, bands: usize, seed: u64) -> (Cube, Mask) {
    let wl: Vec<f64> = STANDARD_WAVELENGTHS_NM
        .iter()
        .step_by(28 / bands)
        .take(bands)
        .copied()
        .collect();
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        wavelengths_nm: wl,
        seed,
    })
    .unwrap();
    (
        scene,
        random_binary_mask(size, size, 0.5, seed + 1).unwrap(),
    )
}

/// The normaliser the solvers used before issue #13: diag(A Aᵀ) taken as
/// exact, whatever the operator (kept to show what the fix changes).
struct OldDiag<'a>(&'a CassiOperator);

/// Only apply, adjoint and diag(A Aᵀ): the trait's default normaliser
/// (approximate, line-searched), as a new operator without its own gets.
struct DiagOnly<'a>(&'a CassiOperator);

impl LinearOperator for DiagOnly<'_> {
    fn domain_len(&self) -> usize {
        self.0.domain_len()
    }
    fn range_len(&self) -> usize {
        self.0.range_len()
    }
    fn apply(&self, x: &[f32], y: &mut [f32]) {
        self.0.apply(x, y)
    }
    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        self.0.adjoint(y, x)
    }
    fn diag_aat(&self) -> Option<Vec<f32>> {
        Some(self.0.diag_aat().into_vec())
    }
}

impl LinearOperator for OldDiag<'_> {
    fn domain_len(&self) -> usize {
        self.0.domain_len()
    }
    fn range_len(&self) -> usize {
        self.0.range_len()
    }
    fn apply(&self, x: &[f32], y: &mut [f32]) {
        self.0.apply(x, y)
    }
    fn adjoint(&self, y: &[f32], x: &mut [f32]) {
        self.0.adjoint(y, x)
    }
    fn aat_normaliser(&self) -> Option<AatNormaliser> {
        Some(AatNormaliser {
            phi: self.0.diag_aat().into_vec(),
            kind: NormaliserKind::Exact,
        })
    }
}

fn tv() -> TvChambolle2d {
    TvChambolle2d::new(TvChambolleParams {
        max_iter: 5,
        ..Default::default()
    })
}

fn gap_tv(op: &dyn LinearOperator, y: &[f32], shape: (usize, usize, usize)) -> Cube {
    let params = GapParams {
        strength: Strength::Constant { value: 0.07 },
        ..GapParams::default()
    };
    let mut d = tv();
    Gap::new(params)
        .solve(op, y, shape, &mut d as &mut dyn Denoiser, &mut Silent)
        .unwrap()
        .cube
}

fn admm_tv(op: &dyn LinearOperator, y: &[f32], shape: (usize, usize, usize)) -> Cube {
    let params = AdmmParams {
        strength: Strength::Constant { value: 0.05 },
        ..AdmmParams::default()
    };
    Admm::new(params)
        .solve(op, y, shape, &mut tv(), &mut Silent)
        .unwrap()
        .cube
}

/// zᵀ Φ z ≥ ‖Aᵀ z‖² for `draws` random z (Φ ⪰ A Aᵀ; equality when exact).
fn assert_majorises(
    op: &dyn LinearOperator,
    phi: &[f32],
    rng: &mut cassi_core::Rng,
    draws: usize,
    what: &str,
) {
    let mut at = vec![0.0f32; op.domain_len()];
    for _ in 0..draws {
        let z: Vec<f32> = (0..op.range_len())
            .map(|_| rng.uniform() as f32 - 0.5)
            .collect();
        op.adjoint(&z, &mut at);
        let lhs: f64 = z
            .iter()
            .zip(phi)
            .map(|(&a, &p)| a as f64 * a as f64 * p as f64)
            .sum();
        let rhs: f64 = at.iter().map(|&a| a as f64 * a as f64).sum();
        assert!(
            lhs >= rhs * (1.0 - 1e-5),
            "{what}: zᵀΦz {lhs} < ‖Aᵀz‖² {rhs}"
        );
    }
}

#[test]
fn the_true_operators_are_adjoint_and_their_normaliser_majorises_aat() {
    let (_, mask) = scene_and_mask(24, 8, 3);
    let mut rng = cassi_core::Rng::new(11);
    for (name, m) in mismatches() {
        for model in MODELS {
            let op = operator(&mask, 8, &m, model);
            let e = adjoint_mismatch(&op, 7);
            assert!(e < 1e-5, "{name} {model:?}: adjoint mismatch {e}");
            let n = op.aat_normaliser().unwrap();
            let exact = n.kind == NormaliserKind::Exact;
            assert_eq!(exact, model == DispersionModel::Rounded, "{name} {model:?}");
            if exact {
                assert_eq!(Some(n.phi.clone()), op.diag_aat());
            }
            assert_majorises(&op, &n.phi, &mut rng, 5, &format!("{name} {model:?}"));
        }
    }
}

#[test]
fn gap_and_admm_reach_data_consistency_on_every_true_operator() {
    let (scene, mask) = scene_and_mask(32, 8, 4);
    for (name, m) in mismatches() {
        for model in MODELS {
            let op = operator(&mask, 8, &m, model);
            let y = op.forward(&scene).unwrap().into_vec();
            let shape = op.cube_shape();
            // the tapped models also through the trait's default normaliser
            // (the crisp-cell model has no diag(A Aᵀ) to give it)
            let diag_only = op.sharp().map(DiagOnly);
            let mut ops: Vec<(&str, &dyn LinearOperator)> = vec![("own", &op)];
            if let Some(d) = &diag_only {
                ops.push(("diag, line search", d));
            }
            for ((normaliser, op), accelerate) in
                ops.into_iter().flat_map(|o| [(o, false), (o, true)])
            {
                let mut h = History::default();
                let params = GapParams {
                    iterations: 60,
                    accelerate,
                    nonnegative: false,
                    ..GapParams::default()
                };
                let sol = Gap::new(params)
                    .solve(op, &y, shape, &mut NoPrior, &mut h)
                    .unwrap();
                let r: Vec<f64> = h.iterations.iter().map(|i| i.relative_residual).collect();
                eprintln!(
                    "GAP {name:8} {model:?} {normaliser} accelerate {accelerate}: residual {:.2e} → {:.2e} (final {:.2e})",
                    r[0],
                    r[r.len() - 1],
                    sol.relative_residual
                );
                // the damped line search (fallback for operators without a
                // normaliser of their own) converges more slowly
                let bound = if normaliser == "own" { 1e-2 } else { 5e-2 };
                assert!(
                    sol.relative_residual < bound,
                    "{name} {model:?} {normaliser} accelerate {accelerate}: residual {}",
                    sol.relative_residual
                );
                if !accelerate && normaliser == "own" {
                    // plain GAP with Φ ⪰ A Aᵀ: the residual never grows (the
                    // line search only promises to approach the projection)
                    assert!(
                        r.windows(2).all(|w| w[1] <= w[0] * (1.0 + 1e-3) + 1e-6),
                        "{name} {model:?}: residual not monotone {r:?}"
                    );
                }
                assert!(
                    r[r.len() - 1] < r[0] / 50.0,
                    "{name} {model:?} {normaliser}"
                );
            }
            let mut h = History::default();
            let sol = Admm::new(AdmmParams {
                iterations: 60,
                nonnegative: false,
                ..AdmmParams::default()
            })
            .solve(&op, &y, shape, &mut NoPrior, &mut h)
            .unwrap();
            eprintln!(
                "ADMM {name:8} {model:?}: residual {:.2e} → {:.2e}",
                h.iterations[0].relative_residual, sol.relative_residual
            );
            assert!(sol.relative_residual < 0.05, "{name} {model:?} ADMM");
            assert!(sol.relative_residual < h.iterations[0].relative_residual / 5.0);
        }
    }
}

#[test]
fn the_true_model_never_loses_to_the_nominal_one() {
    let (scene, mask) = scene_and_mask(64, 8, 1);
    let (l, h, w) = scene.shape();
    let mut failures = Vec::new();
    let mut old_losses = 0;
    for (name, m) in mismatches() {
        for model in MODELS {
            for noisy in [false, true] {
                let spec = SimulationSpec {
                    mismatch: m,
                    model,
                    noise: noisy.then(NoiseModel::default),
                };
                let y = simulate_oversampled(&scene, &mask, &spec, 2).unwrap();
                let problem = |psi: Mismatch| {
                    let assumed = Model::new(&mask, l, 2.0, psi, model).unwrap();
                    ModelProblem::new(&y, &assumed).unwrap()
                };
                let (nominal, truth) = (problem(Mismatch::nominal(2.0)), problem(m));
                let score = |c: &Cube| psnr(&scene, &c.clipped_to_unit()).unwrap();
                let ys = |p: &ModelProblem| p.y.as_slice().to_vec();
                let (yn, yt) = (ys(&nominal), ys(&truth));
                let shape = (l, h, w);
                // the normaliser before issue #13, for the tapped models
                let old = truth.op.sharp().map(OldDiag);
                let old_score = |solve: fn(&dyn LinearOperator, &[f32], _) -> Cube| {
                    old.as_ref()
                        .map_or(f64::NAN, |o| score(&solve(o, &yt, shape)))
                };
                let rows = [
                    (
                        "GAP-TV",
                        score(&gap_tv(&nominal.op, &yn, shape)),
                        score(&gap_tv(&truth.op, &yt, shape)),
                        old_score(gap_tv),
                    ),
                    (
                        "ADMM-TV",
                        score(&admm_tv(&nominal.op, &yn, shape)),
                        score(&admm_tv(&truth.op, &yt, shape)),
                        old_score(admm_tv),
                    ),
                ];
                for (method, nom, tru, old) in rows {
                    eprintln!(
                        "{method:8} {name:8} {model:?} noisy {noisy}: nominal {nom:.2} dB, true {tru:.2} dB (old diag normaliser {old:.2} dB)"
                    );
                    if model == DispersionModel::Rounded {
                        // A Aᵀ diagonal: the same normaliser, bit for bit
                        assert_eq!(tru, old, "{method} {name}: rounded changed");
                    }
                    old_losses += (old < nom) as usize;
                    if tru < nom {
                        failures.push(format!(
                            "{method} {name} {model:?} noisy {noisy}: {tru:.2} < {nom:.2}"
                        ));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "the true model lost: {failures:#?}");
    // and this test sees issue #13: with diag(A Aᵀ) as if exact, the true
    // subpixel model lost to the nominal one (GAP-TV on "mix", ADMM-TV on all)
    assert!(
        old_losses >= 8,
        "old normaliser lost only {old_losses} times"
    );
}

/// Each band's light spread along the dispersion (`BandSpread`, a real
/// camera's continuous spectrum), in every model family, sharp or blurred:
/// the adjoint holds, the normaliser majorises A Aᵀ, and GAP reaches data
/// consistency.
#[test]
fn every_band_spread_keeps_the_adjoint_the_normaliser_and_convergence() {
    let (scene, mask) = scene_and_mask(32, 8, 6);
    let mut rng = cassi_core::Rng::new(12);
    let (_, m) = mismatches().swap_remove(3);
    for spread in [BandSpread::Uniform, BandSpread::Linear] {
        for model in MODELS {
            for sigma in [0.0, 0.45] {
                let psi = Mismatch {
                    blur_sigma_px: sigma,
                    ..m
                };
                let op = Model::new(&mask, 8, 2.0, psi, model)
                    .unwrap()
                    .with_band_spread(spread)
                    .operator()
                    .unwrap();
                let what = format!("{spread:?} {model:?} σ {sigma}");
                // the spread is in it: not the point model's operator
                assert!(
                    op.blur().is_some() || model == DispersionModel::CrispCells,
                    "{what}"
                );
                let e = adjoint_mismatch(&op, 9);
                assert!(e < 1e-5, "{what}: adjoint mismatch {e}");
                let n = op.aat_normaliser().unwrap();
                assert_majorises(&op, &n.phi, &mut rng, 3, &what);
                let y = op.forward(&scene).unwrap().into_vec();
                let sol = Gap::new(GapParams {
                    iterations: 60,
                    nonnegative: false,
                    ..GapParams::default()
                })
                .solve(&op, &y, op.cube_shape(), &mut NoPrior, &mut Silent)
                .unwrap();
                assert!(
                    sol.relative_residual < 2e-2,
                    "{what}: GAP residual {}",
                    sol.relative_residual
                );
            }
        }
    }
}

/// On an instrument whose bands spread (the 4× physical simulator, crisp
/// mask, blur, noise: no inverse crime), GAP-TV and ADMM-TV with the model
/// that spreads them at the true ψ never lose to the point model at the
/// same ψ, nor to the spread model at the nominal ψ.
#[test]
fn the_spread_model_never_loses_to_the_point_model_on_a_spread_instrument() {
    let (scene, mask) = scene_and_mask(64, 8, 2);
    let (l, h, w) = scene.shape();
    let wl: Vec<f64> = STANDARD_WAVELENGTHS_NM
        .iter()
        .step_by(28 / l)
        .take(l)
        .copied()
        .collect();
    let truth = Mismatch {
        dx: 0.4,
        dy: -0.3,
        a1: 2.04,
        blur_sigma_px: 0.35,
        ..Mismatch::nominal(2.0)
    };
    let mut failures = Vec::new();
    for spread in [BandSpread::Uniform, BandSpread::Linear] {
        let spec = PhysicalSpec {
            oversample: 4,
            blur_sigma_px: truth.blur_sigma_px,
            band_spread: spread,
            ..PhysicalSpec::default()
        };
        let noise = NoiseModel {
            photon_peak: Some(2e4),
            read_noise: 3.0,
            seed: 4,
        };
        let y = simulate_physical(&scene, &mask, &wl, &truth, &spec, Some(&noise)).unwrap();
        let model = DispersionModel::DispersedMask;
        let score = |psi: Mismatch,
                     spread: BandSpread,
                     solve: fn(&dyn LinearOperator, &[f32], _) -> Cube| {
            let assumed = Model::new(&mask, l, 2.0, psi, model)
                .unwrap()
                .with_band_spread(spread);
            let p = ModelProblem::new(&y, &assumed).unwrap();
            psnr(
                &scene,
                &solve(&p.op, p.y.as_slice(), (l, h, w)).clipped_to_unit(),
            )
            .unwrap()
        };
        for (method, solve) in [
            (
                "GAP-TV",
                gap_tv as fn(&dyn LinearOperator, &[f32], _) -> Cube,
            ),
            ("ADMM-TV", admm_tv),
        ] {
            let spread_true = score(truth, spread, solve);
            let point_true = score(truth, BandSpread::Point, solve);
            let spread_nominal = score(Mismatch::nominal(2.0), spread, solve);
            eprintln!(
                "{method} {spread:?}: spread model at ψ {spread_true:.2} dB, point model at ψ \
                 {point_true:.2} dB, spread model at the nominal ψ {spread_nominal:.2} dB"
            );
            if spread_true < point_true || spread_true < spread_nominal {
                failures.push(format!("{method} {spread:?}"));
            }
        }
    }
    assert!(failures.is_empty(), "the spread model lost: {failures:?}");
}
