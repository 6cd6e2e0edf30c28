//! Every figure renders to a PNG that decodes at the requested size, is not
//! blank, and has its title text drawn; bad input is an error, not a panic.

use std::path::{Path, PathBuf};

use cassi_eval::figures::*;

/// A fresh directory under the system temp dir, removed on drop (kept, under
/// `$CASSI_EVAL_TEST_OUT` instead, when that variable is set: to look at the
/// test figures).
struct TempDir(PathBuf, bool);

impl TempDir {
    fn new(name: &str) -> Self {
        let keep = std::env::var_os("CASSI_EVAL_TEST_OUT");
        let p = match &keep {
            Some(d) => PathBuf::from(d).join(name),
            None => std::env::temp_dir().join(format!("cassi-eval-{}-{name}", std::process::id())),
        };
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p, keep.is_some())
    }
    fn path(&self, f: &str) -> PathBuf {
        self.0.join(f)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if !self.1 {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

const SIZE: Size = Size::new(480, 320);
/// Rows of the title band that hold the title's glyphs at this size (the
/// band is 32 px; the legend starts below it).
const TITLE_ROWS: u32 = 26;

struct Png {
    w: u32,
    h: u32,
    rgb: Vec<u8>,
}

impl Png {
    fn open(path: &Path) -> Png {
        let img = image::ImageReader::open(path)
            .unwrap()
            .with_guessed_format()
            .unwrap()
            .decode()
            .unwrap()
            .to_rgb8();
        Png {
            w: img.width(),
            h: img.height(),
            rgb: img.into_raw(),
        }
    }
    fn from_image(im: &RgbImage) -> Png {
        Png {
            w: im.cols as u32,
            h: im.rows as u32,
            rgb: im.data.clone(),
        }
    }
    fn px(&self, x: u32, y: u32) -> [u8; 3] {
        let i = 3 * (y * self.w + x) as usize;
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }
    fn luma(&self, x: u32, y: u32) -> u8 {
        let [r, g, b] = self.px(x, y);
        ((u32::from(r) * 3 + u32::from(g) * 6 + u32::from(b)) / 10) as u8
    }
    fn has_color(&self, c: [u8; 3]) -> bool {
        self.rgb.chunks_exact(3).any(|p| p == c)
    }
}

/// The figure has ink: more than 2 % of pixels are not white, in several colours.
fn assert_not_blank(p: &Png) {
    let non_white = p
        .rgb
        .chunks_exact(3)
        .filter(|c| *c != [255, 255, 255])
        .count();
    assert!(
        non_white * 50 > (p.w * p.h) as usize,
        "only {non_white} non-white pixels"
    );
    let mut colours: Vec<[u8; 3]> = p.rgb.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 8, "only {} colours", colours.len());
}

/// The title band holds rendered text: dark glyph pixels, anti-aliased
/// edges (many grey levels), and centred (the title is centred).
fn assert_title_rendered(p: &Png) {
    let (mut dark, mut lo_x, mut hi_x) = (0, u32::MAX, 0);
    let mut greys = std::collections::BTreeSet::new();
    for y in 0..TITLE_ROWS {
        for x in 0..p.w {
            let l = p.luma(x, y);
            if l < 96 {
                dark += 1;
                lo_x = lo_x.min(x);
                hi_x = hi_x.max(x);
            }
            if (40..216).contains(&l) {
                greys.insert(l);
            }
        }
    }
    assert!(
        dark > 40,
        "title band has {dark} dark pixels: no text drawn"
    );
    assert!(
        greys.len() > 10,
        "title band has {} grey levels: not anti-aliased",
        greys.len()
    );
    let centre = (lo_x + hi_x) as i64 / 2;
    assert!(
        (centre - p.w as i64 / 2).abs() < 12,
        "title not centred: {lo_x}..{hi_x}"
    );
}

/// Renders through `write` and checks the PNG; returns it.
fn check_written(dir: &TempDir, name: &str, write: impl FnOnce(&Path) -> Result<()>) -> Png {
    let path = dir.path(name);
    write(&path).unwrap();
    let png = Png::open(&path);
    assert_eq!((png.w, png.h), (SIZE.width, SIZE.height));
    assert_not_blank(&png);
    assert_title_rendered(&png);
    // Atomic write: nothing but the PNG is left in the directory.
    let names: Vec<_> = std::fs::read_dir(&dir.0)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(names.is_empty(), "temporary files left: {names:?}");
    png
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn bars() -> GroupedBars {
    GroupedBars {
        groups: strings(&["GAP-TV", "ADMM-TV", "MST-S"]),
        series: ["Ideal", "Assumed", "Corrected", "Oracle"]
            .iter()
            .enumerate()
            .map(|(j, s)| BarSeries {
                name: s.to_string(),
                values: vec![30.0 + j as f64, 25.5 - j as f64, 33.2],
            })
            .collect(),
        y_label: "PSNR (dB)".into(),
        show_values: true,
        value_decimals: 1,
        y_range: None,
    }
}

fn lines() -> LineChart {
    LineChart {
        series: (0..3)
            .map(|j| LineSeries {
                name: format!("series {j}"),
                points: (0..5)
                    .map(|i| (i as f64 * 0.5, 30.0 - (i * j) as f64))
                    .collect(),
            })
            .collect(),
        x_label: "mismatch scale".into(),
        y_label: "PSNR (dB)".into(),
        ..Default::default()
    }
}

fn scatter() -> EstimatedVsTrue {
    let panel = |name: &str, k: f64| ScatterPanel {
        name: name.into(),
        unit: "px".into(),
        series: vec![
            (0..6).map(|i| (i as f64 * k, i as f64 * k + 0.1)).collect(),
            vec![(k, 0.9 * k)],
        ],
    };
    EstimatedVsTrue {
        series_names: strings(&["paper", "fast"]),
        panels: vec![
            panel("dx", 1.0),
            panel("dy", -1.0),
            panel("θ", 0.2),
            panel("a1", 2.0),
            panel("α", 0.5),
        ],
    }
}

fn solid(rows: usize, cols: usize, c: [u8; 3]) -> RgbImage {
    RgbImage {
        rows,
        cols,
        data: c.iter().copied().cycle().take(3 * rows * cols).collect(),
    }
}

fn panel() -> ImagePanel {
    let err = |t: &str, v: f32| ErrorMap {
        title: t.into(),
        rows: 12,
        cols: 16,
        values: (0..192).map(|i| v * (i % 16) as f32 / 15.0).collect(),
    };
    ImagePanel {
        columns: vec![
            PanelColumn {
                title: "Truth".into(),
                image: solid(12, 16, [255, 0, 0]),
                error: None,
            },
            PanelColumn {
                title: "Assumed".into(),
                image: solid(12, 16, [0, 0, 255]),
                error: Some(err("|A − T|", 0.2)),
            },
            PanelColumn {
                title: "Corrected".into(),
                image: solid(12, 16, [0, 255, 0]),
                error: Some(err("|C − T|", 0.05)),
            },
        ],
        error_label: "|error|".into(),
        error_range: None,
    }
}

fn spectra() -> Spectra {
    let wl: Vec<f64> = (0..28).map(|k| 450.0 + 7.0 * k as f64).collect();
    let s = |a: f64| {
        (0..28)
            .map(|k| 0.3 + a * (k as f64 / 27.0))
            .collect::<Vec<_>>()
    };
    Spectra {
        wavelengths_nm: wl,
        truth_name: String::new(),
        series_names: strings(&["Ideal", "Assumed"]),
        pixels: vec![
            PixelSpectra {
                label: "pixel A".into(),
                truth: s(0.5),
                estimates: vec![s(0.45), s(0.2)],
            },
            PixelSpectra {
                label: "pixel B".into(),
                truth: s(-0.2),
                estimates: vec![s(-0.25), s(0.1)],
            },
        ],
        y_label: "intensity".into(),
    }
}

#[test]
fn grouped_bars_render() {
    let dir = TempDir::new("bars");
    let png = check_written(&dir, "bars.png", |p| {
        write_grouped_bars(&bars(), "PSNR by method", SIZE, p)
    });
    // Each series has its palette colour (Okabe–Ito blue, vermillion, …).
    for c in [
        [0x00, 0x72, 0xB2],
        [0xD5, 0x5E, 0x00],
        [0x00, 0x9E, 0x73],
        [0xCC, 0x79, 0xA7],
    ] {
        assert!(png.has_color(c), "series colour {c:?} missing");
    }
}

#[test]
fn title_text_depends_on_the_string() {
    // Same data, two titles: the title band differs, the rest is identical,
    // so what is drawn there is the text.
    let a = Png::from_image(&render_grouped_bars(&bars(), "AAAA", SIZE).unwrap());
    let b = Png::from_image(&render_grouped_bars(&bars(), "WWWW WWWW", SIZE).unwrap());
    let row = 3 * SIZE.width as usize;
    let band = TITLE_ROWS as usize * row;
    assert_ne!(a.rgb[..band], b.rgb[..band]);
    assert_eq!(a.rgb[40 * row..], b.rgb[40 * row..]);
    // Without a title the band is white.
    let none = Png::from_image(&render_grouped_bars(&bars(), "", SIZE).unwrap());
    assert!(none.rgb[..4 * row].iter().all(|&v| v == 255));
}

#[test]
fn line_chart_renders_numeric_and_categorical() {
    let dir = TempDir::new("lines");
    check_written(&dir, "lines.png", |p| {
        write_line_chart(&lines(), "Sensitivity", SIZE, p)
    });
    let mut per_scene = lines();
    per_scene.x_categories = (0..5).map(|i| format!("scene{i:02}")).collect();
    for s in &mut per_scene.series {
        for (i, p) in s.points.iter_mut().enumerate() {
            p.0 = i as f64;
        }
    }
    check_written(&dir, "per_scene.png", |p| {
        write_line_chart(&per_scene, "Per-scene PSNR", SIZE, p)
    });
}

#[test]
fn scatter_renders_five_panels() {
    let dir = TempDir::new("scatter");
    check_written(&dir, "scatter.png", |p| {
        write_estimated_vs_true(&scatter(), "Estimated vs true", SIZE, p)
    });
}

#[test]
fn image_panel_shows_images_and_colour_bar() {
    let dir = TempDir::new("panel");
    let png = check_written(&dir, "panel.png", |p| {
        write_image_panel(&panel(), "Qualitative", SIZE, p)
    });
    for c in [[255, 0, 0], [0, 0, 255], [0, 255, 0]] {
        assert!(png.has_color(c), "image colour {c:?} missing");
    }
    // The shared scale runs 0 … 0.2: both ends of viridis appear (in the
    // colour bar and in the larger error map).
    assert!(png.has_color([0x44, 0x01, 0x54]));
    assert!(png.has_color([0xFD, 0xE7, 0x25]));
    // A fitting size keeps the width and gives a sensible height.
    let fit = panel().fitting_size(900, "Qualitative");
    assert_eq!(fit.width, 900);
    assert!(
        fit.height >= Size::MIN.height && fit.height < 900,
        "{fit:?}"
    );
}

#[test]
fn spectra_render() {
    let dir = TempDir::new("spectra");
    let png = check_written(&dir, "spectra.png", |p| {
        write_spectra(&spectra(), "Spectra", SIZE, p)
    });
    assert!(png.has_color([0, 0, 0]), "the truth is drawn in black");
}

fn assert_invalid<T>(r: Result<T>, needle: &str) {
    match r {
        Err(e @ FigureError::InvalidInput { .. }) => {
            let msg = e.to_string();
            assert!(msg.contains(needle), "'{msg}' does not mention '{needle}'");
        }
        Err(e) => panic!("expected InvalidInput mentioning '{needle}', got {e:?}"),
        Ok(_) => panic!("expected InvalidInput mentioning '{needle}', got Ok"),
    }
}

#[test]
fn bad_bar_input_is_an_error() {
    let r = |d: &GroupedBars| render_grouped_bars(d, "t", SIZE);
    assert_invalid(r(&GroupedBars::default()), "groups is empty");
    let mut d = bars();
    d.series.clear();
    assert_invalid(r(&d), "series is empty");
    let mut d = bars();
    d.series[1].values.pop();
    assert_invalid(r(&d), "series 'Assumed' has 2 values, expected 3");
    let mut d = bars();
    d.series[2].values[0] = f64::NAN;
    assert_invalid(r(&d), "not finite");
    let mut d = bars();
    d.y_range = Some((40.0, 20.0));
    assert_invalid(r(&d), "y_range");
    assert_invalid(
        render_grouped_bars(&bars(), "t", Size::new(10, 10)),
        "figure size",
    );
    let dir = TempDir::new("bad-bars");
    assert_invalid(
        write_grouped_bars(&bars(), "t", SIZE, dir.path("x.jpg")),
        ".png",
    );
    // A missing directory is an I/O error, not a panic.
    let e = write_grouped_bars(&bars(), "t", SIZE, dir.path("no/such/dir.png")).unwrap_err();
    assert!(matches!(e, FigureError::Io(_)), "{e:?}");
}

#[test]
fn bad_line_input_is_an_error() {
    let r = |d: &LineChart| render_line_chart(d, "t", SIZE);
    assert_invalid(r(&LineChart::default()), "series is empty");
    let mut d = lines();
    d.series[0].points.clear();
    assert_invalid(r(&d), "points is empty");
    let mut d = lines();
    d.series[1].points[2].1 = f64::INFINITY;
    assert_invalid(r(&d), "not finite");
    let mut d = lines();
    d.x_categories = strings(&["a", "b"]);
    assert_invalid(r(&d), "outside the category indices");
}

#[test]
fn bad_scatter_input_is_an_error() {
    let r = |d: &EstimatedVsTrue| render_estimated_vs_true(d, "t", SIZE);
    assert_invalid(r(&EstimatedVsTrue::default()), "series_names is empty");
    let mut d = scatter();
    d.panels[0].series.pop();
    assert_invalid(r(&d), "panel 'dx' series has 1 values, expected 2");
    let mut d = scatter();
    d.panels[1].series = vec![vec![], vec![]];
    assert_invalid(r(&d), "panel 'dy' points is empty");
    let mut d = scatter();
    d.panels[2].series[0][0].0 = f64::NAN;
    assert_invalid(r(&d), "not finite");
}

#[test]
fn bad_panel_input_is_an_error() {
    let r = |d: &ImagePanel| render_image_panel(d, "t", SIZE);
    assert_invalid(r(&ImagePanel::default()), "columns is empty");
    let mut d = panel();
    d.columns[0].image.data.pop();
    assert_invalid(r(&d), "image 'Truth'");
    let mut d = panel();
    d.columns[1].error.as_mut().unwrap().values[5] = f32::NAN;
    assert_invalid(r(&d), "not finite");
    let mut d = panel();
    d.columns[2].error.as_mut().unwrap().rows = 0;
    assert_invalid(r(&d), "error map '|C − T|'");
    let mut d = panel();
    d.error_range = Some((0.0, 0.0));
    assert_invalid(r(&d), "error_range");
}

#[test]
fn bad_spectra_input_is_an_error() {
    let r = |d: &Spectra| render_spectra(d, "t", SIZE);
    assert_invalid(r(&Spectra::default()), "wavelengths_nm is empty");
    let mut d = spectra();
    d.wavelengths_nm.swap(3, 4);
    assert_invalid(r(&d), "strictly increasing");
    let mut d = spectra();
    d.pixels[0].truth.pop();
    assert_invalid(r(&d), "pixel 'pixel A' truth has 27 values, expected 28");
    let mut d = spectra();
    d.pixels[1].estimates.pop();
    assert_invalid(r(&d), "estimates has 1 values, expected 2");
    let mut d = spectra();
    d.pixels[1].estimates[0][3] = f64::NAN;
    assert_invalid(r(&d), "not finite");
}

#[test]
fn flat_and_single_point_data_render() {
    // Degenerate but valid input draws something sensible, no panic.
    let mut d = bars();
    for s in &mut d.series {
        s.values = vec![0.0; 3];
    }
    render_grouped_bars(&d, "zeros", SIZE).unwrap();
    let one = LineChart {
        series: vec![LineSeries {
            name: "one".into(),
            points: vec![(1.0, 1.0)],
        }],
        ..Default::default()
    };
    render_line_chart(&one, "one point", SIZE).unwrap();
    let mut p = panel();
    for c in &mut p.columns {
        if let Some(e) = &mut c.error {
            e.values.iter_mut().for_each(|v| *v = 0.0);
        }
    }
    render_image_panel(&p, "zero error", SIZE).unwrap();
    let mut s = spectra();
    s.wavelengths_nm = vec![500.0];
    for px in &mut s.pixels {
        px.truth = vec![0.5];
        px.estimates = vec![vec![0.5], vec![0.5]];
    }
    render_spectra(&s, "one band", SIZE).unwrap();
}

#[test]
fn unplottable_ranges_and_extreme_input_are_errors_not_panics() {
    let mut d = bars();
    d.series[0].values[0] = -1e308;
    d.series[1].values[0] = 1e308;
    assert_invalid(render_grouped_bars(&d, "t", SIZE), "cannot be drawn");
    let mut l = lines();
    for s in &mut l.series {
        s.points = vec![(1e16, 1.0), (1e16 + 2.0, 2.0)];
    }
    assert_invalid(render_line_chart(&l, "t", SIZE), "cannot be drawn");
    // Very long text is cut with "…", many columns squeeze, tiny sizes work.
    let long = "a very long title ".repeat(400);
    render_grouped_bars(&bars(), &long, SIZE).unwrap();
    let mut p = panel();
    let col = p.columns[1].clone();
    p.columns.extend(std::iter::repeat_n(col, 40));
    p.columns[3].title = long.clone();
    render_image_panel(&p, "many", Size::MIN).unwrap();
    let mut s = scatter();
    s.panels[0].name = long;
    render_estimated_vs_true(&s, "t", Size::MIN).unwrap();
}
