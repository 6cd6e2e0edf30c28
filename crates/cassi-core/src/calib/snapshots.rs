//! Several snapshots of one instrument, each calibrated alone, combined
//! into one answer. The single-snapshot errors are mostly the scene's
//! (a red scene pins the red bands' positions, a textured one misplaces the
//! mask along the dx–a1 ridge), so different scenes err differently and
//! their median averages out the bias a single snapshot cannot see; their
//! scatter measures it. The result is a [`Calibration`] (readable wherever one is)
//! whose [`SnapshotSpread`] holds the snapshots' answers and whether they
//! agree within their own error bars.

use serde::{Deserialize, Serialize};

use super::{Calibration, StageReport, TradeOff, Uncertainty};
use crate::error::CassiError;
use crate::params::{Mismatch, Parameter};
use crate::stats::{chi_squared_sf, median, student_t_two_sided};

/// Where the combination centres each parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Centre {
    /// The snapshots' plain mean.
    Mean,
    /// The mean weighted by each snapshot's stated 1/σ².
    InverseVariance,
    /// The snapshots' median.
    Median,
}

/// How [`combine_snapshots`] combines.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CombineParams {
    pub centre: Centre,
    /// The correlation assumed between two snapshots' errors when their
    /// stated errors are combined: part of a snapshot's error is the
    /// instrument's (the model's bias at that ψ), common to every scene,
    /// which no scatter shows and no average removes. 0.5, set on the
    /// physical benchmark's tuning half (`bench/snapshot_rules.py`): with
    /// independent errors (0) the median's 1σ covered θ in 13 of 20 random
    /// instruments and dy in 4 of 6 aligned ones (0.5: 17 and 6); the single
    /// snapshots' errors, split into a part common to an instrument's five
    /// and a part of each, put 0.2–0.7 of the variance in the common part
    /// (dx and σ least, α most; the first ten instruments).
    pub snapshot_correlation: f64,
    /// The p-value of the snapshots' χ² (their scatter against their stated
    /// errors) below which a parameter is reported as disagreeing.
    pub disagree_below_p: f64,
}

/// The defaults were chosen on the physical benchmark's tuning half: 20
/// random and 6 aligned instruments, each imaging the five tuning scenes
/// (`bench/results/calibrate_snapshots_tuning.json`, `…_round1.json`;
/// `bench/snapshot_rules.py … --rho=0.5`). The median and the mean put as
/// many random instruments' six parameters within tolerance (14 of 20; the
/// single snapshots 47 of 100) but one snapshot 0.98 px off in dx moved the
/// mean 0.25 px (dx RMSE 0.060 px against the median's 0.027), and two
/// clusters of answers (the real snapshots' dy–α placements) have a mean
/// that neither supports. With ρ = 0.5 the median's 1σ covered dx 19, dy
/// 19, θ 17, a1 19, α 18, σ 20 of 20, its 95 % interval all 20 of each.
impl Default for CombineParams {
    fn default() -> Self {
        Self {
            centre: Centre::Median,
            snapshot_correlation: 0.5,
            disagree_below_p: 0.01,
        }
    }
}

/// Whether the snapshots agree on one parameter within their stated errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Consistency {
    pub parameter: Parameter,
    /// Σ (xᵢ − x̄_w)² / σᵢ², x̄_w the inverse-variance mean.
    pub chi_squared: f64,
    /// Snapshots − 1.
    pub dof: usize,
    /// P(χ²_dof ≥ `chi_squared`): small when the snapshots scatter more than
    /// their error bars say.
    pub p_value: f64,
    /// The snapshots' standard deviation.
    pub spread: f64,
    /// The snapshot (its index) without which the others agree best (the
    /// smallest χ² of the rest): the one farthest out; `None` for two
    /// snapshots, where either is. Not the largest term of `chi_squared`:
    /// a snapshot with too small an error bar pulls x̄_w to itself and
    /// makes the others look far.
    pub farthest: Option<usize>,
    /// `p_value` < [`CombineParams::disagree_below_p`].
    pub disagree: bool,
}

/// What a combined calibration was combined from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SnapshotSpread {
    pub params: CombineParams,
    /// Each snapshot's answer, in the order given.
    pub parameters: Vec<Mismatch>,
    /// Per calibrated parameter whose errors every snapshot stated.
    pub consistency: Vec<Consistency>,
    /// Where the answer is the snapshots' joint fit
    /// ([`super::refit_jointly`]): the combination it started from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint_fit_from: Option<Mismatch>,
}

/// One parameter's combination: centre, standard error, 95 % half-width
/// (each where every snapshot stated one).
struct Combined {
    value: f64,
    standard: Option<f64>,
    interval_95: Option<f64>,
}

/// `calibrations` (two or more, of one instrument: the same model and
/// preset, and one held curvature or a curvature fitted in every one)
/// combined into one [`Calibration`]: each calibrated parameter (a fitted
/// curvature too) centred as `params` says (by default the median),
/// with the larger of
/// two error bars — the snapshots' stated errors combined as correlated at
/// [`CombineParams::snapshot_correlation`] (σ √((1 + ρ(K − 1))/K) for the
/// mean of K equal σ) and their scatter (s/√K for the mean, s their
/// standard deviation, scaled by Student's t at K − 1 degrees of freedom
/// for 68.27 % and 95 %); the median's both √(π/2) the mean's. A
/// standard error (95 % half-width) only where every snapshot stated one:
/// the combination states no error bar whose kind was not stated (the
/// rounded model's a1, the paper preset's intervals). The
/// stages are the snapshots' answers ("snapshot i"); σ to reconstruct with
/// is theirs centred alike (the median, or the mean); the pairs named are
/// those at least half the snapshots named. Scores are the snapshots'
/// means (each on its own measurement, so not comparable with a single
/// calibration's).
pub fn combine_snapshots(
    calibrations: &[&Calibration],
    params: &CombineParams,
) -> Result<Calibration, CassiError> {
    let k = calibrations.len();
    if k < 2 {
        return Err(CassiError::Meaningless {
            what: "combining snapshots".into(),
            reason: format!("{k} calibration given; combining needs two or more"),
        });
    }
    let first = calibrations[0];
    // a curvature every snapshot fitted (each states its error) combines
    // like the other parameters; a held one must be one value
    let fitted_curvature = calibrations
        .iter()
        .all(|c| c.uncertainty.get(Parameter::A2).is_some());
    for (i, c) in calibrations.iter().enumerate() {
        if c.model != first.model {
            return Err(CassiError::Meaningless {
                what: format!("snapshot {i}'s calibration"),
                reason: format!(
                    "model {:?}, snapshot 0's {:?}: one instrument, one model",
                    c.model, first.model
                ),
            });
        }
        if c.preset != first.preset {
            return Err(CassiError::Meaningless {
                what: format!("snapshot {i}'s calibration"),
                reason: format!(
                    "preset {:?}, snapshot 0's {:?}: their error bars mean different things; \
                     calibrate every snapshot with one preset",
                    c.preset, first.preset
                ),
            });
        }
        if c.band_offsets != first.band_offsets {
            return Err(CassiError::Meaningless {
                what: format!("snapshot {i}'s calibration"),
                reason: "its band offsets differ from snapshot 0's: one instrument, one band \
                         table held — calibrate every snapshot with the same --band-offsets"
                    .into(),
            });
        }
        if c.band_spread != first.band_spread {
            return Err(CassiError::Meaningless {
                what: format!("snapshot {i}'s calibration"),
                reason: format!(
                    "its band spread ({}) differs from snapshot 0's ({}): one instrument, one \
                     model — calibrate every snapshot with the same --band-spread",
                    c.band_spread.name(),
                    first.band_spread.name()
                ),
            });
        }
        if !fitted_curvature && c.parameters.a2 != first.parameters.a2 {
            return Err(CassiError::Meaningless {
                what: format!("snapshot {i}'s calibration"),
                reason: format!(
                    "curvature a2 {}, snapshot 0's {}, not fitted in all of them (no stated \
                     error): one instrument, one held curvature — hold one value, or fit it in \
                     every snapshot (--fit-curvature)",
                    c.parameters.a2, first.parameters.a2
                ),
            });
        }
    }
    let mut parameters = first.parameters;
    let mut standard = Uncertainty::default();
    let mut interval_95 = Uncertainty::default();
    let mut consistency = Vec::new();
    let combined_parameters = Parameter::CALIBRATED
        .into_iter()
        .chain(fitted_curvature.then_some(Parameter::A2));
    for p in combined_parameters {
        let values: Vec<f64> = calibrations.iter().map(|c| p.get(&c.parameters)).collect();
        let sigmas: Option<Vec<f64>> = calibrations.iter().map(|c| c.uncertainty.get(p)).collect();
        let halves: Option<Vec<f64>> = calibrations.iter().map(|c| c.interval_95.get(p)).collect();
        let combined = combine(&values, sigmas.as_deref(), halves.as_deref(), params);
        p.set(&mut parameters, combined.value);
        standard.0.insert(p, combined.standard);
        interval_95.0.insert(p, combined.interval_95);
        if let Some(s) = sigmas.as_deref().filter(|s| s.iter().all(|&s| s > 0.0)) {
            consistency.push(agreement(p, &values, s, params.disagree_below_p));
        }
    }
    parameters.blur_sigma_px = parameters.blur_sigma_px.abs();
    // the σ each model fits and the margins each centred alike (none
    // where no snapshot has one)
    let centred = |values: &[f64]| match params.centre {
        Centre::Median => median(values),
        Centre::Mean | Centre::InverseVariance => mean(values),
    };
    let model_sigma: Vec<f64> = calibrations
        .iter()
        .map(|c| c.model_blur_sigma_px.unwrap_or(c.parameters.blur_sigma_px))
        .collect();
    let model_blur_sigma_px = calibrations
        .iter()
        .any(|c| c.model_blur_sigma_px.is_some())
        .then(|| centred(&model_sigma));
    let margins: Vec<f64> = calibrations
        .iter()
        .map(|c| c.on_grid_margin_px.unwrap_or(0.0))
        .collect();
    let on_grid_margin_px = calibrations
        .iter()
        .any(|c| c.on_grid_margin_px.is_some())
        .then(|| centred(&margins));
    let stages = calibrations
        .iter()
        .enumerate()
        .map(|(i, c)| StageReport {
            name: format!("snapshot {i}"),
            evaluations: c.evaluations,
            seconds: c.seconds,
            parameters: c.parameters,
            score: c.score,
            passed_over: None,
        })
        .collect();
    Ok(Calibration {
        preset: first.preset.clone(),
        model: first.model,
        parameters,
        score: mean(&calibrations.iter().map(|c| c.score).collect::<Vec<_>>()),
        nominal_score: mean(
            &calibrations
                .iter()
                .map(|c| c.nominal_score)
                .collect::<Vec<_>>(),
        ),
        uncertainty: standard,
        interval_95,
        trade_offs: named_by_half(calibrations),
        uncertainty_fit: None,
        ridge_probes: None,
        model_blur_sigma_px,
        on_grid_margin_px,
        band_offsets: first.band_offsets.clone(),
        band_spread: first.band_spread,
        stages,
        seconds: calibrations.iter().map(|c| c.seconds).sum(),
        evaluations: calibrations.iter().map(|c| c.evaluations).sum(),
        snapshots: Some(SnapshotSpread {
            params: *params,
            parameters: calibrations.iter().map(|c| c.parameters).collect(),
            consistency,
            joint_fit_from: None,
        }),
    })
}

/// One parameter over the snapshots: `values`, their stated standard
/// errors and 95 % half-widths where every snapshot has one.
fn combine(
    values: &[f64],
    sigmas: Option<&[f64]>,
    halves: Option<&[f64]>,
    params: &CombineParams,
) -> Combined {
    let k = values.len() as f64;
    let dof = k - 1.0;
    let positive = sigmas.filter(|s| s.iter().all(|&s| s > 0.0));
    // the centre as a weighted mean (the median: the mean's weights, its
    // errors √(π/2) the mean's for normal errors)
    let (weights, value, factor) = match (params.centre, positive) {
        (Centre::InverseVariance, Some(s)) => {
            let w: Vec<f64> = s.iter().map(|s| 1.0 / (s * s)).collect();
            let sum: f64 = w.iter().sum();
            let a: Vec<f64> = w.iter().map(|w| w / sum).collect();
            let value = values.iter().zip(&a).map(|(x, a)| x * a).sum();
            (a, value, 1.0)
        }
        (Centre::Median, _) => (
            vec![1.0 / k; values.len()],
            median(values),
            std::f64::consts::FRAC_PI_2.sqrt(),
        ),
        _ => (vec![1.0 / k; values.len()], mean(values), 1.0),
    };
    let rho = params.snapshot_correlation;
    // Var Σ aᵢeᵢ for errors of standard deviations `s` correlated at ρ
    let formal = |s: &[f64]| {
        let own: f64 = weights.iter().zip(s).map(|(a, s)| (a * s).powi(2)).sum();
        let all: f64 = weights.iter().zip(s).map(|(a, s)| a * s).sum();
        factor * (own + rho * (all * all - own)).max(0.0).sqrt()
    };
    // the scatter about the weighted mean, as its standard error:
    // √(Σ aᵢ (xᵢ − x̄)² / (K − 1)) — s/√K for equal weights, the formal
    // error times the Birge ratio √(χ²/(K − 1)) for inverse-variance ones
    let scatter = {
        let centre: f64 = values.iter().zip(&weights).map(|(x, a)| x * a).sum();
        let ss: f64 = values
            .iter()
            .zip(&weights)
            .map(|(x, a)| a * (x - centre).powi(2))
            .sum();
        factor * (ss / dof).sqrt()
    };
    let t68 = student_t_two_sided(ONE_SIGMA, dof);
    let t95 = student_t_two_sided(0.95, dof);
    Combined {
        value,
        standard: sigmas.map(|s| formal(s).max(t68 * scatter)),
        interval_95: halves.map(|h| formal(h).max(t95 * scatter)),
    }
}

/// The coverage of ±1σ of a normal distribution.
const ONE_SIGMA: f64 = 0.682_689_492_137_086;

/// Σ wᵢ (xᵢ − x̄_w)² over the snapshots `keep` says.
fn chi_squared_of(values: &[f64], w: &[f64], keep: impl Fn(usize) -> bool) -> f64 {
    let (mut sum, mut weight) = (0.0, 0.0);
    for i in (0..values.len()).filter(|&i| keep(i)) {
        sum += w[i] * values[i];
        weight += w[i];
    }
    let centre = sum / weight;
    (0..values.len())
        .filter(|&i| keep(i))
        .map(|i| w[i] * (values[i] - centre).powi(2))
        .sum()
}

fn agreement(p: Parameter, values: &[f64], sigmas: &[f64], below_p: f64) -> Consistency {
    let w: Vec<f64> = sigmas.iter().map(|s| 1.0 / (s * s)).collect();
    let chi_squared = chi_squared_of(values, &w, |_| true);
    let dof = values.len() - 1;
    let p_value = chi_squared_sf(chi_squared, dof as f64);
    let without = |i: usize| chi_squared_of(values, &w, |j| j != i);
    // of two, either is as far out
    let farthest = (values.len() > 2)
        .then(|| (0..values.len()).min_by(|&a, &b| without(a).total_cmp(&without(b))))
        .flatten();
    Consistency {
        parameter: p,
        chi_squared,
        dof,
        p_value,
        spread: sd(values),
        farthest,
        disagree: p_value < below_p,
    }
}

/// The trade-offs at least half the snapshots named, their correlation
/// averaged over those that did.
fn named_by_half(calibrations: &[&Calibration]) -> Vec<TradeOff> {
    let mut out: Vec<TradeOff> = Vec::new();
    let mut counts: Vec<usize> = Vec::new();
    for t in calibrations.iter().flat_map(|c| &c.trade_offs) {
        match out.iter().position(|o| o.a == t.a && o.b == t.b) {
            Some(i) => {
                out[i].correlation += t.correlation;
                counts[i] += 1;
            }
            None => {
                out.push(*t);
                counts.push(1);
            }
        }
    }
    out.into_iter()
        .zip(counts)
        .filter(|&(_, n)| 2 * n >= calibrations.len())
        .map(|(t, n)| TradeOff {
            correlation: t.correlation / n as f64,
            ..t
        })
        .collect()
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// The sample standard deviation (K − 1 in the denominator).
fn sd(v: &[f64]) -> f64 {
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() as f64 - 1.0)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::DispersionModel;
    use crate::rng::Rng;

    /// A calibration answering `dx` (the rest nominal) with the stated 1σ
    /// `sigma` and 95 % half-width 2σ on every parameter.
    fn snapshot(dx: f64, sigma: f64) -> Calibration {
        let stated = |v: f64| {
            Uncertainty(
                Parameter::CALIBRATED
                    .iter()
                    .map(|&p| (p, Some(v)))
                    .collect(),
            )
        };
        Calibration {
            preset: "default".into(),
            model: DispersionModel::DispersedMask,
            parameters: Mismatch {
                dx,
                blur_sigma_px: 0.5,
                ..Mismatch::nominal(2.0)
            },
            score: 1.0,
            nominal_score: 2.0,
            uncertainty: stated(sigma),
            interval_95: stated(2.0 * sigma),
            trade_offs: Vec::new(),
            uncertainty_fit: None,
            ridge_probes: None,
            model_blur_sigma_px: None,
            on_grid_margin_px: None,
            band_offsets: None,
            band_spread: crate::optics::BandSpread::Point,
            snapshots: None,
            stages: Vec::new(),
            seconds: 1.0,
            evaluations: 10,
        }
    }

    fn combined(dx: &[f64], sigma: f64, centre: Centre) -> Calibration {
        let cals: Vec<Calibration> = dx.iter().map(|&d| snapshot(d, sigma)).collect();
        let refs: Vec<&Calibration> = cals.iter().collect();
        let params = CombineParams {
            centre,
            ..CombineParams::default()
        };
        combine_snapshots(&refs, &params).unwrap()
    }

    /// The centres, and the error bar: the stated errors' (σ/√K for the
    /// mean) where the snapshots agree, the scatter's (t · s/√K) where they
    /// do not.
    #[test]
    fn the_mean_and_its_error_bar_come_from_the_snapshots() {
        let dx = [0.1, 0.2, 0.3, 0.4, 1.0];
        let c = combined(&dx, 0.01, Centre::Mean);
        assert!((c.parameters.dx - 0.4).abs() < 1e-12);
        let sd = (dx.iter().map(|x| (x - 0.4f64).powi(2)).sum::<f64>() / 4.0).sqrt();
        let s = c.uncertainty.get(Parameter::Dx).unwrap();
        assert!((s - 1.1417 * sd / 5f64.sqrt()).abs() < 1e-3 * s, "{s}");
        let h = c.interval_95.get(Parameter::Dx).unwrap();
        assert!((h - 2.7764 * sd / 5f64.sqrt()).abs() < 1e-3 * h, "{h}");
        // agreeing snapshots: every dy is nominal, the stated errors rule,
        // correlated at ρ: σ √((1 + ρ(K − 1))/K)
        let shrink = |rho: f64| ((1.0 + rho * 4.0) / 5.0f64).sqrt();
        let rho = CombineParams::default().snapshot_correlation;
        assert!((c.uncertainty.get(Parameter::Dy).unwrap() - 0.01 * shrink(rho)).abs() < 1e-12);
        assert!((c.interval_95.get(Parameter::Dy).unwrap() - 0.02 * shrink(rho)).abs() < 1e-12);
        // independent errors: σ/√K; wholly common ones: σ, no gain
        for rho in [0.0, 1.0] {
            let cals: Vec<Calibration> = dx.iter().map(|&d| snapshot(d, 0.01)).collect();
            let refs: Vec<&Calibration> = cals.iter().collect();
            let params = CombineParams {
                centre: Centre::Mean,
                snapshot_correlation: rho,
                ..CombineParams::default()
            };
            let c = combine_snapshots(&refs, &params).unwrap();
            let dy = c.uncertainty.get(Parameter::Dy).unwrap();
            assert!((dy - 0.01 * shrink(rho)).abs() < 1e-12, "ρ {rho}: {dy}");
        }
        // the median, and the inverse-variance mean (equal σ: the mean)
        assert!((combined(&dx, 0.01, Centre::Median).parameters.dx - 0.3).abs() < 1e-12);
        assert!((combined(&dx, 0.01, Centre::InverseVariance).parameters.dx - 0.4).abs() < 1e-12);
        // dx disagrees far beyond ±0.01, dy agrees
        let spread = c.snapshots.as_ref().unwrap();
        let of = |p| {
            spread
                .consistency
                .iter()
                .find(|c| c.parameter == p)
                .unwrap()
        };
        assert!(of(Parameter::Dx).disagree && of(Parameter::Dx).p_value < 1e-6);
        // without dx 1.0 the others agree best
        assert_eq!(of(Parameter::Dx).farthest, Some(4));
        assert!(!of(Parameter::Dy).disagree);
        assert_eq!(spread.parameters.len(), 5);
        assert_eq!(c.stages.len(), 5);
        assert_eq!(c.evaluations, 50);
    }

    /// One snapshot far out with a tiny error bar pulls the weighted centre
    /// to itself; it is still the one named farthest out.
    #[test]
    fn the_snapshot_named_farthest_out_is_the_one_the_rest_disagree_with() {
        let mut cals: Vec<Calibration> = [0.0, 0.05, -0.05, 0.02]
            .iter()
            .map(|&d| snapshot(d, 0.1))
            .collect();
        cals.push(snapshot(-0.9, 0.003));
        let refs: Vec<&Calibration> = cals.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        let spread = c.snapshots.unwrap();
        let dx = spread
            .consistency
            .iter()
            .find(|c| c.parameter == Parameter::Dx);
        assert!(
            dx.is_some_and(|dx| dx.disagree && dx.farthest == Some(4)),
            "{dx:?}"
        );
    }

    /// Snapshots whose stated errors are 10× too small: the scatter term
    /// makes the 95 % interval cover about 95 % and the 1σ about 68 %
    /// (Student's t at K − 1 dof); honest stated errors are flagged as
    /// disagreeing about as often as the test's level says.
    #[test]
    fn the_combined_intervals_cover_when_the_stated_errors_do_not() {
        let mut rng = Rng::new(7);
        let trials = 4000;
        let (mut in_95, mut in_1, mut flagged) = (0, 0, 0);
        for _ in 0..trials {
            let dx: Vec<f64> = (0..5).map(|_| 0.1 * rng.normal()).collect();
            let c = combined(&dx, 0.01, Centre::Mean);
            let e = c.parameters.dx.abs();
            in_95 += usize::from(e <= c.interval_95.get(Parameter::Dx).unwrap());
            in_1 += usize::from(e <= c.uncertainty.get(Parameter::Dx).unwrap());
            let honest = combined(&dx, 0.1, Centre::Mean);
            let spread = honest.snapshots.unwrap();
            let dx = spread
                .consistency
                .iter()
                .find(|c| c.parameter == Parameter::Dx);
            flagged += usize::from(dx.unwrap().disagree);
        }
        let share = |n: usize| n as f64 / trials as f64;
        assert!(
            (share(in_95) - 0.95).abs() < 0.015,
            "95 %: {}",
            share(in_95)
        );
        assert!((share(in_1) - 0.683).abs() < 0.03, "1σ: {}", share(in_1));
        assert!(share(flagged) < 0.02, "flagged {}", share(flagged));
    }

    #[test]
    fn combining_refuses_one_snapshot_and_mixed_instruments() {
        let a = snapshot(0.0, 0.01);
        assert!(combine_snapshots(&[&a], &CombineParams::default()).is_err());
        let mut b = snapshot(0.1, 0.01);
        b.model = DispersionModel::Subpixel;
        let e = combine_snapshots(&[&a, &b], &CombineParams::default()).unwrap_err();
        assert!(e.to_string().contains("snapshot 1"), "{e}");
        let mut c = snapshot(0.1, 0.01);
        c.parameters.a2 = 0.001;
        assert!(combine_snapshots(&[&a, &c], &CombineParams::default()).is_err());
        // a fitted curvature in one snapshot, held in the other: refused
        c.uncertainty.0.insert(Parameter::A2, Some(0.001));
        let e = combine_snapshots(&[&a, &c], &CombineParams::default()).unwrap_err();
        assert!(e.to_string().contains("--fit-curvature"), "{e}");
        let mut d = snapshot(0.1, 0.01);
        d.preset = "paper".into();
        let e = combine_snapshots(&[&a, &d], &CombineParams::default()).unwrap_err();
        assert!(e.to_string().contains("preset"), "{e}");
    }

    /// Snapshots that each fitted the curvature (each stating its error)
    /// combine it like the other parameters: its value the centre of
    /// theirs, its error stated.
    #[test]
    fn fitted_curvatures_combine_like_the_other_parameters() {
        let cals: Vec<Calibration> = [(0.0, -0.001), (0.1, -0.002), (0.2, -0.003)]
            .iter()
            .map(|&(dx, a2)| {
                let mut c = snapshot(dx, 0.01);
                c.parameters.a2 = a2;
                c.uncertainty.0.insert(Parameter::A2, Some(0.0014));
                c.interval_95.0.insert(Parameter::A2, Some(0.002));
                c
            })
            .collect();
        let refs: Vec<&Calibration> = cals.iter().collect();
        let combined = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        assert!(
            (combined.parameters.a2 + 0.002).abs() < 1e-12,
            "{combined:?}"
        );
        // its errors are the rule's for these values and stated errors
        let rule = combine(
            &[-0.001, -0.002, -0.003],
            Some(&[0.0014; 3]),
            Some(&[0.002; 3]),
            &CombineParams::default(),
        );
        assert_eq!(combined.uncertainty.get(Parameter::A2), rule.standard);
        assert_eq!(combined.interval_95.get(Parameter::A2), rule.interval_95);
        assert!(rule.standard.is_some_and(|s| s > 0.0));
    }

    /// Where the snapshots stated no error bar of a kind (the rounded
    /// model's a1, the paper preset's intervals) the combination states
    /// none either, though their answers scatter.
    #[test]
    fn an_error_bar_the_snapshots_did_not_state_is_not_invented() {
        let mut cals: Vec<Calibration> =
            [0.0, 0.3, 0.7].iter().map(|&d| snapshot(d, 0.01)).collect();
        for c in &mut cals {
            c.interval_95 = Uncertainty::default();
            c.uncertainty.0.insert(Parameter::A1, None);
            c.parameters.a1 += c.parameters.dx / 100.0;
        }
        let refs: Vec<&Calibration> = cals.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        assert!(c.uncertainty.get(Parameter::Dx).is_some_and(|s| s > 0.0));
        assert_eq!(c.uncertainty.get(Parameter::A1), None);
        assert!(
            Parameter::CALIBRATED
                .iter()
                .all(|&p| c.interval_95.get(p).is_none())
        );
        // nor is a1's agreement tested without its errors
        let spread = c.snapshots.unwrap();
        assert!(
            spread
                .consistency
                .iter()
                .all(|k| k.parameter != Parameter::A1)
        );
    }

    /// A trade-off two of three snapshots named is kept, its correlation
    /// their mean; one named once is dropped.
    #[test]
    fn the_trade_offs_kept_are_those_half_the_snapshots_named() {
        let pair = |a, b, correlation| TradeOff { a, b, correlation };
        let mut cals: Vec<Calibration> = (0..3).map(|i| snapshot(i as f64, 0.01)).collect();
        cals[0].trade_offs = vec![pair(Parameter::Dy, Parameter::AlphaDeg, -0.9)];
        cals[1].trade_offs = vec![
            pair(Parameter::Dy, Parameter::AlphaDeg, -0.8),
            pair(Parameter::Dx, Parameter::A1, -0.85),
        ];
        let refs: Vec<&Calibration> = cals.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        assert_eq!(c.trade_offs.len(), 1);
        assert_eq!(c.trade_offs[0].a, Parameter::Dy);
        assert!((c.trade_offs[0].correlation + 0.85).abs() < 1e-12);
    }

    /// The reconstruction σ is the snapshots' centre (two: their mean)
    /// where any had the model's own, the on-grid margins' centre added
    /// where any had one; the record reads back as it was written.
    #[test]
    fn the_combination_is_a_calibration_record() {
        let mut cals: Vec<Calibration> = (0..2).map(|i| snapshot(i as f64, 0.01)).collect();
        cals[0].model_blur_sigma_px = Some(0.4);
        let refs: Vec<&Calibration> = cals.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        assert!((c.model_blur_sigma_px.unwrap() - 0.45).abs() < 1e-12);
        assert!((c.reconstruction_parameters().blur_sigma_px - 0.45).abs() < 1e-12);
        assert_eq!(c.on_grid_margin_px, None);
        // one snapshot on the pixel grid: its margin centred with the other's none
        cals[1].on_grid_margin_px = Some(0.03);
        let refs: Vec<&Calibration> = cals.iter().collect();
        let c = combine_snapshots(&refs, &CombineParams::default()).unwrap();
        assert!((c.on_grid_margin_px.unwrap() - 0.015).abs() < 1e-12);
        assert!((c.reconstruction_parameters().blur_sigma_px - 0.465).abs() < 1e-12);
        let json = serde_json::to_string(&c).unwrap();
        let back: Calibration = serde_json::from_str(&json).unwrap();
        assert_eq!(serde_json::to_string(&back).unwrap(), json);
        assert_eq!(back.snapshots, c.snapshots);
    }
}
