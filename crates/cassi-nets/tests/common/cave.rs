//! MST-S against GAP-TV on the CAVE scenes of ../shared/data: noise-free
//! measurements of the nominal instrument (rounded model, TSA simulation
//! mask), both reconstructions clipped to [0, 1] and scored against the
//! scene. Shared by the `mst_s_cave` test and the `cave` benchmark.

use std::path::{Path, PathBuf};
use std::time::Instant;

use cassi_core::metrics::{Metrics, evaluate};
use cassi_core::optics::{DispersionModel, SimulationSpec, simulate};
use cassi_core::recon::{Method, Model};
use cassi_core::solvers::Silent;
use cassi_core::{Cube, Mask, MaskPose, Mismatch};
use cassi_nets::Network;

/// The TSA simulation mask (256 × 256).
pub fn tsa_mask(data: &Path) -> Mask {
    cassi_io::load_frame(data.join("masks/tsa_simu_mask256.mat"), None)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// The scene files, sorted by name.
pub fn scenes(data: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(data.join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "npy"))
        .collect();
    v.sort();
    v
}

/// One method's score and time on one scene.
pub struct Scored {
    pub metrics: Metrics,
    pub seconds: f64,
}

/// GAP-TV (its tuned defaults) and the network on the nominal, noise-free
/// measurement of `scene`.
pub fn gap_tv_and_network(scene: &Path, mask: &Mask, net: &Network) -> (Scored, Scored) {
    let truth: Cube = cassi_io::load_cube(scene, None, cassi_io::CubeLayout::Auto)
        .unwrap_or_else(|e| panic!("{e}"));
    let nominal = Mismatch::nominal(2.0);
    let spec = SimulationSpec {
        mismatch: nominal,
        model: DispersionModel::Rounded,
        noise: None,
    };
    let y = simulate(&truth, mask, &spec).unwrap();
    let t = Instant::now();
    let model = Model::new(mask, truth.bands(), 2.0, nominal, DispersionModel::Rounded).unwrap();
    let gap = Method::by_name("gap-tv")
        .unwrap()
        .solve(&y, &model, &mut Silent)
        .unwrap();
    let gap = Scored {
        seconds: t.elapsed().as_secs_f64(),
        metrics: evaluate(&truth, &gap.cube.clipped_to_unit()).unwrap(),
    };
    let t = Instant::now();
    let out = net.reconstruct(&y, mask, &MaskPose::default()).unwrap();
    assert_eq!(out.width_fitted, None);
    let net = Scored {
        seconds: t.elapsed().as_secs_f64(),
        metrics: evaluate(&truth, &out.cube.clipped_to_unit()).unwrap(),
    };
    (gap, net)
}
