//! Renders one of each figure into a directory, from made-up numbers and a
//! synthetic scene with simulated reconstruction errors:
//!
//! ```text
//! cargo run --release -p cassi-eval --example figures_demo -- OUT_DIR
//! ```

use std::path::PathBuf;

use cassi_core::color::pseudo_rgb;
use cassi_core::synth::{SceneSpec, synthetic_scene};
use cassi_core::{Cube, Rng, STANDARD_WAVELENGTHS_NM};
use cassi_eval::figures::*;

type AnyResult<T> = std::result::Result<T, Box<dyn std::error::Error>>;

const SCENARIOS: [&str; 4] = ["Ideal", "Assumed", "Corrected", "Oracle"];

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn bars() -> GroupedBars {
    let methods = ["GAP-TV", "ADMM-TV", "PnP-HSI", "MST-S", "MST-L", "HDNet"];
    let psnr = [
        [32.1, 24.3, 31.2, 31.9],
        [32.8, 24.9, 31.7, 32.4],
        [34.0, 25.2, 33.1, 33.8],
        [35.0, 22.1, 33.9, 34.7],
        [36.1, 22.5, 34.6, 35.8],
        [35.4, 22.0, 34.2, 35.1],
    ];
    GroupedBars {
        groups: strings(&methods),
        series: SCENARIOS
            .iter()
            .enumerate()
            .map(|(j, s)| BarSeries {
                name: s.to_string(),
                values: psnr.iter().map(|r| r[j]).collect(),
            })
            .collect(),
        y_label: "PSNR (dB)".into(),
        show_values: true,
        value_decimals: 1,
        y_range: None,
    }
}

fn sensitivity() -> LineChart {
    let scales = [0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0];
    let curve = |base: f64, slope: f64, floor: f64| -> Vec<(f64, f64)> {
        scales
            .iter()
            .map(|&s| (s, (base - slope * s * s.sqrt()).max(floor)))
            .collect()
    };
    LineChart {
        series: vec![
            LineSeries {
                name: "Assumed".into(),
                points: curve(32.0, 7.0, 17.0),
            },
            LineSeries {
                name: "Corrected".into(),
                points: curve(31.8, 0.5, 17.0),
            },
            LineSeries {
                name: "Oracle".into(),
                points: curve(32.0, 0.15, 17.0),
            },
        ],
        x_label: "mismatch scale (× nominal)".into(),
        y_label: "PSNR (dB)".into(),
        ..Default::default()
    }
}

fn per_scene() -> LineChart {
    let scenes: Vec<String> = (1..=10).map(|i| format!("scene{i:02}")).collect();
    let mut rng = Rng::new(7);
    let base: Vec<f64> = (0..10).map(|_| rng.uniform_in(28.0, 38.0)).collect();
    let drop = [0.0, 9.0, 1.0, 0.3];
    LineChart {
        series: SCENARIOS
            .iter()
            .zip(drop)
            .map(|(s, d)| LineSeries {
                name: s.to_string(),
                points: base
                    .iter()
                    .enumerate()
                    .map(|(i, b)| (i as f64, b - d + 0.5 * rng.normal()))
                    .collect(),
            })
            .collect(),
        x_label: "scene".into(),
        y_label: "PSNR (dB)".into(),
        x_categories: scenes,
        ..Default::default()
    }
}

fn estimated_vs_true() -> EstimatedVsTrue {
    let mut rng = Rng::new(3);
    let params = [
        ("dx", "px", 2.0, 0.08),
        ("dy", "px", 2.0, 0.08),
        ("θ", "°", 1.0, 0.05),
        ("a1", "px/band", 0.3, 0.01),
        ("α", "°", 1.5, 0.1),
    ];
    let mut panel = |(name, unit, spread, err): (&str, &str, f64, f64), offset: f64| {
        let mut series = Vec::new();
        for noise in [err, 2.5 * err] {
            series.push(
                (0..10)
                    .map(|_| {
                        let t = offset + rng.uniform_in(-spread, spread);
                        (t, t + noise * rng.normal())
                    })
                    .collect(),
            );
        }
        ScatterPanel {
            name: name.into(),
            unit: unit.into(),
            series,
        }
    };
    let panels = params
        .iter()
        .map(|&p| panel(p, if p.0 == "a1" { 2.0 } else { 0.0 }))
        .collect();
    EstimatedVsTrue {
        series_names: strings(&["preset paper", "preset fast"]),
        panels,
    }
}

/// A reconstruction with simulated errors: a blend towards a shifted copy of
/// the truth (mismatch artefacts) plus noise.
fn degrade(truth: &Cube, shift: usize, blend: f32, noise: f64, seed: u64) -> Cube {
    let (l, h, w) = truth.shape();
    let mut rng = Rng::new(seed);
    let mut out = Cube::zeros(l, h, w);
    for k in 0..l {
        for r in 0..h {
            for c in 0..w {
                let s = truth.get(k, r, (c + shift * (k % 3)).min(w - 1));
                let v = (1.0 - blend) * truth.get(k, r, c) + blend * s;
                out.set(k, r, c, (v + (noise * rng.normal()) as f32).clamp(0.0, 1.0));
            }
        }
    }
    out
}

fn qualitative() -> AnyResult<(ImagePanel, Spectra)> {
    let wl = STANDARD_WAVELENGTHS_NM.to_vec();
    let spec = SceneSpec {
        rows: 96,
        cols: 128,
        wavelengths_nm: wl.clone(),
        seed: 11,
    };
    let truth = synthetic_scene(&spec)?;
    let recs = [
        degrade(&truth, 0, 0.0, 0.01, 1),
        degrade(&truth, 3, 0.5, 0.03, 2),
        degrade(&truth, 1, 0.1, 0.012, 3),
        degrade(&truth, 0, 0.0, 0.011, 4),
    ];
    let (l, h, w) = truth.shape();
    let mut columns = vec![PanelColumn {
        title: "Truth".into(),
        image: pseudo_rgb(&truth, &wl)?,
        error: None,
    }];
    for (name, rec) in SCENARIOS.iter().zip(&recs) {
        let mut err = vec![0f32; h * w];
        let mut sq = 0.0f64;
        for k in 0..l {
            for (e, (a, b)) in err.iter_mut().zip(rec.band(k).iter().zip(truth.band(k))) {
                *e += (a - b).abs() / l as f32;
                sq += f64::from((a - b) * (a - b));
            }
        }
        let psnr = -10.0 * (sq / (l * h * w) as f64).log10();
        columns.push(PanelColumn {
            title: format!("{name} ({psnr:.1} dB)"),
            image: pseudo_rgb(rec, &wl)?,
            error: Some(ErrorMap {
                title: format!("|{name} − truth|"),
                rows: h,
                cols: w,
                values: err,
            }),
        });
    }
    let panel = ImagePanel {
        columns,
        error_label: "mean |error| over bands".into(),
        error_range: None,
    };
    let pixels = [(20usize, 30usize), (50, 90), (80, 60)]
        .iter()
        .map(|&(r, c)| PixelSpectra {
            label: format!("pixel (row {r}, col {c})"),
            truth: (0..l).map(|k| f64::from(truth.get(k, r, c))).collect(),
            estimates: recs
                .iter()
                .map(|rec| (0..l).map(|k| f64::from(rec.get(k, r, c))).collect())
                .collect(),
        })
        .collect();
    let spectra = Spectra {
        wavelengths_nm: wl,
        truth_name: "Truth".into(),
        series_names: strings(&SCENARIOS),
        pixels,
        y_label: "intensity".into(),
    };
    Ok((panel, spectra))
}

fn main() -> AnyResult<()> {
    let dir = PathBuf::from(
        std::env::args()
            .nth(1)
            .ok_or("usage: figures_demo OUT_DIR")?,
    );
    std::fs::create_dir_all(&dir)?;
    write_grouped_bars(
        &bars(),
        "PSNR by method and scenario (10 scenes, mean)",
        Size::new(1100, 560),
        dir.join("bars.png"),
    )?;
    write_line_chart(
        &sensitivity(),
        "Sensitivity: GAP-TV PSNR vs mismatch scale",
        Size::new(900, 560),
        dir.join("sensitivity.png"),
    )?;
    write_line_chart(
        &per_scene(),
        "Per-scene PSNR, GAP-TV",
        Size::new(1000, 560),
        dir.join("per_scene.png"),
    )?;
    write_estimated_vs_true(
        &estimated_vs_true(),
        "Estimated vs true mismatch parameters (10 scenes)",
        Size::new(1200, 760),
        dir.join("estimated_vs_true.png"),
    )?;
    let (panel, spectra) = qualitative()?;
    let title = "Scene 11: pseudo-RGB and per-pixel error";
    write_image_panel(
        &panel,
        title,
        panel.fitting_size(1400, title),
        dir.join("panel.png"),
    )?;
    write_spectra(
        &spectra,
        "Spectra at three pixels, truth vs scenarios",
        Size::new(1400, 480),
        dir.join("spectra.png"),
    )?;
    println!("wrote 6 figures into {}", dir.display());
    Ok(())
}
