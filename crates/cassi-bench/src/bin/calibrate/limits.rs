//! `--limits`: where the blind calibration stands against what the data
//! allow. Per case, two measurements with the TRUE scene known:
//!
//! * the oracle-scene fit: ψ minimising f(ψ) = min_s ‖y − s·A_ψ x‖² / N
//!   (A_ψ the calibrated model's [`ModelOperator`] with ψ's blur, its output cropped
//!   or zero-padded to the detector; s in closed form), Nelder–Mead over all
//!   six parameters (σ as |σ|) from the blind estimate, restarted at its
//!   best point while a restart still lowers f. The physical
//!   simulator integrates a bilinearly interpolated scene over pixel areas,
//!   so the scene it effectively sees is slightly smoother than `x`: that
//!   model error is part of this limit and is left in;
//! * the Cramér–Rao bound at the noise level: the Fisher matrix of the
//!   scene-known model at the true ψ (central differences; one-sided for σ
//!   below its step), with the scale s as a nuisance parameter, under the
//!   simulator's noise (Poisson at `photon_peak` e⁻ on the clean maximum,
//!   Gaussian read noise in e⁻); CRB = sqrt(diag(F⁻¹)) of the six ψ rows;
//! * the error budget of the blind texture fit: the same fit
//!   ([`texture_fit`], from the blind estimate) with its scene estimate x̃
//!   replaced step by step — the proxy reconstruction at the TRUE ψ
//!   (smoothed as shipped: what remains once the front end's ψ no longer
//!   shapes x̃), the true scene smoothed as shipped (what remains once x̃ is
//!   the scene), the true scene unsmoothed (the texture objective itself);
//! * the scene fit's objective (its first pass's score, the coarse scene
//!   solved cold at each point: [`scene_fit_score`]) at the truth, at the
//!   first pass's answer, at the final one and one pixel from the first
//!   pass's answer along dx and a1 (six probes). Where the truth scores
//!   lower than the first pass's answer, a miss is the search's (a start
//!   on the wrong side of a ridge); where it scores higher, the objective
//!   itself prefers the miss.

use std::time::Instant;

use cassi_bench::{predict_with, psi_of};
use cassi_core::calib::{
    CalibrationProblem, DefaultPreset, SCENE_SMOOTH_PX, SceneEstimate, SceneFitSettings,
    coarse_scene_of, gap_tv_reconstruction, gaussian_taps, nelder_mead, scene_fit_score,
    smooth_bands, texture_fit,
};
use cassi_core::denoise::{TvChambolleParams, TvScratch2d, tv_chambolle_2d};
use cassi_core::linop::LinearOperator;
use cassi_core::optics::{DispersionModel, GaussianBlur, ModelOperator};
use cassi_core::recon::Model;
use cassi_core::{Cube, Measurement, Mismatch, Parameter};
use serde_json::{Value, json};

use super::{per_parameter, tolerance};

/// Nelder–Mead's initial steps per parameter (Parameter::CALIBRATED order).
const ORACLE_STEPS: [f64; 6] = [0.1, 0.1, 0.05, 0.005, 0.1, 0.1];
const ORACLE_MAX_EVALS: usize = 400;
const ORACLE_F_TOL: f64 = 1e-10;
/// Restarts (fresh simplex at the best point, same steps) after the first
/// leg, until a leg improves f by less than ORACLE_RESTART_GAIN (relative).
const ORACLE_MAX_RESTARTS: usize = 2;
const ORACLE_RESTART_GAIN: f64 = 1e-6;
/// Central-difference steps of the Jacobian (Parameter::CALIBRATED order).
const CRB_STEPS: [f64; 6] = [0.01, 0.01, 0.01, 0.0005, 0.01, 0.01];

/// The detector's noise, as the simulator applies it (noise.rs).
#[derive(Debug, Clone, Copy)]
pub struct DetectorNoise {
    pub photon_peak: f64,
    pub read_noise_e: f64,
}

/// The scene-known forward model ψ ↦ A_ψ x on the detector's grid, in
/// the calibrated model (its family and what it holds beside ψ: band
/// offsets, band spread).
struct SceneKnown<'a> {
    instrument: Model<'a>,
    scene: &'a Cube,
    rows: usize,
    cols: usize,
}

impl SceneKnown<'_> {
    /// A_ψ x cropped / zero-padded to rows × cols, or `None` for a ψ the
    /// operator rejects.
    fn model(&self, psi: &Mismatch) -> Option<Vec<f64>> {
        predict_with(&self.instrument, self.scene, psi, (self.rows, self.cols))
    }
}

fn vector_of(psi: &Mismatch) -> Vec<f64> {
    Parameter::CALIBRATED.iter().map(|p| p.get(psi)).collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// min_s ‖y − s·m‖² / N and the optimal s.
fn scaled_residual(y: &[f64], m: &[f64]) -> (f64, f64) {
    let (ym, mm) = (dot(y, m), dot(m, m));
    let s = if mm > 0.0 { ym / mm } else { 0.0 };
    let r = dot(y, y) - s * ym;
    (r.max(0.0) / y.len() as f64, s)
}

fn as_f64(y: &Measurement) -> Vec<f64> {
    y.as_slice().iter().map(|&v| v as f64).collect()
}

/// The oracle-scene objective at ψ (∞ where the operator rejects ψ).
fn objective(model: &SceneKnown, y: &[f64], psi: &Mismatch) -> f64 {
    model
        .model(psi)
        .map_or(f64::INFINITY, |m| scaled_residual(y, &m).0)
}

/// The oracle-scene fit from `start`; its JSON record against `truth`.
fn oracle_fit(model: &SceneKnown, y: &[f64], start: &Mismatch, truth: &Mismatch) -> Value {
    let t = Instant::now();
    let x_tol: Vec<f64> = ORACLE_STEPS.iter().map(|s| s * 1e-3).collect();
    let leg = |x0: &[f64]| {
        nelder_mead(
            |x| objective(model, y, &psi_of(start, x)),
            x0,
            &ORACLE_STEPS,
            ORACLE_MAX_EVALS,
            &x_tol,
            ORACLE_F_TOL,
        )
    };
    let (mut x, mut f, mut evals) = leg(&vector_of(start));
    let mut legs = 1;
    while legs <= ORACLE_MAX_RESTARTS {
        let (xn, fnew, en) = leg(&x);
        evals += en;
        legs += 1;
        let gain = (f - fnew) / f.abs().max(f64::MIN_POSITIVE);
        if fnew < f {
            (x, f) = (xn, fnew);
        }
        if gain < ORACLE_RESTART_GAIN {
            break;
        }
    }
    let est = psi_of(start, &x);
    let err = |p: Parameter| p.get(&est) - p.get(truth);
    json!({
        "estimate": per_parameter(|p| json!(p.get(&est))),
        "error": per_parameter(|p| json!(err(p))),
        "within_tolerance": per_parameter(|p| json!(err(p).abs() <= tolerance(p))),
        "all_within_tolerance": Parameter::CALIBRATED.iter().all(|&p| err(p).abs() <= tolerance(p)),
        "objective": f,
        "objective_at_truth": objective(model, y, truth),
        "objective_at_start": objective(model, y, start),
        "evaluations": evals,
        "nelder_mead_legs": legs,
        "seconds": t.elapsed().as_secs_f64(),
    })
}

/// ∂m/∂p at ψ by central differences (one-sided for σ below its step).
fn derivative(model: &SceneKnown, psi: &Mismatch, p: Parameter, h: f64) -> Option<Vec<f64>> {
    let at = |v: f64| {
        let mut q = *psi;
        p.set(&mut q, v);
        model.model(&q)
    };
    let v = p.get(psi);
    let (lo, hi) = if p == Parameter::BlurSigmaPx && v < h {
        (v, v + h)
    } else {
        (v - h, v + h)
    };
    let (a, b) = (at(lo)?, at(hi)?);
    Some(a.iter().zip(&b).map(|(a, b)| (b - a) / (hi - lo)).collect())
}

/// The inverse of a symmetric positive-definite matrix (Gauss–Jordan with
/// partial pivoting); `None` when singular.
fn invert(mut a: Vec<Vec<f64>>) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let mut inv: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| f64::from(i == j)).collect())
        .collect();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        inv.swap(col, piv);
        let d = a[col][col];
        for j in 0..n {
            a[col][j] /= d;
            inv[col][j] /= d;
        }
        for i in (0..n).filter(|&i| i != col) {
            let f = a[i][col];
            for j in 0..n {
                a[i][j] -= f * a[col][j];
                inv[i][j] -= f * inv[col][j];
            }
        }
    }
    Some(inv)
}

/// The CRB per parameter at `truth` for the clean measurement `clean`
/// under `noise`; the scale s is a seventh (nuisance) parameter.
fn crb(model: &SceneKnown, clean: &[f64], truth: &Mismatch, noise: DetectorNoise) -> Value {
    let Some(m0) = model.model(truth) else {
        return json!(null);
    };
    let (_, s) = scaled_residual(clean, &m0);
    let mut columns: Vec<Vec<f64>> = Vec::new();
    for (&p, &h) in Parameter::CALIBRATED.iter().zip(&CRB_STEPS) {
        let Some(d) = derivative(model, truth, p, h) else {
            return json!(null);
        };
        columns.push(d.into_iter().map(|v| s * v).collect());
    }
    columns.push(m0);
    let peak = clean.iter().copied().fold(0.0f64, f64::max);
    let k = noise.photon_peak / peak;
    let read2 = noise.read_noise_e * noise.read_noise_e;
    let weight: Vec<f64> = clean
        .iter()
        .map(|&c| k * k / (c.max(0.0) * k + read2))
        .collect();
    let n = columns.len();
    let fisher: Vec<Vec<f64>> = (0..n)
        .map(|a| {
            (0..n)
                .map(|b| {
                    (0..weight.len())
                        .map(|i| columns[a][i] * columns[b][i] * weight[i])
                        .sum()
                })
                .collect()
        })
        .collect();
    let Some(inv) = invert(fisher) else {
        return json!(null);
    };
    per_parameter(|p| {
        let i = Parameter::CALIBRATED
            .iter()
            .position(|&q| q == p)
            .unwrap_or(0);
        let v = inv[i][i];
        json!((v > 0.0).then(|| v.sqrt()))
    })
}

/// Both limit measurements of one case: `y` its (noisy) measurement,
/// `clean` the same without noise, `blind` the blind calibration's ψ,
/// `instrument` the calibrated model (the problem's).
pub fn measure(
    y: &Measurement,
    clean: &Measurement,
    scene: &Cube,
    instrument: Model,
    blind: &Mismatch,
    truth: &Mismatch,
    noise: DetectorNoise,
) -> Value {
    let (rows, cols) = y.shape();
    let model = SceneKnown {
        instrument,
        scene,
        rows,
        cols,
    };
    let oracle = oracle_fit(&model, &as_f64(y), blind, truth);
    let t = Instant::now();
    let bound = crb(&model, &as_f64(clean), truth, noise);
    json!({ "oracle_scene": oracle, "crb": bound, "crb_seconds": t.elapsed().as_secs_f64() })
}

/// `--limits-gap-tv FAMILY`: the scene-known fit (as [`measure`]'s, in
/// `family`, from the blind estimate) with GAP-TV's reconstruction of `y`
/// in place of the true scene — made in the calibrated model at the truth
/// (the best a reconstruct-then-fit round could reach with this
/// reconstruction) and at the blind estimate (one such round, what a
/// blind pipeline could run). `gap_iterations` GAP-TV iterations.
pub fn gap_tv_scene_fits(
    problem: &CalibrationProblem<'_>,
    blind: &Mismatch,
    truth: &Mismatch,
    family: DispersionModel,
    gap_iterations: usize,
) -> anyhow::Result<Value> {
    let y = problem.measurement;
    let (rows, cols) = y.shape();
    let mut out = serde_json::Map::new();
    let keys = [
        ("at_truth", truth, false),
        ("at_estimate", blind, false),
        ("at_estimate_without_imprint", blind, true),
    ];
    for (key, at, unprinted) in keys {
        let t = Instant::now();
        let mut scene = gap_tv_reconstruction(problem, at, gap_iterations)?;
        if unprinted {
            remove_imprint(problem, at, &mut scene)?;
        }
        let gap_seconds = t.elapsed().as_secs_f64();
        let known = SceneKnown {
            instrument: problem.nominal.with_dispersion(family),
            scene: &scene,
            rows,
            cols,
        };
        let mut fit = oracle_fit(&known, &as_f64(y), blind, truth);
        fit["gap_tv_seconds"] = json!(gap_seconds);
        out.insert(key.into(), fit);
    }
    Ok(json!({
        "family": family,
        "gap_tv_iterations": gap_iterations,
        "fits": out,
    }))
}

/// What the scene-known fit of [`told_scene_fits`] is told of the
/// scene: every band smoothed by a Gaussian (`--limits-smoothed-scene PX`)
/// or TV-denoised (`--limits-tv-scene WEIGHT`: Chambolle's isotropic 2-D TV
/// per band, skimage's weight and defaults — edges kept, texture below
/// the edges' scale flattened).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KnownScene {
    Smoothed {
        px: f64,
    },
    TvDenoised {
        weight: f64,
    },
    /// Every pixel's spectrum through `nodes` evenly spaced spectral nodes
    /// (`--limits-spectral-scene NODES`), piecewise linear between them as
    /// the scene fit's coarse scene is, at full spatial resolution: what
    /// the coarse scene's spectral basis leaves out, alone.
    SpectralNodes {
        nodes: usize,
    },
    /// The same through `nodes` bands placed where the scene's own
    /// spectra bend (`--limits-placed-spectral-scene NODES`: the first and
    /// last band and those between that leave the least squared
    /// interpolation error over the scene): what a basis of that size
    /// placed for the scene would leave out.
    PlacedSpectralNodes {
        nodes: usize,
    },
}

impl KnownScene {
    /// The scene as the fit is told it, and what the record says of the
    /// telling (the width, weight or nodes; the placed nodes' bands).
    fn told(self, scene: &Cube) -> (Cube, Value) {
        let (bands, h, w) = scene.shape();
        match self {
            KnownScene::Smoothed { px } => {
                let mut smoothed = scene.clone().into_vec();
                smooth_bands(&mut smoothed, h, w, &gaussian_taps(px as f32));
                let told = Cube::from_vec(bands, h, w, smoothed).expect("the scene's own shape");
                (told, json!({ "smooth_px": px }))
            }
            KnownScene::TvDenoised { weight } => {
                let mut denoised = scene.clone();
                tv_chambolle_2d(
                    &mut denoised,
                    weight as f32,
                    &TvChambolleParams::default(),
                    &mut TvScratch2d::default(),
                );
                (denoised, json!({ "tv_weight": weight }))
            }
            // the scene fit's own basis on 1-px cells: its spectral
            // interpolation alone
            KnownScene::SpectralNodes { nodes } => {
                let basis = SceneFitSettings {
                    cell_px: 1,
                    spectral_nodes: nodes,
                    ..SceneFitSettings::default()
                };
                (
                    coarse_scene_of(scene, &basis),
                    json!({ "spectral_nodes": nodes }),
                )
            }
            KnownScene::PlacedSpectralNodes { nodes } => {
                let at = placed_band_nodes(scene, nodes);
                let told = Cube::from_vec(bands, h, w, through_band_nodes(scene, &at))
                    .expect("the scene's own shape");
                let record = json!({ "spectral_nodes": nodes, "spectral_nodes_at_bands": at });
                (told, record)
            }
        }
    }
}

/// `scene` with every pixel's spectrum interpolated linearly between its
/// values at the bands `at` (ascending, the first band and the last among
/// them; the bands there kept).
fn through_band_nodes(scene: &Cube, at: &[usize]) -> Vec<f32> {
    let (bands, h, w) = scene.shape();
    let plane = h * w;
    let x = scene.as_slice();
    let mut out = x.to_vec();
    for pair in at.windows(2) {
        let (i, j) = (pair[0], pair[1]);
        for k in i + 1..j.min(bands) {
            let f = (k - i) as f32 / (j - i) as f32;
            for p in 0..plane {
                let (a, b) = (x[i * plane + p], x[j * plane + p]);
                out[k * plane + p] = a + f * (b - a);
            }
        }
    }
    out
}

/// The `nodes` bands (the first and the last among them) between which
/// linear interpolation leaves the least squared error over `scene`'s
/// spectra: dynamic programming over the segments' errors.
fn placed_band_nodes(scene: &Cube, nodes: usize) -> Vec<usize> {
    let (bands, h, w) = scene.shape();
    let plane = h * w;
    let x = scene.as_slice();
    if nodes >= bands || bands < 3 {
        return (0..bands).collect();
    }
    let nodes = nodes.max(2);
    // err[i][j]: the squared error of the bands strictly between i and j
    let mut err = vec![vec![0.0f64; bands]; bands];
    for i in 0..bands {
        for j in i + 2..bands {
            let mut e = 0.0f64;
            for k in i + 1..j {
                let f = (k - i) as f32 / (j - i) as f32;
                for p in 0..plane {
                    let (a, b) = (x[i * plane + p], x[j * plane + p]);
                    let d = (x[k * plane + p] - (a + f * (b - a))) as f64;
                    e += d * d;
                }
            }
            err[i][j] = e;
        }
    }
    // best[m][j]: the least error of m segments from band 0 ending at j
    let segments = nodes - 1;
    let mut best = vec![vec![f64::INFINITY; bands]; segments + 1];
    let mut from = vec![vec![0usize; bands]; segments + 1];
    best[0][0] = 0.0;
    for m in 1..=segments {
        for j in m..bands {
            for i in m - 1..j {
                let e = best[m - 1][i] + err[i][j];
                if e < best[m][j] {
                    best[m][j] = e;
                    from[m][j] = i;
                }
            }
        }
    }
    let mut at = vec![bands - 1];
    let mut j = bands - 1;
    for m in (1..=segments).rev() {
        j = from[m][j];
        at.push(j);
    }
    at.reverse();
    at
}

/// `--limits-smoothed-scene PX` / `--limits-tv-scene WEIGHT`: the
/// scene-known fit (as [`measure`]'s, in the calibrated model, from the
/// blind estimate) with the true scene and with the scene as `known` tells it:
/// every band smoothed by a Gaussian of σ PX (edge-replicating, so the
/// frame's borders keep their light) — how far a fit would get that knew
/// the scene down to that scale and nothing finer — or TV-denoised, which
/// keeps the edges and flattens the texture between them. Where the told
/// fit misses as the blind one does, the miss is what the telling left
/// out. The record holds the told scene's RMS difference from the scene
/// (and the scene's RMS), to set the two kinds side by side; its fits keep
/// the keys of the Gaussian kind's first records (`smoothed_scene` for
/// the told scene, whichever kind).
pub fn told_scene_fits(
    y: &Measurement,
    scene: &Cube,
    instrument: Model,
    blind: &Mismatch,
    truth: &Mismatch,
    known: KnownScene,
) -> Value {
    let (rows, cols) = y.shape();
    let (told, telling) = known.told(scene);
    let rms = |v: &[f32], from: Option<&[f32]>| {
        let sum: f64 = match from {
            Some(b) => v
                .iter()
                .zip(b)
                .map(|(&a, &b)| ((a - b) as f64).powi(2))
                .sum(),
            None => v.iter().map(|&a| (a as f64).powi(2)).sum(),
        };
        (sum / v.len().max(1) as f64).sqrt()
    };
    let change = rms(told.as_slice(), Some(scene.as_slice()));
    let level = rms(scene.as_slice(), None);
    let y = as_f64(y);
    let mut out = serde_json::Map::new();
    for (key, known) in [("true_scene", scene), ("smoothed_scene", &told)] {
        let model = SceneKnown {
            instrument,
            scene: known,
            rows,
            cols,
        };
        out.insert(key.into(), oracle_fit(&model, &y, blind, truth));
    }
    let mut record = json!({
        "family": instrument.dispersion(),
        "scene_rms": level,
        "told_scene_rms_change": change,
        "fits": out,
    });
    if let (Some(record), Value::Object(telling)) = (record.as_object_mut(), telling) {
        record.extend(telling);
    }
    record
}

/// Each parameter's name and signed error from an `error` record, on one
/// line (`dx +0.0123  dy -0.0040  …`).
pub fn error_line(e: &Value) -> String {
    Parameter::CALIBRATED
        .iter()
        .map(|p| {
            format!(
                "{} {:+.4}",
                p.name(),
                e[p.key()].as_f64().unwrap_or(f64::NAN)
            )
        })
        .collect::<Vec<_>>()
        .join("  ")
}

/// Scale of the local means the imprint is measured against, pixels.
const IMPRINT_SMOOTH_PX: f64 = 3.0;

/// A probe (stop 45): GAP-TV's scene at `at` with the code's imprint at
/// `at` regressed out of each band. A reconstruction carries the code it
/// was made with (x̂ = Aᵀ(…) multiplies each band by its back-projected
/// code), which pulls any fit on it back to `at`; the scene's own texture
/// is uncorrelated with the code. Band k's template is (Aᵀ𝟙)_k, the code
/// as the band sees it (pose, dispersion and blur at `at`); its relative
/// texture c = t / G∗t − 1 is regressed out of the band's, r = x / G∗x − 1:
/// x ← x − β G∗x · c, β = ⟨r, c⟩ / ⟨c, c⟩ over the frame less a margin.
/// Measured: it does not release the fit (tuning half, 10 random poses:
/// geometry within 8 of 10 with the imprint, 6 without; notebook, stop 45).
fn remove_imprint(
    problem: &CalibrationProblem<'_>,
    at: &Mismatch,
    scene: &mut Cube,
) -> anyhow::Result<()> {
    let op = ModelOperator::new(problem.nominal_mask(), problem.bands(), at, problem.model())?;
    let mut template = vec![0.0f32; op.domain_len()];
    op.adjoint(&vec![1.0f32; op.range_len()], &mut template);
    let (bands, rows, cols) = scene.shape();
    anyhow::ensure!(template.len() == bands * rows * cols, "template size");
    let blur = GaussianBlur::new(IMPRINT_SMOOTH_PX, rows, cols)?;
    let n = rows * cols;
    let (mut local, mut tmp) = (vec![0.0f32; n], vec![0.0f32; n]);
    let mut code_local = vec![0.0f32; n];
    let mut code_texture = vec![0.0f64; n];
    // β from pixels the local means' zero padding does not reach
    let margin = (3.0 * IMPRINT_SMOOTH_PX).ceil() as usize;
    let interior = |r: usize, c: usize| {
        (margin..rows.saturating_sub(margin)).contains(&r)
            && (margin..cols.saturating_sub(margin)).contains(&c)
    };
    let x = scene.as_mut_slice();
    for k in 0..bands {
        let (band, code) = (&mut x[k * n..(k + 1) * n], &template[k * n..(k + 1) * n]);
        blur.apply(band, &mut local, &mut tmp);
        blur.apply(code, &mut code_local, &mut tmp);
        let relative = |v: f32, m: f32| if m > 1e-6 { v / m - 1.0 } else { 0.0 };
        for i in 0..n {
            code_texture[i] = relative(code[i], code_local[i]) as f64;
        }
        let (mut rc, mut cc) = (0.0f64, 0.0f64);
        for i in (0..n).filter(|&i| interior(i / cols, i % cols)) {
            let c = code_texture[i];
            rc += relative(band[i], local[i]) as f64 * c;
            cc += c * c;
        }
        let beta = if cc > 0.0 { rc / cc } else { 0.0 };
        for i in 0..n {
            band[i] -= (beta * local[i] as f64 * code_texture[i]) as f32;
        }
    }
    Ok(())
}

/// The error budget's steps: key and the scene estimate, given the truth.
fn budget_steps<'s>(scene: &'s Cube, truth: &Mismatch) -> [(&'static str, SceneEstimate<'s>); 3] {
    let given = |smooth_px| SceneEstimate::Given {
        scene: scene.as_slice(),
        smooth_px,
    };
    [
        ("proxy_at_truth", SceneEstimate::Proxy { at: *truth }),
        ("true_scene_smoothed", given(SCENE_SMOOTH_PX)),
        ("true_scene", given(0.0)),
    ]
}

/// The error budget of one case (see the module doc): per step the
/// texture fit's estimate and error.
pub fn error_budget(
    problem: &CalibrationProblem<'_>,
    preset: &DefaultPreset,
    scene: &Cube,
    blind: &Mismatch,
    truth: &Mismatch,
) -> anyhow::Result<Value> {
    let mut out = serde_json::Map::new();
    for (key, estimate) in budget_steps(scene, truth) {
        let t = Instant::now();
        let est = texture_fit(problem, preset, blind, estimate)?;
        let err = |p: Parameter| p.get(&est) - p.get(truth);
        out.insert(
            key.into(),
            json!({
                "estimate": per_parameter(|p| json!(p.get(&est))),
                "error": per_parameter(|p| json!(err(p))),
                "all_within_tolerance": Parameter::CALIBRATED.iter().all(|&p| err(p).abs() <= tolerance(p)),
                "seconds": t.elapsed().as_secs_f64(),
            }),
        );
    }
    Ok(Value::Object(out))
}

/// The scene fit's first-pass objective at the truth, at the first pass's
/// answer (`first_pass`) and at the final answer (`blind`); see the module
/// doc. `settings` the preset's scene fit (its fine pass is not scored).
pub fn scene_objective(
    problem: &CalibrationProblem<'_>,
    settings: &SceneFitSettings,
    first_pass: &Mismatch,
    blind: &Mismatch,
    truth: &Mismatch,
) -> anyhow::Result<Value> {
    let t = Instant::now();
    let first = settings.first_pass_only();
    let score = |psi: &Mismatch| scene_fit_score(problem, &first, psi);
    let (at_truth, at_first_pass, at_estimate) = (score(truth)?, score(first_pass)?, score(blind)?);
    // one pixel along dx and a1 from the first pass's answer: every band
    // moved (dx), band 0 moved with the last held, the last band moved
    // with band 0 held (where the rare ~1 px misses sit)
    let per_band = 1.0 / (problem.nominal.bands().max(2) - 1) as f64;
    let mut ridge_probes = Vec::new();
    for (name, dx, a1) in [
        ("all_bands", 1.0, 0.0),
        ("first_band", 1.0, -per_band),
        ("last_band", 0.0, per_band),
    ] {
        for sign in [-1.0, 1.0] {
            let mut probe = *first_pass;
            probe.dx += sign * dx;
            probe.a1 += sign * a1;
            ridge_probes.push(json!({ "moved": name, "sign": sign, "score": score(&probe)? }));
        }
    }
    Ok(json!({
        "at_truth": at_truth,
        "at_first_pass": at_first_pass,
        "at_estimate": at_estimate,
        "ridge_probes": ridge_probes,
        "truth_scores_lower": at_truth < at_first_pass,
        "seconds": t.elapsed().as_secs_f64(),
    }))
}

/// The error budget's keys, in order.
const BUDGET_KEYS: [&str; 3] = ["proxy_at_truth", "true_scene_smoothed", "true_scene"];

/// The one-line report of a case's limits.
pub fn describe(limits: &Value) -> String {
    let o = &limits["oracle_scene"];
    let cell = |group: &Value, p: Parameter| {
        group[p.key()]
            .as_f64()
            .map_or("–".into(), |v| format!("{v:+.4}"))
    };
    let line = |label: &str, group: &Value| {
        let cells: Vec<String> = Parameter::CALIBRATED
            .iter()
            .map(|&p| format!("{} {}", p.name(), cell(group, p)))
            .collect();
        format!("  {label:<7} {}", cells.join("  "))
    };
    let budget: Vec<String> = BUDGET_KEYS
        .iter()
        .filter(|k| limits["error_budget"].get(**k).is_some())
        .map(|k| line(&format!("x̃ {k}"), &limits["error_budget"][*k]["error"]))
        .collect();
    let objective = &limits["scene_objective"];
    let scene_objective = match objective["at_truth"].as_f64() {
        Some(truth) => format!(
            "\n  scene fit's objective: truth {truth:.5e}, first pass {:.5e}, final {:.5e}",
            objective["at_first_pass"].as_f64().unwrap_or(f64::NAN),
            objective["at_estimate"].as_f64().unwrap_or(f64::NAN),
        ),
        None => String::new(),
    };
    format!(
        "{}  | f {:.4e} (truth {:.4e}), {} evals in {} legs, {:.1} s\n{}{}{scene_objective}",
        line("oracle", &o["error"]),
        o["objective"].as_f64().unwrap_or(f64::NAN),
        o["objective_at_truth"].as_f64().unwrap_or(f64::NAN),
        o["evaluations"],
        o["nelder_mead_legs"],
        o["seconds"].as_f64().unwrap_or(f64::NAN),
        line("CRB", &limits["crb"]),
        budget.iter().map(|l| format!("\n{l}")).collect::<String>(),
    )
}

// ---------------------------------------------------------------- summary

fn rmse(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt())
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    (!v.is_empty()).then(|| v[v.len() / 2])
}

/// Blind vs scene-known vs noise bound per parameter over `rows` (None
/// when no row has limits).
pub fn summarise(rows: &[&Value]) -> Option<Value> {
    let with: Vec<&Value> = rows
        .iter()
        .copied()
        .filter(|r| r.get("limits").is_some())
        .collect();
    if with.is_empty() {
        return None;
    }
    let collect = |f: &dyn Fn(&Value) -> Option<f64>| with.iter().filter_map(|r| f(r)).collect();
    let all_within = with
        .iter()
        .filter(|r| r["limits"]["oracle_scene"]["all_within_tolerance"] == true)
        .count();
    // misses (some parameter out of tolerance) whose truth the scene fit's
    // objective scores lower than the first pass's answer: the search's
    let objective = |r: &&Value| r["limits"]["scene_objective"]["truth_scores_lower"].as_bool();
    let missed: Vec<&&Value> = with
        .iter()
        .filter(|r| r["all_within_tolerance"] == false && objective(r).is_some())
        .collect();
    let search_misses = missed.iter().filter(|r| objective(r) == Some(true)).count();
    Some(json!({
        "n": with.len(),
        "oracle_all_within_tolerance": all_within as f64 / with.len() as f64,
        "misses_scored": missed.len(),
        "misses_truth_scores_lower": search_misses,
        "parameters": per_parameter(|p| {
            let blind: Vec<f64> = collect(&|r| r["error"][p.key()].as_f64());
            let oracle: Vec<f64> =
                collect(&|r| r["limits"]["oracle_scene"]["error"][p.key()].as_f64());
            let bound: Vec<f64> = collect(&|r| r["limits"]["crb"][p.key()].as_f64());
            let within = oracle.iter().filter(|e| e.abs() <= tolerance(p)).count();
            let budget: serde_json::Map<String, Value> = BUDGET_KEYS
                .iter()
                .map(|k| {
                    let e: Vec<f64> =
                        collect(&|r| r["limits"]["error_budget"][*k]["error"][p.key()].as_f64());
                    (format!("texture_{k}_rmse"), json!(rmse(&e)))
                })
                .collect();
            let mut cell = json!({
                "blind_rmse": rmse(&blind),
                "oracle_scene_rmse": rmse(&oracle),
                "oracle_scene_max_abs_error": oracle.iter().fold(0.0f64, |a, e| a.max(e.abs())),
                "oracle_scene_within_tolerance": within as f64 / oracle.len().max(1) as f64,
                "median_crb": median(bound.clone()),
                "max_crb": bound.iter().copied().reduce(f64::max),
                "tolerance": tolerance(p),
            });
            if let Some(c) = cell.as_object_mut() {
                c.extend(budget);
            }
            cell
        }),
    }))
}

/// The summary table's limit line: blind RMSE / oracle-scene RMSE / median CRB.
pub fn print(limits: &Value) {
    let p = &limits["parameters"];
    let num = |v: &Value| v.as_f64().map_or("–".into(), |x| format!("{x:.4}"));
    let cells: Vec<String> = Parameter::CALIBRATED
        .iter()
        .map(|q| {
            let c = &p[q.key()];
            format!(
                "{} {}/{}/{}",
                q.name(),
                num(&c["blind_rmse"]),
                num(&c["oracle_scene_rmse"]),
                num(&c["median_crb"])
            )
        })
        .collect();
    let budget: Vec<String> = Parameter::CALIBRATED
        .iter()
        .map(|q| {
            let c = &p[q.key()];
            let steps: Vec<String> = BUDGET_KEYS
                .iter()
                .map(|k| num(&c[format!("texture_{k}_rmse")]))
                .collect();
            format!("{} {}", q.name(), steps.join("/"))
        })
        .collect();
    eprintln!(
        "{:<23} texture-fit RMSE with x̃ = proxy at true ψ / true scene smoothed / true scene: {}",
        "",
        budget.join("  ")
    );
    if let (Some(n), Some(lower)) = (
        limits["misses_scored"].as_u64(),
        limits["misses_truth_scores_lower"].as_u64(),
    ) && n > 0
    {
        eprintln!(
            "{:<23} misses whose truth the scene fit's objective scores lower (the search's): {lower} of {n}",
            ""
        );
    }
    eprintln!(
        "{:<23} limits (blind RMSE / scene-known RMSE / median CRB): {} | scene-known all-within {:.0}%",
        "",
        cells.join("  "),
        100.0
            * limits["oracle_all_within_tolerance"]
                .as_f64()
                .unwrap_or(f64::NAN)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use cassi_core::Mask;
    use cassi_core::synth::random_binary_mask;

    /// A scene that is a smooth field times the code each band sees loses
    /// the code (it comes out near the field times the code's local mean);
    /// the smooth field alone, uncorrelated with the code, is left as it was.
    #[test]
    fn removing_the_imprint_takes_the_code_out_and_leaves_the_scene() {
        let (rows, cols, bands) = (48, 48, 4);
        let mask = random_binary_mask(rows, cols, 0.5, 3).unwrap();
        let y = Measurement::zeros(rows, cols + 2 * (bands - 1));
        let problem =
            CalibrationProblem::nominal(&y, &mask, bands, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let at = Mismatch {
            dx: 0.3,
            blur_sigma_px: 0.3,
            ..Mismatch::nominal(2.0)
        };
        let op = ModelOperator::new(&mask, bands, &at, problem.model()).unwrap();
        let mut code = vec![0.0f32; op.domain_len()];
        op.adjoint(&vec![1.0f32; op.range_len()], &mut code);
        let field: Vec<f32> = (0..bands * rows * cols)
            .map(|i| {
                let (k, r, c) = (i / (rows * cols), (i / cols) % rows, i % cols);
                1.0 + 0.3 * k as f32 + 0.01 * r as f32 + 0.005 * c as f32
            })
            .collect();
        let mean_code = code.iter().sum::<f32>() / code.len() as f32;
        // the field times the code: off the field (times the code's mean) by the code
        let printed: Vec<f32> = field.iter().zip(&code).map(|(f, t)| f * t).collect();
        let off = |x: &[f32]| -> f64 {
            let interior = |i: &usize| {
                let (r, c) = ((i / cols) % rows, i % cols);
                (6..rows - 6).contains(&r) && (6..cols - 6).contains(&c)
            };
            let (mut e, mut n) = (0.0, 0.0);
            for i in (0..x.len()).filter(interior) {
                e += (x[i] as f64 - (field[i] * mean_code) as f64).powi(2);
                n += ((field[i] * mean_code) as f64).powi(2);
            }
            (e / n).sqrt()
        };
        let mut scene = Cube::from_vec(bands, rows, cols, printed).unwrap();
        let before = off(scene.as_slice());
        remove_imprint(&problem, &at, &mut scene).unwrap();
        let after = off(scene.as_slice());
        assert!(before > 0.3 && after < 0.25 * before, "{before} -> {after}");
        // no code in it: nothing to remove
        let mut smooth = Cube::from_vec(bands, rows, cols, field.clone()).unwrap();
        remove_imprint(&problem, &at, &mut smooth).unwrap();
        let moved = smooth
            .as_slice()
            .iter()
            .zip(&field)
            .map(|(a, b)| ((a - b) / b).abs())
            .fold(0.0f32, f32::max);
        eprintln!("imprint off the field {before:.3} -> {after:.3}; field moved {moved:.4}");
        assert!(moved < 0.02, "{moved}");
    }

    /// A 40×40 mask, a 4-band scene (a binary texture times a ramp over
    /// the bands) and the ψ* the tests' data are made at.
    fn textured_case(mask_seed: u64, texture_seed: u64) -> (Mask, Cube, Mismatch) {
        let (rows, cols, bands) = (40, 40, 4);
        let mask = random_binary_mask(rows, cols, 0.5, mask_seed).unwrap();
        let texture = random_binary_mask(rows, cols, 0.5, texture_seed).unwrap();
        let scene: Vec<f32> = (0..bands * rows * cols)
            .map(|i| {
                let (k, p) = (i / (rows * cols), i % (rows * cols));
                (1.0 + 0.2 * k as f32) * (0.6 + 0.4 * texture.as_slice()[p])
            })
            .collect();
        let scene = Cube::from_vec(bands, rows, cols, scene).unwrap();
        let truth = Mismatch {
            dx: 0.3,
            dy: -0.2,
            blur_sigma_px: 0.4,
            ..Mismatch::nominal(2.0)
        };
        (mask, scene, truth)
    }

    /// `instrument`'s noiseless measurement of `scene` at `psi` on its
    /// own detector.
    fn noiseless(instrument: &Model, scene: &Cube, psi: &Mismatch) -> Measurement {
        let (bands, rows, cols) = scene.shape();
        let (my, mx) = (rows, cols + 2 * (bands - 1));
        let clean = predict_with(instrument, scene, psi, (my, mx)).unwrap();
        Measurement::from_vec(my, mx, clean.iter().map(|&v| v as f32).collect()).unwrap()
    }

    /// The spectral-node scene keeps a spectrum linear in the band index,
    /// and every band with as many nodes as bands; a peak between nodes it
    /// flattens, one on a node it keeps with straight flanks.
    #[test]
    fn the_spectral_node_scene_keeps_what_its_nodes_hold() {
        let (bands, rows, cols) = (7, 2, 3);
        let cube = |f: &dyn Fn(usize, usize) -> f32| {
            let v = (0..bands)
                .flat_map(|k| (0..rows * cols).map(move |i| (k, i)))
                .map(|(k, i)| f(k, i))
                .collect();
            Cube::from_vec(bands, rows, cols, v).unwrap()
        };
        let linear = cube(&|k, i| 0.1 * k as f32 + 0.01 * i as f32);
        let through_spectral_nodes =
            |cube: &Cube, nodes| KnownScene::SpectralNodes { nodes }.told(cube).0.into_vec();
        for nodes in [2, 3, 4] {
            let through = through_spectral_nodes(&linear, nodes);
            for (a, b) in through.iter().zip(linear.as_slice()) {
                assert!((a - b).abs() < 1e-6, "{nodes} nodes: {a} vs {b}");
            }
        }
        // a peak at band 3: with 3 nodes (bands 0, 3, 6) it is a node and
        // its flanks become the lines to it; with 2 (bands 0 and 6) it is
        // flattened away
        let peak = cube(&|k, _| if k == 3 { 1.0 } else { 0.0 });
        let plane = rows * cols;
        let three = through_spectral_nodes(&peak, 3);
        for (k, want) in [
            (0, 0.0),
            (1, 1.0 / 3.0),
            (2, 2.0 / 3.0),
            (3, 1.0),
            (5, 1.0 / 3.0),
        ] {
            assert!(
                (three[k * plane] - want).abs() < 1e-6,
                "band {k}: {}",
                three[k * plane]
            );
        }
        let two = through_spectral_nodes(&peak, 2);
        assert!(two.iter().all(|v| v.abs() < 1e-6), "{two:?}");
        assert_eq!(through_spectral_nodes(&peak, bands), peak.as_slice());
        // placed where the spectrum bends: the peak and its feet, exactly
        let at = placed_band_nodes(&peak, 5);
        assert_eq!(
            (at[0], at[at.len() - 1], at.len()),
            (0, bands - 1, 5),
            "{at:?}"
        );
        assert!([2, 3, 4].iter().all(|k| at.contains(k)), "{at:?}");
        assert_eq!(through_band_nodes(&peak, &at), peak.as_slice());
    }

    /// Noiseless data of a textured scene at ψ*: the fit that knows the
    /// whole scene returns ψ* and explains the data; the fit that knows it
    /// smoothed by 1 px, or TV-denoised, cannot explain the texture, so it
    /// leaves a larger objective — the record holds both fits, what the
    /// fit was told, how far that is from the scene, and the family.
    #[test]
    fn the_smoothed_scene_fit_knows_less_than_the_true_scene_fit() {
        let (mask, scene, truth) = textured_case(5, 6);
        let instrument = Model::nominal(&mask, 4, 2.0, DispersionModel::DispersedMask).unwrap();
        let y = noiseless(&instrument, &scene, &truth);
        let start = Mismatch {
            dx: 0.35,
            dy: -0.15,
            ..truth
        };
        for known in [
            KnownScene::Smoothed { px: 1.0 },
            KnownScene::TvDenoised { weight: 0.1 },
        ] {
            let record = told_scene_fits(&y, &scene, instrument, &start, &truth, known);
            match known {
                KnownScene::Smoothed { px } => assert_eq!(record["smooth_px"], px),
                KnownScene::TvDenoised { weight } => assert_eq!(record["tv_weight"], weight),
                // this scene's spectra are linear: its nodes keep it
                KnownScene::SpectralNodes { .. } | KnownScene::PlacedSpectralNodes { .. } => {
                    unreachable!("not told here")
                }
            }
            let change = record["told_scene_rms_change"].as_f64().unwrap();
            let level = record["scene_rms"].as_f64().unwrap();
            assert!(
                change > 0.01 * level && change < level,
                "{known:?}: the told scene moved by {change} (scene RMS {level})"
            );
            let fits = &record["fits"];
            let objective = |key: &str| fits[key]["objective"].as_f64().unwrap();
            let dx_error = fits["true_scene"]["error"]["dx"].as_f64().unwrap();
            assert!(dx_error.abs() < 0.01, "true scene: dx off by {dx_error}");
            assert!(
                objective("smoothed_scene") > 100.0 * objective("true_scene").max(1e-12),
                "{known:?}: told {} against true {}",
                objective("smoothed_scene"),
                objective("true_scene")
            );
        }
    }

    /// The limits measure in the calibrated model, what it holds beside ψ
    /// included: on data whose bands spread, the scene-known fit in the
    /// spread model returns ψ and explains the data; in the point model it
    /// cannot (its σ takes part of the spread); the bound is finite and
    /// small at the noise level.
    #[test]
    fn the_limits_hold_the_models_band_spread() {
        let (mask, scene, truth) = textured_case(7, 8);
        let point = Model::nominal(&mask, 4, 2.0, DispersionModel::DispersedMask).unwrap();
        let spread = point.with_band_spread(cassi_core::optics::BandSpread::Uniform);
        let y = noiseless(&spread, &scene, &truth);
        let start = Mismatch {
            dx: 0.35,
            dy: -0.15,
            blur_sigma_px: 0.45,
            ..truth
        };
        let noise = DetectorNoise {
            photon_peak: 2.0e4,
            read_noise_e: 3.0,
        };
        let held = measure(&y, &y, &scene, spread, &start, &truth, noise);
        let dropped = measure(&y, &y, &scene, point, &start, &truth, noise);
        let error = |r: &Value, p: &str| r["oracle_scene"]["error"][p].as_f64().unwrap();
        for p in ["dx", "dy", "blur_sigma_px"] {
            assert!(
                error(&held, p).abs() < 0.01,
                "spread model: {p} off by {}",
                error(&held, p)
            );
        }
        let objective = |r: &Value| r["oracle_scene"]["objective"].as_f64().unwrap();
        assert!(
            objective(&dropped) > 100.0 * objective(&held).max(1e-12),
            "point model {} against spread model {}",
            objective(&dropped),
            objective(&held)
        );
        assert!(
            error(&dropped, "blur_sigma_px") > 0.1,
            "the point model's σ should take the spread: off by {}",
            error(&dropped, "blur_sigma_px")
        );
        for p in ["dx", "dy", "blur_sigma_px"] {
            let bound = held["crb"][p].as_f64().unwrap();
            assert!(bound > 0.0 && bound < 0.01, "CRB {p} {bound}");
        }
    }
}
