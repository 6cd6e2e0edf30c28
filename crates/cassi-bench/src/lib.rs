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
