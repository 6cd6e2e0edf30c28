//! Opening a file of any supported format as a list of variables.

use std::path::Path;

use serde::Serialize;

use cassi_core::limits;

use crate::array::{VarInfo, element_count, list_vars, shape_str};
use crate::decode::Stats;
use crate::decode::{F32Sink, Sink, StatsSink};
use crate::error::{IoError, Result};
use crate::escape::esc;
use crate::mat5::Mat5;
use crate::mat73::Mat73;
use crate::npy::{Npy, Npz};

/// Largest variable `describe` reads for statistics.
pub(crate) const STATS_MAX: usize = 1 << 22;

/// Largest never-written HDF5 dataset (fill value only) that is materialised.
pub(crate) const UNSTORED_MAX: usize = 1 << 20;

/// The file formats cassi reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum FileFormat {
    /// MATLAB Level 5 MAT-file (`-v6`/`-v7`, compressed or not).
    #[serde(rename = "mat-v5")]
    MatV5,
    /// MATLAB v7.3 MAT-file (HDF5 behind a 512-byte MATLAB header).
    #[serde(rename = "mat-v7.3")]
    MatV73,
    /// NumPy `.npy`.
    #[serde(rename = "npy")]
    Npy,
    /// NumPy `.npz` (zip of `.npy`).
    #[serde(rename = "npz")]
    Npz,
}

impl std::fmt::Display for FileFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            FileFormat::MatV5 => "MATLAB v5 MAT-file",
            FileFormat::MatV73 => "MATLAB v7.3 MAT-file (HDF5)",
            FileFormat::Npy => "NumPy .npy",
            FileFormat::Npz => "NumPy .npz",
        })
    }
}

/// The format family an extension names (before looking at a .mat's header).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Ext {
    Mat,
    Npy,
    Npz,
}

pub(crate) fn extension(path: &Path, for_writing: bool) -> Result<Ext> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase());
    match ext.as_deref() {
        Some("mat") => Ok(Ext::Mat),
        Some("npy") => Ok(Ext::Npy),
        Some("npz") => Ok(Ext::Npz),
        other => {
            let what = match other {
                Some(e) => format!("the extension '.{e}' is not one of"),
                None => "the file name has no extension; expected one of".to_string(),
            };
            Err(IoError::UnknownFormat {
                path: path.to_path_buf(),
                detail: format!(
                    "{what} .mat, .npy, .npz{}",
                    if for_writing {
                        " (choose the output format by extension)"
                    } else {
                        ""
                    }
                ),
            })
        }
    }
}

/// An opened file.
pub(crate) enum Opened {
    Mat5(Mat5),
    Mat73(Mat73),
    Npy(Npy),
    Npz(Npz),
}

fn read_all(path: &Path) -> Result<Vec<u8>> {
    if path.is_dir() {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: "is a directory, not a file".into(),
        });
    }
    std::fs::read(path).map_err(|e| IoError::from_read(path, e))
}

const HDF5_MAGIC: &[u8; 8] = b"\x89HDF\r\n\x1a\n";

impl Opened {
    pub(crate) fn open(path: &Path) -> Result<Self> {
        match extension(path, false)? {
            Ext::Npy => Ok(Opened::Npy(Npy::parse(path, read_all(path)?)?)),
            Ext::Npz => {
                if !path.exists() {
                    return Err(IoError::NotFound {
                        path: path.to_path_buf(),
                    });
                }
                Ok(Opened::Npz(Npz::open(path)?))
            }
            Ext::Mat => {
                let bytes = read_all(path)?;
                let is_hdf5 = |at: usize| bytes.get(at..at + 8) == Some(&HDF5_MAGIC[..]);
                let v73_text = bytes.starts_with(b"MATLAB 7.3");
                if is_hdf5(0) || is_hdf5(512) || (v73_text && bytes.len() >= 128) {
                    return Ok(Opened::Mat73(Mat73::parse(path, bytes)?));
                }
                if bytes.len() < 128 {
                    return Err(if bytes.starts_with(b"MATLAB") || bytes.is_empty() {
                        IoError::Truncated {
                            path: path.to_path_buf(),
                            format: "MATLAB MAT-file",
                            detail: format!(
                                "{} bytes, shorter than the 128-byte header",
                                bytes.len()
                            ),
                        }
                    } else {
                        IoError::Corrupt {
                            path: path.to_path_buf(),
                            format: "MATLAB MAT-file",
                            detail: format!("only {} bytes and no MATLAB header", bytes.len()),
                        }
                    });
                }
                if crate::mat5::header_endian(&bytes).is_some() {
                    return Ok(Opened::Mat5(Mat5::parse(path, bytes)?));
                }
                let detail = if bytes.starts_with(b"MATLAB") {
                    "the MATLAB header has an unknown version (supported: v5/v6/v7 and v7.3)"
                        .to_string()
                } else {
                    "no MATLAB v5 header and no HDF5 signature (MATLAB v4 files and text files are not supported)"
                        .to_string()
                };
                Err(IoError::Corrupt {
                    path: path.to_path_buf(),
                    format: "MATLAB MAT-file",
                    detail,
                })
            }
        }
    }

    fn format_name(&self) -> &'static str {
        match self {
            Opened::Mat5(_) => "MATLAB v5 MAT-file",
            Opened::Mat73(_) => "MATLAB v7.3 MAT-file (HDF5)",
            Opened::Npy(_) => "NumPy .npy file",
            Opened::Npz(_) => "NumPy .npz file",
        }
    }

    pub(crate) fn format(&self) -> FileFormat {
        match self {
            Opened::Mat5(_) => FileFormat::MatV5,
            Opened::Mat73(_) => FileFormat::MatV73,
            Opened::Npy(_) => FileFormat::Npy,
            Opened::Npz(_) => FileFormat::Npz,
        }
    }

    pub(crate) fn vars(&self) -> Vec<VarInfo> {
        match self {
            Opened::Mat5(m) => m.vars(),
            Opened::Mat73(m) => m.vars(),
            Opened::Npy(n) => n.vars(),
            Opened::Npz(n) => n.vars(),
        }
    }

    /// Hands variable `i`'s stored bytes to `sink` (see each reader).
    fn stream(&mut self, path: &Path, i: usize, sink: &mut dyn Sink) -> Result<()> {
        match self {
            Opened::Mat5(m) => m.stream(path, i, sink),
            Opened::Mat73(m) => m.stream(path, i, sink),
            Opened::Npy(n) => n.stream(path, sink),
            Opened::Npz(n) => n.stream(path, i, sink),
        }
    }

    /// Why variable `info` cannot be materialised as it is declared, before
    /// anything is allocated for it: an HDF5 dataset that stores nothing but
    /// declares many elements, or a shape over the element budget. Returns
    /// the element count otherwise.
    pub(crate) fn check_size(&self, path: &Path, info: &VarInfo) -> Result<usize> {
        let count = element_count(&info.shape);
        if info.unstored && count.is_none_or(|n| n > UNSTORED_MAX) {
            return Err(IoError::core(
                path,
                cassi_core::CassiError::TooLarge {
                    what: format!(
                        "variable '{}' ({} {})",
                        esc(&info.name),
                        shape_str(&info.shape),
                        esc(&info.dtype)
                    ),
                    detail: format!(
                        "it declares {} elements but stores none (the dataset was never \
                         written, only its fill value exists); refusing to materialise more \
                         than {UNSTORED_MAX} fill values",
                        count.map_or("more than 2^64".to_string(), |n| n.to_string()),
                    ),
                },
            ));
        }
        if let (Some(n), Some(el), Some(max)) = (count, info.elem, info.max_bytes)
            && (n as u64).saturating_mul(el.size as u64) > max
        {
            return Err(IoError::Truncated {
                path: path.to_path_buf(),
                format: self.format_name(),
                detail: format!(
                    "variable '{}' ({} {}) declares {n} elements ({} bytes) but the file holds \
                     at most {max} bytes for it",
                    info.name,
                    shape_str(&info.shape),
                    info.dtype,
                    (n as u64).saturating_mul(el.size as u64)
                ),
            });
        }
        let what = format!(
            "variable '{}' ({} {})",
            esc(&info.name),
            shape_str(&info.shape),
            esc(&info.dtype)
        );
        limits::check_elements(&what, &info.shape, "as declared in the file")
            .map_err(|e| IoError::core(path, e))
    }

    /// Decodes variable `i` into C-order f32, checked finite and in range,
    /// after checking its declared size (see [`Opened::check_size`]).
    pub(crate) fn read_f32(&mut self, path: &Path, i: usize, info: &VarInfo) -> Result<Vec<f32>> {
        let Some(el) = info.elem else {
            return Err(IoError::UnsupportedType {
                path: path.to_path_buf(),
                name: info.name.clone(),
                dtype: info.dtype.clone(),
                hint: info.note.clone(),
            });
        };
        let count = self.check_size(path, info)?;
        let mut sink = F32Sink::new(el, &info.shape, count, info.fortran);
        self.stream(path, i, &mut sink)?;
        sink.finish(path, &info.name)
    }

    /// Statistics of numeric variable `i`, or why they were skipped: only
    /// variables of at most [`STATS_MAX`] elements, within the budget and
    /// with their bytes present are read (streamed: nothing is allocated
    /// per element).
    pub(crate) fn stats(
        &mut self,
        path: &Path,
        i: usize,
        info: &VarInfo,
    ) -> Result<std::result::Result<Stats, String>> {
        let Some(el) = info.elem else {
            // A MATLAB empty array: no values.
            return Ok(Ok(Stats {
                count: 0,
                min: None,
                max: None,
                mean: None,
                non_finite: 0,
            }));
        };
        let count = match self.check_size(path, info) {
            Ok(n) => n,
            Err(e) => {
                // The reason, without the file name (the summary names it).
                let msg = e.to_string();
                let prefix = format!("{}: ", path.display());
                return Ok(Err(msg.strip_prefix(&prefix).unwrap_or(&msg).to_string()));
            }
        };
        if count > STATS_MAX {
            return Ok(Err(format!(
                "{count} elements, more than the {STATS_MAX} read for statistics"
            )));
        }
        let mut sink = StatsSink::new(el);
        self.stream(path, i, &mut sink)?;
        Ok(Ok(sink.finish()))
    }

    /// Picks the variable to load: by name, or the only numeric one.
    pub(crate) fn select(&self, path: &Path, var: Option<&str>) -> Result<(usize, VarInfo)> {
        let vars = self.vars();
        let chosen = match var {
            // A .npy holds one unnamed array: any name selects it.
            Some(_) if matches!(self, Opened::Npy(_)) => vars.first().map(|v| (0, v.clone())),
            Some(name) => vars
                .iter()
                .position(|v| v.name == name)
                .map(|i| (i, vars[i].clone())),
            None => {
                let numeric: Vec<usize> = (0..vars.len()).filter(|&i| vars[i].numeric).collect();
                match numeric.as_slice() {
                    [i] => Some((*i, vars[*i].clone())),
                    [] if vars.is_empty() => {
                        return Err(IoError::AmbiguousVariable {
                            path: path.to_path_buf(),
                            reason: "the file holds no variables".into(),
                            present: list_vars(&vars),
                        });
                    }
                    [] => {
                        return Err(IoError::AmbiguousVariable {
                            path: path.to_path_buf(),
                            reason: "the file holds no numeric variable".into(),
                            present: list_vars(&vars),
                        });
                    }
                    many => {
                        return Err(IoError::AmbiguousVariable {
                            path: path.to_path_buf(),
                            reason: format!(
                                "no variable name given and the file holds {} numeric variables",
                                many.len()
                            ),
                            present: list_vars(&vars),
                        });
                    }
                }
            }
        };
        let Some((i, info)) = chosen else {
            return Err(IoError::VariableNotFound {
                path: path.to_path_buf(),
                name: var.unwrap_or_default().to_string(),
                present: list_vars(&vars),
            });
        };
        if !info.numeric {
            return Err(IoError::UnsupportedType {
                path: path.to_path_buf(),
                name: info.name.clone(),
                dtype: info.dtype.clone(),
                hint: info.note.clone(),
            });
        }
        Ok((i, info))
    }
}
