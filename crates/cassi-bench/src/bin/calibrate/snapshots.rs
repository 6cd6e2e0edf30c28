//! `--snapshots N`: several snapshots of one instrument. Each of N random
//! instruments (and, unless `--no-aligned`, the three aligned-with-blur
//! ones) measures every scene of the half; each snapshot is calibrated
//! alone, as a single-snapshot case, then the instrument's snapshots are
//! combined (`cassi_core::calib::combine_snapshots`) and the combination
//! is judged against the instrument's truth.
//!
//! Seeds: random instrument i draws its ψ from `base + 200 + i` (i < 50),
//! aligned instrument j (σ = `ALIGNED_SIGMAS[j]`) is `base + 250 + j`;
//! the snapshot of the half's scene `index` draws its noise from
//! `16 · (instrument seed) + index`. The single-snapshot cases use slots
//! 0–19 and offsets 400–459 of their half, so no seed of theirs is reused.

use anyhow::{Result, ensure};
use cassi_bench::physical_random_mismatch;
use std::time::Instant;

use cassi_core::calib::{
    Calibration, CalibrationProblem, CombineParams, DefaultPreset, combine_snapshots,
    joint_scene_fit, refit_jointly,
};
use cassi_core::optics::DispersionModel;
use cassi_core::{Mask, Measurement, Mismatch, Parameter};
use serde_json::{Value, json};

use super::{
    ALIGNED_SIGMAS, Args, Case, Half, Kind, STRIDE, fmt_signed, per_parameter, seed_base, share,
    tolerance,
};

const RANDOM_OFFSET: u64 = 200;
const ALIGNED_OFFSET: u64 = 250;
/// At most this many random instruments per half (their seeds end before
/// the aligned ones').
pub(super) const MAX_INSTRUMENTS: usize = (ALIGNED_OFFSET - RANDOM_OFFSET) as usize;
/// A snapshot's noise seed is this × its instrument's seed + the scene's
/// index in the half (a half has fewer scenes).
const NOISE_SEED_STRIDE: u64 = 16;

/// One instrument of a half: its kind, seed and ψ.
struct Instrument {
    kind: Kind,
    seed: u64,
    truth: Mismatch,
}

fn instruments(args: &Args, half: Half, random: usize) -> Vec<Instrument> {
    let base = seed_base(args, half);
    let mut out: Vec<Instrument> = (0..random as u64)
        .map(|i| {
            let seed = base + RANDOM_OFFSET + i;
            Instrument {
                kind: Kind::Random,
                seed,
                truth: physical_random_mismatch(seed),
            }
        })
        .collect();
    if args.aligned {
        for (j, sigma) in ALIGNED_SIGMAS.into_iter().enumerate() {
            out.push(Instrument {
                kind: Kind::AlignedBlur,
                seed: base + ALIGNED_OFFSET + j as u64,
                truth: Mismatch {
                    blur_sigma_px: sigma,
                    ..Mismatch::nominal(STRIDE)
                },
            });
        }
    }
    out
}

/// The snapshots scene `scene` (the half's `index`-th) takes, one per
/// instrument.
pub(super) fn scene_cases(
    args: &Args,
    half: Half,
    scene: usize,
    index: u64,
    random: usize,
) -> Vec<Case> {
    instruments(args, half, random)
        .into_iter()
        .map(|inst| Case {
            half,
            scene,
            kind: inst.kind,
            seed: NOISE_SEED_STRIDE * inst.seed + index,
            truth: inst.truth,
            instrument_seed: Some(inst.seed),
        })
        .collect()
}

/// What `--joint` fits each instrument's snapshots with: their
/// measurements (in the rows' order) and the calibration's setting.
pub(super) struct JointInputs<'a> {
    pub measurements: &'a [Measurement],
    pub mask: &'a Mask,
    pub model: DispersionModel,
    /// The scenes' band count.
    pub bands: usize,
    /// `--joint-model`: the joint fit on another model than the snapshots'
    /// (a probe), from the combination's answer with its σ (the blur
    /// pass's: the instrument's, which the crisp-cell model fits).
    pub fit_model: Option<DispersionModel>,
    pub preset: &'a DefaultPreset,
}

/// The instrument's snapshots (`members` of the rows) fitted as one from
/// their combination: the geometry the joint fit's, σ the combination's
/// (the joint fit holds the scene fit's own σ, from which it starts).
fn joint_fit(
    inputs: &JointInputs<'_>,
    members: &[usize],
    combined: &Calibration,
) -> Result<(Mismatch, Mismatch, f64)> {
    let model = inputs.fit_model.unwrap_or(inputs.model);
    let problems = members
        .iter()
        .map(|&i| {
            CalibrationProblem::nominal(
                &inputs.measurements[i],
                inputs.mask,
                inputs.bands,
                STRIDE,
                model,
            )
        })
        .collect::<cassi_core::Result<Vec<_>>>()?;
    let t0 = Instant::now();
    let (answer, stages) = match inputs.fit_model {
        None => {
            let refit = refit_jointly(combined, &problems, inputs.preset)?;
            (refit.parameters, refit.stages)
        }
        Some(_) => {
            let settings = inputs
                .preset
                .scene_fit
                .expect("--joint needs the scene fit");
            let fit = joint_scene_fit(
                &problems,
                &settings,
                &inputs.preset.proxy,
                &combined.parameters,
            )?;
            (fit.parameters, fit.stages)
        }
    };
    let seconds = t0.elapsed().as_secs_f64();
    // the joint detail pass's answer, with the combination's σ as the
    // answer has it
    let detail = Mismatch {
        blur_sigma_px: answer.blur_sigma_px,
        ..stages[stages.len() - 2].parameters
    };
    Ok((answer, detail, seconds))
}

/// Each instrument's snapshots combined: one record per instrument, its
/// truth, the combination's estimate, errors, stated uncertainty and the
/// snapshots' consistency; with `joint`, also their joint fit's estimate.
/// `rows` and `cals` are the single-snapshot records and calibrations, in
/// the same order.
pub(super) fn groups(
    rows: &[Value],
    cals: &[Calibration],
    joint: Option<&JointInputs<'_>>,
) -> Result<Vec<Value>> {
    ensure!(rows.len() == cals.len(), "one calibration per snapshot");
    let mut seeds: Vec<u64> = rows
        .iter()
        .filter_map(|r| r["instrument_seed"].as_u64())
        .collect();
    seeds.sort_unstable();
    seeds.dedup();
    let mut out = Vec::new();
    for seed in seeds {
        let members: Vec<usize> = (0..rows.len())
            .filter(|&i| rows[i]["instrument_seed"].as_u64() == Some(seed))
            .collect();
        let first = &rows[members[0]];
        let truth = |p: Parameter| first["truth"][p.key()].as_f64().unwrap_or(f64::NAN);
        let snapshots: Vec<&Calibration> = members.iter().map(|&i| &cals[i]).collect();
        let combined = combine_snapshots(&snapshots, &CombineParams::default())?;
        let est = combined.parameters;
        let err = |p: Parameter| p.get(&est) - truth(p);
        eprintln!(
            "{:<8} instrument {seed} ({}, {} snapshots) combined err {}",
            first["half"].as_str().unwrap_or(""),
            first["kind"].as_str().unwrap_or(""),
            members.len(),
            Parameter::CALIBRATED
                .iter()
                .map(|&p| format!("{} {}", p.name(), fmt_signed(p, err(p))))
                .collect::<Vec<_>>()
                .join("  ")
        );
        let judged = |est: &Mismatch| {
            let err = |p: Parameter| p.get(est) - truth(p);
            json!({
                "estimate": per_parameter(|p| json!(p.get(est))),
                "error": per_parameter(|p| json!(err(p))),
                "within_tolerance": per_parameter(|p| json!(err(p).abs() <= tolerance(p))),
                "all_within_tolerance": Parameter::CALIBRATED.iter().all(|&p| err(p).abs() <= tolerance(p)),
            })
        };
        let joint = match joint {
            Some(inputs) => {
                let (answer, detail, seconds) = joint_fit(inputs, &members, &combined)?;
                let mut record = judged(&answer);
                record["detail_pass"] = judged(&detail);
                record["seconds"] = json!(seconds);
                eprintln!(
                    "         joint fit err {} ({seconds:.1} s)",
                    Parameter::CALIBRATED
                        .iter()
                        .map(|&p| format!(
                            "{} {}",
                            p.name(),
                            fmt_signed(p, p.get(&answer) - truth(p))
                        ))
                        .collect::<Vec<_>>()
                        .join("  ")
                );
                Some(record)
            }
            None => None,
        };
        out.push(json!({
            "joint": joint,
            "half": first["half"],
            "kind": first["kind"],
            "headline": first["headline"],
            "instrument_seed": seed,
            "snapshots": members.len(),
            "scenes": members.iter().map(|&i| rows[i]["scene"].clone()).collect::<Vec<_>>(),
            "truth": first["truth"],
            "estimate": per_parameter(|p| json!(p.get(&est))),
            "error": per_parameter(|p| json!(err(p))),
            "uncertainty": per_parameter(|p| json!(combined.uncertainty.get(p))),
            "interval_95": per_parameter(|p| json!(combined.interval_95.get(p))),
            "consistency": combined.snapshots.as_ref().map(|s| &s.consistency),
            "within_tolerance": per_parameter(|p| json!(err(p).abs() <= tolerance(p))),
            "all_within_tolerance": Parameter::CALIBRATED.iter().all(|&p| err(p).abs() <= tolerance(p)),
            // the snapshots alone, for comparison: how many were within
            "snapshots_all_within": members.iter().filter(|&&i| rows[i]["all_within_tolerance"] == json!(true)).count(),
        }));
    }
    Ok(out)
}

/// Per kind: how many combinations were within tolerance (all six, each
/// parameter), and the coverage of their stated 1σ and 95 % intervals.
pub(super) fn summarise(groups: &[Value]) -> Value {
    let mut kinds: Vec<&str> = groups.iter().filter_map(|g| g["kind"].as_str()).collect();
    kinds.sort_unstable();
    kinds.dedup();
    let per_kind = |rows: &[&Value]| {
        let n = rows.len();
        let count = |f: &dyn Fn(&Value) -> bool| rows.iter().filter(|r| f(r)).count();
        let err = |r: &Value, p: Parameter| r["error"][p.key()].as_f64().unwrap_or(f64::NAN).abs();
        let within_k = |group: &'static str, p: Parameter, k: f64| {
            let hits = count(&|r| {
                r[group][p.key()]
                    .as_f64()
                    .is_some_and(|s| err(r, p) <= k * s)
            });
            share(hits, n)
        };
        json!({
            "instruments": n,
            "all_within_tolerance": share(count(&|r| r["all_within_tolerance"] == json!(true)), n),
            "within_tolerance": per_parameter(|p| share(count(&|r| err(r, p) <= tolerance(p)), n)),
            "rmse": per_parameter(|p| {
                json!((rows.iter().map(|r| err(r, p).powi(2)).sum::<f64>() / n.max(1) as f64).sqrt())
            }),
            "coverage_1sigma": per_parameter(|p| within_k("uncertainty", p, 1.0)),
            "coverage_95": per_parameter(|p| within_k("interval_95", p, 1.0)),
            "snapshots_all_within": share(
                rows.iter().map(|r| r["snapshots_all_within"].as_u64().unwrap_or(0) as usize).sum(),
                rows.iter().map(|r| r["snapshots"].as_u64().unwrap_or(0) as usize).sum(),
            ),
            // `--joint`: the joint fits, judged alike
            "joint": rows.iter().all(|r| !r["joint"].is_null()).then(|| {
                let jerr = |r: &Value, p: Parameter| r["joint"]["error"][p.key()].as_f64().unwrap_or(f64::NAN).abs();
                json!({
                    "all_within_tolerance": share(count(&|r| r["joint"]["all_within_tolerance"] == json!(true)), n),
                    "within_tolerance": per_parameter(|p| share(count(&|r| jerr(r, p) <= tolerance(p)), n)),
                    "rmse": per_parameter(|p| {
                        json!((rows.iter().map(|r| jerr(r, p).powi(2)).sum::<f64>() / n.max(1) as f64).sqrt())
                    }),
                })
            }),
        })
    };
    let mut out = serde_json::Map::new();
    for kind in kinds {
        let rows: Vec<&Value> = groups.iter().filter(|g| g["kind"] == json!(kind)).collect();
        out.insert(kind.to_string(), per_kind(&rows));
    }
    let headline: Vec<&Value> = groups
        .iter()
        .filter(|g| g["headline"] == json!(true))
        .collect();
    out.insert("headline".into(), per_kind(&headline));
    Value::Object(out)
}
