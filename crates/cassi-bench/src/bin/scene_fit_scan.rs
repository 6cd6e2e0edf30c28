//! Where the scene fit's aligned-instrument bias comes from: its score
//! along one parameter (dx unless `--parameter KEY`; every other parameter
//! at the truth, the coarse scene solved to convergence at each point) on the tuning half's aligned-with-blur
//! instruments at σ 0.5 px (`--sigma 0.3|0.7` for the benchmark's other
//! aligned slots; the calibration benchmark's seeds), each
//! measured four ways:
//!
//! - `physical`: the benchmark's instrument (4× oversampled simulator,
//!   256×310 detector, 2·10⁴ e⁻ peak, 3 e⁻ read noise);
//! - `physical_coarse_scene`: the same instrument looking at the scene as
//!   the fit's coarse basis holds it ([`coarse_scene_of`]): no detail the
//!   fit cannot explain;
//! - `inverse_crime`: the fitted model's own operator (dispersed-mask,
//!   blurred) on the full scene, the same noise: no physics the model
//!   lacks. Labelled as such.
//! - `model_on_gap_tv_scene`: the same operator on GAP-TV's scene of the
//!   `physical` measurement (at the true ψ), the same noise: what a
//!   bootstrap of the fit's bias ([`cassi_core::calib::BlurBootstrap`])
//!   sees. Where its minimum sits where `physical`'s does, the bootstrap
//!   measures the bias.
//!
//! With `--weighted WINDOW_PX,FLOOR_QUANTILE` the objective is the
//! residual-weighted one ([`ResidualWeighting`], its weights from the
//! residual at the truth, held).
//!
//! A score whose minimum leaves the truth in `physical` and `inverse_crime`
//! but not in `physical_coarse_scene` is moved by the scene's detail,
//! not by the model. Only tuning-half scenes (a diagnosis, not a figure).
//!
//! Run: `cargo run --release -p cassi-bench --bin scene_fit_scan [-- --parameter
//! dx|dy|theta_deg|a1|alpha_deg|blur_sigma_px] [--sigma 0.3|0.5|0.7]
//! [--weighted W,Q]`. Writes `bench/results/scene_fit_scan.json` for dx,
//! `scene_fit_scan_<key>.json` otherwise, `…_sigma<σ>.json` at another σ,
//! `…_weighted<W>_<Q>.json` weighted (or $CASSI_BENCH_OUT). Records made
//! before the fourth row have three.

use std::time::Instant;

use cassi_bench::shared_data;
use cassi_core::calib::{
    CalibrationProblem, ResidualWeighting, SceneFitSettings, coarse_scene_of,
    reweighted_scene_fit_scores, scene_fit_score,
};
use cassi_core::optics::{
    DispersionModel, ModelOperator, NoiseModel, PhysicalSpec, simulate_physical,
};
use cassi_core::recon::{Method, MethodId, Model};
use cassi_core::solvers::Silent;
use cassi_core::{Cube, Mask, Measurement, Mismatch, Parameter, STANDARD_WAVELENGTHS_NM};
use cassi_eval::machine::Machine;

/// The calibration benchmark's: tuning seeds 14 000 + 20·scene + slot,
/// its aligned blurs (σ px, slot) and its detector and noise.
const TUNING_SCENES: usize = 5;
const SEED_BASE: u64 = 14_000;
const ALIGNED_SLOTS: [(f64, u64); 3] = [(0.3, 17), (0.5, 18), (0.7, 19)];
/// σ 0.5 px unless `--sigma` says otherwise.
const DEFAULT_SLOT: (f64, u64) = ALIGNED_SLOTS[1];
const DETECTOR: (usize, usize) = (256, 310);
const STEPS: i32 = 10;

/// The scan's step per parameter: ±10 steps span the aligned answers'
/// spread on the tuning half.
fn step(p: Parameter) -> f64 {
    match p {
        Parameter::Dx | Parameter::Dy | Parameter::BlurSigmaPx => 0.05,
        Parameter::ThetaDeg => 0.01,
        Parameter::A1 => 0.002,
        Parameter::A2 => 0.0001,
        Parameter::AlphaDeg => 0.03,
    }
}

/// Where a sampled curve is lowest: the parabola through the lowest sample
/// and its two neighbours (the sample itself at an end).
fn minimum(xs: &[f64], ys: &[f64]) -> f64 {
    let i = (0..ys.len())
        .min_by(|&a, &b| ys[a].total_cmp(&ys[b]))
        .unwrap_or(0);
    if i == 0 || i + 1 == ys.len() {
        return xs[i];
    }
    let (a, b, c) = (ys[i - 1], ys[i], ys[i + 1]);
    let curvature = a - 2.0 * b + c;
    if curvature <= 0.0 {
        return xs[i];
    }
    xs[i] + 0.5 * (a - c) / curvature * (xs[i + 1] - xs[i])
}

/// How a case's measurement is made (see the module doc).
#[derive(Clone, Copy, PartialEq)]
enum Measured {
    Physical,
    PhysicalCoarseScene,
    InverseCrime,
    ModelOnReconstruction,
}

impl Measured {
    const ALL: [Measured; 4] = [
        Self::Physical,
        Self::PhysicalCoarseScene,
        Self::InverseCrime,
        Self::ModelOnReconstruction,
    ];

    /// Its name in the record.
    fn key(self) -> &'static str {
        match self {
            Self::Physical => "physical",
            Self::PhysicalCoarseScene => "physical_coarse_scene",
            Self::InverseCrime => "inverse_crime",
            Self::ModelOnReconstruction => "model_on_gap_tv_scene",
        }
    }
}

/// The case's measurement of `kind`; `physical` is its `Physical` one,
/// made first (the reconstruction row starts from it).
fn measure(
    kind: Measured,
    scene: &Cube,
    settings: &SceneFitSettings,
    mask: &Mask,
    truth: &Mismatch,
    seed: u64,
    physical: Option<&Measurement>,
) -> anyhow::Result<Measurement> {
    let noise = NoiseModel {
        photon_peak: Some(2e4),
        read_noise: 3.0,
        seed,
    };
    let model_of = |seen: &Cube| -> anyhow::Result<Measurement> {
        let op = ModelOperator::new(mask, seen.bands(), truth, DispersionModel::DispersedMask)?;
        Ok(noise.apply(&op.forward(seen)?)?)
    };
    Ok(match kind {
        Measured::InverseCrime => model_of(scene)?,
        Measured::ModelOnReconstruction => {
            // what a bootstrap of the blind fit could see: the model's
            // operator on GAP-TV's scene from the physical measurement
            // (at the true ψ: the most the bootstrap could know)
            let y =
                physical.ok_or_else(|| anyhow::anyhow!("the physical measurement comes first"))?;
            let model = Model::new(
                mask,
                scene.bands(),
                2.0,
                *truth,
                DispersionModel::DispersedMask,
            )?;
            let gap_tv = Method::defaults(MethodId::GapTv)
                .ok_or_else(|| anyhow::anyhow!("GAP-TV has defaults"))?;
            let rec = gap_tv.solve(y, &model, &mut Silent)?;
            model_of(&rec.cube.clipped_to_unit())?
        }
        Measured::Physical | Measured::PhysicalCoarseScene => {
            let spec = PhysicalSpec {
                oversample: 4,
                blur_sigma_px: truth.blur_sigma_px,
                detector: Some(DETECTOR),
                ..PhysicalSpec::default()
            };
            let seen = if kind == Measured::PhysicalCoarseScene {
                &coarse_scene_of(scene, settings)
            } else {
                scene
            };
            simulate_physical(
                seen,
                mask,
                &STANDARD_WAVELENGTHS_NM,
                truth,
                &spec,
                Some(&noise),
            )?
        }
    })
}

fn main() -> anyhow::Result<()> {
    let t0 = Instant::now();
    const USAGE: &str = "usage: scene_fit_scan [--parameter KEY] [--sigma 0.3|0.5|0.7] [--weighted WINDOW_PX,FLOOR_QUANTILE]";
    cassi_bench::exit_on_help(USAGE.trim_start_matches("usage: "));
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let (mut parameter, mut aligned) = (Parameter::Dx, DEFAULT_SLOT);
    let mut weighting: Option<ResidualWeighting> = None;
    let mut args = argv.iter();
    while let Some(flag) = args.next() {
        let value = args
            .next()
            .ok_or_else(|| anyhow::anyhow!("{flag}: a value expected; {USAGE}"))?;
        match flag.as_str() {
            "--parameter" => {
                parameter = Parameter::CALIBRATED
                    .into_iter()
                    .find(|p| p.key() == value)
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "--parameter {value}: expected dx, dy, theta_deg, a1, alpha_deg or blur_sigma_px"
                        )
                    })?
            }
            "--sigma" => {
                aligned = ALIGNED_SLOTS
                    .into_iter()
                    .find(|&(sigma, _)| value.parse::<f64>().ok() == Some(sigma))
                    .ok_or_else(|| {
                        anyhow::anyhow!(
                            "--sigma {value}: the benchmark's aligned blurs are 0.3, 0.5 and 0.7 px"
                        )
                    })?
            }
            "--weighted" => {
                let parts: Vec<f64> = value
                    .split(',')
                    .map(|v| v.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| anyhow::anyhow!("--weighted {value}: {e}; {USAGE}"))?;
                let [window_px, floor_quantile] = parts[..] else {
                    anyhow::bail!("--weighted {value}: two numbers expected; {USAGE}");
                };
                weighting = Some(ResidualWeighting {
                    window_px,
                    floor_quantile,
                });
            }
            _ => anyhow::bail!("{flag}: unknown; {USAGE}"),
        }
    }
    let (sigma_px, slot) = aligned;
    let path = std::env::var("CASSI_BENCH_OUT").unwrap_or_else(|_| {
        let mut name = match parameter {
            Parameter::Dx => "scene_fit_scan".to_string(),
            p => format!("scene_fit_scan_{}", p.key()),
        };
        if aligned != DEFAULT_SLOT {
            name += &format!("_sigma{sigma_px}");
        }
        if let Some(w) = weighting {
            name += &format!("_weighted{}_{}", w.window_px, w.floor_quantile);
        }
        format!(
            "{}/../../bench/results/{name}.json",
            env!("CARGO_MANIFEST_DIR")
        )
    });
    // the record's folder before the work, not after it
    if let Some(dir) = std::path::Path::new(&path).parent() {
        std::fs::create_dir_all(dir)
            .map_err(|e| anyhow::anyhow!("creating the output folder {}: {e}", dir.display()))?;
    }
    let data = shared_data();
    let mask = cassi_io::load_frame(data.join("masks/tsa_simu_mask256.mat"), Some("mask"))?;
    let scenes = cassi_bench::cave_scenes(&data)?;
    let mut settings = SceneFitSettings::default();
    // converged solves: the score itself, not a warm-started fit's
    settings.cold_solve.iterations = 300;
    settings.cold_solve.tolerance = 1e-8;
    let truth = Mismatch {
        blur_sigma_px: sigma_px,
        ..Mismatch::nominal(2.0)
    };
    let at_truth = parameter.get(&truth);
    // a blur below zero is no instrument: σ's scan starts at 0 when ±10
    // steps would cross it
    let values: Vec<f64> = (-STEPS..=STEPS)
        .map(|i| at_truth + i as f64 * step(parameter))
        .filter(|&v| parameter != Parameter::BlurSigmaPx || v >= -1e-12)
        .map(|v| v.max(0.0))
        .collect();
    let centre_at = values
        .iter()
        .position(|&v| (v - at_truth).abs() < 1e-9)
        .expect("the truth is on the scan");
    let mut rows = Vec::new();
    for (index, path) in scenes.iter().take(TUNING_SCENES).enumerate() {
        let name = cassi_bench::scene_name(path);
        let scene = cassi_io::load_cube(path, None, cassi_io::CubeLayout::Auto)?;
        let seed = SEED_BASE + 20 * index as u64 + slot;
        // Measured::ALL starts with it: the later rows may start from it
        let mut physical: Option<Measurement> = None;
        for kind in Measured::ALL {
            let y = measure(
                kind,
                &scene,
                &settings,
                &mask,
                &truth,
                seed,
                physical.as_ref(),
            )?;
            if kind == Measured::Physical {
                physical = Some(y.clone());
            }
            let problem = CalibrationProblem::nominal(
                &y,
                &mask,
                scene.bands(),
                2.0,
                DispersionModel::DispersedMask,
            )?;
            let psis: Vec<Mismatch> = values
                .iter()
                .map(|&v| {
                    let mut psi = truth;
                    parameter.set(&mut psi, v);
                    psi
                })
                .collect();
            let scores = match &weighting {
                // the weights from the residual at the truth, held
                Some(w) => reweighted_scene_fit_scores(&problem, &settings, w, &truth, &psis)?,
                None => psis
                    .iter()
                    .map(|psi| scene_fit_score(&problem, &settings, psi))
                    .collect::<Result<Vec<f64>, _>>()?,
            };
            let centre = scores[centre_at];
            let lowest = minimum(&values, &scores);
            let truth_is_a_local_maximum =
                centre_at > 0 && centre > scores[centre_at - 1] && centre > scores[centre_at + 1];
            eprintln!(
                "{name:28} {:22} minimum at {} {lowest:+.4}; truth a local maximum: {truth_is_a_local_maximum}",
                kind.key(),
                parameter.key()
            );
            rows.push(serde_json::json!({
                "scene": name, "seed": seed, "measurement": kind.key(),
                "inverse_crime": kind == Measured::InverseCrime,
                "parameter": parameter.key(), "values": values, "score": scores,
                "minimum_at": lowest,
                "truth_is_a_local_maximum": truth_is_a_local_maximum,
            }));
        }
    }
    let out = serde_json::json!({
        "benchmark": "scene_fit_scan",
        "what": "the scene fit's score (cold CGLS, 300 iterations, tol 1e-8) along one parameter, every other parameter at the truth",
        "parameter": parameter.key(),
        "instrument": { "truth": truth, "oversample": 4, "detector": DETECTOR, "photon_peak": 2e4,
                        "read_noise_e": 3.0, "mask": "masks/tsa_simu_mask256.mat",
                        "seeds": format!("the calibration benchmark's tuning aligned-blur σ {sigma_px} px slot: 14 000 + 20·scene + {slot}") },
        "settings": settings,
        "residual_weighting": weighting,
        "machine": Machine::this(),
        "seconds": t0.elapsed().as_secs_f64(),
        "rows": rows,
    });
    cassi_bench::write_record(&path, &out)?;
    eprintln!("wrote {path}");
    Ok(())
}
