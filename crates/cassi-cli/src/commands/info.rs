//! `cassi info FILE`.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use crate::report::Reporter;

#[derive(Args)]
pub struct InfoArgs {
    /// A .mat (v5 or v7.3), .npy or .npz file.
    pub file: PathBuf,
}

pub fn run(args: &InfoArgs, reporter: &Reporter) -> anyhow::Result<()> {
    let summary = cassi_io::describe(&args.file)?;
    if reporter.json() {
        reporter.emit(&serde_json::to_value(&summary).context("serialising the summary")?);
    } else {
        reporter.say(&summary.to_string());
    }
    Ok(())
}
