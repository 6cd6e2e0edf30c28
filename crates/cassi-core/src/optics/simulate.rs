//! A CASSI snapshot of a scene through the true (mismatched) instrument.

use serde::{Deserialize, Serialize};

use super::dispersion::{Dispersion, DispersionModel};
use super::model_operator::ModelOperator;
use super::noise::NoiseModel;
use super::operator::CassiOperator;
use crate::cube::{Cube, Frame, Mask, Measurement};
use crate::error::{Result, shape_error};
use crate::params::Mismatch;

/// Everything besides the scene and the nominal mask that fixes a simulated
/// measurement; stored beside it so it can be reproduced.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimulationSpec {
    /// The true instrument relative to the nominal one.
    pub mismatch: Mismatch,
    pub model: DispersionModel,
    /// `None`: a noise-free measurement.
    pub noise: Option<NoiseModel>,
}

/// y = A_true x (+ noise). The scene must have the mask's rows and cols.
pub fn simulate(scene: &Cube, nominal_mask: &Mask, spec: &SimulationSpec) -> Result<Measurement> {
    check_inputs(scene, nominal_mask)?;
    let op = ModelOperator::new(nominal_mask, scene.bands(), &spec.mismatch, spec.model)?;
    let clean = op.forward(scene)?;
    match &spec.noise {
        Some(noise) => noise.apply(&clean),
        None => Ok(clean),
    }
}

/// Like [`simulate`], but the instrument is modelled on a `factor`× finer
/// grid (each scene and mask pixel split into factor × factor, shifts and
/// dispersion scaled by `factor`, rotation about the same centre) and the
/// detector binned back by averaging. The result has the shape `simulate`
/// gives, yet was not made by the operator a reconstruction uses: an
/// evaluation with the true parameters is then not an inverse crime.
///
/// This is the older, simpler 2× study model (block-replicated scene, the
/// bilinearly warped block mask, the discrete `model` on the fine grid) that
/// `cassi-eval`'s subpixel study uses; it is kept as it is so that study's
/// numbers stay comparable. The physical instrument (crisp mask squares,
/// interpolated scene, blur, a fixed detector, ADC) is
/// [`super::physical::simulate_physical`].
pub fn simulate_oversampled(
    scene: &Cube,
    nominal_mask: &Mask,
    spec: &SimulationSpec,
    factor: usize,
) -> Result<Measurement> {
    check_inputs(scene, nominal_mask)?;
    if factor == 0 {
        return Err(crate::error::CassiError::InvalidParameter {
            name: "oversampling factor",
            value: 0.0,
            reason: "must be at least 1".into(),
        });
    }
    let (bands, rows, cols) = scene.shape();
    let f = factor;
    let fine_mask = Frame::from_vec(
        rows * f,
        cols * f,
        (0..rows * f * cols * f)
            .map(|i| nominal_mask.row(i / (cols * f) / f)[i % (cols * f) / f])
            .collect(),
    )?;
    let mut fine_scene = Cube::zeros(bands, rows * f, cols * f);
    {
        let plane = rows * f * cols * f;
        let out = fine_scene.as_mut_slice();
        for k in 0..bands {
            for i in 0..plane {
                let (r, c) = (i / (cols * f) / f, i % (cols * f) / f);
                out[k * plane + i] = scene.get(k, r, c);
            }
        }
    }
    let m = spec.mismatch;
    let fine_mismatch = Mismatch {
        dx: m.dx * f as f64,
        dy: m.dy * f as f64,
        a1: m.a1 * f as f64,
        a2: m.a2 * f as f64,
        ..m
    };
    // the fine grid's block mask is crisp cells already: the crisp-cell
    // model's instrument is the dispersed-mask model there
    let fine_model = if spec.model.places_cells() {
        DispersionModel::DispersedMask
    } else {
        spec.model
    };
    let fine = CassiOperator::with_mismatch(&fine_mask, bands, &fine_mismatch, fine_model)?
        .forward(&fine_scene)?;
    let coarse_cols = cols + Dispersion::new(bands, m.dispersion(), spec.model)?.extra_cols();
    let mut clean = Frame::zeros(rows, coarse_cols);
    let norm = 1.0 / (f * f) as f32;
    for r in 0..rows {
        for fr in r * f..(r + 1) * f {
            let src = fine.row(fr);
            for (c, o) in clean.row_mut(r).iter_mut().enumerate() {
                let hi = ((c + 1) * f).min(src.len());
                *o += src[(c * f).min(hi)..hi].iter().sum::<f32>() * norm;
            }
        }
    }
    match &spec.noise {
        Some(noise) => noise.apply(&clean),
        None => Ok(clean),
    }
}

fn check_inputs(scene: &Cube, nominal_mask: &Mask) -> Result<()> {
    if (scene.rows(), scene.cols()) != nominal_mask.shape() {
        return Err(shape_error(
            "scene (rows, cols)",
            format!("{}×{}", scene.rows(), scene.cols()),
            format!(
                "{}×{} (the mask's size)",
                nominal_mask.rows(),
                nominal_mask.cols()
            ),
        ));
    }
    scene.check_finite("scene")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_mismatch_widens_the_detector_by_one_column() {
        let scene = Cube::from_vec(28, 8, 8, vec![0.5; 28 * 64]).unwrap();
        let mask = Frame::from_vec(8, 8, vec![1.0; 64]).unwrap();
        let spec = SimulationSpec {
            mismatch: Mismatch::paper(),
            model: DispersionModel::Rounded,
            noise: None,
        };
        assert_eq!(simulate(&scene, &mask, &spec).unwrap().shape(), (8, 8 + 55));
        let e = simulate(&Cube::zeros(28, 8, 9), &mask, &spec)
            .unwrap_err()
            .to_string();
        assert!(e.contains("8×9") && e.contains("8×8"), "{e}");
        let mut bad = scene.clone();
        bad.set(3, 1, 2, f32::INFINITY);
        assert!(
            simulate(&bad, &mask, &spec)
                .unwrap_err()
                .to_string()
                .contains("band 3, row 1, col 2")
        );
    }

    /// On a smooth scene the 2× oversampled instrument agrees with the
    /// native one to within the discretisation difference and has the same
    /// shape; for the subpixel model it is measurably not the native
    /// operator (so an oracle reconstruction is no inverse crime).
    #[test]
    fn oversampled_simulation_is_close_to_but_not_the_native_operator() {
        let (bands, n) = (6, 32);
        let scene = Cube::from_vec(
            bands,
            n,
            n,
            (0..bands * n * n)
                .map(|i| {
                    let (k, r, c) = (i / (n * n), i / n % n, i % n);
                    0.5 + 0.3 * ((r as f32 * 0.2 + k as f32 * 0.3).sin() * (c as f32 * 0.15).cos())
                })
                .collect(),
        )
        .unwrap();
        let mask = crate::synth::random_binary_mask(n, n, 0.5, 3).unwrap();
        for model in [DispersionModel::Rounded, DispersionModel::Subpixel] {
            let spec = SimulationSpec {
                mismatch: Mismatch {
                    alpha_deg: 1.0,
                    ..Mismatch::paper()
                },
                model,
                noise: None,
            };
            let native = simulate(&scene, &mask, &spec).unwrap();
            let fine = simulate_oversampled(&scene, &mask, &spec, 2).unwrap();
            assert_eq!(native.shape(), fine.shape());
            let (mut diff, mut energy) = (0.0f64, 0.0f64);
            for (a, b) in native.as_slice().iter().zip(fine.as_slice()) {
                diff += ((a - b) as f64).powi(2);
                energy += (*a as f64).powi(2);
            }
            let rel = (diff / energy).sqrt();
            assert!(rel < 0.35, "{model:?}: relative difference {rel}");
            if model == DispersionModel::Subpixel {
                // here 5 %: the fine grid splits light differently
                assert!(rel > 0.01, "{model:?}: relative difference {rel}");
            }
            // factor 1 is the native simulation exactly
            assert_eq!(
                simulate_oversampled(&scene, &mask, &spec, 1).unwrap(),
                native
            );
        }
    }
}
