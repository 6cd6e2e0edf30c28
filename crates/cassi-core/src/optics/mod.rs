//! The CASSI optics model: mask misalignment, dispersion, the forward
//! operator and its adjoint, detector noise, simulation.

pub mod band_offsets;
pub mod band_spread;
pub mod blur;
pub mod crisp_cells;
pub mod dispersion;
pub mod input_checks;
pub mod model_operator;
pub mod noise;
pub mod operator;
pub mod physical;
pub mod simulate;
pub mod warp;

pub use band_offsets::BandOffsets;
pub use band_spread::BandSpread;
pub use blur::{Blurred, GaussianBlur, pixel_kernel, pixel_strip_kernel};
pub use crisp_cells::CrispCellOperator;
pub use dispersion::{Dispersion, DispersionModel, Tap};
pub use input_checks::{MaskCode, mask_code, validate_measurement, validate_mismatch_for_mask};
pub use model_operator::ModelOperator;
pub use noise::NoiseModel;
pub use operator::{CassiOperator, validate_mask};
pub use physical::{
    DispersionStep, Halo, PhysicalSpec, physical_detector_shape, quantise_adc, simulate_physical,
    simulate_physical_clean,
};
pub use simulate::{SimulationSpec, simulate, simulate_oversampled};
pub use warp::{
    WarpWithDerivatives, landing_phase, warp_mask, warp_mask_area, warp_mask_with_derivatives,
};
