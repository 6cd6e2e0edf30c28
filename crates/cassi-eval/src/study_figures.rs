//! The report's figures, drawn from a study's results: PSNR by method and
//! scenario, PSNR per scene, estimated vs true parameters, sensitivity
//! curves, the ablation, and the qualitative panel and spectra of one scene.

use std::path::Path;

use cassi_core::color::pseudo_rgb;
use cassi_core::{Cube, Instrument};

use crate::figures::*;
use crate::protocol::{Reconstructions, Scenario, SceneResult};
use crate::summary::Summary;
use crate::sweep_rows::Sweeps;

/// A figure written for the report: caption and path relative to the study
/// folder.
#[derive(Debug, Clone)]
pub struct Figure {
    pub caption: String,
    pub path: String,
}

/// The scenarios shown in the figures, in their fixed colour order.
const SHOWN: [Scenario; 4] = [
    Scenario::IdealNoisy,
    Scenario::Assumed,
    Scenario::Corrected,
    Scenario::Oracle,
];

fn name(s: Scenario) -> String {
    match s {
        Scenario::IdealClean => "Ideal (noise-free)",
        Scenario::IdealNoisy => "I Ideal (noisy)",
        Scenario::Assumed => "II Assumed",
        Scenario::Corrected => "III Corrected",
        Scenario::Oracle => "IV Oracle",
    }
    .to_string()
}

/// Wavelengths for a cube of `bands` bands (the standard 28 when it fits).
pub fn wavelengths(bands: usize) -> Vec<f64> {
    Instrument::with_bands(bands, 2.0)
        .map(|i| i.wavelengths_nm)
        .unwrap_or_else(|_| (0..bands).map(|k| k as f64).collect())
}

/// Writes the summary figures into `<out>/figures/` and lists them.
pub fn write_summary_figures(
    out: &Path,
    results: &[SceneResult],
    summary: &Summary,
    sweeps: &Sweeps,
    preset: &str,
) -> anyhow::Result<Vec<Figure>> {
    let dir = out.join("figures");
    std::fs::create_dir_all(&dir)?;
    let mut figs = Vec::new();
    let mut add = |caption: String, file: &str| {
        figs.push(Figure {
            caption,
            path: format!("figures/{file}"),
        })
    };

    let bars = GroupedBars {
        groups: summary.methods.iter().map(|m| m.method.clone()).collect(),
        series: SHOWN
            .iter()
            .map(|&s| BarSeries {
                name: name(s),
                values: summary
                    .methods
                    .iter()
                    .map(|m| m.scenario(s).map_or(0.0, |x| x.psnr))
                    .collect(),
            })
            .collect(),
        y_label: "mean PSNR (dB)".into(),
        show_values: true,
        value_decimals: 2,
        y_range: None,
    };
    write_grouped_bars(
        &bars,
        "Mean PSNR by method and scenario",
        Size::new(900, 520),
        dir.join("psnr_by_method.png"),
    )?;
    add(
        "Mean PSNR over the scenes, by method and scenario".into(),
        "psnr_by_method.png",
    );

    if let Some(method) = summary.methods.first() {
        let m = &method.method;
        let chart = LineChart {
            series: SHOWN
                .iter()
                .map(|&s| LineSeries {
                    name: name(s),
                    points: results
                        .iter()
                        .enumerate()
                        .filter_map(|(i, r)| Some((i as f64, r.outcome(m, s)?.metrics.psnr)))
                        .collect(),
                })
                .collect(),
            x_label: "scene".into(),
            y_label: "PSNR (dB)".into(),
            x_categories: results.iter().map(|r| r.scene.clone()).collect(),
            x_range: None,
            y_range: None,
        };
        write_line_chart(
            &chart,
            &format!("PSNR per scene ({m})"),
            Size::new(900, 560),
            dir.join("psnr_per_scene.png"),
        )?;
        add(format!("PSNR per scene, {m}"), "psnr_per_scene.png");
    }

    let panel = |p: cassi_core::Parameter| ScatterPanel {
        name: p.name().into(),
        unit: p.unit().into(),
        series: vec![
            results
                .iter()
                .map(|r| (p.get(&r.truth), p.get(&r.calibration.parameters)))
                .collect(),
        ],
    };
    let scatter = EstimatedVsTrue {
        series_names: vec![format!("{preset} preset")],
        panels: cassi_core::Parameter::CALIBRATED.map(panel).to_vec(),
    };
    write_estimated_vs_true(
        &scatter,
        "Estimated vs true parameters, per scene",
        Size::new(960, 620),
        dir.join("parameters.png"),
    )?;
    add(
        "Estimated vs true mismatch parameters per scene (dashed: y = x)".into(),
        "parameters.png",
    );

    if !sweeps.sensitivity.is_empty() {
        let mut series = Vec::new();
        let method = summary.methods.first().map(|m| m.method.clone());
        for (preset, points) in &sweeps.sensitivity {
            for (s, label) in [
                (Scenario::Assumed, "II"),
                (Scenario::Corrected, "III"),
                (Scenario::Oracle, "IV"),
            ] {
                // II and IV do not depend on the preset: draw them once
                if s != Scenario::Corrected
                    && !series.is_empty()
                    && preset != &sweeps.sensitivity[0].0
                {
                    continue;
                }
                let tag = if s == Scenario::Corrected {
                    format!("{label} ({preset})")
                } else {
                    name(s)
                };
                series.push(LineSeries {
                    name: tag,
                    points: points
                        .iter()
                        .filter_map(|p| {
                            let m = p
                                .summary
                                .methods
                                .iter()
                                .find(|m| Some(&m.method) == method.as_ref())?;
                            Some((p.scale, m.scenario(s)?.psnr))
                        })
                        .collect(),
                });
            }
        }
        let chart = LineChart {
            series,
            x_label: "mismatch scale (× the paper's)".into(),
            y_label: "mean PSNR (dB)".into(),
            x_categories: Vec::new(),
            x_range: None,
            y_range: None,
        };
        write_line_chart(
            &chart,
            &format!(
                "Sensitivity to the mismatch size ({})",
                method.unwrap_or_default()
            ),
            Size::new(900, 540),
            dir.join("sensitivity.png"),
        )?;
        add(
            "Mean PSNR as the mismatch grows (all five parameters scaled)".into(),
            "sensitivity.png",
        );
    }

    if let Some(rows) = &sweeps.ablation {
        let method = rows.first().map(|r| r.method.clone()).unwrap_or_default();
        let rows: Vec<_> = rows.iter().filter(|r| r.method == method).collect();
        let mut presets: Vec<String> = Vec::new();
        for r in &rows {
            if !presets.contains(&r.preset) {
                presets.push(r.preset.clone());
            }
        }
        let variants = crate::sweep_rows::AblationVariant::ALL;
        let bars = GroupedBars {
            groups: presets.iter().map(|p| format!("{p} preset")).collect(),
            series: variants
                .iter()
                .map(|v| BarSeries {
                    name: v.generic_label().to_string(),
                    values: presets
                        .iter()
                        .map(|p| {
                            rows.iter()
                                .find(|r| &r.preset == p && r.variant == *v)
                                .map_or(0.0, |r| r.psnr)
                        })
                        .collect(),
                })
                .collect(),
            y_label: "mean PSNR (dB)".into(),
            show_values: true,
            value_decimals: 2,
            y_range: None,
        };
        write_grouped_bars(
            &bars,
            &format!("Ablation of the calibration pipeline ({method})"),
            Size::new(900, 520),
            dir.join("ablation.png"),
        )?;
        add(
            "Nominal model, search stages only (paper: grids; default: first stage), full pipeline, oracle".into(),
            "ablation.png",
        );
    }
    Ok(figs)
}

/// The qualitative panel (pseudo-RGB of the truth and of each scenario, with
/// the per-pixel error on one colour scale) and spectra at three pixels, for
/// one scene; written into `<out>/figures/` (`qualitative.png`,
/// `spectra.png`; the report captions them).
pub fn write_qualitative(
    out: &Path,
    scene_name: &str,
    method: &str,
    truth: &Cube,
    recons: &Reconstructions,
) -> anyhow::Result<()> {
    let dir = out.join("figures");
    std::fs::create_dir_all(&dir)?;
    let wl = wavelengths(truth.bands());
    let (bands, rows, cols) = truth.shape();
    let shown: Vec<&(Scenario, Cube)> = recons.iter().filter(|(s, _)| SHOWN.contains(s)).collect();
    let mut columns = vec![PanelColumn {
        title: "Truth".into(),
        image: pseudo_rgb(truth, &wl)?,
        error: None,
    }];
    for (s, cube) in &shown {
        // root-mean-square error over bands, per pixel
        let values: Vec<f32> = (0..rows * cols)
            .map(|i| {
                let (r, c) = (i / cols, i % cols);
                let se: f32 = (0..bands)
                    .map(|k| (cube.get(k, r, c) - truth.get(k, r, c)).powi(2))
                    .sum();
                (se / bands as f32).sqrt()
            })
            .collect();
        let psnr = cassi_core::metrics::psnr(truth, cube)?;
        columns.push(PanelColumn {
            title: format!("{} ({psnr:.1} dB)", name(*s)),
            image: pseudo_rgb(cube, &wl)?,
            error: Some(ErrorMap {
                title: format!("{} error", name(*s)),
                rows,
                cols,
                values,
            }),
        });
    }
    let panel = ImagePanel {
        columns,
        error_label: "RMS error over bands".into(),
        error_range: None,
    };
    let title = format!("{scene_name}, {method}: pseudo-RGB and per-pixel error");
    let size = panel.fitting_size(1400, &title);
    write_image_panel(&panel, &title, size, dir.join("qualitative.png"))?;

    // three pixels: the most colourful (largest spectral variance) in each
    // vertical third of the scene
    let pixels: Vec<(usize, usize)> = (0..3)
        .map(|third| {
            let (c0, c1) = (third * cols / 3, (third + 1) * cols / 3);
            let mut best = (f32::MIN, (rows / 2, (c0 + c1) / 2));
            for r in (rows / 8..rows - rows / 8).step_by(2) {
                for c in (c0..c1).step_by(2) {
                    let v: Vec<f32> = (0..bands).map(|k| truth.get(k, r, c)).collect();
                    let mean = v.iter().sum::<f32>() / bands as f32;
                    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f32>();
                    if var > best.0 {
                        best = (var, (r, c));
                    }
                }
            }
            best.1
        })
        .collect();
    let spectrum = |cube: &Cube, (r, c): (usize, usize)| -> Vec<f64> {
        (0..bands).map(|k| cube.get(k, r, c) as f64).collect()
    };
    let spectra = Spectra {
        wavelengths_nm: wl,
        truth_name: "Truth".into(),
        series_names: shown.iter().map(|(s, _)| name(*s)).collect(),
        pixels: pixels
            .iter()
            .map(|&p| PixelSpectra {
                label: format!("pixel (row {}, col {})", p.0, p.1),
                truth: spectrum(truth, p),
                estimates: shown.iter().map(|(_, cube)| spectrum(cube, p)).collect(),
            })
            .collect(),
        y_label: "intensity".into(),
    };
    write_spectra(
        &spectra,
        &format!("{scene_name}, {method}: spectra, truth vs scenarios"),
        Size::new(1200, 460),
        dir.join("spectra.png"),
    )?;
    Ok(())
}
