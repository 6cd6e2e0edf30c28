//! Several snapshots of one instrument fitted as one: one ψ, each
//! snapshot its own coarse scene, the scene fit's objectives averaged.
//! Combining answers ([`super::combine_snapshots`]) averages what each
//! snapshot's blind fit concluded; the joint fit lets every snapshot's data
//! pull on one geometry, so a snapshot whose scene pins dx but not a1 and
//! one that pins a1 but not dx each lend the other what it lacks.
//!
//! It refits the geometry (dx, dy, θ, a1, α) from a start — the snapshots'
//! combination — by the default's detail pass and then its fine pass, each
//! with every snapshot's objective averaged (each ‖r‖²/‖H y‖², so a bright
//! snapshot does not outweigh a dim one); σ stays the start's (the scene
//! fit's own σ; the blur pass's is the instrument's, kept by the caller).

use super::detail_pass::DetailPass;
use super::quasi_newton::{LeastSquares, minimise};
use super::scene_fit::{FinePass, SceneFit, SceneFitSettings, Solved, settled_step};
use super::{Calibration, CalibrationProblem, DefaultPreset, Parameter, ProxyParams, StageReport};
use crate::error::{CassiError, Result};
use crate::params::Mismatch;

use std::time::Instant;

/// What the joint fit found.
#[derive(Debug, Clone)]
pub struct JointFit {
    /// The fine pass's answer (σ the start's).
    pub parameters: Mismatch,
    /// Its two passes: the detail pass, then the fine pass (each score the
    /// snapshots' mean; the fine pass's penalised).
    pub stages: Vec<StageReport>,
}

/// The name of the joint fit's detail pass in the stage reports.
pub const JOINT_DETAIL_PASS_STAGE: &str =
    "joint fit's detail pass (one ψ, each snapshot's coarse scene × texture)";

/// The name of the joint fit's fine pass in the stage reports, its node
/// spacing then said: "… (one ψ, each snapshot's 4-px scene, ridge)".
pub const JOINT_FINE_PASS_STAGE: &str = "joint fit's fine pass";

/// One ψ with every snapshot's coarse scene solved at it.
struct JointPoint {
    psi: Mismatch,
    each: Vec<Solved>,
    /// Every snapshot's residual divided by √‖H y‖², one after another.
    residual: Vec<f32>,
}

/// The snapshots' fits over the `free` parameters of their one ψ.
struct Joint<'a, 'f> {
    fits: &'a [SceneFit<'f>],
    free: &'a [Parameter],
}

impl Joint<'_, '_> {
    fn point(&self, psi: Mismatch, each: Vec<Solved>) -> JointPoint {
        let mut residual = Vec::with_capacity(each.iter().map(|s| s.residual.len()).sum());
        for (fit, solved) in self.fits.iter().zip(&each) {
            let scale = (1.0 / fit.data_energy().max(f64::MIN_POSITIVE).sqrt()) as f32;
            residual.extend(solved.residual.iter().map(|&r| r * scale));
        }
        JointPoint {
            psi,
            each,
            residual,
        }
    }

    /// Every snapshot solved at `psi`, from `from`'s scenes by `solve`.
    fn solve_all(
        &self,
        psi: &Mismatch,
        from: &[&[f32]],
        solve: impl Fn(&SceneFit<'_>, &Mismatch, &[f32]) -> Result<Solved>,
    ) -> Result<JointPoint> {
        let each = self
            .fits
            .iter()
            .zip(from)
            .map(|(fit, z)| solve(fit, psi, z))
            .collect::<Result<Vec<_>>>()?;
        Ok(self.point(*psi, each))
    }
}

impl LeastSquares for Joint<'_, '_> {
    type Point = JointPoint;
    fn coordinates(&self, at: &JointPoint) -> Vec<f64> {
        self.free.iter().map(|&p| p.get(&at.psi)).collect()
    }
    fn residual<'p>(&self, at: &'p JointPoint) -> &'p [f32] {
        &at.residual
    }
    /// The snapshots' mean score (a ridge's penalty included, as each
    /// fit's own score has it).
    fn score(&self, at: &JointPoint) -> f64 {
        at.each.iter().map(|s| s.score).sum::<f64>() / self.fits.len() as f64
    }
    /// ‖r‖² of the scaled residual is the scores' sum: E = their count.
    fn energy(&self) -> f64 {
        self.fits.len() as f64
    }
    fn step(&self, at: &JointPoint, step: &[f64]) -> Result<JointPoint> {
        let mut psi = at.psi;
        for (&p, &d) in self.free.iter().zip(step) {
            let v = p.get(&psi) + d;
            p.set(&mut psi, v);
        }
        psi.blur_sigma_px = psi.blur_sigma_px.abs();
        let from: Vec<&[f32]> = at.each.iter().map(|s| s.z.as_slice()).collect();
        self.solve_all(&psi, &from, |fit, psi, z| fit.solve(psi, Some(z)))
    }
    fn jacobian(&self, at: &JointPoint) -> Result<Vec<Vec<f32>>> {
        let mut columns = vec![Vec::with_capacity(at.residual.len()); self.free.len()];
        for (fit, solved) in self.fits.iter().zip(&at.each) {
            let scale = (1.0 / fit.data_energy().max(f64::MIN_POSITIVE).sqrt()) as f32;
            for (column, part) in columns.iter_mut().zip(fit.jacobian(solved, self.free)?) {
                column.extend(part.iter().map(|&v| v * scale));
            }
        }
        Ok(columns)
    }
    fn settled(&self, step: &[f64]) -> bool {
        self.free
            .iter()
            .zip(step)
            .all(|(&p, &d)| d.abs() < settled_step(p))
    }
}

/// The geometry of `problems` (snapshots of one instrument: one mask, one
/// band count, one model) fitted jointly from `start` by `settings`'
/// detail pass and fine pass (both must be on), the detail maps made by
/// `proxy` at `start`.
pub fn joint_scene_fit(
    problems: &[CalibrationProblem<'_>],
    settings: &SceneFitSettings,
    proxy: &ProxyParams,
    start: &Mismatch,
) -> Result<JointFit> {
    let invalid = |reason: String| CassiError::Meaningless {
        what: "a joint fit of several snapshots".into(),
        reason,
    };
    if problems.len() < 2 {
        return Err(invalid(format!(
            "a joint fit needs two snapshots or more, got {}",
            problems.len()
        )));
    }
    let first = &problems[0];
    for (i, p) in problems.iter().enumerate() {
        p.validate()?;
        if p.bands() != first.bands() || p.model() != first.model() {
            return Err(invalid(format!(
                "snapshot {i}: {} bands, model {:?}; snapshot 0: {} bands, model {:?}",
                p.bands(),
                p.model(),
                first.bands(),
                first.model()
            )));
        }
    }
    let (Some(detail), Some(fine)) = (settings.detail_pass, settings.fine_pass) else {
        return Err(invalid(
            "the joint fit runs the scene fit's detail and fine passes: both must be on".into(),
        ));
    };
    let smooth = settings.first_pass_only();
    let firsts = problems
        .iter()
        .map(|p| SceneFit::new(p, smooth))
        .collect::<Result<Vec<_>>>()?;
    let report = |name: &str, t0: Instant, found: &(JointPoint, usize)| StageReport {
        name: name.into(),
        evaluations: found.1,
        seconds: t0.elapsed().as_secs_f64(),
        parameters: found.0.psi,
        score: mean_score(&found.0),
        passed_over: None,
    };
    let t0 = Instant::now();
    let detailed = detail_pass(problems, &firsts, settings, &detail, proxy, start)?;
    let detail_stage = report(JOINT_DETAIL_PASS_STAGE, t0, &detailed);
    let t0 = Instant::now();
    let fined = fine_pass(problems, &firsts, settings, &fine, &detailed)?;
    Ok(JointFit {
        parameters: fined.0.psi,
        stages: vec![
            detail_stage,
            report(
                &format!(
                    "{JOINT_FINE_PASS_STAGE} (one ψ, each snapshot's {}-px scene, ridge)",
                    fine.cell_px
                ),
                t0,
                &fined,
            ),
        ],
    })
}

fn mean_score(at: &JointPoint) -> f64 {
    at.each.iter().map(|s| s.score).sum::<f64>() / at.each.len() as f64
}

/// `combined` (the snapshots' combination, [`super::combine_snapshots`])
/// refitted by [`joint_scene_fit`] on the snapshots' measurements
/// (`problems`, in the combination's order) from the combination's
/// answer with the scene fit's own σ: the geometry the joint fit's, σ the
/// combination's (the blur pass's σ, the instrument's; the scene fit's own
/// σ to reconstruct with stays the combination's too), every error bar the
/// combination's — on the physical benchmark the joint answer is within
/// the combination's 95 % interval in every parameter of all 26 tuning and
/// all 19 held-out instruments (`bench/joint_fit_table.py`). The combination's
/// answer is kept in [`super::SnapshotSpread::joint_fit_from`]; the two
/// passes are added to the stages.
pub fn refit_jointly(
    combined: &Calibration,
    problems: &[CalibrationProblem<'_>],
    preset: &DefaultPreset,
) -> Result<Calibration> {
    let refuse = |reason: String| CassiError::Meaningless {
        what: "refitting a combination jointly".into(),
        reason,
    };
    let Some(spread) = &combined.snapshots else {
        return Err(refuse(
            "the calibration is not a combination of snapshots (cassi combine)".into(),
        ));
    };
    if spread.joint_fit_from.is_some() {
        return Err(refuse(
            "the combination has been refitted jointly already".into(),
        ));
    }
    if spread.parameters.len() != problems.len() {
        return Err(refuse(format!(
            "{} snapshots combined, {} measurements given: one per snapshot, in order",
            spread.parameters.len(),
            problems.len()
        )));
    }
    if let Some(p) = problems.iter().find(|p| p.model() != combined.model) {
        return Err(refuse(format!(
            "the combination is of the {:?} model, a measurement's problem the {:?}",
            combined.model,
            p.model()
        )));
    }
    if problems.iter().any(|p| {
        p.band_offsets() != combined.band_offsets.as_ref()
            || p.band_spread() != combined.band_spread
    }) {
        return Err(refuse(
            "the measurements' problems must hold the band offsets and band spread the \
             snapshots were calibrated with (the combination's)"
                .into(),
        ));
    }
    if !combined.model.samples_mask_per_band() {
        return Err(refuse(format!(
            "the joint fit is the scene fit's, which the {:?} model does not run (it needs a model \
             that samples the mask per band: dispersed-mask or crisp-cells)",
            combined.model
        )));
    }
    let settings = preset
        .scene_fit
        .ok_or_else(|| refuse("the joint fit is the scene fit's: the preset has none".into()))?;
    let start = Mismatch {
        blur_sigma_px: combined.reconstruction_parameters().blur_sigma_px,
        ..combined.parameters
    };
    let fit = joint_scene_fit(problems, &settings, &preset.proxy, &start)?;
    let mut out = combined.clone();
    out.parameters = Mismatch {
        blur_sigma_px: combined.parameters.blur_sigma_px,
        ..fit.parameters
    };
    for stage in fit.stages {
        out.seconds += stage.seconds;
        out.evaluations += stage.evaluations;
        out.stages.push(stage);
    }
    if let Some(spread) = &mut out.snapshots {
        spread.joint_fit_from = Some(combined.parameters);
    }
    Ok(out)
}

/// The pass's free parameters that the default's passes move (σ held).
fn geometry(free: &[Parameter]) -> Vec<Parameter> {
    free.iter()
        .copied()
        .filter(|&p| p != Parameter::BlurSigmaPx)
        .collect()
}

/// Each snapshot's scene × its own detail map, the geometry refitted
/// jointly from `start`; each scene starts from its smooth fit's at
/// `start` (from zero where the detail pass would start cold).
fn detail_pass(
    problems: &[CalibrationProblem<'_>],
    firsts: &[SceneFit<'_>],
    settings: &SceneFitSettings,
    pass: &DetailPass,
    proxy: &ProxyParams,
    start: &Mismatch,
) -> Result<(JointPoint, usize)> {
    let fits = problems
        .iter()
        .map(|p| Ok(SceneFit::new(p, *settings)?.with_detail(pass.detail_map(p, start, proxy)?)))
        .collect::<Result<Vec<_>>>()?;
    let cold = pass.starts_cold(start.blur_sigma_px);
    let smooth: Vec<Vec<f32>> = if cold {
        vec![Vec::new(); fits.len()]
    } else {
        firsts
            .iter()
            .map(|f| Ok(f.solve(start, None)?.z))
            .collect::<Result<_>>()?
    };
    let free = geometry(pass.free.parameters());
    let joint = Joint {
        fits: &fits,
        free: &free,
    };
    let from: Vec<&[f32]> = smooth.iter().map(Vec::as_slice).collect();
    let first = joint.solve_all(start, &from, |fit, psi, z| {
        fit.solve_cold(psi, (!z.is_empty()).then_some(z))
    })?;
    let found = minimise(&joint, first, settings.max_steps)?;
    Ok((found.best, fits.len() * (2 + found.evaluations)))
}

/// Each snapshot's scene on the fine pass's nodes, ridge-anchored at its
/// detail pass's smooth factor, the geometry refitted jointly from the
/// detail pass's answer.
fn fine_pass(
    problems: &[CalibrationProblem<'_>],
    firsts: &[SceneFit<'_>],
    settings: &SceneFitSettings,
    pass: &FinePass,
    detailed: &(JointPoint, usize),
) -> Result<(JointPoint, usize)> {
    let fine_settings = SceneFitSettings {
        cell_px: pass.cell_px,
        cold_solve: pass.first_solve,
        max_steps: pass.max_steps,
        fine_pass: None,
        ..*settings
    };
    let mut fits = Vec::with_capacity(problems.len());
    let mut scenes = Vec::with_capacity(problems.len());
    for ((p, first), solved) in problems.iter().zip(firsts).zip(&detailed.0.each) {
        let fine = SceneFit::new(p, fine_settings)?;
        let scene = fine.coefficients_from(first, &solved.z);
        let anchor = match pass.anchor {
            super::RidgeAnchor::Zero => None,
            super::RidgeAnchor::FirstPassScene => Some(scene.clone()),
        };
        fits.push(fine.with_ridge(pass.ridge, anchor));
        scenes.push(scene);
    }
    let free = geometry(pass.free.parameters());
    let joint = Joint {
        fits: &fits,
        free: &free,
    };
    let from: Vec<&[f32]> = scenes.iter().map(Vec::as_slice).collect();
    let first = joint.solve_all(&detailed.0.psi, &from, |fit, psi, z| {
        fit.solve_cold(psi, Some(z))
    })?;
    let found = minimise(&joint, first, pass.max_steps)?;
    Ok((found.best, fits.len() * (1 + found.evaluations)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::DefaultPreset;
    use crate::calib::quasi_newton::normal_equations;
    use crate::calib::scene_fit::tests::{BANDS, measured_scene, truth};
    use crate::optics::DispersionModel;
    use crate::solvers::CglsParams;

    fn problem<'a>(y: &'a crate::Measurement, mask: &'a crate::Mask) -> CalibrationProblem<'a> {
        CalibrationProblem::nominal(y, mask, BANDS, 2.0, DispersionModel::DispersedMask).unwrap()
    }

    /// The joint score is the snapshots' mean score, and 2 Jᵀr / E of the
    /// scaled, stacked residual is its derivative with every scene
    /// re-solved — with the fine pass's ridge too, whose penalty is in the
    /// score and not in r.
    #[test]
    fn the_joint_gradient_is_the_mean_scores_derivative() {
        let (y1, mask) = measured_scene(&truth(), true, 5);
        let (y2, _) = measured_scene(&truth(), true, 6);
        let problems = [problem(&y1, &mask), problem(&y2, &mask)];
        let converged = CglsParams {
            iterations: 400,
            tolerance: 1e-9,
        };
        let settings = SceneFitSettings {
            cold_solve: converged,
            warm_solve: converged,
            ..SceneFitSettings::default()
        };
        let at = Mismatch {
            dx: 0.45,
            dy: -0.5,
            blur_sigma_px: 0.7,
            ..truth()
        };
        for ridge in [0.0, FinePass::default().ridge] {
            let fits: Vec<SceneFit<'_>> = problems
                .iter()
                .map(|p| SceneFit::new(p, settings).unwrap().with_ridge(ridge, None))
                .collect();
            let free = geometry(&Parameter::CALIBRATED);
            let joint = Joint {
                fits: &fits,
                free: &free,
            };
            let no_scene: Vec<&[f32]> = vec![&[], &[]];
            let point = joint
                .solve_all(&at, &no_scene, |fit, psi, _| fit.solve(psi, None))
                .unwrap();
            let alone: Vec<f64> = fits
                .iter()
                .map(|f| f.solve(&at, None).unwrap().score)
                .collect();
            let mean = (alone[0] + alone[1]) / 2.0;
            assert!(
                (joint.score(&point) - mean).abs() <= 1e-9 * mean,
                "ridge {ridge}"
            );
            if ridge == 0.0 {
                let stacked: f64 = point.residual.iter().map(|&r| r as f64 * r as f64).sum();
                assert!((stacked / joint.energy() - mean).abs() <= 1e-4 * mean);
            }
            let columns = joint.jacobian(&point).unwrap();
            let (_, jtr) = normal_equations(&columns, &point.residual);
            for (i, &p) in free.iter().enumerate() {
                let analytic = 2.0 * jtr[i] / joint.energy();
                // four of the Jacobian's difference steps (five settled steps each)
                let h = 20.0 * settled_step(p);
                let score = |d: f64| {
                    let mut step = vec![0.0; free.len()];
                    step[i] = d;
                    joint.score(&joint.step(&point, &step).unwrap())
                };
                let numeric = (score(h) - score(-h)) / (2.0 * h);
                assert!(
                    (analytic - numeric).abs() <= 0.1 * numeric.abs().max(1e-3 * mean / h),
                    "ridge {ridge}, {p:?}: held-z {analytic:.4e}, re-solved {numeric:.4e}"
                );
            }
        }
    }

    /// Two snapshots of one instrument (different scenes; the 4×
    /// oversampled simulator with noise: no operator the fit uses made
    /// them), from a start 0.15 px, 0.006 px/band and 0.15° off: the joint
    /// fit returns the geometry within the tolerances, lowers its
    /// objective, and holds σ.
    #[test]
    fn the_joint_fit_recovers_an_instrument_from_two_scenes() {
        let t = truth();
        let (y1, mask) = measured_scene(&t, true, 5);
        let (y2, _) = measured_scene(&t, true, 6);
        let problems = [problem(&y1, &mask), problem(&y2, &mask)];
        let preset = DefaultPreset::default();
        let settings = preset.scene_fit.unwrap();
        let start = Mismatch {
            dx: t.dx + 0.15,
            dy: t.dy - 0.1,
            a1: t.a1 + 0.006,
            alpha_deg: t.alpha_deg + 0.15,
            ..t
        };
        let found = joint_scene_fit(&problems, &settings, &preset.proxy, &start).unwrap();
        for (p, tol) in [
            (Parameter::Dx, 0.05),
            (Parameter::Dy, 0.05),
            (Parameter::ThetaDeg, 0.05),
            (Parameter::A1, 0.005),
            (Parameter::AlphaDeg, 0.1),
        ] {
            let e = p.get(&found.parameters) - p.get(&t);
            assert!(
                e.abs() <= tol,
                "{p:?} error {e:+.4} ({:?})",
                found.parameters
            );
        }
        assert_eq!(found.parameters.blur_sigma_px, start.blur_sigma_px);
        let names: Vec<&str> = found.stages.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names[0], JOINT_DETAIL_PASS_STAGE);
        assert_eq!(
            names[1],
            "joint fit's fine pass (one ψ, each snapshot's 4-px scene, ridge)"
        );
        assert_eq!(found.stages[1].parameters, found.parameters);
        assert!(
            found
                .stages
                .iter()
                .all(|s| s.evaluations > 2 * problems.len())
        );
    }

    /// One snapshot, snapshots of different band counts, or a scene fit
    /// without its detail or fine pass: refused, saying why.
    #[test]
    fn what_is_not_a_joint_fit_is_refused() {
        let (y1, mask) = measured_scene(&truth(), false, 5);
        let preset = DefaultPreset::default();
        let settings = preset.scene_fit.unwrap();
        let one = [problem(&y1, &mask)];
        let err = joint_scene_fit(&one, &settings, &preset.proxy, &truth()).unwrap_err();
        assert!(
            err.to_string().contains("two snapshots or more, got 1"),
            "{err}"
        );
        let other_bands =
            CalibrationProblem::nominal(&y1, &mask, BANDS - 2, 2.0, DispersionModel::DispersedMask)
                .unwrap();
        let two = [problem(&y1, &mask), other_bands];
        let err = joint_scene_fit(&two, &settings, &preset.proxy, &truth()).unwrap_err();
        assert!(err.to_string().contains("snapshot 1: 14 bands"), "{err}");
        let same = [problem(&y1, &mask), problem(&y1, &mask)];
        for off in [
            SceneFitSettings {
                detail_pass: None,
                ..settings
            },
            SceneFitSettings {
                fine_pass: None,
                ..settings
            },
        ] {
            let err = joint_scene_fit(&same, &off, &preset.proxy, &truth()).unwrap_err();
            assert!(err.to_string().contains("both must be on"), "{err}");
        }
    }
}
