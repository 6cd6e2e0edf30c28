//! `--rho-sensitivity`: how precisely each parameter must be known for
//! GAP-TV to recover ρ ≥ 95 % on a case. GAP-TV reconstructs with the
//! true ψ but one parameter moved by a share of the tolerance on
//! it (both ways); ρ at each move against the case's own II and IV. Where
//! IV − II is small (an aligned instrument at σ 0.3 px: 0.2–0.9 dB) a move
//! well inside the tolerance can cost more than 5 % of ρ: the figure is
//! then stricter than the parameter tolerances, and this measures by how
//! much.

use anyhow::Result;
use cassi_core::{Mismatch, Parameter};
use serde_json::{Value, json};

/// The moves, as shares of each parameter's tolerance.
pub(crate) const SHARES: [f64; 6] = [-1.0, -0.5, -0.2, 0.2, 0.5, 1.0];

/// For each calibrated parameter, ρ at truth + share · tolerance for each
/// share in [`SHARES`] (`psnr_at` reconstructs with a ψ; `rho` scores a
/// PSNR against the case's II and IV: `None` where IV − II is too small).
pub(crate) fn measure(
    truth: &Mismatch,
    tolerance: impl Fn(Parameter) -> f64,
    psnr_at: impl Fn(&Mismatch) -> Result<f64>,
    rho: impl Fn(f64) -> Option<f64>,
) -> Result<Value> {
    let mut per = serde_json::Map::new();
    for p in Parameter::CALIBRATED {
        let mut rows = Vec::new();
        for share in SHARES {
            let mut psi = *truth;
            let moved = p.get(truth) + share * tolerance(p);
            // σ enters the model as |σ|: a move below 0 is not a model
            if p == Parameter::BlurSigmaPx && moved < 0.0 {
                continue;
            }
            p.set(&mut psi, moved);
            let db = psnr_at(&psi)?;
            rows.push(json!({ "share": share, "move": share * tolerance(p), "psnr_db": db, "rho": rho(db) }));
        }
        per.insert(p.key().to_string(), Value::Array(rows));
    }
    Ok(Value::Object(per))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each parameter is moved alone, by share × its tolerance, from the
    /// truth; σ is never moved below 0; ρ is scored from the PSNR at the move.
    #[test]
    fn moves_one_parameter_at_a_time_by_shares_of_its_tolerance() {
        let truth = Mismatch {
            blur_sigma_px: 0.03,
            ..Mismatch::paper()
        };
        let tolerance = |p: Parameter| match p {
            Parameter::A1 => 0.005,
            Parameter::AlphaDeg => 0.1,
            _ => 0.05,
        };
        // a PSNR that names the move: 20 dB less the moved distance summed
        // over every parameter, each over its tolerance
        let psnr_at = |psi: &Mismatch| -> Result<f64> {
            Ok(20.0
                - Parameter::CALIBRATED
                    .iter()
                    .map(|&p| (p.get(psi) - p.get(&truth)).abs() / tolerance(p))
                    .sum::<f64>())
        };
        let got = measure(&truth, tolerance, psnr_at, |db| Some(db / 20.0)).unwrap();
        for p in Parameter::CALIBRATED {
            let rows = got[p.key()].as_array().unwrap();
            let expected: Vec<f64> = SHARES
                .into_iter()
                .filter(|&s| p != Parameter::BlurSigmaPx || 0.03 + s * 0.05 >= 0.0)
                .collect();
            assert_eq!(rows.len(), expected.len(), "{}", p.key());
            for (row, share) in rows.iter().zip(expected) {
                assert_eq!(row["share"].as_f64(), Some(share));
                let moved = row["move"].as_f64().unwrap();
                assert!((moved - share * tolerance(p)).abs() < 1e-12);
                // only p moved: the PSNR lost exactly |share|
                let db = row["psnr_db"].as_f64().unwrap();
                assert!(
                    (db - (20.0 - share.abs())).abs() < 1e-9,
                    "{} {share}: {db}",
                    p.key()
                );
                assert!((row["rho"].as_f64().unwrap() - db / 20.0).abs() < 1e-12);
            }
        }
    }
}
