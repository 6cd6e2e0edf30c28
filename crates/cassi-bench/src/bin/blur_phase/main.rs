//! Whether the dispersed-mask model's blur σ depends on where the mask
//! and the bands land within a detector pixel. The model samples the
//! crisp mask where each band lands (its box average: a linear
//! interpolation of the code at a fractional offset) and then blurs with
//! the Gaussian integrated over pixels, (G_σ ∗ tri) sampled at integers;
//! the instrument blurs the crisp code before integrating it, which at a
//! fractional offset f is (G_σ ∗ tri)(t − f). The two agree at σ = 0 or
//! f = 0 and differ between (the linear interpolation smooths the blurred
//! code's mid frequencies), so at fractional offsets the model should need
//! a smaller σ. Along columns the dispersion's sum over bands shifted by
//! ~2 px filters out those frequencies; along rows nothing does. The
//! scene-known fits on the physical benchmark's random poses come out
//! ~0.09 px low in σ and unbiased on aligned instruments (whole-pixel pose,
//! a1 = 2), which this would explain.
//!
//! Per case (mask offset dx and slope a1 set so that the bands' fractional
//! offsets are all 0, all ½, or spread over [0, 1); then dy ½, θ, α alone,
//! then all together): the
//! 4× oversampled simulator, no noise, the true scene, and the σ that
//! minimises min_s ‖y − s·A_ψ x‖² with every other parameter at the
//! truth (a scan in 0.01 px steps, refined by the parabola through the
//! lowest three), and the residual at the truth. A constant scene first
//! (only the mask's code and the blur), then tuning-half scenes: a model
//! study, not a figure.
//!
//! Each case is also fitted by the crisp-cell model (the fix:
//! `cassi_core::optics::CrispCellOperator`, each side of a pixel's mask
//! edge blurred from where it lies) and, with θ = α = 0, by the prototype
//! that measured what the fix would gain ([`cell_model`]: each mask cell a
//! crisp square of the scene at its centre, blurred and integrated at its
//! own offset).
//!
//! Run: `cargo run --release -p cassi-bench --bin blur_phase [-- --scenes N]`
//! → `bench/results/blur_phase.json` (or $CASSI_BENCH_OUT).

mod cell_model;

use anyhow::Result;
use cassi_bench::{predict_on_detector, relative_residual2, scene_name};
use cassi_core::optics::{DispersionModel, PhysicalSpec, simulate_physical};
use cassi_core::{Cube, Mask, Mismatch, STANDARD_WAVELENGTHS_NM};
use cassi_eval::machine::Machine;
use serde_json::json;

pub(crate) const DETECTOR: (usize, usize) = (256, 310);
const SIGMAS: [f64; 2] = [0.3, 0.6];
const STEP: f64 = 0.01;

/// (name, the mismatch without its blur): where the bands land within a
/// pixel, then each other kind of sub-pixel placement on its own, then all
/// together (a random pose of the benchmark's size).
fn phases(bands: usize) -> Vec<(&'static str, Mismatch)> {
    let at = |dx, dy, theta_deg, a1, alpha_deg| Mismatch {
        dx,
        dy,
        theta_deg,
        a1,
        alpha_deg,
        blur_sigma_px: 0.0,
        a2: 0.0,
    };
    let spread = 2.0 + 1.0 / bands as f64;
    vec![
        ("whole pixels (dx 0, a1 2)", at(0.0, 0.0, 0.0, 2.0, 0.0)),
        (
            "every band at ½ (dx 0.5, a1 2)",
            at(0.5, 0.0, 0.0, 2.0, 0.0),
        ),
        (
            "spread over [0, 1) (a1 2 + 1/L)",
            at(0.0, 0.0, 0.0, spread, 0.0),
        ),
        (
            "spread, mask at ½ (dx 0.5, a1 2 + 1/L)",
            at(0.5, 0.0, 0.0, spread, 0.0),
        ),
        ("rows at ½ (dy 0.5)", at(0.0, 0.5, 0.0, 2.0, 0.0)),
        ("rows at ¼ (dy 0.25)", at(0.0, 0.25, 0.0, 2.0, 0.0)),
        ("rows whole (dy 1)", at(0.0, 1.0, 0.0, 2.0, 0.0)),
        ("columns at ¼ (dx 0.25)", at(0.25, 0.0, 0.0, 2.0, 0.0)),
        ("both at ½ (dx 0.5, dy 0.5)", at(0.5, 0.5, 0.0, 2.0, 0.0)),
        ("rotated (θ 0.4°)", at(0.0, 0.0, 0.4, 2.0, 0.0)),
        ("dispersion tilted (α 0.5°)", at(0.0, 0.0, 0.0, 2.0, 0.5)),
        (
            "all (dx 0.37, dy −1.2, θ 0.4°, a1 2.03, α 0.5°)",
            at(0.37, -1.2, 0.4, 2.03, 0.5),
        ),
    ]
}

/// The σ the model fits to `y` with the scene and every other parameter
/// known, and the residual there.
fn fitted_sigma(
    y: &[f64],
    mask: &Mask,
    scene: &Cube,
    truth: &Mismatch,
    model: DispersionModel,
) -> (f64, f64) {
    let score = |sigma: f64| {
        let psi = Mismatch {
            blur_sigma_px: sigma,
            ..*truth
        };
        predict_on_detector(mask, scene, &psi, model, DETECTOR)
            .map_or(f64::INFINITY, |m| relative_residual2(y, &m))
    };
    let grid: Vec<f64> = (0..=90).map(|i| i as f64 * STEP).collect();
    let scores: Vec<f64> = grid.iter().map(|&s| score(s)).collect();
    let i = (0..scores.len())
        .min_by(|&a, &b| scores[a].total_cmp(&scores[b]))
        .unwrap_or(0);
    if i == 0 || i + 1 == scores.len() {
        return (grid[i], scores[i].sqrt());
    }
    let (a, b, c) = (scores[i - 1], scores[i], scores[i + 1]);
    let curvature = a - 2.0 * b + c;
    let shift = if curvature > 0.0 {
        0.5 * (a - c) / curvature
    } else {
        0.0
    };
    (grid[i] + shift * STEP, b.sqrt())
}

fn main() -> Result<()> {
    let cassi_bench::ModelStudy { out, mask, scenes } = cassi_bench::model_study("blur_phase", 2)?;
    let mut cases = Vec::new();
    // a constant scene first: only the mask's code and the blur differ
    let (bands, rows, cols) = (STANDARD_WAVELENGTHS_NM.len(), mask.rows(), mask.cols());
    let flat = Cube::from_vec(bands, rows, cols, vec![1.0; bands * rows * cols])?;
    let mut inputs = vec![("constant scene".to_string(), flat)];
    for path in &scenes {
        let scene = cassi_io::load_cube(path, None, cassi_io::CubeLayout::Auto)?;
        inputs.push((scene_name(path), scene));
    }
    for (name, scene) in &inputs {
        for sigma in SIGMAS {
            for (phase, placement) in phases(scene.bands()) {
                let truth = Mismatch {
                    blur_sigma_px: sigma,
                    ..placement
                };
                let spec = PhysicalSpec {
                    oversample: 4,
                    blur_sigma_px: sigma,
                    detector: Some(DETECTOR),
                    ..PhysicalSpec::default()
                };
                let y =
                    simulate_physical(scene, &mask, &STANDARD_WAVELENGTHS_NM, &truth, &spec, None)?;
                let y: Vec<f64> = y.as_slice().iter().map(|&v| v as f64).collect();
                let (fitted, residual) =
                    fitted_sigma(&y, &mask, scene, &truth, DispersionModel::DispersedMask);
                // the crisp-cell model (the fix, any pose)
                let (crisp, crisp_residual) =
                    fitted_sigma(&y, &mask, scene, &truth, DispersionModel::CrispCells);
                let crisp_at_truth = predict_on_detector(
                    &mask,
                    scene,
                    &truth,
                    DispersionModel::CrispCells,
                    DETECTOR,
                )
                .map(|m| relative_residual2(&y, &m).sqrt());
                eprintln!(
                    "    crisp cells: fitted σ {crisp:.3} (error {:+.3}), residual {crisp_residual:.4} (at the truth {:.4})",
                    crisp - sigma,
                    crisp_at_truth.unwrap_or(f64::NAN)
                );
                // the prototype of the fix, where it applies (θ = α = 0)
                let cell = (truth.theta_deg == 0.0 && truth.alpha_deg == 0.0).then(|| {
                    let at = relative_residual2(&y, &cell_model::forward(&mask, scene, &truth));
                    (
                        cell_model::fitted_sigma(&y, &mask, scene, &truth),
                        at.sqrt(),
                    )
                });
                if let Some((cs, at)) = cell {
                    eprintln!(
                        "    cell model: fitted σ {cs:.3} (error {:+.3}), residual at the truth {at:.4}",
                        cs - sigma
                    );
                }
                let at_truth = predict_on_detector(
                    &mask,
                    scene,
                    &truth,
                    DispersionModel::DispersedMask,
                    DETECTOR,
                )
                .map(|m| relative_residual2(&y, &m).sqrt());
                eprintln!(
                    "{:<28} σ {sigma:.2}  {phase:<48} fitted σ {fitted:.3} (error {:+.3}), residual {residual:.4} (at the truth {:.4})",
                    name,
                    fitted - sigma,
                    at_truth.unwrap_or(f64::NAN)
                );
                cases.push(json!({
                    "scene": name, "true_sigma_px": sigma, "phase": phase,
                    "mismatch": truth,
                    "fitted_sigma_px": fitted, "error_px": fitted - sigma,
                    "relative_residual_at_fitted_sigma": residual,
                    "relative_residual_at_truth": at_truth,
                    "crisp_cells": json!({
                        "fitted_sigma_px": crisp, "error_px": crisp - sigma,
                        "relative_residual_at_fitted_sigma": crisp_residual,
                        "relative_residual_at_truth": crisp_at_truth,
                    }),
                    "cell_model": cell.map(|(fitted, at)| json!({
                        "fitted_sigma_px": fitted, "error_px": fitted - sigma,
                        "relative_residual_at_truth": at,
                    })),
                }));
            }
        }
    }
    let record = json!({
        "benchmark": "blur_phase",
        "what": "the σ the dispersed-mask model and the crisp-cell model fit, scene and every \
                 other parameter known, to the 4× simulator (no noise) with the bands landing on \
                 whole pixels, at ½, spread over [0, 1), with dy ½, θ, α alone and all together \
                 (and the cell-model prototype where θ = α = 0)",
        "machine": Machine::this(),
        "detector": DETECTOR,
        "cases": cases,
    });
    cassi_bench::write_record(&out, &record)?;
    eprintln!("wrote {out}");
    Ok(())
}
