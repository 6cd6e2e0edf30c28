//! Atomic file writes: write a hidden temporary file in the destination's
//! directory, flush it to disk, then rename it over the destination. A crash
//! or Ctrl-C leaves either the old file or the complete new one, never a
//! half-written output.
//!
//! When a write replaces an existing file, the new file gets the old one's
//! permission bits. A destination that is a symbolic link is followed: the
//! file it points to is replaced and the link stays.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{IoError, Result};
use crate::temporaries::{discard, lock_temps, new_temp, sweep_once, unregister};

/// Gives `tmp` the permission bits of `dest` when `dest` exists.
fn keep_permissions(dest: &Path, tmp: &Path) -> std::io::Result<()> {
    match std::fs::metadata(dest) {
        Ok(meta) => std::fs::set_permissions(tmp, meta.permissions()),
        Err(_) => Ok(()),
    }
}

/// Writes the file at `path` atomically; `fill` writes the content. While an
/// output set is being staged (see [`crate::OutputSet`]), the finished
/// temporary is handed to the set instead of being renamed.
pub(crate) fn write_with(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&File>) -> std::io::Result<()>,
) -> Result<()> {
    if path.file_name().is_none() {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: "the output path has no file name".into(),
        });
    }
    // the file a symbolic link points to is the one replaced
    let target = crate::output_set::resolve(path).map_err(|e| IoError::write(path, e))?;
    if target.is_dir() {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: "the output path is a directory".into(),
        });
    }
    let staged = crate::output_set::claim(path, &target)?;
    let file_name = target.file_name().expect("resolved paths end in a name");
    let dir = match target.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    sweep_once(&dir);
    let (file, tmp) = new_temp(&dir, file_name).map_err(|e| IoError::write(path, e))?;
    let result = (|| {
        let mut w = BufWriter::new(&file);
        fill(&mut w)?;
        w.flush()?;
        drop(w);
        file.sync_all()?;
        keep_permissions(&target, &tmp)
    })();
    drop(file);
    if let Err(e) = result {
        discard(&tmp);
        return Err(IoError::write(path, e));
    }
    if staged {
        return crate::output_set::record(path, target, tmp);
    }
    let mut temps = lock_temps();
    match std::fs::rename(&tmp, &target) {
        Ok(()) => {
            unregister(&mut temps, &tmp);
            Ok(())
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            unregister(&mut temps, &tmp);
            Err(IoError::write(path, e))
        }
    }
}

/// Writes `bytes` to `path` atomically.
pub(crate) fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with(path, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn replacing_keeps_permissions_and_follows_links() {
        use std::os::unix::fs::PermissionsExt;
        let dir = std::env::temp_dir().join(format!("cassi-io-perm-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("a.json");
        std::fs::write(&file, b"old").unwrap();
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o640)).unwrap();
        write_bytes(&file, b"new").unwrap();
        assert_eq!(std::fs::read(&file).unwrap(), b"new");
        let mode = std::fs::metadata(&file).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o640);
        let link = dir.join("link.json");
        std::os::unix::fs::symlink("a.json", &link).unwrap();
        write_bytes(&link, b"through the link").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&file).unwrap(), b"through the link");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
