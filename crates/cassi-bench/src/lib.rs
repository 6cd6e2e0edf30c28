//! Shared helpers of the benchmark binaries.

/// Peak resident memory of this process so far (VmHWM), in MiB, on Linux.
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::NAN
    } else {
        v[v.len() / 2]
    }
}

/// `../shared/data` beside the workspace, or $CASSI_SHARED_DATA (the
/// binaries' default; tests use `cassi_io::shared_data::for_test`).
pub fn shared_data() -> std::path::PathBuf {
    cassi_io::shared_data::default_dir()
}

/// The TSA snapshots a real-data bench reads, with the real mask: the real
/// ones (`<shared data>/real/scene*.mat`, variable `meas_real`) or a
/// control's simulated ones (`DIR/scene*.npy`).
pub struct TsaSnapshots {
    /// Where they were read from.
    pub dir: std::path::PathBuf,
    /// Those whose name contains one of the wanted names (all when none), sorted.
    pub paths: Vec<std::path::PathBuf>,
    pub mask: cassi_core::Mask,
    mask_path: std::path::PathBuf,
    variable: Option<&'static str>,
}

impl TsaSnapshots {
    /// The snapshots in `measurements` (a control's folder; `None`: the real
    /// ones) whose names contain one of `only`; refused when none match.
    pub fn find(measurements: Option<&std::path::Path>, only: &[String]) -> anyhow::Result<Self> {
        use anyhow::Context;
        let real = shared_data().join("real");
        let mask_path = real.join("tsa_real_mask660.mat");
        let mask = cassi_io::load_frame(&mask_path, Some("mask"))?;
        let (dir, ext, variable) = match measurements {
            None => (real, "mat", Some("meas_real")),
            Some(d) => (d.to_path_buf(), "npy", None),
        };
        let mut paths: Vec<_> = std::fs::read_dir(&dir)
            .with_context(|| format!("{}: the snapshots are needed", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let name = scene_name(p);
                name.starts_with("scene")
                    && p.extension().is_some_and(|e| e == ext)
                    && (only.is_empty() || only.iter().any(|o| name.contains(o.as_str())))
            })
            .collect();
        paths.sort();
        anyhow::ensure!(
            !paths.is_empty(),
            "no snapshot scene*.{ext} in {} matches {only:?}",
            dir.display()
        );
        Ok(Self {
            dir,
            paths,
            mask,
            mask_path,
            variable,
        })
    }

    /// The snapshot at `path`, refused unless it has the mask's rows.
    pub fn load(&self, path: &std::path::Path) -> anyhow::Result<cassi_core::Measurement> {
        let meas: cassi_core::Measurement = cassi_io::load_frame(path, self.variable)?;
        anyhow::ensure!(
            meas.rows() == self.mask.rows(),
            "{}: {} rows, the mask {} has {}",
            path.display(),
            meas.rows(),
            self.mask_path.display(),
            self.mask.rows()
        );
        Ok(meas)
    }
}

/// A scene's name in tables and records: its file name without the
/// extension (`cave_beads`).
pub fn scene_name(path: &std::path::Path) -> String {
    path.file_stem()
        .unwrap_or_default()
        .to_string_lossy()
        .to_string()
}

/// The CAVE scenes (`scenes/*.npy` under `data`), sorted by name; an error
/// naming the folder when there are none.
pub fn cave_scenes(data: &std::path::Path) -> anyhow::Result<Vec<std::path::PathBuf>> {
    use anyhow::Context;
    let dir = data.join("scenes");
    let mut scenes: Vec<std::path::PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("{}: the CAVE scenes are needed", data.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "npy"))
        .collect();
    scenes.sort();
    if scenes.is_empty() {
        anyhow::bail!("no scenes in {}", dir.display());
    }
    Ok(scenes)
}

/// The physical self-calibration benchmark's random ψ for `seed` (issue 14):
/// dx, dy ∈ ±2.5 px, θ ∈ ±0.8°, a1 ∈ 1.93–2.07, α ∈ ±1°, σ ∈ 0–0.8 px,
/// drawn from `Rng::new(seed)` in that order.
pub fn physical_random_mismatch(seed: u64) -> cassi_core::Mismatch {
    let mut rng = cassi_core::Rng::new(seed);
    cassi_core::Mismatch {
        dx: rng.uniform_in(-2.5, 2.5),
        dy: rng.uniform_in(-2.5, 2.5),
        theta_deg: rng.uniform_in(-0.8, 0.8),
        a1: rng.uniform_in(1.93, 2.07),
        alpha_deg: rng.uniform_in(-1.0, 1.0),
        blur_sigma_px: rng.uniform_in(0.0, 0.8),
        a2: 0.0,
    }
}

/// `held` with the calibrated parameters set from `x` (in
/// `Parameter::CALIBRATED` order): what `held` has beyond them (a held
/// curvature a2) stays. σ as |σ|: a simplex may step below zero.
pub fn psi_of(held: &cassi_core::Mismatch, x: &[f64]) -> cassi_core::Mismatch {
    let mut psi = *held;
    for (&p, &v) in cassi_core::Parameter::CALIBRATED.iter().zip(x) {
        p.set(&mut psi, v);
    }
    psi.blur_sigma_px = psi.blur_sigma_px.abs();
    psi
}

/// A_ψ `scene` through `model` with ψ's blur, cropped / zero-padded to a
/// `rows × cols` detector (origin at detector pixel (0, 0)); `None` for a
/// ψ the operator rejects.
pub fn predict_on_detector(
    mask: &cassi_core::Mask,
    scene: &cassi_core::Cube,
    psi: &cassi_core::Mismatch,
    model: cassi_core::optics::DispersionModel,
    shape: (usize, usize),
) -> Option<Vec<f64>> {
    let instrument = cassi_core::recon::Model::nominal(mask, scene.bands(), 2.0, model).ok()?;
    predict_with(&instrument, scene, psi, shape)
}

/// [`predict_on_detector`] through `instrument`'s operator at ψ: what it
/// holds beside ψ (band offsets, band spread) held too.
pub fn predict_with(
    instrument: &cassi_core::recon::Model,
    scene: &cassi_core::Cube,
    psi: &cassi_core::Mismatch,
    (rows, cols): (usize, usize),
) -> Option<Vec<f64>> {
    use cassi_core::linop::LinearOperator;
    let op = instrument.operator_at(psi).ok()?;
    let (mr, mc) = op.measurement_shape();
    let mut full = vec![0.0f32; mr * mc];
    op.apply(scene.as_slice(), &mut full);
    let mut out = vec![0.0f64; rows * cols];
    for r in 0..mr.min(rows) {
        for c in 0..mc.min(cols) {
            out[r * cols + c] = full[r * mc + c] as f64;
        }
    }
    Some(out)
}

/// min_s ‖y − s·m‖² / ‖y‖²: the share of `y` a scaled `m` leaves unexplained.
pub fn relative_residual2(y: &[f64], m: &[f64]) -> f64 {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let (ym, mm, yy) = (dot(y, m), dot(m, m), dot(y, y));
    let s = if mm > 0.0 { ym / mm } else { 0.0 };
    ((yy - s * ym) / yy).max(0.0)
}

/// The minimiser of `f` on [a, b] to within `tol`, by golden section: for a
/// one-parameter fit whose objective is unimodal there (a blur σ with
/// everything else known).
pub fn golden_section(f: impl Fn(f64) -> f64, (mut a, mut b): (f64, f64), tol: f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    while b - a > tol {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}

/// `--help` or `-h` anywhere on the command line prints `usage` and ends
/// the process (exit 0), before any work; for a bench whose own parser
/// refuses unknown arguments.
pub fn exit_on_help(usage: &str) {
    if std::env::args().skip(1).any(|a| a == "-h" || a == "--help") {
        println!("usage: {usage}");
        std::process::exit(0);
    }
}

/// A bench's command line checked before any work, for a bench without a
/// parser of its own: [`exit_on_help`], then a `--flag` not in `flags` —
/// or, for a bench that takes none, any argument — is an error naming it
/// with the usage (the benches that took no arguments used to ignore them
/// and start their whole run on `--help`).
pub fn check_arguments(usage: &str, flags: &[&str]) -> anyhow::Result<()> {
    exit_on_help(usage);
    let argv: Vec<String> = std::env::args().skip(1).collect();
    unknown_arguments(&argv, usage, flags)
}

/// [`check_arguments`]'s refusal on `argv` (help already handled).
fn unknown_arguments(argv: &[String], usage: &str, flags: &[&str]) -> anyhow::Result<()> {
    for a in argv {
        let known = !flags.is_empty() && (flags.contains(&a.as_str()) || !a.starts_with("--"));
        anyhow::ensure!(known, "unknown argument '{a}'\nusage: {usage}");
    }
    Ok(())
}

/// A bench's record written atomically (pretty JSON, one trailing newline).
pub fn write_record(
    path: impl AsRef<std::path::Path>,
    record: &serde_json::Value,
) -> anyhow::Result<()> {
    cassi_io::write_atomic(
        path,
        (serde_json::to_string_pretty(record)? + "\n").as_bytes(),
    )?;
    Ok(())
}

/// Where a bench writes its record: $CASSI_BENCH_OUT, else
/// `bench/results/<name>`; its folder made before the work starts, so a
/// bad path fails at once rather than after the run.
pub fn bench_out(name: &str) -> anyhow::Result<String> {
    use anyhow::Context;
    let out = std::env::var("CASSI_BENCH_OUT")
        .unwrap_or_else(|_| format!("{}/../../bench/results/{name}", env!("CARGO_MANIFEST_DIR")));
    if let Some(dir) = std::path::Path::new(&out)
        .parent()
        .filter(|d| !d.as_os_str().is_empty())
    {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("creating the output folder {}", dir.display()))?;
    }
    Ok(out)
}

/// What a tuning-half model study (`blur_phase`, `model_fidelity`) reads:
/// its record's path, the TSA simulation mask and the first `scenes` CAVE
/// scenes (at most the tuning half's five).
pub struct ModelStudy {
    pub out: String,
    pub mask: cassi_core::Mask,
    pub scenes: Vec<std::path::PathBuf>,
}

/// The inputs of the model study `name`, from its command line (`[--scenes
/// N]`, `default_scenes` without it); the record's folder made first.
pub fn model_study(name: &str, default_scenes: usize) -> anyhow::Result<ModelStudy> {
    check_arguments(&format!("{name} [--scenes N]"), &["--scenes"])?;
    let argv: Vec<String> = std::env::args().skip(1).collect();
    let wanted: usize = match argv.as_slice() {
        [] => default_scenes,
        [flag, n] if flag == "--scenes" => n.parse()?,
        _ => anyhow::bail!("usage: {name} [--scenes N]"),
    };
    let out = bench_out(&format!("{name}.json"))?;
    let data = shared_data();
    let mask = cassi_io::load_frame(data.join("masks/tsa_simu_mask256.mat"), Some("mask"))?;
    let scenes = cave_scenes(&data)?
        .into_iter()
        .take(wanted.min(5))
        .collect();
    Ok(ModelStudy { out, mask, scenes })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn argv(a: &[&str]) -> Vec<String> {
        a.iter().map(|s| s.to_string()).collect()
    }

    /// A bench without flags refuses any argument; one with flags refuses
    /// an unknown flag by name and lets values through.
    #[test]
    fn a_bench_command_line_is_checked_before_the_work() {
        assert!(unknown_arguments(&argv(&[]), "u", &[]).is_ok());
        assert!(unknown_arguments(&argv(&["--limit", "3"]), "u", &["--limit"]).is_ok());
        let e = unknown_arguments(&argv(&["3"]), "u x", &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("'3'") && e.contains("usage: u x"), "{e}");
        let e = unknown_arguments(&argv(&["--limt", "3"]), "u", &["--limit"]).unwrap_err();
        assert!(e.to_string().contains("'--limt'"), "{e}");
    }
}
