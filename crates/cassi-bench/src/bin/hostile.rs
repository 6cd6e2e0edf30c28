//! Hostile-input harness for the `cassi` CLI (issue #12's acceptance figure): seeded
//! mutations of .npy/.npz/MAT v5/MAT v7.3/.pth/.safetensors/JSON inputs, hand-built memory
//! bombs, absurd parameters, meaningless inputs, output-equals-input reproducers, interrupts,
//! concurrent runs and determinism checks. Every case runs the `cassi` binary as a child with a
//! wall-clock timeout and records exit status, peak RSS (wait4), panics, input hashes and
//! output-folder snapshots before/after; the verdicts are written as JSON and summarised in a table.
//!
//! Run: `cargo run --release -p cassi-bench --bin hostile -- --cassi target/release/cassi
//! [--seeds DIR] [--count N] [--out bench/results/hostile.json] [--work DIR] [--keep]
//! [--seed S] [--mem-cap-mib M]`. See crates/cassi-bench/HOSTILE.md.

// The case tables below are tuples: clearer than one-off structs.
#![allow(clippy::type_complexity)]
#![deny(clippy::undocumented_unsafe_blocks)]

#[path = "../hostile/files.rs"]
mod files;
#[path = "../hostile/run.rs"]
mod run;

use std::collections::BTreeMap;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Context, bail};
use files::Rng;
use run::{Outcome, Spec};
use serde_json::{Value, json};

const RSS_LIMIT_MIB: f64 = 512.0;
/// A run that fails "up front" should fail in well under this.
const UP_FRONT_S: f64 = 1.0;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    /// Exit 0 or 1, no crash; a failed run leaves the folder as it was.
    Any,
    /// Must fail (exit ≠ 0, no crash) with a message naming `must_name`; inputs intact.
    Fail,
    /// A meaningless input: fail, or succeed with a warning on stderr.
    FailOrWarn,
    /// Must fail before doing work: quickly, with no outputs, naming the flag.
    FailUpFront,
    /// Must succeed.
    Success,
}

struct Case {
    category: String,
    family: String,
    label: String,
    note: String,
    dir: PathBuf,
    args: Vec<String>,
    env: Vec<(String, String)>,
    timeout: Duration,
    signal: Option<(i32, Duration)>,
    /// Files (relative to dir) whose content must not change.
    inputs: Vec<String>,
    expect: Expect,
    /// Strings the error message must contain.
    must_name: Vec<String>,
    /// Files (relative to dir) whose permission bits must survive a successful run.
    keep_mode: Vec<String>,
}

impl Case {
    fn new(category: &str, family: &str, label: &str, dir: &Path, args: &[&str]) -> Self {
        Case {
            category: category.into(),
            family: family.into(),
            label: label.into(),
            note: String::new(),
            dir: dir.to_path_buf(),
            args: args.iter().map(|s| s.to_string()).collect(),
            env: vec![("RAYON_NUM_THREADS".into(), "2".into())],
            timeout: Duration::from_secs(20),
            signal: None,
            inputs: Vec::new(),
            expect: Expect::Any,
            must_name: Vec::new(),
            keep_mode: Vec::new(),
        }
    }
    fn inputs(mut self, v: &[&str]) -> Self {
        self.inputs = v.iter().map(|s| s.to_string()).collect();
        self
    }
    fn expect(mut self, e: Expect, names: &[&str]) -> Self {
        self.expect = e;
        self.must_name = names.iter().map(|s| s.to_string()).collect();
        self
    }
    fn timeout(mut self, s: u64) -> Self {
        self.timeout = Duration::from_secs(s);
        self
    }
    fn note(mut self, n: impl Into<String>) -> Self {
        self.note = n.into();
        self
    }
}

#[derive(Default, Clone)]
struct Flags {
    panic: bool,
    destroyed: Vec<String>,
    partial: Vec<String>,
    temp: Vec<String>,
    rss: bool,
    meaningless: bool,
    hang: bool,
    esc: bool,
    determinism: bool,
    other: Vec<String>,
}

impl Flags {
    fn violations(&self) -> Vec<String> {
        let mut v = Vec::new();
        if self.panic {
            v.push("panic/crash".to_string());
        }
        if !self.destroyed.is_empty() {
            v.push(format!("input destroyed: {}", self.destroyed.join(", ")));
        }
        if !self.partial.is_empty() {
            v.push(format!(
                "partial/mixed outputs: {}",
                self.partial.join(", ")
            ));
        }
        if !self.temp.is_empty() {
            v.push(format!("temp files left: {}", self.temp.join(", ")));
        }
        if self.rss {
            v.push(format!("peak RSS > {RSS_LIMIT_MIB} MiB"));
        }
        if self.meaningless {
            v.push("meaningless/absurd input accepted silently".into());
        }
        if self.hang {
            v.push("hang (timeout)".into());
        }
        if self.esc {
            v.push("ESC byte in output".into());
        }
        if self.determinism {
            v.push("determinism mismatch".into());
        }
        v.extend(self.other.iter().cloned());
        v
    }
}

#[derive(Default)]
struct Totals {
    cases: usize,
    failing: usize,
    panics: usize,
    destroyed: usize,
    partial: usize,
    temp: usize,
    rss_over: usize,
    meaningless: usize,
    hangs: usize,
    esc: usize,
    determinism: usize,
    other: usize,
    peak_mib: f64,
    peak_case: usize,
    wall_s: f64,
    external: usize,
}

struct Ctx {
    bin: PathBuf,
    work: PathBuf,
    base: PathBuf,
    scratch: PathBuf,
    mem_cap: u64,
    keep: bool,
    next_id: usize,
    records: Vec<Value>,
    totals: BTreeMap<String, Totals>,
    notes: Vec<String>,
}

fn s(v: &[&str]) -> Vec<String> {
    v.iter().map(|x| x.to_string()).collect()
}

fn has_warning(o: &Outcome) -> bool {
    o.stderr_text().to_lowercase().contains("warning")
}

fn head(b: &[u8], n: usize) -> String {
    let t = String::from_utf8_lossy(b);
    let t = t.trim();
    if t.len() <= n {
        t.to_string()
    } else {
        let mut k = n;
        while !t.is_char_boundary(k) {
            k -= 1;
        }
        format!("{}…", &t[..k])
    }
}

impl Ctx {
    fn case_dir(&mut self, tag: &str) -> PathBuf {
        let d = self
            .work
            .join("cases")
            .join(format!("{:05}-{tag}", self.next_id));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Copy base files / folders into `dir`.
    /// Copies base files into a case folder; an .npy comes with the JSON
    /// sidecar beside it, as `cassi simulate` writes them.
    fn stage(&self, dir: &Path, names: &[&str]) {
        for n in names {
            copy_rec(&self.base.join(n), &dir.join(n));
            if let Some(stem) = n.strip_suffix(".npy") {
                let sidecar = format!("{stem}.json");
                if self.base.join(&sidecar).is_file() {
                    copy_rec(&self.base.join(&sidecar), &dir.join(&sidecar));
                }
            }
        }
    }

    fn exec(&self, spec: &Spec) -> Outcome {
        run::run(&self.bin, spec, &self.scratch, self.mem_cap)
    }

    /// Runs a case, judges it, records it. Returns the outcome and flags.
    fn run_case(&mut self, c: Case) -> (Outcome, Flags) {
        let before_in: Vec<Option<String>> = c
            .inputs
            .iter()
            .map(|i| run::file_hash(&c.dir.join(i)))
            .collect();
        let snap0 = run::snapshot(&c.dir);
        let spec = Spec {
            args: c.args.clone(),
            cwd: c.dir.clone(),
            env: c.env.clone(),
            timeout: c.timeout,
            signal: c.signal,
        };
        let o = self.exec(&spec);
        let snap1 = run::snapshot(&c.dir);
        let mut f = Flags::default();
        self.judge(&c, &o, &before_in, &snap0, &snap1, &mut f);
        self.record(&c, &o, f.clone(), json!({}));
        (o, f)
    }

    fn judge(
        &self,
        c: &Case,
        o: &Outcome,
        before_in: &[Option<String>],
        snap0: &BTreeMap<String, run::FileState>,
        snap1: &BTreeMap<String, run::FileState>,
        f: &mut Flags,
    ) {
        f.panic = o.crashed() && !o.alloc_capped();
        f.hang = o.hung;
        f.rss = o.peak_mib() > RSS_LIMIT_MIB || o.alloc_capped();
        f.esc = o.stdout.contains(&0x1b) || o.stderr.contains(&0x1b);
        for (i, h0) in c.inputs.iter().zip(before_in) {
            let h1 = run::file_hash(&c.dir.join(i));
            if h0.is_some() && *h0 != h1 {
                f.destroyed.push(i.clone());
            }
        }
        let (added, removed, changed) = run::diff(snap0, snap1);
        f.temp = added
            .iter()
            .filter(|a| run::is_temp_name(a))
            .cloned()
            .collect();
        let failed = !o.ok();
        if failed {
            // an interrupted or failed `eval` keeps its finished scenes in
            // `.pending/` for --resume: beside the previous set, not in it
            let resumable = |p: &String| p.starts_with(".pending") || p.contains("/.pending");
            let added: Vec<&String> = added.iter().filter(|a| !resumable(a)).collect();
            for a in added {
                if !run::is_temp_name(a) {
                    f.partial.push(format!("new {a}"));
                }
            }
            for r in &removed {
                f.partial.push(format!("removed {r}"));
            }
            for ch in &changed {
                if !c.inputs.contains(ch) {
                    f.partial.push(format!("changed {ch}"));
                }
            }
        }
        let err = o.stderr_text();
        // 130: the conventional exit of a run stopped by the signal we sent
        let interrupted = c.signal.is_some() && o.code == Some(130);
        let unclean_code = !interrupted && matches!(o.code, Some(c) if c != 0 && c != 1 && c != 2);
        if unclean_code && !o.crashed() {
            f.other
                .push(format!("unexpected exit code {}", o.code.unwrap_or(-1)));
        }
        match c.expect {
            Expect::Any => {}
            Expect::Success => {
                if failed {
                    f.other
                        .push(format!("expected success: {}", head(&o.stderr, 160)));
                }
            }
            Expect::Fail | Expect::FailUpFront | Expect::FailOrWarn => {
                if !failed {
                    if c.expect == Expect::FailOrWarn && has_warning(o) {
                        // legitimate with a warning
                    } else if c.category.starts_with("repro/1") {
                        f.other.push("accepted output = input".into());
                    } else {
                        f.meaningless = true;
                    }
                } else if !o.crashed() && !o.hung {
                    // a flag counts as named as `--flag`, `flag` or `flag` with `_` for `-`
                    let named = |n: &str| {
                        let bare = n.trim_start_matches('-');
                        err.contains(n)
                            || err.contains(bare)
                            || err.contains(&bare.replace('-', "_"))
                    };
                    let missing: Vec<&String> =
                        c.must_name.iter().filter(|n| !named(n.as_str())).collect();
                    if !missing.is_empty() {
                        f.other.push(format!(
                            "message does not name {}",
                            missing
                                .iter()
                                .map(|s| s.as_str())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ));
                    }
                    if c.expect == Expect::FailUpFront && o.wall_s > UP_FRONT_S {
                        f.other.push(format!("failed late ({:.2} s)", o.wall_s));
                    }
                }
            }
        }
        if !failed {
            for k in &c.keep_mode {
                let m0 = snap0.get(k).map(|s| s.mode);
                let m1 = snap1.get(k).map(|s| s.mode);
                if m0.is_some() && m0 != m1 {
                    f.other.push(format!(
                        "permissions of {k} changed {:o} -> {:o}",
                        m0.unwrap_or(0),
                        m1.unwrap_or(0)
                    ));
                }
            }
        }
    }

    fn record(&mut self, c: &Case, o: &Outcome, f: Flags, extra: Value) {
        let id = self.next_id;
        self.next_id += 1;
        let v = f.violations();
        let t = self.totals.entry(c.category.clone()).or_default();
        t.cases += 1;
        t.wall_s += o.wall_s;
        if !v.is_empty() {
            t.failing += 1;
        }
        t.panics += f.panic as usize;
        t.external += o.killed_externally() as usize;
        t.destroyed += !f.destroyed.is_empty() as usize;
        t.partial += !f.partial.is_empty() as usize;
        t.temp += !f.temp.is_empty() as usize;
        t.rss_over += f.rss as usize;
        t.meaningless += f.meaningless as usize;
        t.hangs += f.hang as usize;
        t.esc += f.esc as usize;
        t.determinism += f.determinism as usize;
        t.other += !f.other.is_empty() as usize;
        if o.peak_mib() > t.peak_mib {
            t.peak_mib = o.peak_mib();
            t.peak_case = id;
        }
        let outcome = if o.hung {
            "hang".to_string()
        } else if let Some(sig) = o.signal {
            format!("signal {sig}")
        } else {
            format!("exit {}", o.code.unwrap_or(-1))
        };
        let warned = o.ok() && has_warning(o);
        self.records.push(json!({
            "id": id,
            "category": c.category,
            "family": c.family,
            "label": c.label,
            "mutation": c.note,
            "command": format!("cassi {}", c.args.iter().map(|a| shell_quote(a)).collect::<Vec<_>>().join(" ")),
            "dir": c.dir.display().to_string(),
            "expect": format!("{:?}", c.expect),
            "must_name": c.must_name,
            "outcome": outcome,
            "exit_code": o.code,
            "signal": o.signal,
            "sent_signal": o.sent_signal,
            "wall_s": (o.wall_s * 1e4).round() / 1e4,
            "peak_rss_mib": (o.peak_mib() * 10.0).round() / 10.0,
            "panic": f.panic,
            "alloc_capped": o.alloc_capped(),
            "killed_externally": o.killed_externally(),
            "inputs_destroyed": f.destroyed,
            "partial_or_mixed": f.partial,
            "temp_files_left": f.temp,
            "esc_in_output": f.esc,
            "meaningless_accepted": f.meaningless,
            "warned": warned,
            "hang": f.hang,
            "determinism_mismatch": f.determinism,
            "violations": v,
            "verdict": if v.is_empty() { "pass" } else { "FAIL" },
            "stderr": head(&o.stderr, 300),
            "extra": extra,
        }));
        if v.is_empty() && !self.keep && c.category.starts_with("mutation") {
            let _ = std::fs::remove_dir_all(&c.dir);
        }
    }
}

fn shell_quote(a: &str) -> String {
    if a.chars()
        .all(|c| c.is_ascii_alphanumeric() || "-_./=,:".contains(c))
    {
        a.to_string()
    } else {
        format!("{a:?}")
    }
}

fn copy_rec(from: &Path, to: &Path) {
    let Ok(md) = std::fs::symlink_metadata(from) else {
        return;
    };
    if md.is_dir() {
        std::fs::create_dir_all(to).unwrap();
        for e in std::fs::read_dir(from).unwrap().flatten() {
            copy_rec(&e.path(), &to.join(e.file_name()));
        }
    } else {
        if let Some(p) = to.parent() {
            std::fs::create_dir_all(p).unwrap();
        }
        std::fs::copy(from, to).unwrap();
    }
}

fn write(p: &Path, b: &[u8]) {
    if let Some(d) = p.parent() {
        std::fs::create_dir_all(d).unwrap();
    }
    std::fs::write(p, b).unwrap();
}

/// JSON with timing-like keys removed (for comparing reports across runs).
fn strip_timing(v: &mut Value) {
    match v {
        Value::Object(m) => {
            m.retain(|k, _| {
                let k = k.to_lowercase();
                !(k.contains("second")
                    || k.contains("time")
                    || k.contains("elapsed")
                    || k.contains("duration")
                    || k.ends_with("_s")
                    || k == "machine"
                    || k == "threads")
            });
            for x in m.values_mut() {
                strip_timing(x);
            }
        }
        Value::Array(a) => a.iter_mut().for_each(strip_timing),
        _ => {}
    }
}

/// Content identity of a file for cross-run comparison: JSON without timings, else bytes.
fn content_key(p: &Path) -> Option<String> {
    let b = std::fs::read(p).ok()?;
    if p.extension().is_some_and(|e| e == "json")
        && let Ok(mut v) = serde_json::from_slice::<Value>(&b)
    {
        strip_timing(&mut v);
        return Some(files::hash(v.to_string().as_bytes()));
    }
    if p.extension().is_some_and(|e| e == "md" || e == "csv") {
        // reports carry timings in text; compare lines without digits after "s"
        let t = String::from_utf8_lossy(&b);
        let kept: String = t
            .lines()
            .filter(|l| !l.contains(" s") && !l.to_lowercase().contains("time"))
            .collect::<Vec<_>>()
            .join("\n");
        return Some(files::hash(kept.as_bytes()));
    }
    Some(files::hash(&b))
}

// ------------------------------------------------------------------ base files

fn make_base(ctx: &mut Ctx) -> anyhow::Result<()> {
    let b = ctx.base.clone();
    std::fs::create_dir_all(&b)?;
    let mut rng = Rng::new(7);
    let mask: Vec<f32> = (0..32 * 32).map(|_| (rng.below(2)) as f32).collect();
    write(&b.join("mask.npy"), &files::npy_f32(&[32, 32], &mask));
    let mask2: Vec<f32> = (0..32 * 32).map(|_| (rng.below(2)) as f32).collect();
    write(&b.join("maskB.npy"), &files::npy_f32(&[32, 32], &mask2));
    let maskd: Vec<f64> = mask.iter().map(|&x| x as f64).collect();
    write(
        &b.join("mask.mat"),
        &files::mat5_double(b"mask", 32, 32, &maskd),
    );
    let scene: Vec<f32> = (0..4 * 32 * 32).map(|_| rng.unit() as f32).collect();
    write(&b.join("scene.npy"), &files::npy_f32(&[4, 32, 32], &scene));
    let scene_small: Vec<f32> = (0..4 * 16 * 16).map(|_| rng.unit() as f32).collect();
    write(
        &b.join("truth16.npy"),
        &files::npy_f32(&[4, 16, 16], &scene_small),
    );
    let must = |args: &[&str]| -> anyhow::Result<()> {
        let o = ctx.exec(&Spec {
            args: s(args),
            cwd: b.clone(),
            env: vec![("RAYON_NUM_THREADS".into(), "2".into())],
            timeout: Duration::from_secs(120),
            signal: None,
        });
        if !o.ok() {
            bail!(
                "base file step `cassi {}` failed: {}",
                args.join(" "),
                o.stderr_text()
            );
        }
        Ok(())
    };
    for ext in ["npz", "mat", "npy"] {
        must(&[
            "simulate",
            "--scene",
            "scene.npy",
            "--mask",
            "mask.npy",
            "-o",
            &format!("m.{ext}"),
        ])?;
    }
    must(&[
        "calibrate",
        "m.npy",
        "--mask",
        "mask.npy",
        "-o",
        "c.json",
        "--write-mask",
        "wmask.mat",
    ])?;
    must(&[
        "reconstruct",
        "m.npy",
        "--mask",
        "mask.npy",
        "-o",
        "r.npy",
        "--iterations",
        "7",
    ])?;
    must(&[
        "simulate",
        "--scene",
        "scene.npy",
        "--mask",
        "mask.npy",
        "--noise-seed",
        "5",
        "-o",
        "s.npy",
    ])?;
    // what the networks take (256×256, 28 bands at step 2), so weights cases
    // reach the checkpoint loaders
    let mask256: Vec<f32> = (0..256 * 256).map(|_| (rng.below(2)) as f32).collect();
    write(
        &b.join("mask256.npy"),
        &files::npy_f32(&[256, 256], &mask256),
    );
    must(&[
        "simulate",
        "--synthetic",
        "--size",
        "256",
        "--mask",
        "mask256.npy",
        "-o",
        "m256.npy",
    ])?;
    std::fs::create_dir_all(b.join("scenes"))?;
    std::fs::copy(b.join("scene.npy"), b.join("scenes/scene.npy"))?;
    must(&[
        "eval", "--scenes", "scenes", "--mask", "mask.npy", "-o", "ev",
    ])?;
    Ok(())
}

// ------------------------------------------------------------------ mutation families

#[derive(Clone, Copy, PartialEq, Debug)]
enum Fmt {
    Npy,
    Npz,
    Mat5,
    Mat73,
    Json,
    Pth,
    Safetensors,
}

impl Fmt {
    fn ext(self) -> &'static str {
        match self {
            Fmt::Npy => "npy",
            Fmt::Npz => "npz",
            Fmt::Mat5 | Fmt::Mat73 => "mat",
            Fmt::Json => "json",
            Fmt::Pth => "pth",
            Fmt::Safetensors => "safetensors",
        }
    }
}

#[derive(Clone, Copy, PartialEq, Debug)]
enum Cmd {
    Info,
    ReconMeas,
    ReconMask,
    ReconCalib,
    Simulate,
    Calibrate,
    Eval,
    Weights,
}

fn mutate(rng: &mut Rng, fmt: Fmt, b: &[u8]) -> (Vec<u8>, String) {
    let op = rng.below(3);
    let hdr = match fmt {
        Fmt::Npy => 128,
        Fmt::Npz => 256,
        Fmt::Mat5 => 256,
        Fmt::Mat73 => 4096,
        Fmt::Json => b.len(),
        Fmt::Pth | Fmt::Safetensors => 1024,
    };
    match op {
        0 => files::truncate(rng, b),
        1 => files::flip(rng, b, hdr),
        _ => match fmt {
            Fmt::Npy => files::npy_header_edit(rng, b),
            Fmt::Npz => {
                if rng.below(5) < 3
                    && let Some(entries) = files::unzip(b)
                    && !entries.is_empty()
                {
                    let k = rng.below(entries.len());
                    let (e, what) = files::npy_header_edit(rng, &entries[k].1);
                    let mut es: Vec<(&str, &[u8])> = entries
                        .iter()
                        .map(|(n, d)| (n.as_str(), d.as_slice()))
                        .collect();
                    es[k].1 = &e;
                    let deflate = rng.below(2) == 0;
                    return (
                        files::npz(&es, deflate),
                        format!("npz entry {}: {what}", entries[k].0),
                    );
                }
                // a zip header field (sizes, offsets, counts)
                let sigs: Vec<usize> = (0..b.len().saturating_sub(4))
                    .filter(|&i| {
                        &b[i..i + 2] == b"PK" && (b[i + 2] == 1 || b[i + 2] == 3 || b[i + 2] == 5)
                    })
                    .collect();
                if sigs.is_empty() {
                    return files::flip(rng, b, hdr);
                }
                let at = *rng.pick(&sigs);
                files::overwrite(rng, b, at + 4, at + 46, false)
            }
            Fmt::Mat5 => {
                if let Some((pos, mut inner)) = files::mat5_first_compressed(b) {
                    let lim = inner.len().min(64);
                    if lim >= 8 {
                        let off = 4 * rng.below(lim / 4);
                        let x = *rng.pick(&files::BIG_U32);
                        inner[off..off + 4].copy_from_slice(&x.to_le_bytes());
                        return (
                            files::mat5_recompress(b, pos, &inner),
                            format!("zlib element: inner u32 at {off} := {x:#x}"),
                        );
                    }
                }
                files::overwrite(rng, b, 128, 200, false)
            }
            Fmt::Mat73 => {
                let spaces = files::hdf5_dataspaces(b);
                if !spaces.is_empty() && rng.below(2) == 0 {
                    let (off, rank) = *rng.pick(&spaces);
                    let mut v = b.to_vec();
                    let k = rng.below(rank);
                    let x = *rng.pick(&files::BIG_U64);
                    let at = off + 8 + 8 * k;
                    v[at..at + 8].copy_from_slice(&x.to_le_bytes());
                    return (v, format!("HDF5 dataspace dim {k} at {at} := {x:#x}"));
                }
                files::overwrite(rng, b, 512, 4096, true)
            }
            Fmt::Json => files::json_edit(rng, &String::from_utf8_lossy(b)),
            Fmt::Pth => {
                if let Some(mut entries) = files::unzip(b)
                    && let Some(k) = entries.iter().position(|(n, _)| n.ends_with("data.pkl"))
                {
                    let (p, what) = if rng.below(2) == 0 {
                        files::flip(rng, &entries[k].1, entries[k].1.len())
                    } else {
                        files::truncate(rng, &entries[k].1)
                    };
                    entries[k].1 = p;
                    let es: Vec<(&str, &[u8])> = entries
                        .iter()
                        .map(|(n, d)| (n.as_str(), d.as_slice()))
                        .collect();
                    return (files::npz(&es, false), format!("data.pkl {what}"));
                }
                files::overwrite(rng, b, 0, 128, false)
            }
            Fmt::Safetensors => {
                if b.len() >= 8 {
                    let n = u64::from_le_bytes(b[..8].try_into().unwrap()) as usize;
                    if rng.below(3) > 0 && n < b.len() - 8 {
                        let hdr_text = String::from_utf8_lossy(&b[8..8 + n]).into_owned();
                        let (h, what) = files::json_edit(rng, &hdr_text);
                        return (
                            files::safetensors(&String::from_utf8_lossy(&h), &b[8 + n..]),
                            format!("header {what}"),
                        );
                    }
                }
                files::overwrite(rng, b, 0, 8, true)
            }
        },
    }
}

struct Family {
    name: &'static str,
    cmd: Cmd,
    fmt: Fmt,
    share: f64,
    seeds: Vec<(String, Vec<u8>)>,
}

fn mutation_cases(ctx: &mut Ctx, seeds_dir: Option<&Path>, count: usize, seed: u64) {
    let rd = |n: &str| std::fs::read(ctx.base.join(n)).unwrap_or_default();
    let fixture = |b: &'static [u8], n: &str| (format!("fixture:{n}"), b.to_vec());
    let mut v5_seeds = vec![
        ("m.mat".to_string(), rd("m.mat")),
        ("mask.mat".to_string(), rd("mask.mat")),
        ("wmask.mat".to_string(), rd("wmask.mat")),
        fixture(
            include_bytes!("../../../cassi-io/tests/data/v5_plain_compressed.mat"),
            "v5_plain_compressed.mat",
        ),
        fixture(
            include_bytes!("../../../cassi-io/tests/data/v5_types_compressed.mat"),
            "v5_types_compressed.mat",
        ),
    ];
    let mut h5_seeds = vec![fixture(
        include_bytes!("../../../cassi-io/tests/data/v73.mat"),
        "v73.mat",
    )];
    let mut pth_seeds = vec![(
        "tiny.pth".to_string(),
        files::pth_zip(&files::pth_pickle(&[2, 3], &[3, 1], 6), &[0u8; 24]),
    )];
    let mut st_seeds: Vec<(String, Vec<u8>)> = vec![(
        "tiny.safetensors".to_string(),
        files::safetensors(
            r#"{"w":{"dtype":"F32","shape":[2,3],"data_offsets":[0,24]}}"#,
            &[0u8; 24],
        ),
    )];
    if let Some(sd) = seeds_dir {
        let mut files = Vec::new();
        fn walk(d: &Path, out: &mut Vec<PathBuf>) {
            if let Ok(rd) = std::fs::read_dir(d) {
                for e in rd.flatten() {
                    let p = e.path();
                    if p.is_dir() {
                        walk(&p, out);
                    } else {
                        out.push(p);
                    }
                }
            }
        }
        walk(sd, &mut files);
        files.sort();
        for p in files {
            let Ok(md) = std::fs::metadata(&p) else {
                continue;
            };
            let name = p.strip_prefix(sd).unwrap_or(&p).display().to_string();
            let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
            // keep copies per case cheap: seeds up to 4 MB
            if md.len() > 4 << 20 {
                continue;
            }
            let Ok(b) = std::fs::read(&p) else { continue };
            let is_h5 = b.len() > 520
                && (&b[..8] == b"\x89HDF\r\n\x1a\n" || &b[512..520] == b"\x89HDF\r\n\x1a\n");
            match ext {
                "mat" if is_h5 => h5_seeds.push((name, b)),
                "mat" if md.len() <= 1 << 20 => v5_seeds.push((name, b)),
                "pth" => pth_seeds.push((name, b)),
                "safetensors" => st_seeds.push((name, b)),
                "h5" | "hdf5" => h5_seeds.push((name, b)),
                _ => {}
            }
        }
    }
    let real_weights = pth_seeds.len() > 1 || st_seeds.len() > 1;
    if !real_weights {
        ctx.notes.push(
            "no real .pth/.safetensors seeds found: weights families mutate the hand-built tiny files only"
                .into(),
        );
    }
    if h5_seeds.len() == 1 {
        ctx.notes.push(
            "no HDF5 (MAT v7.3) seed under --seeds: the v7.3 family mutates the repository fixture cassi-io/tests/data/v73.mat only"
                .into(),
        );
    }
    let npy_seeds = vec![
        ("m.npy".to_string(), rd("m.npy")),
        ("mask.npy".to_string(), rd("mask.npy")),
        ("scene.npy".to_string(), rd("scene.npy")),
    ];
    let npz_seeds = vec![
        ("m.npz".to_string(), rd("m.npz")),
        fixture(
            include_bytes!("../../../cassi-io/tests/data/arrays_compressed.npz"),
            "arrays_compressed.npz",
        ),
        fixture(
            include_bytes!("../../../cassi-io/tests/data/arrays.npz"),
            "arrays.npz",
        ),
    ];
    let json_seeds = vec![
        ("c.json".to_string(), rd("c.json")),
        ("m.json (sidecar)".to_string(), rd("m.json")),
    ];
    let nets = ctx.nets();
    if !nets {
        ctx.notes.push("the cassi binary was built without `--features nets`: the .pth/.safetensors families still run (reconstruct --method mst-s --weights), but the weights loaders are not reached".into());
    }
    let fams = vec![
        Family {
            name: "info-npy",
            cmd: Cmd::Info,
            fmt: Fmt::Npy,
            share: 0.14,
            seeds: npy_seeds.clone(),
        },
        Family {
            name: "info-npz",
            cmd: Cmd::Info,
            fmt: Fmt::Npz,
            share: 0.12,
            seeds: npz_seeds.clone(),
        },
        Family {
            name: "info-mat5",
            cmd: Cmd::Info,
            fmt: Fmt::Mat5,
            share: 0.16,
            seeds: v5_seeds.clone(),
        },
        Family {
            name: "info-mat73",
            cmd: Cmd::Info,
            fmt: Fmt::Mat73,
            share: 0.14,
            seeds: h5_seeds.clone(),
        },
        Family {
            name: "reconstruct-meas-npy",
            cmd: Cmd::ReconMeas,
            fmt: Fmt::Npy,
            share: 0.07,
            seeds: vec![npy_seeds[0].clone()],
        },
        Family {
            name: "reconstruct-meas-npz",
            cmd: Cmd::ReconMeas,
            fmt: Fmt::Npz,
            share: 0.03,
            seeds: vec![npz_seeds[0].clone()],
        },
        Family {
            name: "reconstruct-meas-mat5",
            cmd: Cmd::ReconMeas,
            fmt: Fmt::Mat5,
            share: 0.03,
            seeds: vec![v5_seeds[0].clone()],
        },
        Family {
            name: "reconstruct-meas-mat73",
            cmd: Cmd::ReconMeas,
            fmt: Fmt::Mat73,
            share: 0.02,
            seeds: h5_seeds.clone(),
        },
        Family {
            name: "reconstruct-mask-npy",
            cmd: Cmd::ReconMask,
            fmt: Fmt::Npy,
            share: 0.03,
            seeds: vec![npy_seeds[1].clone()],
        },
        Family {
            name: "reconstruct-mask-mat5",
            cmd: Cmd::ReconMask,
            fmt: Fmt::Mat5,
            share: 0.02,
            seeds: vec![v5_seeds[1].clone(), v5_seeds[2].clone()],
        },
        Family {
            name: "reconstruct-calibration-json",
            cmd: Cmd::ReconCalib,
            fmt: Fmt::Json,
            share: 0.08,
            seeds: json_seeds,
        },
        Family {
            name: "simulate-scene-npy",
            cmd: Cmd::Simulate,
            fmt: Fmt::Npy,
            share: 0.05,
            seeds: vec![npy_seeds[2].clone()],
        },
        Family {
            name: "calibrate-meas-npy",
            cmd: Cmd::Calibrate,
            fmt: Fmt::Npy,
            share: 0.02,
            seeds: vec![npy_seeds[0].clone()],
        },
        Family {
            name: "eval-scene-npy",
            cmd: Cmd::Eval,
            fmt: Fmt::Npy,
            share: 0.007,
            seeds: vec![npy_seeds[2].clone()],
        },
        Family {
            name: "weights-pth",
            cmd: Cmd::Weights,
            fmt: Fmt::Pth,
            share: if nets { 0.04 } else { 0.015 },
            seeds: pth_seeds,
        },
        Family {
            name: "weights-safetensors",
            cmd: Cmd::Weights,
            fmt: Fmt::Safetensors,
            share: if nets { 0.03 } else { 0.01 },
            seeds: st_seeds,
        },
    ];
    let total_share: f64 = fams.iter().map(|f| f.share).sum();
    let mut plan: Vec<usize> = fams
        .iter()
        .map(|f| ((count as f64) * f.share / total_share).round() as usize)
        .collect();
    let planned: usize = plan.iter().sum();
    if planned < count {
        plan[0] += count - planned;
    }
    let mut rng = Rng::new(seed);
    for (fam, n) in fams.iter().zip(plan) {
        let t0 = Instant::now();
        for k in 0..n {
            let (seed_name, seed_bytes) = rng.pick(&fam.seeds).clone();
            let (bytes, what) = mutate(&mut rng, fam.fmt, &seed_bytes);
            let dir = ctx.case_dir(fam.name);
            let file = format!("x.{}", fam.fmt.ext());
            let label = format!("{} #{k}", fam.name);
            let mut case = match fam.cmd {
                Cmd::Info => {
                    write(&dir.join(&file), &bytes);
                    let json_mode = rng.below(4) == 0;
                    let mut args = vec!["info", file.as_str()];
                    if json_mode {
                        args.push("--json");
                    }
                    Case::new("mutation/info", fam.name, &label, &dir, &args)
                        .inputs(&[file.as_str()])
                }
                Cmd::ReconMeas => {
                    write(&dir.join(&file), &bytes);
                    ctx.stage(&dir, &["mask.npy", "r.npy", "r.png", "r.json"]);
                    Case::new(
                        "mutation/reconstruct",
                        fam.name,
                        &label,
                        &dir,
                        &["reconstruct", &file, "--mask", "mask.npy", "-o", "r.npy"],
                    )
                    .inputs(&[file.as_str(), "mask.npy"])
                }
                Cmd::ReconMask => {
                    write(&dir.join(&file), &bytes);
                    ctx.stage(&dir, &["m.npy", "r.npy", "r.png", "r.json"]);
                    Case::new(
                        "mutation/reconstruct",
                        fam.name,
                        &label,
                        &dir,
                        &["reconstruct", "m.npy", "--mask", &file, "-o", "r.npy"],
                    )
                    .inputs(&[file.as_str(), "m.npy"])
                }
                Cmd::ReconCalib => {
                    let file = "cal.json".to_string();
                    write(&dir.join(&file), &bytes);
                    ctx.stage(&dir, &["m.npy", "mask.npy", "r.npy", "r.png", "r.json"]);
                    Case::new(
                        "mutation/reconstruct",
                        fam.name,
                        &label,
                        &dir,
                        &[
                            "reconstruct",
                            "m.npy",
                            "--mask",
                            "mask.npy",
                            "--calibration",
                            &file,
                            "-o",
                            "r.npy",
                        ],
                    )
                    .inputs(&[file.as_str(), "m.npy", "mask.npy"])
                }
                Cmd::Simulate => {
                    write(&dir.join(&file), &bytes);
                    ctx.stage(&dir, &["mask.npy", "s.npy", "s.json"]);
                    Case::new(
                        "mutation/simulate",
                        fam.name,
                        &label,
                        &dir,
                        &[
                            "simulate", "--scene", &file, "--mask", "mask.npy", "-o", "s.npy",
                        ],
                    )
                    .inputs(&[file.as_str(), "mask.npy"])
                }
                Cmd::Calibrate => {
                    write(&dir.join(&file), &bytes);
                    ctx.stage(&dir, &["mask.npy", "c.json"]);
                    Case::new(
                        "mutation/calibrate",
                        fam.name,
                        &label,
                        &dir,
                        &["calibrate", &file, "--mask", "mask.npy", "-o", "c.json"],
                    )
                    .inputs(&[file.as_str(), "mask.npy"])
                    .timeout(60)
                }
                Cmd::Eval => {
                    let file = format!("scenes/{file}");
                    write(&dir.join(&file), &bytes);
                    ctx.stage(&dir, &["mask.npy", "ev"]);
                    Case::new(
                        "mutation/eval",
                        fam.name,
                        &label,
                        &dir,
                        &[
                            "eval", "--scenes", "scenes", "--mask", "mask.npy", "-o", "ev",
                        ],
                    )
                    .inputs(&[file.as_str(), "mask.npy"])
                    .timeout(90)
                }
                Cmd::Weights => {
                    write(&dir.join(&file), &bytes);
                    ctx.stage(
                        &dir,
                        &["m256.npy", "mask256.npy", "r.npy", "r.png", "r.json"],
                    );
                    Case::new(
                        "mutation/weights",
                        fam.name,
                        &label,
                        &dir,
                        &[
                            "reconstruct",
                            "m256.npy",
                            "--mask",
                            "mask256.npy",
                            "--method",
                            "mst-s",
                            "--weights",
                            &file,
                            "-o",
                            "r.npy",
                        ],
                    )
                    .inputs(&[file.as_str(), "m256.npy", "mask256.npy"])
                    .timeout(60)
                }
            };
            case = case.note(format!("{seed_name}: {what}"));
            ctx.run_case(case);
        }
        eprintln!(
            "  {:<30} {:>5} cases  {:>6.1} s",
            fam.name,
            ctx.totals_family(fam.name),
            t0.elapsed().as_secs_f64()
        );
    }
}

impl Ctx {
    fn totals_family(&self, fam: &str) -> usize {
        self.records.iter().filter(|r| r["family"] == fam).count()
    }

    fn nets(&self) -> bool {
        let d = self.scratch.join("netsprobe");
        std::fs::create_dir_all(&d).unwrap();
        let o = self.exec(&Spec {
            args: s(&[
                "reconstruct",
                "none.npy",
                "--mask",
                "none.npy",
                "--method",
                "mst-s",
                "--weights",
                "none.pth",
                "-o",
                "none-out.npy",
            ]),
            cwd: d,
            env: vec![],
            timeout: Duration::from_secs(20),
            signal: None,
        });
        !o.stderr_text().contains("built without")
    }
}

// ------------------------------------------------------------------ named reproducers

fn reproducers(ctx: &mut Ctx) {
    let all = [
        "m.npy",
        "m.npz",
        "m.mat",
        "m.json",
        "mask.npy",
        "mask.mat",
        "scene.npy",
        "c.json",
        "truth16.npy",
    ];
    let prev_r = ["r.npy", "r.png", "r.json"];

    // ---- 1: output equal to an input
    let c1 = "repro/1-output-is-input";
    type Setup = fn(&Path);
    let none: Setup = |_| {};
    let ones: Vec<(&str, Setup, Vec<&str>, Vec<&str>, Vec<&str>)> = vec![
        (
            "reconstruct -o = measurement",
            none,
            vec!["reconstruct", "m.npy", "--mask", "mask.npy", "-o", "m.npy"],
            vec!["m.npy", "mask.npy", "m.json"],
            vec!["m.npy"],
        ),
        (
            "reconstruct -o = mask",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "mask.npy",
            ],
            vec!["m.npy", "mask.npy"],
            vec!["mask.npy"],
        ),
        (
            "reconstruct -o ./measurement (other spelling)",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "./m.npy",
            ],
            vec!["m.npy", "mask.npy"],
            vec!["m.npy"],
        ),
        (
            "reconstruct -o = --truth",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--truth",
                "scene.npy",
                "-o",
                "scene.npy",
            ],
            vec!["m.npy", "mask.npy", "scene.npy"],
            vec!["scene.npy"],
        ),
        (
            "simulate --scene s.npy -o s.npy",
            none,
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "scene.npy",
            ],
            vec!["scene.npy", "mask.npy"],
            vec!["scene.npy"],
        ),
        (
            "simulate -o = mask",
            none,
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "mask.npy",
            ],
            vec!["scene.npy", "mask.npy"],
            vec!["mask.npy"],
        ),
        (
            "calibrate --write-mask = input mask",
            none,
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "c2.json",
                "--write-mask",
                "mask.npy",
            ],
            vec!["m.npy", "mask.npy"],
            vec!["mask.npy"],
        ),
        (
            "calibrate --write-mask = measurement",
            none,
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "c2.json",
                "--write-mask",
                "m.npy",
            ],
            vec!["m.npy", "mask.npy"],
            vec!["m.npy"],
        ),
        (
            "calibrate -o = measurement",
            none,
            vec!["calibrate", "m.npy", "--mask", "mask.npy", "-o", "m.npy"],
            vec!["m.npy", "mask.npy"],
            vec!["m.npy"],
        ),
        (
            "calibrate -o m.json over the simulation sidecar",
            none,
            vec!["calibrate", "m.npy", "--mask", "mask.npy", "-o", "m.json"],
            vec!["m.npy", "mask.npy", "m.json"],
            vec!["m.json"],
        ),
        (
            "reconstruct -o c.npy: derived c.json = --calibration",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--calibration",
                "c.json",
                "-o",
                "c.npy",
            ],
            vec!["m.npy", "mask.npy", "c.json"],
            vec!["c.json"],
        ),
        (
            "reconstruct -o m.npz: derived m.json = --calibration sidecar",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--calibration",
                "m.json",
                "-o",
                "m.npz",
            ],
            vec!["m.npy", "mask.npy", "m.json"],
            vec!["m.json"],
        ),
        (
            "reconstruct -o hard link of the measurement",
            |d| {
                std::fs::hard_link(d.join("m.npy"), d.join("hl.npy")).unwrap();
            },
            vec!["reconstruct", "m.npy", "--mask", "mask.npy", "-o", "hl.npy"],
            vec!["m.npy", "mask.npy"],
            vec!["m.npy", "hl.npy"],
        ),
        (
            "reconstruct -o symlink to the measurement",
            |d| {
                std::os::unix::fs::symlink("m.npy", d.join("sl.npy")).unwrap();
            },
            vec!["reconstruct", "m.npy", "--mask", "mask.npy", "-o", "sl.npy"],
            vec!["m.npy", "mask.npy"],
            vec!["m.npy", "sl.npy"],
        ),
        (
            "simulate -o symlink to the mask",
            |d| {
                std::os::unix::fs::symlink("mask.npy", d.join("ml.npy")).unwrap();
            },
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "ml.npy",
            ],
            vec!["scene.npy", "mask.npy"],
            vec!["mask.npy", "ml.npy"],
        ),
        (
            "simulate -o hard link of the scene",
            |d| {
                std::fs::hard_link(d.join("scene.npy"), d.join("hs.npy")).unwrap();
            },
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "hs.npy",
            ],
            vec!["scene.npy", "mask.npy"],
            vec!["scene.npy", "hs.npy"],
        ),
        (
            "calibrate --write-mask hard link of the mask",
            |d| {
                std::fs::hard_link(d.join("mask.npy"), d.join("hm.npy")).unwrap();
            },
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "c2.json",
                "--write-mask",
                "hm.npy",
            ],
            vec!["m.npy", "mask.npy"],
            vec!["mask.npy", "hm.npy"],
        ),
        (
            "reconstruct -o through a symlinked folder",
            |d| {
                std::fs::create_dir_all(d.join("sub")).unwrap();
                std::os::unix::fs::symlink("..", d.join("sub/up")).unwrap();
            },
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "sub/up/m.npy",
            ],
            vec!["m.npy", "mask.npy"],
            vec!["m.npy"],
        ),
        (
            "reconstruct -o m.npy on a .mat measurement's derived json (sidecar) ",
            none,
            vec![
                "reconstruct",
                "m.mat",
                "--mask",
                "mask.npy",
                "--calibration",
                "m.json",
                "-o",
                "m.npy",
            ],
            vec!["m.mat", "mask.npy", "m.json"],
            vec!["m.json"],
        ),
    ];
    for (label, setup, args, inputs, names) in ones {
        let d = ctx.case_dir("repro1");
        ctx.stage(&d, &all);
        setup(&d);
        let c = Case::new(c1, "output-is-input", label, &d, &args)
            .inputs(&inputs)
            .expect(Expect::Fail, &names)
            .timeout(60);
        ctx.run_case(c);
    }

    // ---- 2: a failed run keeps the previous result
    let c2 = "repro/2-failed-run-keeps-previous";
    let twos: Vec<(&str, Setup, Vec<&str>)> = vec![
        (
            "reconstruct --bands 1 over a previous result",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--bands",
                "1",
                "-o",
                "r.npy",
            ],
        ),
        (
            "reconstruct with a mismatched --truth over a previous result",
            none,
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--truth",
                "truth16.npy",
                "-o",
                "r.npy",
            ],
        ),
        (
            "reconstruct whose preview path is a folder",
            |d| {
                std::fs::remove_file(d.join("r.png")).unwrap();
                std::fs::create_dir(d.join("r.png")).unwrap();
            },
            vec!["reconstruct", "m.npy", "--mask", "mask.npy", "-o", "r.npy"],
        ),
        (
            "reconstruct whose report path is a folder",
            |d| {
                std::fs::remove_file(d.join("r.json")).unwrap();
                std::fs::create_dir(d.join("r.json")).unwrap();
            },
            vec!["reconstruct", "m.npy", "--mask", "mask.npy", "-o", "r.npy"],
        ),
        (
            "calibrate with --write-mask into a missing folder",
            none,
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "mask.npy",
                "-o",
                "c.json",
                "--write-mask",
                "nodir/wm.npy",
            ],
        ),
        (
            "simulate whose sidecar path is a folder",
            |d| {
                std::fs::remove_file(d.join("s.json")).unwrap();
                std::fs::create_dir(d.join("s.json")).unwrap();
            },
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "s.npy",
            ],
        ),
        (
            "simulate --preview whose preview path is a folder",
            |d| {
                std::fs::create_dir(d.join("s.png")).unwrap();
            },
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "--preview",
                "-o",
                "s.npy",
            ],
        ),
        (
            "eval over a previous study with a broken second scene",
            |d| {
                std::fs::write(
                    d.join("scenes/zz_broken.npy"),
                    b"\x93NUMPY\x01\x00\x10\x00{'descr': '<f4',",
                )
                .unwrap();
            },
            vec![
                "eval", "--scenes", "scenes", "--mask", "mask.npy", "-o", "ev",
            ],
        ),
    ];
    for (label, setup, args) in twos {
        let d = ctx.case_dir("repro2");
        ctx.stage(&d, &all);
        ctx.stage(&d, &prev_r);
        ctx.stage(&d, &["s.npy", "s.json", "scenes", "ev"]);
        setup(&d);
        // inputs: what the command reads, never its own -o target
        let out = args.iter().position(|a| *a == "-o").map(|i| args[i + 1]);
        let ins: Vec<&str> = ["m.npy", "mask.npy", "scene.npy", "c.json"]
            .into_iter()
            .filter(|i| Some(*i) != out)
            .collect();
        let c = Case::new(c2, "failed-run", label, &d, &args)
            .inputs(&ins)
            .timeout(90);
        ctx.run_case(c);
    }

    // ---- 3: tiny files, big memory
    let c3 = "repro/3-memory";
    let h5 = include_bytes!("../../../cassi-io/tests/data/v73.mat");
    let bombs: Vec<(&str, Vec<u8>)> = vec![
        (
            "h5bomb.mat",
            files::hdf5_bomb(h5, &[16384, 8192], 8).unwrap_or_default(),
        ),
        ("tiny.pth", files::pth_strided_bomb()),
        ("zeros.npz", files::npz_zero_bomb(&[16384, 16384])),
        ("zbomb.mat", files::mat5_zlib_bomb(8192, 4096)),
        (
            "bigst.safetensors",
            files::safetensors(
                r#"{"w":{"dtype":"F32","shape":[32768,32768],"data_offsets":[0,4294967296]}}"#,
                &[0u8; 64],
            ),
        ),
        (
            "hugehdr.npy",
            files::npy_raw("<f4", "(16384, 16384)", false, &[0u8; 64]),
        ),
    ];
    let bd = ctx.work.join("bombs");
    std::fs::create_dir_all(&bd).unwrap();
    for (n, b) in &bombs {
        write(&bd.join(n), b);
    }
    let sizes: Vec<String> = bombs
        .iter()
        .map(|(n, b)| format!("{n} {} bytes", b.len()))
        .collect();
    ctx.notes
        .push(format!("memory bombs: {}", sizes.join(", ")));
    let threes: Vec<(&str, &str, Vec<&str>)> = vec![
        (
            "info on a 6 KB HDF5 .mat with a never-written 1 GiB dataset",
            "h5bomb.mat",
            vec!["info", "h5bomb.mat"],
        ),
        (
            "reconstruct a never-written 1 GiB HDF5 measurement",
            "h5bomb.mat",
            vec![
                "reconstruct",
                "h5bomb.mat",
                "--mask",
                "mask.npy",
                "-o",
                "r.npy",
            ],
        ),
        (
            "info on a .pth with a strided 2^30-element view",
            "tiny.pth",
            vec!["info", "tiny.pth"],
        ),
        (
            "reconstruct --method mst-s --weights: .pth strided 2^30 view",
            "tiny.pth",
            vec![
                "reconstruct",
                "m256.npy",
                "--mask",
                "mask256.npy",
                "--method",
                "mst-s",
                "--weights",
                "tiny.pth",
                "-o",
                "r.npy",
            ],
        ),
        (
            "info on a 1 MB .npz of zeros (1 GiB inflated)",
            "zeros.npz",
            vec!["info", "zeros.npz"],
        ),
        (
            "reconstruct a 1 MB .npz of zeros",
            "zeros.npz",
            vec![
                "reconstruct",
                "zeros.npz",
                "--mask",
                "mask.npy",
                "-o",
                "r.npy",
            ],
        ),
        (
            "simulate --scene: 1 MB .npz of zeros",
            "zeros.npz",
            vec![
                "simulate",
                "--scene",
                "zeros.npz",
                "--mask",
                "mask.npy",
                "-o",
                "s.npy",
            ],
        ),
        (
            "info on a 261 KB zlib MAT (256 MiB inflated)",
            "zbomb.mat",
            vec!["info", "zbomb.mat"],
        ),
        (
            "reconstruct a 261 KB zlib MAT",
            "zbomb.mat",
            vec![
                "reconstruct",
                "zbomb.mat",
                "--mask",
                "mask.npy",
                "-o",
                "r.npy",
            ],
        ),
        (
            "calibrate a 261 KB zlib MAT",
            "zbomb.mat",
            vec![
                "calibrate",
                "zbomb.mat",
                "--mask",
                "mask.npy",
                "-o",
                "c.json",
            ],
        ),
        (
            "reconstruct --weights: safetensors claiming 4 GiB",
            "bigst.safetensors",
            vec![
                "reconstruct",
                "m256.npy",
                "--mask",
                "mask256.npy",
                "--method",
                "mst-s",
                "--weights",
                "bigst.safetensors",
                "-o",
                "r.npy",
            ],
        ),
        (
            "info on an .npy whose header claims 1 GiB",
            "hugehdr.npy",
            vec!["info", "hugehdr.npy"],
        ),
        (
            "reconstruct an .npy whose header claims 1 GiB",
            "hugehdr.npy",
            vec![
                "reconstruct",
                "hugehdr.npy",
                "--mask",
                "mask.npy",
                "-o",
                "r.npy",
            ],
        ),
    ];
    for (label, file, args) in threes {
        let d = ctx.case_dir("repro3");
        ctx.stage(
            &d,
            &[
                "m.npy",
                "mask.npy",
                "m256.npy",
                "mask256.npy",
                "c.json",
                "s.npy",
                "s.json",
            ],
        );
        ctx.stage(&d, &prev_r);
        let _ = std::fs::hard_link(bd.join(file), d.join(file))
            .or_else(|_| std::fs::copy(bd.join(file), d.join(file)).map(|_| ()));
        let c = Case::new(c3, "memory", label, &d, &args)
            .inputs(&[file, "m.npy", "mask.npy"])
            .timeout(60);
        ctx.run_case(c);
    }

    // ---- 4: absurd parameters
    let c4 = "repro/4-absurd-parameters";
    let fours: Vec<(&str, Vec<&str>, &str)> = vec![
        (
            "reconstruct --stride 0.001",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--stride",
                "0.001",
                "-o",
                "r.npy",
            ],
            "--stride",
        ),
        (
            "reconstruct --stride 0.01 (5,501 bands)",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--stride",
                "0.01",
                "-o",
                "r.npy",
            ],
            "--stride",
        ),
        (
            "calibrate --stride 0.01",
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "mask.npy",
                "--stride",
                "0.01",
                "-o",
                "c.json",
            ],
            "--stride",
        ),
        (
            "reconstruct --stride nan",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--stride",
                "nan",
                "-o",
                "r.npy",
            ],
            "--stride",
        ),
        (
            "reconstruct --stride -2",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--stride=-2",
                "-o",
                "r.npy",
            ],
            "--stride",
        ),
        (
            "simulate --stride 1e9",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "4",
                "--random-mask",
                "--stride",
                "1e9",
                "-o",
                "x.npy",
            ],
            "--stride",
        ),
        (
            "simulate --size 20000",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "20000",
                "--random-mask",
                "-o",
                "x.npy",
            ],
            "--size",
        ),
        (
            "simulate --size 0",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "0",
                "--random-mask",
                "-o",
                "x.npy",
            ],
            "--size",
        ),
        (
            "simulate --bands 100000",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "100000",
                "--random-mask",
                "-o",
                "x.npy",
            ],
            "--bands",
        ),
        (
            "reconstruct --bands 100000",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--bands",
                "100000",
                "-o",
                "r.npy",
            ],
            "--bands",
        ),
        (
            "calibrate --bands 100000",
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "mask.npy",
                "--bands",
                "100000",
                "-o",
                "c.json",
            ],
            "--bands",
        ),
        (
            "eval --size 20000",
            vec!["eval", "--synthetic", "--size", "20000", "-o", "ev2"],
            "--size",
        ),
        (
            "reconstruct --iterations 4000000000",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--iterations",
                "4000000000",
                "-o",
                "r.npy",
            ],
            "--iterations",
        ),
        (
            "simulate --open-fraction 2",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "4",
                "--random-mask",
                "--open-fraction",
                "2",
                "-o",
                "x.npy",
            ],
            "--open-fraction",
        ),
        (
            "simulate --photon-peak -5",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "4",
                "--random-mask",
                "--photon-peak=-5",
                "-o",
                "x.npy",
            ],
            "--photon-peak",
        ),
        (
            "simulate --read-noise inf",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "4",
                "--random-mask",
                "--read-noise",
                "inf",
                "-o",
                "x.npy",
            ],
            "--read-noise",
        ),
        (
            "simulate --theta nan",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "32",
                "--bands",
                "4",
                "--random-mask",
                "--theta",
                "nan",
                "-o",
                "x.npy",
            ],
            "--theta",
        ),
        (
            "reconstruct --weight -1",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--weight=-1",
                "-o",
                "r.npy",
            ],
            "--weight",
        ),
    ];
    for (label, args, flag) in fours {
        let d = ctx.case_dir("repro4");
        ctx.stage(&d, &["m.npy", "mask.npy", "c.json"]);
        ctx.stage(&d, &prev_r);
        let c = Case::new(c4, "absurd-parameter", label, &d, &args)
            .inputs(&["m.npy", "mask.npy"])
            .expect(Expect::FailUpFront, &[flag])
            .timeout(15);
        ctx.run_case(c);
    }

    // ---- 5: meaningless inputs
    let c5 = "repro/5-meaningless";
    let md = ctx.work.join("meaningless");
    std::fs::create_dir_all(&md).unwrap();
    write(
        &md.join("zero_meas.npy"),
        &files::npy_f32(&[32, 38], &[0.0; 32 * 38]),
    );
    write(
        &md.join("zero_mask.npy"),
        &files::npy_f32(&[32, 32], &[0.0; 32 * 32]),
    );
    write(
        &md.join("neg_meas.npy"),
        &files::npy_f32(&[32, 38], &vec![-0.5; 32 * 38]),
    );
    let mut rng = Rng::new(311);
    let m300: Vec<f32> = (0..256 * 300).map(|_| rng.below(2) as f32).collect();
    write(&md.join("mask300.npy"), &files::npy_f32(&[256, 300], &m300));
    let y311: Vec<f32> = (0..256 * 311).map(|_| rng.unit() as f32).collect();
    write(&md.join("meas311.npy"), &files::npy_f32(&[256, 311], &y311));
    let hot: Vec<f32> = (0..4 * 32 * 32).map(|_| 1e30).collect();
    write(
        &md.join("hot_scene.npy"),
        &files::npy_f32(&[4, 32, 32], &hot),
    );
    let cal: Value =
        serde_json::from_slice(&std::fs::read(ctx.base.join("c.json")).unwrap()).unwrap();
    let mut cal_dx = cal.clone();
    cal_dx["parameters"]["dx"] = json!(1e308);
    let mut cal_a1 = cal.clone();
    cal_a1["parameters"]["a1"] = json!(1e-300);
    let mut cal_pos = cal.clone();
    cal_pos["parameters"] = json!([1, 2, 3, 4, 5]);
    let mut side =
        serde_json::from_slice::<Value>(&std::fs::read(ctx.base.join("m.json")).unwrap()).unwrap();
    side["simulation"]["mismatch"]["dx"] = json!(1e308);
    write(&md.join("cal_dx1e308.json"), cal_dx.to_string().as_bytes());
    write(
        &md.join("cal_a1_1e-300.json"),
        cal_a1.to_string().as_bytes(),
    );
    write(
        &md.join("cal_positional.json"),
        cal_pos.to_string().as_bytes(),
    );
    write(&md.join("side_dx1e308.json"), side.to_string().as_bytes());
    let fives: Vec<(&str, Vec<&str>, Vec<&str>)> = vec![
        (
            "calibrate an all-zero measurement",
            vec![
                "calibrate",
                "zero_meas.npy",
                "--mask",
                "mask.npy",
                "-o",
                "c.json",
            ],
            vec!["zero_meas.npy"],
        ),
        (
            "reconstruct an all-zero measurement",
            vec![
                "reconstruct",
                "zero_meas.npy",
                "--mask",
                "mask.npy",
                "-o",
                "r.npy",
            ],
            vec!["zero_meas.npy"],
        ),
        (
            "reconstruct with an all-zero mask",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "zero_mask.npy",
                "-o",
                "r.npy",
            ],
            vec!["zero_mask.npy"],
        ),
        (
            "calibrate with an all-zero mask",
            vec![
                "calibrate",
                "m.npy",
                "--mask",
                "zero_mask.npy",
                "-o",
                "c.json",
            ],
            vec!["zero_mask.npy"],
        ),
        (
            "simulate with an all-zero mask",
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "zero_mask.npy",
                "-o",
                "s.npy",
            ],
            vec!["zero_mask.npy"],
        ),
        (
            "calibrate all-negative measurements",
            vec![
                "calibrate",
                "neg_meas.npy",
                "--mask",
                "mask.npy",
                "-o",
                "c.json",
            ],
            vec!["neg_meas.npy"],
        ),
        (
            "reconstruct all-negative measurements",
            vec![
                "reconstruct",
                "neg_meas.npy",
                "--mask",
                "mask.npy",
                "-o",
                "r.npy",
            ],
            vec!["neg_meas.npy"],
        ),
        (
            "simulate --dx 1e9",
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "--dx",
                "1e9",
                "-o",
                "s.npy",
            ],
            vec!["--dx"],
        ),
        (
            "eval --dx 1e9",
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--dx",
                "1e9",
                "-o",
                "ev2",
            ],
            vec!["--dx"],
        ),
        (
            "reconstruct --calibration with dx 1e308",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--calibration",
                "cal_dx1e308.json",
                "-o",
                "r.npy",
            ],
            vec!["cal_dx1e308.json"],
        ),
        (
            "reconstruct --calibration with a1 1e-300",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--calibration",
                "cal_a1_1e-300.json",
                "-o",
                "r.npy",
            ],
            vec!["cal_a1_1e-300.json"],
        ),
        (
            "reconstruct --calibration with positional parameters [1,2,3,4,5]",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--calibration",
                "cal_positional.json",
                "-o",
                "r.npy",
            ],
            vec!["cal_positional.json"],
        ),
        (
            "reconstruct --calibration sidecar with dx 1e308",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--calibration",
                "side_dx1e308.json",
                "-o",
                "r.npy",
            ],
            vec!["side_dx1e308.json"],
        ),
        (
            "reconstruct a 256x311 measurement with a 256x300 mask",
            vec![
                "reconstruct",
                "meas311.npy",
                "--mask",
                "mask300.npy",
                "-o",
                "r.npy",
            ],
            vec![],
        ),
        (
            "calibrate a 256x311 measurement with a 256x300 mask",
            vec![
                "calibrate",
                "meas311.npy",
                "--mask",
                "mask300.npy",
                "-o",
                "c.json",
            ],
            vec![],
        ),
        (
            "simulate a scene of 1e30 values",
            vec![
                "simulate",
                "--scene",
                "hot_scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "s.npy",
            ],
            vec!["hot_scene.npy"],
        ),
    ];
    for (label, args, names) in fives {
        let d = ctx.case_dir("repro5");
        ctx.stage(
            &d,
            &[
                "m.npy",
                "mask.npy",
                "scene.npy",
                "c.json",
                "s.npy",
                "s.json",
            ],
        );
        ctx.stage(&d, &prev_r);
        copy_rec(&md, &d);
        let mut c = Case::new(c5, "meaningless", label, &d, &args)
            .inputs(&["m.npy", "mask.npy", "scene.npy"])
            .expect(Expect::FailOrWarn, &names)
            .timeout(90);
        c.must_name = names.iter().map(|s| s.to_string()).collect();
        ctx.run_case(c);
    }

    // ---- 7: escapes, late failures, nan flags, permissions
    let c7 = "repro/7-misc";
    let esc_npz = files::npz(
        &[(
            "\x1b]0;pwned\x07\x1b[31mred\x1b[0m.npy",
            &std::fs::read(ctx.base.join("mask.npy")).unwrap(),
        )],
        false,
    );
    let esc_mat = files::mat5_double(b"a\x1b[2Jb\x1b[31m", 2, 2, &[0.0, 1.0, 1.0, 0.0]);
    let esc_npz_bad = files::npz(&[("\x1b[2Jevil.npy", b"\x93NUMPY garbage")], false);
    let sevens: Vec<(&str, Vec<(&str, Vec<u8>)>, Vec<&str>, Expect, Vec<&str>)> = vec![
        (
            "info: npz entry name with terminal escapes",
            vec![("esc.npz", esc_npz.clone())],
            vec!["info", "esc.npz"],
            Expect::Any,
            vec![],
        ),
        (
            "info --json: npz entry name with terminal escapes",
            vec![("esc.npz", esc_npz.clone())],
            vec!["info", "esc.npz", "--json"],
            Expect::Any,
            vec![],
        ),
        (
            "info: MAT variable name with terminal escapes",
            vec![("esc.mat", esc_mat.clone())],
            vec!["info", "esc.mat"],
            Expect::Any,
            vec![],
        ),
        (
            "info: broken npz entry with terminal escapes",
            vec![("escbad.npz", esc_npz_bad)],
            vec!["info", "escbad.npz"],
            Expect::Any,
            vec![],
        ),
        (
            "reconstruct --mask-var absent in an escape-named npz",
            vec![("esc.npz", esc_npz)],
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "esc.npz",
                "--mask-var",
                "nothere",
                "-o",
                "r.npy",
            ],
            Expect::Any,
            vec![],
        ),
        (
            "reconstruct --meas-var absent in an escape-named MAT",
            vec![("esc.mat", esc_mat)],
            vec![
                "reconstruct",
                "esc.mat",
                "--mask",
                "mask.npy",
                "--meas-var",
                "zz",
                "-o",
                "r.npy",
            ],
            Expect::Any,
            vec![],
        ),
        (
            "info on a path with terminal escapes",
            vec![("\x1b[2Jx.npy", b"not an npy".to_vec())],
            vec!["info", "\x1b[2Jx.npy"],
            Expect::Any,
            vec![],
        ),
        (
            "eval --count 0",
            vec![],
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--count",
                "0",
                "-o",
                "ev2",
            ],
            Expect::FailUpFront,
            vec!["--count"],
        ),
        (
            "eval --size 8",
            vec![],
            vec!["eval", "--synthetic", "--size", "8", "-o", "ev2"],
            Expect::FailUpFront,
            vec!["--size"],
        ),
        (
            "eval --sensitivity=nan",
            vec![],
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--sensitivity=nan",
                "-o",
                "ev2",
            ],
            Expect::FailUpFront,
            vec!["--sensitivity"],
        ),
        (
            "eval --sensitivity=-1",
            vec![],
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--sensitivity=-1",
                "-o",
                "ev2",
            ],
            Expect::FailUpFront,
            vec!["--sensitivity"],
        ),
        (
            "eval --limit 0",
            vec![],
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--limit",
                "0",
                "-o",
                "ev2",
            ],
            Expect::FailUpFront,
            vec!["--limit"],
        ),
    ];
    for (label, files, args, expect, names) in sevens {
        let d = ctx.case_dir("repro7");
        ctx.stage(&d, &["m.npy", "mask.npy"]);
        ctx.stage(&d, &prev_r);
        let mut ins = vec!["m.npy", "mask.npy"];
        for (n, b) in &files {
            write(&d.join(n), b);
            ins.push(n);
        }
        let c = Case::new(c7, "misc", label, &d, &args)
            .inputs(&ins)
            .expect(expect, &names)
            .timeout(60);
        ctx.run_case(c);
    }
    // permissions of replaced outputs
    for (label, args, files, mode) in [
        (
            "reconstruct keeps 0640 on replaced outputs",
            vec!["reconstruct", "m.npy", "--mask", "mask.npy", "-o", "r.npy"],
            vec!["r.npy", "r.png", "r.json"],
            0o640,
        ),
        (
            "simulate keeps 0600 on replaced outputs",
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "s.npy",
            ],
            vec!["s.npy", "s.json"],
            0o600,
        ),
        (
            "calibrate keeps 0664 on a replaced calibration",
            vec!["calibrate", "m.npy", "--mask", "mask.npy", "-o", "c.json"],
            vec!["c.json"],
            0o664,
        ),
    ] {
        let d = ctx.case_dir("repro7perm");
        ctx.stage(
            &d,
            &[
                "m.npy",
                "mask.npy",
                "scene.npy",
                "c.json",
                "s.npy",
                "s.json",
            ],
        );
        ctx.stage(&d, &prev_r);
        for f in &files {
            std::fs::set_permissions(d.join(f), std::fs::Permissions::from_mode(mode)).unwrap();
        }
        let mut c = Case::new(c7, "permissions", label, &d, &args)
            .inputs(&["m.npy", "mask.npy"])
            .expect(Expect::Success, &[])
            .timeout(60);
        c.keep_mode = files.iter().map(|s| s.to_string()).collect();
        ctx.run_case(c);
    }
}

// ------------------------------------------------------------------ 6: eval --resume

fn resume_cases(ctx: &mut Ctx) {
    let cat = "repro/6-resume";
    let variants: Vec<(&str, Vec<&str>)> = vec![
        (
            "--resume after changing --mask",
            vec!["--mask", "maskB.npy"],
        ),
        (
            "--resume after changing --dx",
            vec!["--mask", "mask.npy", "--dx", "1.0"],
        ),
        (
            "--resume after changing --iterations",
            vec!["--mask", "mask.npy", "--iterations", "20"],
        ),
        (
            "--resume after changing --noise-seed",
            vec!["--mask", "mask.npy", "--noise-seed", "9"],
        ),
    ];
    for (label, change) in variants {
        let d = ctx.case_dir("resume");
        ctx.stage(&d, &["mask.npy", "maskB.npy"]);
        let first = s(&[
            "eval",
            "--synthetic",
            "--size",
            "32",
            "--count",
            "1",
            "--mask",
            "mask.npy",
            "-o",
            "ev",
        ]);
        let o1 = ctx.exec(&Spec {
            args: first,
            cwd: d.clone(),
            env: vec![],
            timeout: Duration::from_secs(90),
            signal: None,
        });
        let before: BTreeMap<String, Option<String>> = list_json(&d.join("ev/scenes"));
        let mut args = vec!["eval", "--synthetic", "--size", "32", "--count", "1"];
        args.extend(change.iter());
        args.extend(["--resume", "-o", "ev"]);
        let c = Case::new(cat, "resume", label, &d, &args)
            .inputs(&["mask.npy", "maskB.npy"])
            .timeout(90);
        let snap0 = run::snapshot(&d);
        let ins: Vec<Option<String>> = c
            .inputs
            .iter()
            .map(|i| run::file_hash(&d.join(i)))
            .collect();
        let o = ctx.exec(&Spec {
            args: c.args.clone(),
            cwd: d.clone(),
            env: c.env.clone(),
            timeout: c.timeout,
            signal: None,
        });
        let snap1 = run::snapshot(&d);
        let mut f = Flags::default();
        ctx.judge(&c, &o, &ins, &snap0, &snap1, &mut f);
        let after = list_json(&d.join("ev/scenes"));
        let text = (o.stdout_text() + &o.stderr_text()).to_lowercase();
        let said = text.contains("recomput") || text.contains("differ") || text.contains("stale");
        if !o1.ok() {
            f.other
                .push(format!("first eval failed: {}", head(&o1.stderr, 160)));
        } else if o.ok() && before == after && !before.is_empty() {
            f.other
                .push("resume reused results of another study (per-scene JSON unchanged)".into());
        }
        ctx.record(
            &c,
            &o,
            f,
            json!({"scene_json_changed": before != after, "said_recomputed": said}),
        );
    }
}

fn list_json(d: &Path) -> BTreeMap<String, Option<String>> {
    let mut m = BTreeMap::new();
    if let Ok(rd) = std::fs::read_dir(d) {
        for e in rd.flatten() {
            m.insert(
                e.file_name().to_string_lossy().into_owned(),
                content_key(&e.path()),
            );
        }
    }
    m
}

// ------------------------------------------------------------------ interrupts

fn interrupt_cases(ctx: &mut Ctx, per_cmd: usize, seed: u64) {
    let ib = ctx.work.join("intbase");
    std::fs::create_dir_all(&ib).unwrap();
    let mut rng = Rng::new(seed ^ 0x1717);
    let n = 96u64;
    let bm: Vec<f32> = (0..n * n).map(|_| rng.below(2) as f32).collect();
    write(&ib.join("bigmask.npy"), &files::npy_f32(&[n, n], &bm));
    let o = ctx.exec(&Spec {
        args: s(&[
            "simulate",
            "--synthetic",
            "--size",
            "96",
            "--bands",
            "28",
            "--mask",
            "bigmask.npy",
            "--paper-mismatch",
            "-o",
            "big.npy",
        ]),
        cwd: ib.clone(),
        env: vec![],
        timeout: Duration::from_secs(60),
        signal: None,
    });
    if !o.ok() {
        ctx.notes.push(format!(
            "interrupts skipped: base simulate failed: {}",
            head(&o.stderr, 200)
        ));
        return;
    }
    // (name, current command, previous-output command, expected outputs)
    let cmds: Vec<(&str, Vec<&str>, Vec<&str>, Vec<&str>)> = vec![
        (
            "simulate",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "256",
                "--bands",
                "28",
                "--random-mask",
                "--preview",
                "--noise-seed",
                "1",
                "-o",
                "s.npy",
            ],
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "256",
                "--bands",
                "28",
                "--random-mask",
                "--preview",
                "--noise-seed",
                "2",
                "-o",
                "s.npy",
            ],
            vec!["s.npy", "s.json", "s.png"],
        ),
        (
            "reconstruct",
            vec![
                "reconstruct",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "--iterations",
                "150",
                "-o",
                "r.npy",
            ],
            vec![
                "reconstruct",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "--iterations",
                "120",
                "-o",
                "r.npy",
            ],
            vec!["r.npy", "r.png", "r.json"],
        ),
        (
            "calibrate",
            vec![
                "calibrate",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "--write-mask",
                "wm.npy",
                "-o",
                "c.json",
            ],
            vec![
                "calibrate",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "--bands",
                "27",
                "--write-mask",
                "wm.npy",
                "-o",
                "c.json",
            ],
            vec!["c.json", "wm.npy"],
        ),
        (
            "eval",
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--count",
                "2",
                "-o",
                "ev",
            ],
            vec![
                "eval",
                "--synthetic",
                "--size",
                "32",
                "--count",
                "2",
                "--noise-seed",
                "3",
                "-o",
                "ev",
            ],
            vec!["ev/report.md", "ev/summary.json"],
        ),
    ];
    for (name, cur, prev, outs) in cmds {
        let pd = ctx.work.join(format!("intprev-{name}"));
        let _ = std::fs::remove_dir_all(&pd);
        copy_rec(&ib, &pd);
        let t = Instant::now();
        let po = ctx.exec(&Spec {
            args: s(&prev),
            cwd: pd.clone(),
            env: vec![],
            timeout: Duration::from_secs(120),
            signal: None,
        });
        let t_prev = t.elapsed().as_secs_f64();
        let to = ctx.exec(&Spec {
            args: s(&cur),
            cwd: pd.clone(),
            env: vec![],
            timeout: Duration::from_secs(120),
            signal: None,
        });
        // restore the previous set (the timing run replaced it)
        let _ = std::fs::remove_dir_all(&pd);
        copy_rec(&ib, &pd);
        ctx.exec(&Spec {
            args: s(&prev),
            cwd: pd.clone(),
            env: vec![],
            timeout: Duration::from_secs(120),
            signal: None,
        });
        if !po.ok() || !to.ok() {
            ctx.notes.push(format!(
                "interrupts of {name} skipped: {}",
                head(if po.ok() { &to.stderr } else { &po.stderr }, 200)
            ));
            continue;
        }
        let t_run = to.wall_s.max(0.005);
        ctx.notes.push(format!(
            "interrupts of {name}: uninterrupted run {:.3} s (previous {:.3} s)",
            t_run, t_prev
        ));
        for k in 0..per_cmd {
            let d = ctx.case_dir(&format!("int-{name}"));
            copy_rec(&pd, &d);
            let sig = if k % 2 == 0 {
                libc::SIGINT
            } else {
                libc::SIGTERM
            };
            let delay = Duration::from_secs_f64(t_run * (0.02 + 1.0 * rng.unit()));
            let mut c = Case::new(
                "interrupt",
                name,
                &format!(
                    "{name} {} after {:.0} ms",
                    if sig == libc::SIGINT {
                        "SIGINT"
                    } else {
                        "SIGTERM"
                    },
                    delay.as_secs_f64() * 1e3
                ),
                &d,
                &cur,
            )
            .inputs(&["big.npy", "bigmask.npy"])
            .timeout(120);
            c.signal = Some((sig, delay));
            let snap0 = run::snapshot(&d);
            let ins: Vec<Option<String>> = c
                .inputs
                .iter()
                .map(|i| run::file_hash(&d.join(i)))
                .collect();
            let o = ctx.exec(&Spec {
                args: c.args.clone(),
                cwd: d.clone(),
                env: c.env.clone(),
                timeout: c.timeout,
                signal: c.signal,
            });
            let snap1 = run::snapshot(&d);
            let mut f = Flags::default();
            ctx.judge(&c, &o, &ins, &snap0, &snap1, &mut f);
            // a signal we sent is no crash
            if o.ok() {
                for out in &outs {
                    if !d.join(out).exists() {
                        f.partial.push(format!("missing {out}"));
                    }
                }
            }
            let interrupted = !o.ok();
            ctx.record(&c, &o, f, json!({"delay_ms": delay.as_secs_f64() * 1e3, "interrupted": interrupted, "uninterrupted_s": t_run}));
        }
    }
}

// ------------------------------------------------------------------ concurrency

fn concurrent_cases(ctx: &mut Ctx) {
    for round in 0..2 {
        let d = ctx.case_dir("concurrent");
        let rd = ctx.case_dir("concurrent-ref");
        for x in [&d, &rd] {
            ctx.stage(x, &["m.npy", "mask.npy", "scene.npy"]);
        }
        let mut jobs: Vec<(Vec<String>, Vec<&str>)> = Vec::new();
        let names = [
            ["r0.npy", "r0.png", "r0.json"],
            ["r1.npy", "r1.png", "r1.json"],
            ["r2.npy", "r2.png", "r2.json"],
            ["r3.npy", "r3.png", "r3.json"],
        ];
        for (k, n) in names.iter().enumerate() {
            jobs.push((
                s(&[
                    "reconstruct",
                    "m.npy",
                    "--mask",
                    "mask.npy",
                    "--bands",
                    "4",
                    "--iterations",
                    &(20 + 10 * k + round).to_string(),
                    "-o",
                    n[0],
                ]),
                n.to_vec(),
            ));
        }
        for k in 0..2 {
            let o = format!("s{k}.npy");
            jobs.push((
                s(&[
                    "simulate",
                    "--scene",
                    "scene.npy",
                    "--mask",
                    "mask.npy",
                    "--noise-seed",
                    &(k + 10 * round).to_string(),
                    "-o",
                    &o,
                ]),
                vec![
                    if k == 0 { "s0.npy" } else { "s1.npy" },
                    if k == 0 { "s0.json" } else { "s1.json" },
                ],
            ));
        }
        for _ in 0..2 {
            jobs.push((
                s(&[
                    "reconstruct",
                    "m.npy",
                    "--mask",
                    "mask.npy",
                    "--bands",
                    "4",
                    "--iterations",
                    "33",
                    "-o",
                    "same.npy",
                ]),
                vec!["same.npy", "same.png", "same.json"],
            ));
        }
        let env = vec![("RAYON_NUM_THREADS".to_string(), "1".to_string())];
        // sequential reference
        for (args, _) in &jobs {
            ctx.exec(&Spec {
                args: args.clone(),
                cwd: rd.clone(),
                env: env.clone(),
                timeout: Duration::from_secs(60),
                signal: None,
            });
        }
        let snap0 = run::snapshot(&d);
        let ins: Vec<String> = ["m.npy", "mask.npy", "scene.npy"]
            .iter()
            .map(|x| run::file_hash(&d.join(x)).unwrap())
            .collect();
        let mut running = Vec::new();
        for (args, _) in &jobs {
            let spec = Spec {
                args: args.clone(),
                cwd: d.clone(),
                env: env.clone(),
                timeout: Duration::from_secs(60),
                signal: None,
            };
            running.push(run::spawn(&ctx.bin, &spec, &ctx.scratch, ctx.mem_cap).expect("spawn"));
        }
        let mut outs: Vec<Option<Outcome>> = vec![None; running.len()];
        while outs.iter().any(|o| o.is_none()) {
            for (i, r) in running.iter_mut().enumerate() {
                if outs[i].is_none() {
                    outs[i] = r.poll();
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        let snap1 = run::snapshot(&d);
        let (added, _, _) = run::diff(&snap0, &snap1);
        let temps: Vec<String> = added
            .iter()
            .filter(|a| run::is_temp_name(a))
            .cloned()
            .collect();
        for (k, ((args, files), o)) in jobs.iter().zip(outs).enumerate() {
            let o = o.unwrap();
            let refs: Vec<&str> = args.iter().map(|x| x.as_str()).collect();
            let c = Case::new(
                "concurrent",
                "concurrent",
                &format!("round {round} job {k}"),
                &d,
                &refs,
            );
            let mut f = Flags {
                panic: o.crashed(),
                hang: o.hung,
                rss: o.peak_mib() > RSS_LIMIT_MIB,
                esc: o.stderr.contains(&0x1b) || o.stdout.contains(&0x1b),
                ..Default::default()
            };
            if k == 0 {
                f.temp = temps.clone();
            }
            if !o.ok() {
                f.other
                    .push(format!("concurrent run failed: {}", head(&o.stderr, 160)));
            }
            for (x, h) in ["m.npy", "mask.npy", "scene.npy"].iter().zip(&ins) {
                if run::file_hash(&d.join(x)).as_ref() != Some(h) {
                    f.destroyed.push(x.to_string());
                }
            }
            for file in files {
                let a = content_key(&d.join(file));
                let b = content_key(&rd.join(file));
                if a.is_none() {
                    f.partial.push(format!("missing {file}"));
                } else if a != b {
                    f.partial
                        .push(format!("{file} differs from the sequential run"));
                }
            }
            ctx.record(&c, &o, f, json!({}));
        }
    }
}

// ------------------------------------------------------------------ determinism

fn determinism_cases(ctx: &mut Ctx) {
    let ib = ctx.work.join("intbase");
    let configs: Vec<(&str, Vec<&str>, Vec<&str>)> = vec![
        (
            "simulate synthetic 64x64x8 with noise, .npy + preview",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "64",
                "--bands",
                "8",
                "--random-mask",
                "--paper-mismatch",
                "--preview",
                "-o",
                "s.npy",
            ],
            vec!["s.npy", "s.png", "s.json"],
        ),
        (
            "simulate from files, .mat",
            vec![
                "simulate",
                "--scene",
                "scene.npy",
                "--mask",
                "mask.npy",
                "-o",
                "s.mat",
            ],
            vec!["s.mat", "s.json"],
        ),
        (
            "simulate subpixel model, .npz",
            vec![
                "simulate",
                "--synthetic",
                "--size",
                "48",
                "--bands",
                "6",
                "--random-mask",
                "--model",
                "subpixel",
                "--alpha",
                "0.5",
                "-o",
                "s.npz",
            ],
            vec!["s.npz", "s.json"],
        ),
        (
            "reconstruct gap-tv 96x96x28",
            vec![
                "reconstruct",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "-o",
                "r.npy",
            ],
            vec!["r.npy", "r.png", "r.json"],
        ),
        (
            "reconstruct admm-tv",
            vec![
                "reconstruct",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "--method",
                "admm-tv",
                "--iterations",
                "40",
                "-o",
                "r.npy",
            ],
            vec!["r.npy", "r.png", "r.json"],
        ),
        (
            "reconstruct pnp-tv",
            vec![
                "reconstruct",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "--method",
                "pnp-tv",
                "--iterations",
                "20",
                "-o",
                "r.npy",
            ],
            vec!["r.npy", "r.png", "r.json"],
        ),
        (
            "reconstruct with a calibration, .mat",
            vec![
                "reconstruct",
                "m.npy",
                "--mask",
                "mask.npy",
                "--bands",
                "4",
                "--calibration",
                "c.json",
                "-o",
                "r.mat",
            ],
            vec!["r.mat", "r.png", "r.json"],
        ),
        (
            "calibrate 96x96x28",
            vec![
                "calibrate",
                "big.npy",
                "--mask",
                "bigmask.npy",
                "-o",
                "c2.json",
            ],
            vec!["c2.json"],
        ),
    ];
    for (label, args, files) in configs {
        let mut dirs = Vec::new();
        let mut outs = Vec::new();
        for th in ["1", "2"] {
            let d = ctx.case_dir(&format!("det{th}"));
            ctx.stage(&d, &["m.npy", "mask.npy", "scene.npy", "c.json"]);
            copy_rec(&ib.join("big.npy"), &d.join("big.npy"));
            copy_rec(&ib.join("bigmask.npy"), &d.join("bigmask.npy"));
            let o = ctx.exec(&Spec {
                args: s(&args),
                cwd: d.clone(),
                env: vec![("RAYON_NUM_THREADS".into(), th.into())],
                timeout: Duration::from_secs(120),
                signal: None,
            });
            dirs.push(d);
            outs.push(o);
        }
        let mut f = Flags {
            panic: outs.iter().any(|o| o.crashed()),
            hang: outs.iter().any(|o| o.hung),
            rss: outs.iter().any(|o| o.peak_mib() > RSS_LIMIT_MIB),
            ..Default::default()
        };
        let mut diffs = Vec::new();
        for file in &files {
            let a = content_key(&dirs[0].join(file));
            let b = content_key(&dirs[1].join(file));
            if a.is_none() || b.is_none() {
                f.other.push(format!("{file} missing"));
            } else if a != b {
                diffs.push(file.to_string());
            }
        }
        for o in &outs {
            if !o.ok() {
                f.other
                    .push(format!("run failed: {}", head(&o.stderr, 160)));
            }
        }
        f.determinism = !diffs.is_empty();
        let c = Case::new("determinism", "threads-1-vs-2", label, &dirs[1], &args);
        let o = outs.pop().unwrap();
        ctx.record(
            &c,
            &o,
            f,
            json!({"differing_files": diffs, "compared": files}),
        );
    }
}

// ------------------------------------------------------------------ report

fn print_table(ctx: &Ctx, elapsed: f64) {
    println!();
    println!(
        "{:<36} {:>6} {:>6} {:>6} {:>6} {:>7} {:>5} {:>6} {:>6} {:>5} {:>4} {:>5} {:>6} {:>9} {:>7}",
        "category",
        "cases",
        "FAIL",
        "panic",
        "destr",
        "partial",
        "temp",
        ">512M",
        "meanl",
        "hang",
        "esc",
        "det",
        "other",
        "peak MiB",
        "at case"
    );
    let mut all = Totals::default();
    let mark = |n: usize| {
        if n > 0 {
            format!("{n}!")
        } else {
            "0".to_string()
        }
    };
    for (cat, t) in &ctx.totals {
        println!(
            "{:<36} {:>6} {:>6} {:>6} {:>6} {:>7} {:>5} {:>6} {:>6} {:>5} {:>4} {:>5} {:>6} {:>9.1} {:>7}",
            cat,
            t.cases,
            mark(t.failing),
            mark(t.panics),
            mark(t.destroyed),
            mark(t.partial),
            mark(t.temp),
            mark(t.rss_over),
            mark(t.meaningless),
            mark(t.hangs),
            mark(t.esc),
            mark(t.determinism),
            mark(t.other),
            t.peak_mib,
            t.peak_case
        );
        all.cases += t.cases;
        all.failing += t.failing;
        all.panics += t.panics;
        all.destroyed += t.destroyed;
        all.partial += t.partial;
        all.temp += t.temp;
        all.rss_over += t.rss_over;
        all.meaningless += t.meaningless;
        all.hangs += t.hangs;
        all.esc += t.esc;
        all.determinism += t.determinism;
        all.other += t.other;
        all.external += t.external;
        if t.peak_mib > all.peak_mib {
            all.peak_mib = t.peak_mib;
            all.peak_case = t.peak_case;
        }
    }
    println!(
        "{:<36} {:>6} {:>6} {:>6} {:>6} {:>7} {:>5} {:>6} {:>6} {:>5} {:>4} {:>5} {:>6} {:>9.1} {:>7}",
        "TOTAL",
        all.cases,
        mark(all.failing),
        mark(all.panics),
        mark(all.destroyed),
        mark(all.partial),
        mark(all.temp),
        mark(all.rss_over),
        mark(all.meaningless),
        mark(all.hangs),
        mark(all.esc),
        mark(all.determinism),
        mark(all.other),
        all.peak_mib,
        all.peak_case
    );
    println!(
        "(FAIL = cases with any violation; partial = partial/mixed output sets; det = determinism mismatches; n! marks a violation)"
    );
    println!();
    println!("Named reproducers and special cases that FAIL:");
    for r in &ctx.records {
        let cat = r["category"].as_str().unwrap_or("");
        if !cat.starts_with("mutation") && r["verdict"] == "FAIL" {
            let v: Vec<&str> = r["violations"]
                .as_array()
                .unwrap()
                .iter()
                .filter_map(|x| x.as_str())
                .collect();
            println!(
                "  [{:>5}] {:<34} {:<60} {} | {}",
                r["id"],
                cat,
                r["label"].as_str().unwrap_or(""),
                r["outcome"].as_str().unwrap_or(""),
                v.join("; ")
            );
        }
    }
    let mut fam: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    for r in &ctx.records {
        if r["category"].as_str().unwrap_or("").starts_with("mutation") {
            let e = fam
                .entry(r["family"].as_str().unwrap_or("").to_string())
                .or_default();
            e.0 += 1;
            e.1 += (r["verdict"] == "FAIL") as usize;
        }
    }
    println!();
    println!("Mutation families (cases / failing):");
    for (k, (n, f)) in fam {
        println!(
            "  {k:<32} {n:>5} / {}",
            if f > 0 { format!("{f}!") } else { "0".into() }
        );
    }
    if all.external > 0 {
        println!(
            "note: {} case(s) were ended by a termination signal the harness did not send (another process's kill / OOM killer); not counted as panics, see killed_externally in the JSON",
            all.external
        );
    }
    for n in &ctx.notes {
        println!("note: {n}");
    }
    println!("{} cases in {:.1} s", all.cases, elapsed);
}

fn main() -> anyhow::Result<()> {
    cassi_bench::check_arguments(
        "hostile --cassi target/release/cassi [--seeds DIR] [--count N] [--out FILE] [--work DIR] \
         [--keep] [--seed S] [--interrupts N] [--mem-cap-mib M] (crates/cassi-bench/HOSTILE.md)",
        &[
            "--cassi",
            "--seeds",
            "--count",
            "--out",
            "--work",
            "--keep",
            "--seed",
            "--interrupts",
            "--mem-cap-mib",
        ],
    )?;
    let args: Vec<String> = std::env::args().collect();
    let opt = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1))
            .cloned()
    };
    let flag = |name: &str| args.iter().any(|a| a == name);
    let bin = PathBuf::from(opt("--cassi").unwrap_or_else(|| "target/release/cassi".into()));
    let bin =
        std::fs::canonicalize(&bin).with_context(|| format!("cassi binary {}", bin.display()))?;
    let count: usize = opt("--count")
        .map(|c| c.parse())
        .transpose()?
        .unwrap_or(3000);
    let seed: u64 = opt("--seed").map(|c| c.parse()).transpose()?.unwrap_or(12);
    let interrupts: usize = opt("--interrupts")
        .map(|c| c.parse())
        .transpose()?
        .unwrap_or(12);
    let out = PathBuf::from(opt("--out").unwrap_or_else(|| "bench/results/hostile.json".into()));
    let mem_cap_mib: u64 = opt("--mem-cap-mib")
        .map(|c| c.parse())
        .transpose()?
        .unwrap_or(6144);
    let seeds_dir = match opt("--seeds") {
        Some(d) => Some(PathBuf::from(d)),
        None => {
            let d = cassi_bench::shared_data();
            d.exists().then_some(d)
        }
    };
    let (work, keep_work) = match opt("--work") {
        Some(w) => (PathBuf::from(w), true),
        None => (
            std::env::temp_dir().join(format!("cassi-hostile-{}", std::process::id())),
            false,
        ),
    };
    let _ = std::fs::remove_dir_all(&work);
    std::fs::create_dir_all(&work)?;
    let work = std::fs::canonicalize(&work)?;
    let scratch = work.join("scratch");
    std::fs::create_dir_all(&scratch)?;
    let mut ctx = Ctx {
        bin: bin.clone(),
        base: work.join("base"),
        work: work.clone(),
        scratch,
        mem_cap: mem_cap_mib << 20,
        keep: flag("--keep"),
        next_id: 0,
        records: Vec::new(),
        totals: BTreeMap::new(),
        notes: Vec::new(),
    };
    let t0 = Instant::now();
    let version = ctx.exec(&Spec {
        args: s(&["--version"]),
        cwd: work.clone(),
        env: vec![],
        timeout: Duration::from_secs(10),
        signal: None,
    });
    eprintln!(
        "hostile: {} ({}) work {}",
        bin.display(),
        version.stdout_text().trim(),
        work.display()
    );
    match &seeds_dir {
        Some(d) => eprintln!("hostile: seeds {}", d.display()),
        None => ctx.notes.push("no --seeds folder (../shared/data absent): real .mat/.pth/.safetensors seed families reduced to repository fixtures and hand-built files".into()),
    }
    make_base(&mut ctx)?;
    eprintln!(
        "hostile: base files ready ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    reproducers(&mut ctx);
    eprintln!(
        "hostile: named reproducers done ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    resume_cases(&mut ctx);
    eprintln!("hostile: resume done ({:.1} s)", t0.elapsed().as_secs_f64());
    mutation_cases(&mut ctx, seeds_dir.as_deref(), count, seed);
    eprintln!(
        "hostile: mutations done ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    interrupt_cases(&mut ctx, interrupts, seed);
    eprintln!(
        "hostile: interrupts done ({:.1} s)",
        t0.elapsed().as_secs_f64()
    );
    concurrent_cases(&mut ctx);
    determinism_cases(&mut ctx);
    let elapsed = t0.elapsed().as_secs_f64();

    let totals: BTreeMap<&String, Value> = ctx
        .totals
        .iter()
        .map(|(k, t)| {
            let peak_label = ctx.records.get(t.peak_case).map(|r| r["label"].clone()).unwrap_or(Value::Null);
            (k, json!({
                "cases": t.cases, "failing_cases": t.failing, "panics": t.panics,
                "inputs_destroyed": t.destroyed, "partial_or_mixed_sets": t.partial,
                "temp_files_left": t.temp, "peak_rss_over_512mb": t.rss_over,
                "meaningless_accepted": t.meaningless, "hangs": t.hangs, "esc_in_output": t.esc,
                "determinism_mismatches": t.determinism, "other_violations": t.other,
                "killed_externally": t.external,
                "peak_rss_mib": (t.peak_mib * 10.0).round() / 10.0, "peak_rss_case": t.peak_case,
                "peak_rss_case_label": peak_label, "wall_s": (t.wall_s * 100.0).round() / 100.0,
            }))
        })
        .collect();
    let report = json!({
        "cassi": bin.display().to_string(),
        "cassi_version": version.stdout_text().trim(),
        "count_requested": count,
        "seed": seed,
        "cases": ctx.records.len(),
        "elapsed_s": (elapsed * 10.0).round() / 10.0,
        "rss_limit_mib": RSS_LIMIT_MIB,
        "address_space_cap_mib": mem_cap_mib,
        "work": work.display().to_string(),
        "notes": ctx.notes,
        "totals": totals,
        "cases_detail": ctx.records,
    });
    if let Some(p) = out.parent() {
        std::fs::create_dir_all(p)?;
    }
    std::fs::write(&out, serde_json::to_string_pretty(&report)?)?;
    print_table(&ctx, elapsed);
    println!("wrote {}", out.display());
    if !keep_work && !ctx.keep {
        // keep failing cases for inspection only when --work was given
        let _ = std::fs::remove_dir_all(&work);
    } else {
        println!("work folder kept: {}", work.display());
    }
    Ok(())
}
