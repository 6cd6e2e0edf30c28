//! `cassi`: the command line. Each subcommand parses its arguments, calls the
//! library, and writes files; no science happens here.

#![forbid(unsafe_code)]

mod commands;
mod interrupt;
mod observer;
mod report;
mod sidecar;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use report::Reporter;

#[derive(Parser)]
#[command(
    name = "cassi",
    version,
    about = "Coded aperture snapshot spectral imaging: simulate, reconstruct and self-calibrate CASSI",
    long_about = None
)]
struct Cli {
    /// Print nothing but errors.
    #[arg(long, short, global = true)]
    quiet: bool,
    /// Print one JSON object with the results on stdout (for scripts).
    #[arg(long, global = true)]
    json: bool,
    /// The largest array (in elements) that a file, a flag or a result may
    /// make; anything bigger is refused before work starts. The default fits
    /// a 660×714×28 real snapshot's cube 2.5 times over.
    #[arg(long, global = true, env = "CASSI_MAX_ELEMENTS", value_name = "N",
          default_value_t = cassi_core::limits::DEFAULT_MAX_ELEMENTS)]
    max_elements: usize,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate a CASSI measurement of a scene through a (mis)aligned instrument.
    Simulate(Box<commands::simulate::SimulateArgs>),
    /// Self-calibrate: estimate the mask misalignment and dispersion drift from one measurement.
    Calibrate(Box<commands::calibrate::CalibrateArgs>),
    /// Combine several snapshots' calibrations of one instrument into one, and say whether they agree.
    Combine(commands::combine::CombineArgs),
    /// Reconstruct a spectral cube from a measurement (GAP-TV, ADMM-TV, PnP-TV).
    Reconstruct(Box<commands::reconstruct::ReconstructArgs>),
    /// The four-scenario study (Ideal, Assumed, Corrected, Oracle) over a set of scenes, with a report.
    Eval(Box<commands::eval::EvalArgs>),
    /// Describe what is in a .mat, .npy or .npz file.
    Info(commands::info::InfoArgs),
    /// Run the whole story on the embedded synthetic scene (no files needed).
    Demo(commands::demo::DemoArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    cassi_core::limits::set_max_elements(cli.max_elements);
    interrupt::install();
    let reporter = Reporter::new(cli.quiet, cli.json);
    let result = match &cli.command {
        Command::Simulate(args) => commands::simulate::run(args, &reporter),
        Command::Calibrate(args) => commands::calibrate::run(args, &reporter),
        Command::Combine(args) => commands::combine::run(args, &reporter),
        Command::Reconstruct(args) => commands::reconstruct::run(args, &reporter),
        Command::Eval(args) => commands::eval::run(args, &reporter),
        Command::Info(args) => commands::info::run(args, &reporter),
        Command::Demo(args) => commands::demo::run(args, &reporter),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if interrupt::is_interrupt(&e) => {
            reporter.clear();
            eprintln!("error: {}", interrupt::Interrupted);
            ExitCode::from(interrupt::EXIT_CODE)
        }
        Err(e) => {
            reporter.clear();
            eprintln!("error: {}", report::terminal_text(&format!("{e:#}")));
            ExitCode::FAILURE
        }
    }
}
