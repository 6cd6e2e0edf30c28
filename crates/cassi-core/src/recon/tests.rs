use super::*;
use crate::cube::Cube;
use crate::denoise::{TvChambolle2d, TvChambolleParams};
use crate::optics::DispersionModel;
use crate::optics::ModelOperator;
use crate::params::Mismatch;
use crate::solvers::{Gap, Silent};
use crate::synth::random_binary_mask;

/// Each iterative method's serde tag (what study records hold) is its
/// registry name, and each registry entry of that kind has defaults.
#[test]
fn iterative_methods_are_named_as_the_registry_names_them() {
    for name in registry::names_of(MethodKind::Iterative) {
        let method = Method::by_name(name).unwrap();
        assert_eq!(method.name(), name);
        assert_eq!(serde_json::to_value(method).unwrap()["method"], name);
    }
    for spec in &registry::METHODS {
        assert_eq!(
            Method::defaults(spec.id).is_some(),
            spec.kind == MethodKind::Iterative,
            "{}",
            spec.name
        );
    }
    let e = Method::by_name("mst-s").unwrap_err().to_string();
    assert!(
        e.contains("not an iterative method") && e.contains("gap-tv"),
        "{e}"
    );
}

/// A `dyn Reconstructor` runs exactly the recipe: GAP with 2-D TV on the
/// operator of the assumed (blurred, moved) instrument, bit for bit.
#[test]
fn a_reconstructor_trait_object_gives_the_recipes_cube() {
    let (bands, rows, cols) = (4, 12, 12);
    let mask = random_binary_mask(rows, cols, 0.5, 3).unwrap();
    let psi = Mismatch {
        dx: 0.4,
        blur_sigma_px: 0.8,
        ..Mismatch::nominal(2.0)
    };
    let dispersion = DispersionModel::Subpixel;
    let truth_op = ModelOperator::new(&mask, bands, &psi, dispersion).unwrap();
    let scene = Cube::from_vec(
        bands,
        rows,
        cols,
        (0..bands * rows * cols)
            .map(|i| ((i * 37 % 101) as f32) / 101.0)
            .collect(),
    )
    .unwrap();
    let y = truth_op.forward(&scene).unwrap();
    let method = Method::by_name("gap-tv")
        .unwrap()
        .with_overrides(Some(8), None);
    let Method::GapTv { gap, tv_iterations } = method else {
        unreachable!("gap-tv is GAP-TV")
    };
    let mut tv = TvChambolle2d::new(TvChambolleParams {
        max_iter: tv_iterations,
        ..Default::default()
    });
    let expected = Gap::new(gap)
        .solve(
            &truth_op,
            y.as_slice(),
            (bands, rows, cols),
            &mut tv,
            &mut Silent,
        )
        .unwrap()
        .cube;

    let model = Model::new(&mask, bands, 2.0, psi, dispersion).unwrap();
    let mut boxed: Box<dyn Reconstructor> = Box::new(method);
    assert_eq!(boxed.name(), "gap-tv");
    let cube = boxed.reconstruct(&y, &model, &mut Silent).unwrap();
    assert_eq!(cube.as_slice(), expected.as_slice());
    let solved = method.solve(&y, &model, &mut Silent).unwrap();
    assert_eq!(solved.cube.as_slice(), expected.as_slice());
}

/// GAP-TV at a blur of a few hundredths of a pixel stays finite where
/// light reaches every detector pixel. The blur's outermost taps once came
/// out subnormal on one side (7e-39 at σ 0.077); the normaliser of a pixel
/// reached through such a tap alone sent the reconstruction to NaN (the
/// calibration benchmark's cloth seed 14081, σ̂ 0.077).
#[test]
fn gap_tv_stays_finite_at_a_blur_of_hundredths_of_a_pixel() {
    let (bands, rows, cols) = (8, 32, 32);
    let mask = random_binary_mask(rows, cols, 0.5, 5).unwrap();
    for sigma in [0.05, 0.077, 0.1, 0.2] {
        let psi = Mismatch {
            dx: 0.6,
            dy: -0.4,
            theta_deg: 0.3,
            alpha_deg: 0.5,
            blur_sigma_px: sigma,
            ..Mismatch::nominal(2.0)
        };
        let model = Model::new(&mask, bands, 2.0, psi, DispersionModel::DispersedMask).unwrap();
        let (mr, mc) = model.operator().unwrap().measurement_shape();
        // light on every detector pixel, as a real frame has
        let y = crate::cube::Measurement::from_vec(
            mr,
            mc,
            (0..mr * mc)
                .map(|i| 0.5 + ((i * 13 % 17) as f32) / 40.0)
                .collect(),
        )
        .unwrap();
        let cube = Method::by_name("gap-tv")
            .unwrap()
            .solve(&y, &model, &mut Silent)
            .unwrap()
            .cube;
        assert!(
            cube.as_slice().iter().all(|v| v.is_finite()),
            "σ {sigma}: a non-finite voxel"
        );
    }
}

/// A prism with a step in its dispersion (bands 4–7 land 0.8 px further;
/// the 4× oversampled simulator, not any fitted operator): GAP-TV with the
/// step's table held (`Model::with_band_offsets`, the true ψ otherwise)
/// recovers the scene better than the same ψ without it (GAP's data
/// residual does not tell them apart: a wrong model fits the frame with a
/// wrong cube) — the true model does not lose to the straight one — for
/// each model that holds band offsets.
#[test]
fn a_held_band_table_reconstructs_a_stepped_prism_better() {
    use crate::optics::{BandOffsets, DispersionStep, PhysicalSpec, simulate_physical};
    use crate::synth::{SceneSpec, synthetic_scene};
    let (bands, size) = (8, 64);
    let wl: Vec<f64> = (0..bands).map(|k| 450.0 + 25.0 * k as f64).collect();
    let scene = synthetic_scene(&SceneSpec {
        rows: size,
        cols: size,
        wavelengths_nm: wl.clone(),
        seed: 3,
    })
    .unwrap();
    let mask = random_binary_mask(size, size, 0.5, 7).unwrap();
    // dy off the pixel grid: the crisp-cell model differs from the
    // dispersed-mask one only where mask edges cut detector pixels
    let psi = Mismatch {
        dx: 0.3,
        dy: 0.35,
        blur_sigma_px: 0.4,
        ..Mismatch::nominal(2.0)
    };
    let step = DispersionStep {
        from_band: 4,
        px: 0.8,
    };
    let spec = PhysicalSpec {
        oversample: 4,
        blur_sigma_px: psi.blur_sigma_px,
        dispersion_step: Some(step),
        ..PhysicalSpec::default()
    };
    let y = simulate_physical(&scene, &mask, &wl, &psi, &spec, None).unwrap();
    // the step as a table, its line through band 0 carried by a1
    let table: Vec<f64> = (0..bands)
        .map(|k| if k >= step.from_band { step.px } else { 0.0 })
        .collect();
    let offsets = BandOffsets::from_table(&table, 2.0).unwrap();
    let line = Mismatch {
        a1: psi.a1 + offsets.table_line[1],
        ..psi
    };
    let gap_tv = Method::by_name("gap-tv").unwrap();
    for dispersion in [DispersionModel::DispersedMask, DispersionModel::CrispCells] {
        let straight = Model::new(&mask, bands, 2.0, psi, dispersion).unwrap();
        let held = Model::new(&mask, bands, 2.0, line, dispersion)
            .unwrap()
            .with_band_offsets(&offsets)
            .unwrap();
        let solve = |m: &Model| gap_tv.solve(&y, m, &mut Silent).unwrap();
        let (a, b) = (solve(&straight), solve(&held));
        let psnr = |c: &Cube| crate::metrics::psnr(&scene, c).unwrap();
        eprintln!(
            "{dispersion:?}: straight {:.2} dB (residual {:.4}), held {:.2} dB (residual {:.4})",
            psnr(&a.cube),
            a.relative_residual,
            psnr(&b.cube),
            b.relative_residual
        );
        assert!(psnr(&b.cube) > psnr(&a.cube) + 0.5, "{dispersion:?}");
    }
}
