//! `cassi reconstruct`: measurement + mask (+ calibration) → cube, preview,
//! and metrics against a truth cube when one is given. The method's kind in
//! the registry picks the path: an iterative solver, or a learned method.

mod args;
mod learned;
mod outputs;
mod solver;

pub use args::ReconstructArgs;

use cassi_core::recon::{Method, MethodKind};

use crate::report::Reporter;

pub fn run(args: &ReconstructArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let checked = args.check_files()?;
    match args.method.kind() {
        MethodKind::Iterative => {
            let method = Method::defaults(args.method)
                .expect("the registry's iterative methods have defaults");
            solver::run(args, method, reporter, &checked)
        }
        MethodKind::Network | MethodKind::LearnedPnp => learned::run(args, reporter, &checked),
    }
}
