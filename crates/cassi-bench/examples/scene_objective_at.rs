//! The scene fit's first-pass objective (the coarse scene solved cold) of a
//! real snapshot at given instruments ψ: a probe of whether a calibration
//! stopped in a local minimum (another ψ scoring lower than its answer).
//!
//! `cargo run --release -p cassi-bench --example scene_objective_at -- MEAS.mat
//! MASK.mat "dx,dy,θ,a1,α,σ" ["dx,dy,θ,a1,α,σ" …]` (the TSA-Net snapshots:
//! variables `meas_real` and `mask`, 28 bands at stride 2, the dispersed-mask
//! model).

use anyhow::{Context, bail};
use cassi_core::Mismatch;
use cassi_core::calib::{CalibrationProblem, SceneFitSettings, scene_fit_score};
use cassi_core::optics::DispersionModel;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 3 {
        bail!("usage: scene_objective_at MEAS.mat MASK.mat \"dx,dy,θ,a1,α,σ\" […]");
    }
    let y = cassi_io::load_frame(&args[0], Some("meas_real"))?;
    let mask = cassi_io::load_frame(&args[1], Some("mask"))?;
    let problem = CalibrationProblem::nominal(&y, &mask, 28, 2.0, DispersionModel::DispersedMask)?;
    let settings = SceneFitSettings::default().first_pass_only();
    for text in &args[2..] {
        let v: Vec<f64> = text
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("ψ {text:?}: expected six numbers dx,dy,θ,a1,α,σ"))?;
        let [dx, dy, theta_deg, a1, alpha_deg, blur_sigma_px] = v[..] else {
            bail!(
                "ψ {text:?}: expected six numbers dx,dy,θ,a1,α,σ, got {}",
                v.len()
            );
        };
        let psi = Mismatch {
            dx,
            dy,
            theta_deg,
            a1,
            alpha_deg,
            blur_sigma_px,
            a2: 0.0,
        };
        println!("{text}\t{:.5}", scene_fit_score(&problem, &settings, &psi)?);
    }
    Ok(())
}
