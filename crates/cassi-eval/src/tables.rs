//! Markdown and CSV tables of a study. Every Markdown table names the
//! metric definitions it uses.

use std::fmt::Write;

use cassi_core::Parameter;
use cassi_core::metrics::METRIC_DEFINITIONS;

use crate::protocol::{Scenario, SceneResult};
use crate::summary::Summary;

/// The definitions as a Markdown footnote block.
pub fn metric_footnote() -> String {
    let mut s = String::from("Metric definitions:\n");
    for line in METRIC_DEFINITIONS.lines() {
        let _ = writeln!(s, "- {line}");
    }
    s
}

/// Mean PSNR / SSIM / SAM per method and scenario, with the calibration
/// gain, the mismatch loss and ρ.
pub fn main_table(summary: &Summary) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| method | scenario | PSNR (dB) | PSNR band-mean (dB) | SSIM | SAM (°) | time (s) |"
    );
    let _ = writeln!(s, "|---|---|---:|---:|---:|---:|---:|");
    for m in &summary.methods {
        for x in &m.scenarios {
            let _ = writeln!(
                s,
                "| {} | {} | {:.2} | {:.2} | {:.4} | {:.2} | {:.2} |",
                m.method,
                x.scenario.label(),
                x.psnr,
                x.psnr_band_mean,
                x.ssim,
                x.sam_deg,
                x.seconds
            );
        }
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "| method | mismatch loss IV − II (dB) | calibration gain III − II (dB) | recovery ρ = (III − II)/(IV − II) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|");
    for m in &summary.methods {
        let _ = writeln!(
            s,
            "| {} | {:.2} | {:.2} | {:.1} % |",
            m.method,
            m.mismatch_loss_db,
            m.calibration_gain_db,
            100.0 * m.recovery_ratio
        );
    }
    s
}

/// PSNR per scene for one method, one column per scenario, and ρ.
pub fn per_scene_table(results: &[SceneResult], method: &str) -> String {
    let mut s = String::from("| scene |");
    for sc in Scenario::ALL {
        let _ = write!(s, " {} |", sc.label());
    }
    s += " ρ |\n|---|";
    s += &"---:|".repeat(Scenario::ALL.len() + 1);
    s += "\n";
    for r in results {
        let _ = write!(s, "| {} |", r.scene);
        let p = |sc| r.outcome(method, sc).map(|o| o.metrics.psnr);
        for sc in Scenario::ALL {
            match p(sc) {
                Some(v) => {
                    let _ = write!(s, " {v:.2} |");
                }
                None => s += " – |",
            }
        }
        match (
            p(Scenario::Assumed),
            p(Scenario::Corrected),
            p(Scenario::Oracle),
        ) {
            (Some(ii), Some(iii), Some(iv)) => {
                let _ = writeln!(s, " {:.1} % |", 100.0 * (iii - ii) / (iv - ii));
            }
            _ => s += " – |\n",
        }
    }
    s
}

/// True and estimated parameters per scene, errors, and the RMSE.
pub fn parameter_table(results: &[SceneResult], summary: &Summary) -> String {
    let mut s = String::from("| scene |");
    for p in Parameter::CALIBRATED {
        let _ = write!(s, " {} true / est. ({}) |", p.name(), p.unit());
    }
    s += " calibration (s) |\n|---|";
    s += &"---|".repeat(Parameter::CALIBRATED.len());
    s += "---:|\n";
    for r in results {
        let (t, e) = (r.truth, r.calibration.parameters);
        let _ = write!(s, "| {} |", r.scene);
        for p in Parameter::CALIBRATED {
            let _ = write!(s, " {} / {} |", p.format(p.get(&t)), p.format(p.get(&e)));
        }
        let _ = writeln!(s, " {:.1} |", r.calibration.seconds);
    }
    let q = summary.parameter_rmse;
    s += "| **RMSE** |";
    for p in Parameter::CALIBRATED {
        let _ = write!(s, " {:.d$} |", q.get(p), d = p.decimals() + 1);
    }
    let _ = writeln!(s, " median {:.1} |", summary.calibration_seconds_median);
    s
}

/// Median time and evaluations of each calibration stage over the scenes.
pub fn stage_table(results: &[SceneResult]) -> String {
    let mut names: Vec<String> = Vec::new();
    for r in results {
        for st in &r.calibration.stages {
            if !names.contains(&st.name) {
                names.push(st.name.clone());
            }
        }
    }
    let mut s = String::from("| stage | median time (s) | median evaluations |\n|---|---:|---:|\n");
    for name in names {
        let stages: Vec<_> = results
            .iter()
            .flat_map(|r| r.calibration.stages.iter().filter(|st| st.name == name))
            .collect();
        let t = cassi_core::stats::median(&stages.iter().map(|st| st.seconds).collect::<Vec<_>>());
        let e = cassi_core::stats::median(
            &stages
                .iter()
                .map(|st| st.evaluations as f64)
                .collect::<Vec<_>>(),
        );
        let _ = writeln!(s, "| {name} | {t:.2} | {e:.0} |");
    }
    s
}

/// Long-format CSV: one row per scene, method and scenario.
pub fn outcomes_csv(results: &[SceneResult]) -> String {
    let mut s =
        String::from("scene,method,scenario,psnr_db,psnr_band_mean_db,ssim,sam_deg,seconds\n");
    for r in results {
        for o in &r.outcomes {
            let _ = writeln!(
                s,
                "{},{},{},{:.4},{:.4},{:.6},{:.4},{:.3}",
                r.scene,
                o.method,
                o.scenario.label(),
                o.metrics.psnr,
                o.metrics.psnr_band_mean,
                o.metrics.ssim,
                o.metrics.sam_deg,
                o.seconds
            );
        }
    }
    s
}

/// CSV of true and estimated parameters per scene (columns named by the
/// parameters' file keys: `theta_deg_true`, `theta_deg_est`, …).
pub fn parameters_csv(results: &[SceneResult]) -> String {
    let mut s = String::from("scene");
    for p in Parameter::CALIBRATED {
        let _ = write!(s, ",{0}_true,{0}_est", p.key());
    }
    s += ",calibration_seconds\n";
    for r in results {
        let (t, e) = (r.truth, r.calibration.parameters);
        s += &r.scene;
        for p in Parameter::CALIBRATED {
            let _ = write!(s, ",{},{}", p.get(&t), p.get(&e));
        }
        let _ = writeln!(s, ",{:.3}", r.calibration.seconds);
    }
    s
}

/// Mean PSNR of II, III, IV, ρ and parameter RMSE at each mismatch scale.
pub fn sensitivity_table(points: &[crate::sweep_rows::SensitivityPoint], preset: &str) -> String {
    let names = Parameter::CALIBRATED.map(|p| p.name()).join(", ");
    let mut s = format!(
        "| scale | mismatch ({names}) | method | II (dB) | III (dB) | IV (dB) | ρ | RMSE dx / dy (px), θ (°) | `{preset}` calibration median (s) |\n|---:|---|---|---:|---:|---:|---:|---|---:|\n"
    );
    for p in points {
        let m = p.mismatch;
        for ms in &p.summary.methods {
            let v = |sc| ms.scenario(sc).map_or(f64::NAN, |x| x.psnr);
            let q = p.summary.parameter_rmse;
            let _ = writeln!(
                s,
                "| {}× | {} | {} | {:.2} | {:.2} | {:.2} | {:.1} % | {:.3} / {:.3}, {:.3} | {:.1} |",
                p.scale,
                Parameter::CALIBRATED
                    .iter()
                    .map(|p| p.format(p.get(&m)))
                    .collect::<Vec<_>>()
                    .join(", "),
                ms.method,
                v(Scenario::Assumed),
                v(Scenario::Corrected),
                v(Scenario::Oracle),
                100.0 * ms.recovery_ratio,
                q.get(Parameter::Dx),
                q.get(Parameter::Dy),
                q.get(Parameter::ThetaDeg),
                p.summary.calibration_seconds_median
            );
        }
    }
    s
}

/// Mean PSNR and pose error per preset, method and pipeline variant.
pub fn ablation_table(rows: &[crate::sweep_rows::AblationRow]) -> String {
    let mut s = String::from(
        "| preset | method | model used | PSNR (dB) | pose RMSE (dx, dy px; θ °) | calibration mean (s) |\n|---|---|---|---:|---:|---:|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {:.3} | {:.1} |",
            r.preset, r.method, r.label, r.psnr, r.pose_rmse_px, r.calibration_seconds_mean
        );
    }
    s
}
