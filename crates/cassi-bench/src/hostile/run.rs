//! Running one cassi child: wall-clock timeout, a signal at a chosen moment, peak RSS from
//! `wait4`, an address-space cap that protects the machine, and folder snapshots.

use std::collections::BTreeMap;
use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

pub struct Spec {
    pub args: Vec<String>,
    pub cwd: PathBuf,
    pub env: Vec<(String, String)>,
    pub timeout: Duration,
    /// Send this signal after this delay.
    pub signal: Option<(i32, Duration)>,
}

#[derive(Clone, Debug, Default)]
pub struct Outcome {
    pub code: Option<i32>,
    pub signal: Option<i32>,
    pub sent_signal: Option<i32>,
    pub wall_s: f64,
    pub maxrss_kib: i64,
    pub stdout: Vec<u8>,
    pub stderr: Vec<u8>,
    pub hung: bool,
}

impl Outcome {
    pub fn ok(&self) -> bool {
        self.code == Some(0)
    }
    pub fn stderr_text(&self) -> String {
        String::from_utf8_lossy(&self.stderr).into_owned()
    }
    pub fn stdout_text(&self) -> String {
        String::from_utf8_lossy(&self.stdout).into_owned()
    }
    pub fn peak_mib(&self) -> f64 {
        self.maxrss_kib as f64 / 1024.0
    }
    /// A panic or a death by a signal we did not send (the timeout's SIGKILL excluded).
    pub fn crashed(&self) -> bool {
        const CRASH: [i32; 7] = [
            libc::SIGSEGV,
            libc::SIGABRT,
            libc::SIGBUS,
            libc::SIGILL,
            libc::SIGFPE,
            libc::SIGTRAP,
            libc::SIGSYS,
        ];
        self.code == Some(101)
            || self.stderr_text().contains("panicked at")
            || (self.signal.is_some_and(|s| CRASH.contains(&s))
                && self.signal != self.sent_signal
                && !self.hung)
    }
    /// Ended by a termination signal (TERM, INT, KILL, HUP, …) that neither the case nor the
    /// timeout sent: something outside the harness killed it (another user's `pkill`, the OOM
    /// killer). Recorded, not counted as a panic.
    pub fn killed_externally(&self) -> bool {
        self.signal.is_some() && self.signal != self.sent_signal && !self.hung && !self.crashed()
    }
    /// Aborted because an allocation failed under the harness's address-space cap.
    pub fn alloc_capped(&self) -> bool {
        self.signal == Some(libc::SIGABRT) && self.stderr_text().contains("memory allocation of")
    }
}

pub struct Running {
    pid: libc::pid_t,
    start: Instant,
    spec_timeout: Duration,
    signal: Option<(i32, Duration)>,
    sent: Option<i32>,
    hung: bool,
    out_path: PathBuf,
    err_path: PathBuf,
}

pub fn spawn(bin: &Path, spec: &Spec, scratch: &Path, mem_cap: u64) -> std::io::Result<Running> {
    static N: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let out_path = scratch.join(format!("stdout{n}"));
    let err_path = scratch.join(format!("stderr{n}"));
    let mut cmd = Command::new(bin);
    cmd.args(&spec.args)
        .current_dir(&spec.cwd)
        .stdin(Stdio::null())
        .stdout(std::fs::File::create(&out_path)?)
        .stderr(std::fs::File::create(&err_path)?);
    for (k, v) in &spec.env {
        cmd.env(k, v);
    }
    // SAFETY: the hook runs in the forked child before exec, where only
    // async-signal-safe calls are allowed: it allocates nothing (the limit is
    // a stack value built from a copied u64) and calls only setrlimit.
    unsafe {
        cmd.pre_exec(move || {
            let lim = libc::rlimit {
                rlim_cur: mem_cap as libc::rlim_t,
                rlim_max: mem_cap as libc::rlim_t,
            };
            libc::setrlimit(libc::RLIMIT_AS, &lim);
            Ok(())
        });
    }
    let child = cmd.spawn()?;
    Ok(Running {
        pid: child.id() as libc::pid_t,
        start: Instant::now(),
        spec_timeout: spec.timeout,
        signal: spec.signal,
        sent: None,
        hung: false,
        out_path,
        err_path,
    })
}

impl Running {
    /// Reaps the child if it has exited; sends the planned signal / the timeout's SIGKILL.
    pub fn poll(&mut self) -> Option<Outcome> {
        let mut status: libc::c_int = 0;
        // SAFETY: `rusage` is a C struct of integers, for which all-zero
        // bytes are a valid value.
        let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
        // SAFETY: both pointers are to live, writable locals of the types
        // wait4 expects.
        let r = unsafe { libc::wait4(self.pid, &mut status, libc::WNOHANG, &mut ru) };
        let el = self.start.elapsed();
        if r == self.pid {
            let (code, signal) = if libc::WIFEXITED(status) {
                (Some(libc::WEXITSTATUS(status)), None)
            } else if libc::WIFSIGNALED(status) {
                (None, Some(libc::WTERMSIG(status)))
            } else {
                (None, None)
            };
            let o = Outcome {
                code,
                signal,
                sent_signal: self.sent,
                wall_s: el.as_secs_f64(),
                maxrss_kib: ru.ru_maxrss,
                stdout: std::fs::read(&self.out_path).unwrap_or_default(),
                stderr: std::fs::read(&self.err_path).unwrap_or_default(),
                hung: self.hung,
            };
            let _ = std::fs::remove_file(&self.out_path);
            let _ = std::fs::remove_file(&self.err_path);
            return Some(o);
        }
        if let Some((sig, at)) = self.signal
            && self.sent.is_none()
            && el >= at
        {
            // SAFETY: kill takes no pointers; `self.pid` is our child and not
            // yet reaped (a reaped one returned above), so it names no other
            // process.
            unsafe { libc::kill(self.pid, sig) };
            self.sent = Some(sig);
        }
        if el > self.spec_timeout && !self.hung {
            // SAFETY: as for the planned signal above.
            unsafe { libc::kill(self.pid, libc::SIGKILL) };
            self.hung = true;
        }
        None
    }

    pub fn wait(mut self) -> Outcome {
        let mut nap = Duration::from_micros(100);
        loop {
            if let Some(o) = self.poll() {
                return o;
            }
            std::thread::sleep(nap);
            nap = (nap * 2).min(Duration::from_millis(3));
        }
    }
}

pub fn run(bin: &Path, spec: &Spec, scratch: &Path, mem_cap: u64) -> Outcome {
    match spawn(bin, spec, scratch, mem_cap) {
        Ok(r) => r.wait(),
        Err(e) => Outcome {
            code: Some(-1),
            stderr: format!("harness: spawn failed: {e}").into_bytes(),
            ..Default::default()
        },
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FileState {
    pub hash: String,
    pub len: u64,
    pub mode: u32,
}

/// Every file under `dir` (recursive), by relative path; symlinks as `-> target`.
pub fn snapshot(dir: &Path) -> BTreeMap<String, FileState> {
    let mut m = BTreeMap::new();
    fn walk(root: &Path, d: &Path, m: &mut BTreeMap<String, FileState>) {
        let Ok(rd) = std::fs::read_dir(d) else {
            return;
        };
        for e in rd.flatten() {
            let p = e.path();
            let rel = p
                .strip_prefix(root)
                .unwrap_or(&p)
                .to_string_lossy()
                .into_owned();
            let Ok(md) = std::fs::symlink_metadata(&p) else {
                continue;
            };
            if md.file_type().is_symlink() {
                let t = std::fs::read_link(&p).unwrap_or_default();
                m.insert(
                    rel,
                    FileState {
                        hash: format!("-> {}", t.display()),
                        len: 0,
                        mode: 0,
                    },
                );
            } else if md.is_dir() {
                m.insert(
                    rel.clone() + "/",
                    FileState {
                        hash: "dir".into(),
                        len: 0,
                        mode: md.permissions().mode() & 0o7777,
                    },
                );
                walk(root, &p, m);
            } else {
                let bytes = std::fs::read(&p).unwrap_or_default();
                m.insert(
                    rel,
                    FileState {
                        hash: super::files::hash(&bytes),
                        len: md.len(),
                        mode: md.permissions().mode() & 0o7777,
                    },
                );
            }
        }
    }
    walk(dir, dir, &mut m);
    m
}

/// Hash of a file's content (following symlinks), or None when unreadable.
pub fn file_hash(p: &Path) -> Option<String> {
    std::fs::read(p).ok().map(|b| super::files::hash(&b))
}

pub fn is_temp_name(name: &str) -> bool {
    let base = name.rsplit('/').next().unwrap_or(name);
    base.contains(".tmp") || base.ends_with('~') || (base.starts_with('.') && base.len() > 1)
}

/// Differences between two snapshots: (added, removed, changed).
pub fn diff(
    a: &BTreeMap<String, FileState>,
    b: &BTreeMap<String, FileState>,
) -> (Vec<String>, Vec<String>, Vec<String>) {
    let added = b.keys().filter(|k| !a.contains_key(*k)).cloned().collect();
    let removed = a.keys().filter(|k| !b.contains_key(*k)).cloned().collect();
    let changed = a
        .iter()
        .filter(|(k, s)| b.get(*k).is_some_and(|t| t != *s))
        .map(|(k, _)| k.clone())
        .collect();
    (added, removed, changed)
}
