//! Atomic file writes: write a hidden temporary file in the destination's
//! directory, flush it to disk, then rename it over the destination. A crash
//! or Ctrl-C leaves either the old file or the complete new one (plus, at
//! worst, a stray `.NAME.tmp…` file), never a half-written output.

use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{IoError, Result};

static COUNTER: AtomicU64 = AtomicU64::new(0);

/// Removes the temporary file unless the write completed.
struct TempGuard {
    path: PathBuf,
    armed: bool,
}

impl Drop for TempGuard {
    fn drop(&mut self) {
        if self.armed {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// Writes the file at `path` atomically; `fill` writes the content.
pub(crate) fn write_with(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&File>) -> std::io::Result<()>,
) -> Result<()> {
    let file_name = path.file_name().ok_or_else(|| IoError::InvalidArgument {
        path: path.to_path_buf(),
        reason: "the output path has no file name".into(),
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if path.is_dir() {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: "the output path is a directory".into(),
        });
    }
    let (file, tmp) = loop {
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(
            ".{}.tmp{}-{}",
            file_name.to_string_lossy(),
            std::process::id(),
            n
        ));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => break (f, tmp),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(IoError::write(path, e)),
        }
    };
    let mut guard = TempGuard {
        path: tmp.clone(),
        armed: true,
    };
    let result = (|| {
        let mut w = BufWriter::new(&file);
        fill(&mut w)?;
        w.flush()?;
        drop(w);
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    drop(file);
    match result {
        Ok(()) => {
            guard.armed = false;
            Ok(())
        }
        Err(e) => Err(IoError::write(path, e)),
    }
}

/// Writes `bytes` to `path` atomically.
pub(crate) fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_with(path, |w| w.write_all(bytes))
}
