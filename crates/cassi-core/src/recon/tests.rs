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
