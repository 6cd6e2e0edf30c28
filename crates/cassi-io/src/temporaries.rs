//! Temporary files of atomic writes: their names, the process-wide list an
//! interrupt handler empties, and the sweep of stale ones left by killed
//! processes.
//!
//! A temporary for `dir/NAME` is `dir/.NAME.cassi-tmp<PID>-<N>`: the writing
//! process's id and a per-process counter. Every temporary this process
//! creates is registered in a process-wide list until it is renamed into
//! place or removed, so an interrupt handler can remove them all
//! ([`remove_temporaries_for_exit`]).
//!
//! A process killed outright (SIGKILL, power loss) cannot clean up. Its
//! temporaries are *stale*: the first write of a later cassi process into the
//! same directory removes every regular file there whose name has the form
//! `.NAME.cassi-tmp<PID>-<N>` (or `.NAME.tmp<PID>-<N>`, the form written by
//! earlier cassi versions) when no process with that PID is alive. A live
//! process's temporaries are never touched; should the PID have been reused
//! by an unrelated live process, the stale file stays until that process is
//! gone.

use std::collections::HashSet;
use std::ffi::OsStr;
use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Every temporary file this process has created and not yet renamed or removed.
static TEMPS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Directories already swept for stale temporaries by this process.
static SWEPT: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// The marker between the destination's name and the PID.
const MARKER: &str = ".cassi-tmp";
/// The marker of earlier cassi versions (`.NAME.tmp<PID>-<N>`).
const LEGACY_MARKER: &str = ".tmp";

pub(crate) fn lock_temps() -> MutexGuard<'static, Vec<PathBuf>> {
    TEMPS.lock().unwrap_or_else(|e| e.into_inner())
}

/// A fresh temporary name for `file_name`: `.NAME.cassi-tmp<PID>-<N>`.
pub(crate) fn temp_name(file_name: &OsStr) -> String {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    format!(
        ".{}{MARKER}{}-{n}",
        file_name.to_string_lossy(),
        std::process::id()
    )
}

/// The PID in a temporary's name, if `name` is one (current or legacy form).
pub(crate) fn temp_pid(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?;
    for marker in [MARKER, LEGACY_MARKER] {
        if let Some(at) = rest.rfind(marker) {
            if at == 0 {
                continue;
            }
            let tail = &rest[at + marker.len()..];
            let (pid, n) = tail.split_once('-')?;
            let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
            if digits(pid) && digits(n) {
                return pid.parse().ok();
            }
        }
    }
    None
}

/// Whether a process with this id exists (conservatively true when unknown,
/// so a temporary is never removed from under a running process).
///
/// Where procfs is mounted (Linux), `/proc/<pid>` exists exactly when
/// `kill(pid, 0)` would find the process: zombies and other users'
/// processes included (but `hidepid=2` hides the latter, so their
/// temporaries count as stale; removing them still needs write permission
/// on the folder). Elsewhere on Unix, `ps -p <pid>` (POSIX) answers; on
/// other systems, or when `ps` cannot run, the process counts as alive.
fn process_alive(pid: u32) -> bool {
    if pid == 0 {
        return true;
    }
    if Path::new("/proc/self").exists() {
        return Path::new("/proc").join(pid.to_string()).exists();
    }
    if cfg!(unix) {
        let ps = std::process::Command::new("ps")
            .args(["-p", &pid.to_string()])
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status();
        return ps.map_or(true, |s| s.success());
    }
    true
}

/// Removes the stale temporaries in `dir` (see the module documentation for
/// the rule); returns the paths removed.
pub fn remove_stale_temporaries(dir: &Path) -> Vec<PathBuf> {
    let me = std::process::id();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut removed = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_pid) else {
            continue;
        };
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if pid == me || !is_file || process_alive(pid) {
            continue;
        }
        let path = entry.path();
        if std::fs::remove_file(&path).is_ok() {
            removed.push(path);
        }
    }
    removed
}

/// Sweeps `dir` for stale temporaries, once per process.
pub(crate) fn sweep_once(dir: &Path) {
    let key = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    {
        let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
        if !swept.get_or_insert_with(HashSet::new).insert(key) {
            return;
        }
    }
    remove_stale_temporaries(dir);
}

/// Removes every temporary this process still has and keeps the list locked
/// for good, so that no new temporary is made and no output set is committed
/// after it. For an interrupt handler about to exit the process: call it,
/// then exit. It waits for a commit in progress to finish.
pub fn remove_temporaries_for_exit() {
    let mut temps = lock_temps();
    for path in temps.drain(..) {
        let _ = std::fs::remove_file(&path);
    }
    std::mem::forget(temps);
}

/// Creates a new, registered temporary in `dir` for `file_name`.
pub(crate) fn new_temp(dir: &Path, file_name: &OsStr) -> std::io::Result<(File, PathBuf)> {
    loop {
        let tmp = dir.join(temp_name(file_name));
        // registered before it exists, under the lock: an exit handler that
        // holds the lock sees every file made
        let mut temps = lock_temps();
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => {
                temps.push(tmp.clone());
                return Ok((f, tmp));
            }
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
}

/// Takes `path` off the list of temporaries (it was renamed into place).
pub(crate) fn unregister(temps: &mut Vec<PathBuf>, path: &Path) {
    if let Some(i) = temps.iter().rposition(|p| p == path) {
        temps.swap_remove(i);
    }
}

/// Removes the temporary file and takes it off the list.
pub(crate) fn discard(path: &Path) {
    let mut temps = lock_temps();
    let _ = std::fs::remove_file(path);
    unregister(&mut temps, path);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_recognised() {
        let name = temp_name(OsStr::new("cube.npy"));
        assert!(name.starts_with(".cube.npy.cassi-tmp"));
        assert_eq!(temp_pid(&name), Some(std::process::id()));
        assert_eq!(temp_pid(".cube.npy.tmp123-4"), Some(123));
        assert_eq!(temp_pid(".a.tmp.b.cassi-tmp77-0"), Some(77));
        for not in [
            "cube.npy.cassi-tmp1-2",
            ".cube.npy",
            ".cube.npy.tmp12",
            ".cube.npy.tmp-3",
            ".cube.npy.tmp1-x",
            "..tmp1-2x",
        ] {
            assert_eq!(temp_pid(not), None, "{not}");
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_reaped_child_is_dead_this_process_and_init_alive() {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        assert!(!process_alive(pid), "{pid}");
        assert!(process_alive(std::process::id()));
        assert!(process_alive(1));
        assert!(!process_alive(2_000_000_000));
        assert!(!process_alive(u32::MAX));
    }

    #[test]
    fn stale_temporaries_of_dead_processes_go_live_ones_stay() {
        let dir = std::env::temp_dir().join(format!("cassi-io-stale-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let dead = dir.join(".x.npy.cassi-tmp2000000000-0");
        let legacy = dir.join(".x.npy.tmp2000000001-5");
        let live = dir.join(format!(".x.npy.cassi-tmp{}-9", std::process::id()));
        let other = dir.join(".x.npy.cassi-tmp1-0"); // init: alive
        let user = dir.join("x.npy.tmp2000000000-0"); // not hidden: not ours
        for p in [&dead, &legacy, &live, &other, &user] {
            std::fs::write(p, b"x").unwrap();
        }
        let mut removed = remove_stale_temporaries(&dir);
        removed.sort();
        let mut want = vec![dead.clone(), legacy.clone()];
        want.sort();
        assert_eq!(removed, want);
        assert!(live.exists() && other.exists() && user.exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
