//! Output sets: all the files one command writes, checked against all the
//! files it reads before any work, staged as temporaries, and moved into
//! place together at the end.
//!
//! ```no_run
//! # fn main() -> cassi_io::Result<()> {
//! use cassi_io::OutputSet;
//! let mut set = OutputSet::new();
//! set.input("the measurement", "m.npy")
//!     .input("--mask", "mask.npy")
//!     .output("-o", "cube.npy")
//!     .output("the preview (-o with .png)", "cube.png");
//! let checked = set.check()?; // collisions refused, folders made: before any work
//! // … the work …
//! let staging = checked.begin()?;
//! // every cassi_io write to a declared output now goes to a temporary
//! // cassi_io::save_cube("cube.npy", …)?; cassi_io::write_rgb_png("cube.png", …)?;
//! staging.commit()?; // all renamed into place, or none (dropping it discards all)
//! # Ok(())
//! # }
//! ```
//!
//! # Collisions
//!
//! Each path is resolved: symbolic links are followed, and for a path that
//! does not exist yet the nearest existing ancestor is canonicalised and the
//! rest appended. Two paths name the same file when they resolve to the same
//! path, or when both exist and have the same device and inode (hard links).
//! An output that is the same file as an input, as another output, or that
//! lies inside a declared output folder together with an input, is refused
//! with an error naming both paths and the flag (role) each came from.
//!
//! # Staging and commit
//!
//! While a [`Staging`] is alive, every atomic write of this crate
//! ([`crate::save_cube`], [`crate::write_atomic`], the PNG writers …) to a
//! declared output (or into a declared output folder) stops short of the
//! final rename and hands its finished temporary to the set; a write to any
//! other path from the thread that began the staging is refused (one from
//! another thread is written directly, as without a staging). [`Staging::commit`] then first keeps a hard link
//! (or, where links are impossible, a copy) of each file about to be
//! replaced, renames every temporary into place, and removes the backups.
//! If a rename fails midway, the files already replaced are put back from
//! their backups (new files removed), the remaining temporaries are removed,
//! and the error says what was restored. Dropping a `Staging` without
//! committing removes its temporaries and leaves every destination untouched.
//! A commit holds the process-wide list of temporaries, so an interrupt
//! handler calling [`crate::remove_temporaries_for_exit`] waits for it.

use std::path::{Component, Path, PathBuf};
use std::sync::Mutex;

use crate::error::{IoError, Result};
use crate::temporaries;

/// A file path with the flag or role it came from.
#[derive(Debug, Clone)]
struct Named {
    role: String,
    path: PathBuf,
}

/// A declared path, resolved.
#[derive(Debug, Clone)]
struct Resolved {
    role: String,
    given: PathBuf,
    path: PathBuf,
    id: Option<(u64, u64)>,
}

impl Resolved {
    fn new(n: &Named) -> Result<Self> {
        let path = resolve(&n.path).map_err(|e| IoError::InvalidArgument {
            path: n.path.clone(),
            reason: format!("cannot resolve the path of {}: {e}", n.role),
        })?;
        Ok(Self {
            role: n.role.clone(),
            given: n.path.clone(),
            id: file_id(&path),
            path,
        })
    }

    fn same_file(&self, other: &Resolved) -> bool {
        self.path == other.path || (self.id.is_some() && self.id == other.id)
    }

    fn label(&self) -> String {
        format!("{} ({})", self.given.display(), self.role)
    }
}

/// (device, inode) of an existing file, following links.
fn file_id(path: &Path) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        None
    }
}

/// The absolute path `path` names once symbolic links are followed; for a
/// path that does not exist, its nearest existing ancestor canonicalised and
/// the rest appended (a dangling link resolves to where it points).
pub(crate) fn resolve(path: &Path) -> std::io::Result<PathBuf> {
    resolve_depth(path, 0)
}

fn resolve_depth(path: &Path, depth: usize) -> std::io::Result<PathBuf> {
    if depth > 40 {
        return Err(std::io::Error::other("too many levels of symbolic links"));
    }
    if let Ok(p) = std::fs::canonicalize(path) {
        return Ok(p);
    }
    let parent = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink()) {
        let target = std::fs::read_link(path)?;
        return resolve_depth(&parent.join(target), depth + 1);
    }
    match path.components().next_back() {
        Some(Component::Normal(name)) => Ok(resolve_depth(&parent, depth + 1)?.join(name)),
        // `dir/..`: the parent of dir once its links are followed
        Some(Component::ParentDir) => {
            let mut p = resolve_depth(&parent, depth + 1)?;
            p.pop();
            Ok(p)
        }
        _ => Err(std::io::Error::other("the path has no file name")),
    }
}

/// The files one command reads and writes; see the module documentation.
#[derive(Debug, Default, Clone)]
pub struct OutputSet {
    inputs: Vec<Named>,
    outputs: Vec<Named>,
    dirs: Vec<Named>,
}

impl OutputSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// A file the command reads; `role` names it in errors (e.g. `--mask`).
    pub fn input(&mut self, role: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.inputs.push(Named {
            role: role.into(),
            path: path.as_ref().to_path_buf(),
        });
        self
    }

    /// A file the command writes; `role` names it in errors (e.g. `-o`, or
    /// `the report (-o with .json)` for a derived name).
    pub fn output(&mut self, role: impl Into<String>, path: impl AsRef<Path>) -> &mut Self {
        self.outputs.push(Named {
            role: role.into(),
            path: path.as_ref().to_path_buf(),
        });
        self
    }

    /// A folder the command writes files into, names not known in advance
    /// (figures): every staged write inside it belongs to the set, and no
    /// input may lie inside it.
    pub fn output_dir(&mut self, role: impl Into<String>, dir: impl AsRef<Path>) -> &mut Self {
        self.dirs.push(Named {
            role: role.into(),
            path: dir.as_ref().to_path_buf(),
        });
        self
    }

    /// Resolves every path and refuses collisions (an output that is an
    /// input, two outputs that are one file, an input inside an output
    /// folder, an output that is a folder), and removes stale temporaries
    /// from the existing output folders. Call it before any work; it creates
    /// nothing (the folders are made by [`CheckedSet::begin`]).
    pub fn check(&self) -> Result<CheckedSet> {
        let inputs: Vec<Resolved> = self
            .inputs
            .iter()
            .map(Resolved::new)
            .collect::<Result<_>>()?;
        let outputs: Vec<Resolved> = self
            .outputs
            .iter()
            .map(Resolved::new)
            .collect::<Result<_>>()?;
        let dirs: Vec<Resolved> = self.dirs.iter().map(Resolved::new).collect::<Result<_>>()?;
        for (k, out) in outputs.iter().enumerate() {
            if out.path.is_dir() {
                return Err(IoError::InvalidArgument {
                    path: out.given.clone(),
                    reason: format!("{} is a folder, not a file", out.role),
                });
            }
            if let Some(input) = inputs.iter().find(|i| out.same_file(i)) {
                return Err(collision(out, input, "would overwrite an input"));
            }
            if let Some(other) = outputs[..k].iter().find(|o| out.same_file(o)) {
                return Err(collision(out, other, "two outputs would be one file"));
            }
        }
        for dir in &dirs {
            if dir.path.exists() && !dir.path.is_dir() {
                return Err(IoError::InvalidArgument {
                    path: dir.given.clone(),
                    reason: format!("{} is a file, not a folder", dir.role),
                });
            }
            if let Some(input) = inputs.iter().find(|i| i.path.starts_with(&dir.path)) {
                return Err(IoError::InvalidArgument {
                    path: dir.given.clone(),
                    reason: format!(
                        "{} is written by this command and holds an input, {}; \
                         nothing was written, choose another output folder",
                        dir.role,
                        input.label()
                    ),
                });
            }
        }
        let mut folders: Vec<PathBuf> = outputs
            .iter()
            .filter_map(|o| o.path.parent().map(Path::to_path_buf))
            .chain(dirs.iter().map(|d| d.path.clone()))
            .collect();
        folders.dedup();
        for dir in folders.iter().filter(|d| d.is_dir()) {
            temporaries::sweep_once(dir);
        }
        Ok(CheckedSet {
            outputs,
            dirs,
            folders,
        })
    }
}

fn collision(out: &Resolved, other: &Resolved, what: &str) -> IoError {
    let how = if out.given == other.given {
        String::new()
    } else if out.path == other.path {
        " (the same path once links are followed)".into()
    } else {
        " (hard links to one file)".into()
    };
    IoError::InvalidArgument {
        path: out.given.clone(),
        reason: format!(
            "{what}: {} is the same file as {}{how}; nothing was written, choose another name",
            out.label(),
            other.label()
        ),
    }
}

/// An output set whose paths passed [`OutputSet::check`].
#[derive(Debug, Clone)]
pub struct CheckedSet {
    outputs: Vec<Resolved>,
    dirs: Vec<Resolved>,
    /// The folders the outputs go into.
    folders: Vec<PathBuf>,
}

/// The set being staged (at most one per process).
struct Active {
    /// The thread that began the staging: its writes to undeclared paths are
    /// refused (other threads' undeclared writes go straight to disk).
    owner: std::thread::ThreadId,
    outputs: Vec<PathBuf>,
    dirs: Vec<PathBuf>,
    /// (destination, temporary), in the order written.
    staged: Vec<(PathBuf, PathBuf)>,
}

static ACTIVE: Mutex<Option<Active>> = Mutex::new(None);

fn lock_active() -> std::sync::MutexGuard<'static, Option<Active>> {
    ACTIVE.lock().unwrap_or_else(|e| e.into_inner())
}

impl CheckedSet {
    /// Creates the output folders and starts staging: until the returned
    /// [`Staging`] is committed or dropped, writes to the declared outputs
    /// go to temporaries.
    pub fn begin(&self) -> Result<Staging> {
        for dir in &self.folders {
            std::fs::create_dir_all(dir).map_err(|e| IoError::InvalidArgument {
                path: dir.clone(),
                reason: format!("cannot create the output folder: {e}"),
            })?;
            temporaries::sweep_once(dir);
        }
        let mut active = lock_active();
        if active.is_some() {
            return Err(IoError::InvalidArgument {
                path: self
                    .outputs
                    .first()
                    .map_or_else(PathBuf::new, |o| o.given.clone()),
                reason: "another output set is already being written".into(),
            });
        }
        *active = Some(Active {
            owner: std::thread::current().id(),
            outputs: self.outputs.iter().map(|o| o.path.clone()).collect(),
            dirs: self.dirs.iter().map(|d| d.path.clone()).collect(),
            staged: Vec::new(),
        });
        Ok(Staging { done: false })
    }
}

/// Whether a staging is active and `target` (resolved) belongs to it; an
/// error for a path outside the active set written by the thread that began it.
pub(crate) fn claim(path: &Path, target: &Path) -> Result<bool> {
    let active = lock_active();
    let Some(a) = active.as_ref() else {
        return Ok(false);
    };
    if a.outputs.iter().any(|o| o == target) || a.dirs.iter().any(|d| target.starts_with(d)) {
        return Ok(true);
    }
    if a.owner != std::thread::current().id() {
        return Ok(false);
    }
    Err(IoError::InvalidArgument {
        path: path.to_path_buf(),
        reason: "not declared as an output of this command (a bug in cassi: \
                 every output must be checked before the work)"
            .into(),
    })
}

/// Hands a finished temporary to the active set (replacing an earlier one
/// for the same destination).
pub(crate) fn record(path: &Path, target: PathBuf, tmp: PathBuf) -> Result<()> {
    let mut active = lock_active();
    let Some(a) = active.as_mut() else {
        drop(active);
        temporaries::discard(&tmp);
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: "the output set was closed while this file was written".into(),
        });
    };
    if let Some(i) = a.staged.iter().position(|(d, _)| *d == target) {
        let (_, old) = a.staged.remove(i);
        temporaries::discard(&old);
    }
    a.staged.push((target, tmp));
    Ok(())
}

/// Whether `path` is a file, or is staged in the active output set (so code
/// that checks for a file it wrote earlier in the same set finds it).
pub fn output_exists(path: impl AsRef<Path>) -> bool {
    let path = path.as_ref();
    if path.is_file() {
        return true;
    }
    let Ok(target) = resolve(path) else {
        return false;
    };
    lock_active()
        .as_ref()
        .is_some_and(|a| a.staged.iter().any(|(d, _)| *d == target))
}

/// The files of an output set being written; see the module documentation.
#[must_use = "dropping a Staging discards its files; call commit()"]
pub struct Staging {
    done: bool,
}

impl Staging {
    /// The destinations staged so far.
    pub fn staged(&self) -> Vec<PathBuf> {
        lock_active()
            .as_ref()
            .map(|a| a.staged.iter().map(|(d, _)| d.clone()).collect())
            .unwrap_or_default()
    }

    /// Moves every staged file into place; all or none (as far as the file
    /// system allows: see the module documentation). Returns the files written.
    pub fn commit(mut self) -> Result<Vec<PathBuf>> {
        self.done = true;
        let staged = lock_active().take().map(|a| a.staged).unwrap_or_default();
        // holding the list of temporaries: an exit handler waits for the commit
        let mut temps = temporaries::lock_temps();
        let drop_temps = |temps: &mut Vec<PathBuf>, list: &[(PathBuf, PathBuf)]| {
            for (_, tmp) in list {
                let _ = std::fs::remove_file(tmp);
                temporaries::unregister(temps, tmp);
            }
        };
        // 1. keep the files about to be replaced
        let mut backups: Vec<Option<PathBuf>> = Vec::with_capacity(staged.len());
        for (dest, _) in &staged {
            if !dest.exists() {
                backups.push(None);
                continue;
            }
            let dir = dest.parent().unwrap_or(Path::new("."));
            let name = dest.file_name().unwrap_or_default();
            let backup = dir.join(temporaries::temp_name(name));
            temps.push(backup.clone());
            let kept = std::fs::hard_link(dest, &backup)
                .or_else(|_| std::fs::copy(dest, &backup).map(|_| ()));
            if let Err(e) = kept {
                let _ = std::fs::remove_file(&backup);
                temporaries::unregister(&mut temps, &backup);
                remove_backups(&mut temps, &backups);
                drop_temps(&mut temps, &staged);
                return Err(IoError::Write {
                    path: dest.clone(),
                    cause: std::io::Error::other(format!(
                        "cannot keep the previous file while replacing it ({e}); \
                         nothing was replaced"
                    )),
                });
            }
            backups.push(Some(backup));
        }
        // 2. move everything into place
        for (k, (dest, tmp)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, dest) {
                let mut restored = Vec::new();
                let mut lost = Vec::new();
                for j in (0..k).rev() {
                    let (d, _) = &staged[j];
                    let back = match &backups[j] {
                        Some(b) => std::fs::rename(b, d),
                        None => std::fs::remove_file(d),
                    };
                    match back {
                        Ok(()) => restored.push(d.display().to_string()),
                        Err(_) => lost.push(d.display().to_string()),
                    }
                }
                drop_temps(&mut temps, &staged[k..]);
                for (_, tmp) in &staged[..k] {
                    temporaries::unregister(&mut temps, tmp);
                }
                remove_backups(&mut temps, &backups);
                let mut detail = format!("cannot move the new file into place: {e}");
                if !restored.is_empty() {
                    detail += &format!("; restored the previous {}", restored.join(", "));
                }
                if !lost.is_empty() {
                    detail += &format!(
                        "; could NOT restore {} (the new version is in place)",
                        lost.join(", ")
                    );
                }
                return Err(IoError::Write {
                    path: dest.clone(),
                    cause: std::io::Error::other(detail),
                });
            }
            temporaries::unregister(&mut temps, tmp);
        }
        // 3. the previous files are no longer needed
        remove_backups(&mut temps, &backups);
        let mut dirs: Vec<&Path> = staged.iter().filter_map(|(d, _)| d.parent()).collect();
        dirs.dedup();
        for dir in dirs {
            if let Ok(d) = std::fs::File::open(dir) {
                let _ = d.sync_all();
            }
        }
        Ok(staged.into_iter().map(|(d, _)| d).collect())
    }
}

fn remove_backups(temps: &mut Vec<PathBuf>, backups: &[Option<PathBuf>]) {
    for b in backups.iter().flatten() {
        let _ = std::fs::remove_file(b);
        temporaries::unregister(temps, b);
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if self.done {
            return;
        }
        let staged = lock_active().take().map(|a| a.staged).unwrap_or_default();
        for (_, tmp) in staged {
            temporaries::discard(&tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Output-set tests share the one process-wide staging slot.
    static SERIAL: Mutex<()> = Mutex::new(());

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("cassi-io-set-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn hidden(dir: &Path) -> Vec<String> {
        std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect()
    }

    #[test]
    fn collisions_name_both_paths_and_roles() {
        let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        let dir = scratch("collide");
        let input = dir.join("m.npy");
        std::fs::write(&input, b"measurement").unwrap();
        std::fs::hard_link(&input, dir.join("hard.npy")).unwrap();
        #[cfg(unix)]
        std::os::unix::fs::symlink("m.npy", dir.join("soft.npy")).unwrap();
        let dotted = dir.join("sub").join("..").join("m.npy");
        let missing = dir.join("nosuch").join("..").join("m.npy");
        let mut cases = vec![input.clone(), dir.join("hard.npy"), dotted, missing];
        #[cfg(unix)]
        cases.push(dir.join("soft.npy"));
        for out in cases {
            let mut set = OutputSet::new();
            std::fs::create_dir_all(dir.join("sub")).unwrap();
            set.input("the measurement", &input).output("-o", &out);
            let e = set.check().unwrap_err().to_string();
            assert!(e.contains("(-o)") && e.contains("(the measurement)"), "{e}");
            assert!(e.contains(&*out.to_string_lossy()), "{e}");
        }
        // two outputs, one file
        let mut set = OutputSet::new();
        set.output("-o", dir.join("a.json"))
            .output("the report", dir.join("a.json"));
        assert!(set.check().unwrap_err().to_string().contains("two outputs"));
        // an input inside an output folder
        let mut set = OutputSet::new();
        set.input("--mask", &input).output_dir("--out", &dir);
        assert!(
            set.check()
                .unwrap_err()
                .to_string()
                .contains("holds an input")
        );
        // fine: a new file beside the input, in a folder made by begin
        let mut set = OutputSet::new();
        set.input("--mask", &input)
            .output("-o", dir.join("new/deeper/out.npy"));
        let checked = set.check().unwrap();
        assert!(!dir.join("new").exists());
        drop(checked.begin().unwrap());
        assert!(dir.join("new/deeper").is_dir());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn commit_is_all_or_nothing() {
        let _g = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
        let dir = scratch("commit");
        let (a, b, c) = (dir.join("a.npy"), dir.join("a.json"), dir.join("a.png"));
        std::fs::write(&a, b"old a").unwrap();
        std::fs::write(&b, b"old b").unwrap();
        let mut set = OutputSet::new();
        set.output("-o", &a).output("json", &b).output("png", &c);
        let checked = set.check().unwrap();

        // dropped: nothing changes, no temporaries
        let staging = checked.begin().unwrap();
        crate::write_atomic(&a, b"new a").unwrap();
        crate::write_atomic(&b, b"new b").unwrap();
        assert!(output_exists(&a) && !c.exists());
        assert_eq!(staging.staged().len(), 2);
        drop(staging);
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));

        // an undeclared path is refused while staging
        let staging = checked.begin().unwrap();
        assert!(crate::write_atomic(dir.join("other.txt"), b"x").is_err());
        // a rename failing midway restores what was replaced
        crate::write_atomic(&a, b"new a").unwrap();
        crate::write_atomic(&b, b"new b").unwrap();
        crate::write_atomic(&c, b"new c").unwrap();
        // the last rename fails: its temporary is gone
        let c_tmp = hidden(&dir)
            .into_iter()
            .find(|n| n.starts_with(".a.png."))
            .unwrap();
        std::fs::remove_file(dir.join(c_tmp)).unwrap();
        let e = staging.commit().unwrap_err().to_string();
        assert!(e.contains("restored the previous"), "{e}");
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        assert!(!c.exists());
        assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));
        // a destination turned into a folder: refused before anything moves
        let staging = checked.begin().unwrap();
        crate::write_atomic(&a, b"new a").unwrap();
        crate::write_atomic(&c, b"new c").unwrap();
        std::fs::create_dir(&c).unwrap();
        std::fs::write(c.join("x"), b"in the way").unwrap();
        assert!(
            staging
                .commit()
                .unwrap_err()
                .to_string()
                .contains("nothing was replaced")
        );
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));
        std::fs::remove_dir_all(&c).unwrap();

        // committed: all new, no temporaries, the second write of a file wins
        let staging = checked.begin().unwrap();
        crate::write_atomic(&a, b"first").unwrap();
        crate::write_atomic(&a, b"new a").unwrap();
        crate::write_atomic(&b, b"new b").unwrap();
        crate::write_atomic(&c, b"new c").unwrap();
        assert_eq!(staging.commit().unwrap().len(), 3);
        assert_eq!(std::fs::read(&a).unwrap(), b"new a");
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
        assert_eq!(std::fs::read(&c).unwrap(), b"new c");
        assert!(hidden(&dir).is_empty(), "{:?}", hidden(&dir));
        assert!(
            !temporaries::lock_temps()
                .iter()
                .any(|t| t.starts_with(&dir))
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
