//! `cassi reconstruct --method mst-s|mst-l|hdnet --weights FILE`: a
//! pretrained network instead of an iterative solver. Needs a build with
//! `--features nets`; without it these methods say how to get one.

use anyhow::bail;

use super::reconstruct::ReconstructArgs;
use crate::report::Reporter;

/// The deep methods; listed in `--help` whether or not they are built in.
pub const NET_METHOD_NAMES: [&str; 3] = ["mst-s", "mst-l", "hdnet"];

pub fn run(args: &ReconstructArgs, reporter: &Reporter) -> anyhow::Result<()> {
    // Flags of the iterative solvers mean nothing to a network: refuse them
    // rather than ignore them.
    for (given, flag) in [
        (args.calibration.is_some(), "--calibration"),
        (args.iterations.is_some(), "--iterations"),
        (args.weight.is_some(), "--weight"),
        (args.model.is_some(), "--model"),
    ] {
        if given {
            bail!(
                "{flag} does not apply to --method {} (a pretrained network for the nominal instrument)",
                args.method
            );
        }
    }
    if args.weights.is_none() {
        bail!(
            "--method {} needs --weights FILE (a PyTorch .pth state dict or .safetensors)",
            args.method
        );
    }
    run_network(args, reporter)
}

#[cfg(not(feature = "nets"))]
fn run_network(args: &ReconstructArgs, _reporter: &Reporter) -> anyhow::Result<()> {
    bail!(
        "--method {}: this cassi was built without the deep networks; \
         rebuild it with `cargo build --release -p cassi-cli --features nets`",
        args.method
    )
}

#[cfg(feature = "nets")]
fn run_network(args: &ReconstructArgs, reporter: &Reporter) -> anyhow::Result<()> {
    use std::path::PathBuf;
    use std::time::Instant;

    use anyhow::Context;
    use cassi_core::Instrument;
    use cassi_core::color::pseudo_rgb;
    use cassi_core::metrics::{Metrics, evaluate};
    use cassi_nets::{MST_BANDS, Reconstructor, TRAINED_STEP};
    use serde::Serialize;

    use super::simulate::check_output;

    #[derive(Serialize)]
    struct NetReconstructionReport {
        measurement: PathBuf,
        mask: PathBuf,
        method: String,
        weights: PathBuf,
        bands: usize,
        seconds: f64,
        /// Metrics of the reconstruction clipped to [0, 1] against the truth.
        metrics: Option<Metrics>,
        metric_definitions: Option<&'static str>,
    }

    check_output(&args.output)?;
    let weights = args.weights.clone().unwrap_or_default();
    if args.input.stride != TRAINED_STEP as f64 {
        bail!(
            "--method {} was trained for --stride {TRAINED_STEP}, not {}",
            args.method,
            args.input.stride
        );
    }
    let (measurement, mask, bands) = args.input.load()?;
    if bands != MST_BANDS {
        bail!(
            "--method {} reconstructs {MST_BANDS} bands; the measurement and mask give {bands}",
            args.method
        );
    }
    let truth = match &args.truth {
        Some(path) => Some(cassi_io::load_cube(
            path,
            args.truth_var.as_deref(),
            args.layout.into(),
        )?),
        None => None,
    };
    let net = reporter.stage(&format!("loading {} weights", args.method), || {
        Ok(Reconstructor::load(&args.method, &weights)?)
    })?;
    let t0 = Instant::now();
    let cube = reporter.stage(&format!("reconstructing ({})", args.method), || {
        Ok(net.reconstruct(&measurement, &mask)?)
    })?;
    let seconds = t0.elapsed().as_secs_f64();
    let metrics = match &truth {
        Some(t) => {
            Some(evaluate(t, &cube.clipped_to_unit()).with_context(|| "comparing with --truth")?)
        }
        None => None,
    };
    let instrument = Instrument::with_bands(bands, args.input.stride)?;
    reporter.stage("writing the cube and preview", || {
        cassi_io::save_cube(&args.output, &cube, "cube")?;
        let rgb = pseudo_rgb(&cube, &instrument.wavelengths_nm)?;
        cassi_io::write_rgb_png(args.output.with_extension("png"), &rgb)?;
        Ok(())
    })?;
    let report = NetReconstructionReport {
        measurement: args.input.measurement.clone(),
        mask: args.input.mask.clone(),
        method: args.method.clone(),
        weights,
        bands,
        seconds,
        metrics,
        metric_definitions: metrics.map(|_| cassi_core::metrics::METRIC_DEFINITIONS),
    };
    let text = serde_json::to_string_pretty(&report)? + "\n";
    cassi_io::write_atomic(args.output.with_extension("json"), text.as_bytes())?;
    let (_, rows, cols) = cube.shape();
    let mut summary = format!(
        "wrote {} ({bands}×{rows}×{cols}) with {}, {seconds:.2} s",
        args.output.display(),
        args.method
    );
    if let Some(m) = metrics {
        summary += &format!(
            "\nPSNR {:.2} dB   SSIM {:.4}   SAM {:.2}°",
            m.psnr, m.ssim, m.sam_deg
        );
    }
    reporter.say(&summary);
    reporter.emit(&serde_json::to_value(&report)?);
    Ok(())
}
