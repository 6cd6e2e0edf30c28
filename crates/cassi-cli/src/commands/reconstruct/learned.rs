//! `cassi reconstruct --method mst-s|mst-l|hdnet|pnp-hsicnn --weights FILE`:
//! a pretrained network, or plug-and-play GAP with the learned HSI-SDeCNN
//! denoiser, instead of a TV solver. Needs a build with `--features nets`;
//! without it these methods say how to get one.
//!
//! `--calibration` applies to both: a network is guided by the mask moved to
//! the calibrated pose (dx, dy, θ) and keeps its trained step-2 dispersion;
//! PnP-HSICNN uses the whole calibrated model, like the TV solvers.

use anyhow::bail;
use cassi_eval::weights::official_weights;

use cassi_io::CheckedSet;

use super::args::ReconstructArgs;
use crate::report::Reporter;

/// `args.method` is a learned method. `checked`: the outputs, checked
/// against the inputs before any work.
pub fn run(
    args: &ReconstructArgs,
    reporter: &Reporter,
    checked: &CheckedSet,
) -> anyhow::Result<()> {
    if !args.method.kind().has_iterations() {
        // Solver flags mean nothing to a network: refuse them rather than
        // ignore them.
        for (given, flag) in [
            (args.iterations.is_some(), "--iterations"),
            (args.weight.is_some(), "--weight"),
            (args.model.is_some(), "--model"),
        ] {
            if given {
                bail!(
                    "{flag} does not apply to --method {} (a pretrained network: no iterations, \
                     no TV weight, its trained dispersion)",
                    args.method
                );
            }
        }
    }
    if args.weights.is_none() {
        bail!(
            "--method {} needs --weights FILE (a PyTorch .pth state dict or .safetensors); \
             official weights: {}",
            args.method,
            official_weights(args.method)
        );
    }
    run_learned(args, reporter, checked)
}

#[cfg(not(feature = "nets"))]
fn run_learned(
    args: &ReconstructArgs,
    _reporter: &Reporter,
    _checked: &CheckedSet,
) -> anyhow::Result<()> {
    bail!(
        "--method {}: this cassi was built without the deep networks; \
         rebuild it with `cargo build --release -p cassi-cli --features nets`",
        args.method
    )
}

#[cfg(feature = "nets")]
fn run_learned(
    args: &ReconstructArgs,
    reporter: &Reporter,
    checked: &CheckedSet,
) -> anyhow::Result<()> {
    use std::path::PathBuf;
    use std::time::Instant;

    use cassi_core::metrics::Metrics;
    use cassi_core::recon::registry::NETWORK_STEP;
    use cassi_core::recon::{MethodId, MethodKind};
    use cassi_core::solvers::IterationInfo;
    use cassi_core::{Cube, Instrument, MaskPose, Mismatch};
    use cassi_nets::{Network, PnpHsicnn, PnpHsicnnParams, Stage};
    use serde::Serialize;

    use super::outputs::{Outputs, score_against_truth};
    use crate::interrupt;

    /// What each learned method reports besides the common fields.
    #[derive(Serialize)]
    #[serde(untagged)]
    enum Details {
        Network {
            /// The pose the mask was moved to (identity: the nominal mask).
            mask_pose: MaskPose,
            /// Networks keep the dispersion they were trained with.
            trained_step: usize,
            /// The calibration's a1 and α when they differ from the trained
            /// dispersion: not used by the network.
            unused_dispersion: Option<cassi_core::DispersionParams>,
        },
        Pnp {
            model_parameters: Mismatch,
            dispersion_model: cassi_core::optics::DispersionModel,
            /// The calibration's held band offsets, which the model used.
            #[serde(skip_serializing_if = "Option::is_none")]
            band_offsets: Option<cassi_core::optics::BandOffsets>,
            /// The calibration's band spread, which the model used.
            #[serde(skip_serializing_if = "cassi_core::optics::BandSpread::is_point")]
            band_spread: cassi_core::optics::BandSpread,
            params: PnpHsicnnParams,
            network_iterations: usize,
            tv_iterations: usize,
            iterations: usize,
            stop: cassi_core::solvers::StopReason,
            relative_residual: f64,
        },
    }

    #[derive(Serialize)]
    struct LearnedReconstructionReport {
        measurement: PathBuf,
        mask: PathBuf,
        calibration: Option<PathBuf>,
        method: MethodId,
        weights: PathBuf,
        bands: usize,
        #[serde(flatten)]
        details: Details,
        width_fitted: Option<(usize, usize)>,
        seconds: f64,
        /// Metrics of the reconstruction clipped to [0, 1] against the truth.
        metrics: Option<Metrics>,
        metric_definitions: Option<&'static str>,
    }

    let weights = args.weights.clone().unwrap_or_default();
    let rules = args.method.spec().shape;
    if let Some(trained) = rules.stride
        && args.input.stride != trained as f64
    {
        bail!(
            "--method {} was trained for --stride {trained}, not {}",
            args.method,
            args.input.stride
        );
    }
    let (measurement, mask, bands) = args
        .input
        .load(reporter, crate::commands::inputs::UncodedMask::Warn)?;
    if let Some(trained) = rules.bands
        && bands != trained
    {
        bail!(
            "--method {} reconstructs {trained} bands; the measurement and mask give {bands}",
            args.method
        );
    }
    let file = args.model_parameters(&mask)?;
    let params = file.parameters;
    let truth = args.load_truth()?;

    let t0 = Instant::now();
    let pnp = args.method.kind() == MethodKind::LearnedPnp;
    let (cube, details, width_fitted): (Cube, Details, Option<(usize, usize)>) = if pnp {
        let model = args.model.or(file.model).unwrap_or_default();
        let settings = PnpHsicnnParams::default().with_overrides(args.iterations, args.weight);
        let mut pnp = reporter.stage("loading the HSI-SDeCNN weights", || {
            Ok(PnpHsicnn::load(&weights, settings)?)
        })?;
        let assumed = args.assumed(&mask, bands, &file, model)?;
        let progress =
            reporter.progress(&format!("{} ", args.method), settings.gap.iterations as u64);
        let mut observer = |info: &IterationInfo| {
            progress.set(info.iteration as u64);
            interrupt::control()
        };
        let r = reporter.stage(&format!("reconstructing ({})", args.method), || {
            Ok(pnp.solve(&measurement, &assumed, &mut observer)?)
        })?;
        drop(progress);
        let count = |s: Stage| r.stages.iter().filter(|&&x| x == s).count();
        let details = Details::Pnp {
            model_parameters: params,
            dispersion_model: model,
            band_offsets: file.band_offsets.clone(),
            band_spread: file.band_spread,
            params: settings,
            network_iterations: count(Stage::Dnn),
            tv_iterations: count(Stage::Tv),
            iterations: r.reconstruction.solution_iterations,
            stop: r.reconstruction.stop,
            relative_residual: r.reconstruction.relative_residual,
        };
        let fitted = r.reconstruction.width_fitted;
        (r.reconstruction.cube, details, fitted)
    } else {
        let unused_dispersion = (args.calibration.is_some()
            && (params.a1 != NETWORK_STEP as f64
                || params.alpha_deg != 0.0
                || file.band_offsets.is_some()
                || !file.band_spread.is_point()))
        .then(|| params.dispersion());
        if unused_dispersion.is_some() {
            let offsets = match (file.band_offsets.is_some(), !file.band_spread.is_point()) {
                (true, true) => ", nor the band offsets and band spread it held",
                (true, false) => ", nor the band offsets it held",
                (false, true) => ", nor the band spread it held",
                (false, false) => "",
            };
            reporter.say(&format!(
                "note: {} keeps its trained dispersion (step {NETWORK_STEP}, α 0°); the \
                 calibration's a1 = {}, α = {}°{offsets} are not used (only the mask pose dx, dy, θ)",
                args.method, params.a1, params.alpha_deg
            ));
        }
        let net = reporter.stage(&format!("loading {} weights", args.method), || {
            Ok(Network::load(args.method, &weights)?)
        })?;
        let pose = params.pose();
        let r = reporter.stage(&format!("reconstructing ({})", args.method), || {
            Ok(net.reconstruct(&measurement, &mask, &pose)?)
        })?;
        let details = Details::Network {
            mask_pose: pose,
            trained_step: NETWORK_STEP,
            unused_dispersion,
        };
        (r.cube, details, r.width_fitted)
    };
    interrupt::check()?;
    let seconds = t0.elapsed().as_secs_f64();

    let metrics = score_against_truth(truth.as_ref(), &cube)?;
    let instrument = Instrument::with_bands(bands, args.input.stride)?;
    let report = LearnedReconstructionReport {
        measurement: args.input.measurement.clone(),
        mask: args.input.mask.clone(),
        calibration: args.calibration.clone(),
        method: args.method,
        weights,
        bands,
        details,
        width_fitted,
        seconds,
        metrics,
        metric_definitions: metrics.map(|_| cassi_core::metrics::METRIC_DEFINITIONS),
    };
    let (_, rows, cols) = cube.shape();
    let summary = format!(
        "wrote {} ({bands}×{rows}×{cols}) with {}, {seconds:.2} s",
        args.output.display(),
        args.method
    );
    let outputs = Outputs {
        path: &args.output,
        cube: &cube,
        wavelengths_nm: &instrument.wavelengths_nm,
        width_fitted,
    };
    outputs.write(reporter, checked, &report, summary, metrics.as_ref())
}
