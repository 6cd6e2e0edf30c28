//! Where tests find the public data: `../shared/data` beside the checkout
//! (masks, real measurements, CAVE scenes, network weights and PyTorch test
//! vectors), or the folder named by `$CASSI_SHARED_DATA`. It is not part of
//! the repository, so a test that needs it asks [`for_test`] and returns
//! early when it is missing; CI sets `CASSI_REQUIRE_SHARED_DATA=1` so that
//! missing data fails the run instead of passing it silently.

use std::ffi::OsString;
use std::path::{Component, Path, PathBuf};

/// The variable naming the data folder (no fallback when it is set).
pub const DIR_VAR: &str = "CASSI_SHARED_DATA";
/// The variable that turns a missing folder from a skip into a failure.
pub const REQUIRE_VAR: &str = "CASSI_REQUIRE_SHARED_DATA";

/// `$CASSI_SHARED_DATA` when set, else `../shared/data` beside the workspace
/// (resolved from this crate's source folder at build time). It may not
/// exist; the benchmark binaries use it as their default `--data`.
pub fn default_dir() -> PathBuf {
    dir_from(std::env::var_os(DIR_VAR))
}

/// The data folder for the calling test, when it and each of `needs`
/// (paths inside it, such as `"nets"` or `"scenes"`) exist.
///
/// Otherwise prints a note naming the test and the missing path and
/// returns `None`, so the test can return and pass; but when
/// `CASSI_REQUIRE_SHARED_DATA` is set (to anything but `0` or empty) it
/// panics with the folder it looked in and how to point it elsewhere.
pub fn for_test(needs: &[&str]) -> Option<PathBuf> {
    let dir = default_dir();
    let Some(missing) = missing(&dir, needs) else {
        return Some(dir);
    };
    let why = absence_message(&missing, std::env::var_os(DIR_VAR).is_some());
    if required(std::env::var_os(REQUIRE_VAR)) {
        panic!("{why}; {REQUIRE_VAR} is set, so the test fails instead of skipping");
    }
    let thread = std::thread::current();
    let test = thread.name().unwrap_or("a test");
    eprintln!("note: {test}: {why}; skipping");
    None
}

fn dir_from(var: Option<OsString>) -> PathBuf {
    match var {
        Some(d) => PathBuf::from(d),
        None => {
            lexically_normal(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
        }
    }
}

/// The first of `dir`, `dir/need`… that does not exist; `None` when all do.
fn missing(dir: &Path, needs: &[&str]) -> Option<PathBuf> {
    std::iter::once(dir.to_path_buf())
        .chain(needs.iter().map(|n| dir.join(n)))
        .find(|p| !p.exists())
}

fn absence_message(missing: &Path, from_var: bool) -> String {
    let source = if from_var {
        format!("named by ${DIR_VAR}")
    } else {
        format!("the default; set {DIR_VAR} to use another folder")
    };
    format!(
        "the shared test data is missing: {} does not exist ({source})",
        missing.display()
    )
}

fn required(var: Option<OsString>) -> bool {
    var.is_some_and(|v| !v.is_empty() && v != "0")
}

/// `a/b/../c` → `a/c`, without touching the file system (so the note names
/// the folder even when it does not exist).
fn lexically_normal(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::ParentDir if out.file_name().is_some() => {
                out.pop();
            }
            Component::CurDir => {}
            c => out.push(c),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_variable_names_the_folder_without_fallback() {
        let d = dir_from(Some("/nonexistent/data".into()));
        assert_eq!(d, Path::new("/nonexistent/data"));
        assert_eq!(missing(&d, &[]), Some(d.clone()));
        assert_eq!(missing(&d, &["nets"]), Some(d));
    }

    #[test]
    fn the_default_is_shared_data_beside_the_workspace() {
        let d = dir_from(None);
        assert!(d.ends_with("shared/data"), "{}", d.display());
        assert!(!d.components().any(|c| c == Component::ParentDir));
        let workspace = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let beside = workspace.join("../shared/data");
        assert_eq!(d.exists(), beside.exists());
    }

    #[test]
    fn the_first_missing_path_is_reported() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
        assert_eq!(missing(dir, &[]), None);
        assert_eq!(missing(dir, &["src", "Cargo.toml"]), None);
        assert_eq!(
            missing(dir, &["src", "no-such", "also-not"]),
            Some(dir.join("no-such"))
        );
    }

    #[test]
    fn the_message_names_the_folder_and_the_variable() {
        let m = absence_message(Path::new("/x/shared/data/nets"), false);
        assert!(
            m.contains("/x/shared/data/nets") && m.contains(DIR_VAR),
            "{m}"
        );
        let m = absence_message(Path::new("/y"), true);
        assert!(m.contains("/y") && m.contains("$CASSI_SHARED_DATA"), "{m}");
    }

    #[test]
    fn only_a_set_nonzero_variable_requires_the_data() {
        assert!(!required(None));
        assert!(!required(Some("".into())));
        assert!(!required(Some("0".into())));
        assert!(required(Some("1".into())));
        assert!(required(Some("yes".into())));
    }

    #[test]
    fn dot_dot_is_resolved_lexically() {
        assert_eq!(
            lexically_normal(Path::new("/a/b/c/../../d/./e")),
            Path::new("/a/d/e")
        );
        assert_eq!(lexically_normal(Path::new("/..")), Path::new("/.."));
    }
}
