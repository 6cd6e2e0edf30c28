//! What every reconstruction writes (the cube, its preview, its report) and
//! its scores against a truth cube.

use std::path::Path;

use anyhow::Context;
use cassi_core::color::pseudo_rgb;
use cassi_core::metrics::{Metrics, evaluate};
use cassi_io::CheckedSet;
use serde::Serialize;

use crate::interrupt;
use crate::report::Reporter;

/// PSNR/SSIM/SAM of the clipped estimate against `--truth`, if given.
pub(crate) fn score_against_truth(
    truth: Option<&cassi_core::Cube>,
    cube: &cassi_core::Cube,
) -> anyhow::Result<Option<Metrics>> {
    truth
        .map(|t| evaluate(t, &cube.clipped_to_unit()).with_context(|| "comparing with --truth"))
        .transpose()
}

/// What every reconstruction writes: the cube, its pseudo-RGB preview, the
/// JSON report beside them, and a summary line (+ metrics) on the terminal.
pub(crate) struct Outputs<'a> {
    pub path: &'a Path,
    pub cube: &'a cassi_core::Cube,
    pub wavelengths_nm: &'a [f64],
    pub width_fitted: Option<(usize, usize)>,
}

impl Outputs<'_> {
    /// Writes the three files as one set ([`ReconstructArgs::check_files`]):
    /// all of them, or — when anything fails, the cube is not finite, or a
    /// signal came — none, the previous ones left as they were.
    pub(crate) fn write(
        &self,
        reporter: &Reporter,
        checked: &CheckedSet,
        report: &impl Serialize,
        mut summary: String,
        metrics: Option<&Metrics>,
    ) -> anyhow::Result<()> {
        self.cube
            .check_finite("the reconstruction")
            .with_context(|| {
                format!(
                    "nothing was written to {} (try fewer iterations or another --weight)",
                    self.path.display()
                )
            })?;
        let rgb = pseudo_rgb(self.cube, self.wavelengths_nm).with_context(|| {
            format!(
                "the preview of {}; nothing was written",
                self.path.display()
            )
        })?;
        let text = serde_json::to_string_pretty(report)? + "\n";
        reporter.stage("writing the cube and preview", || {
            let staging = checked.begin()?;
            cassi_io::save_cube(self.path, self.cube, "cube")?;
            cassi_io::write_rgb_png(self.path.with_extension("png"), &rgb)?;
            cassi_io::write_atomic(self.path.with_extension("json"), text.as_bytes())?;
            interrupt::check()?;
            staging.commit()?;
            Ok(())
        })?;
        if let Some((got, want)) = self.width_fitted {
            reporter.say(&format!(
                "note: the measurement has {got} columns, the model {want}: fitted on the right"
            ));
        }
        if let Some(m) = metrics {
            summary += &format!(
                "\nPSNR {:.2} dB   SSIM {:.4}   SAM {:.2}°",
                m.psnr, m.ssim, m.sam_deg
            );
        }
        reporter.say(&summary);
        reporter.emit(&serde_json::to_value(report)?);
        Ok(())
    }
}
