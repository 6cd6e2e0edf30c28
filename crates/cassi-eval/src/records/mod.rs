//! The files cassi writes to be read back — the calibration file, the
//! simulation sidecar, a study's per-scene results and its summary — as
//! typed records in one place. Each carries a header, `format` (its kind)
//! and `version`, flattened into its JSON object so readers of the fields
//! see the same object as before. One reader ([`read_record`]) says, naming
//! the file, what is wrong with one it cannot read; one writer
//! ([`write_record`]) adds the header. Files written before the header
//! existed are read as version 0 when their shape is the record's.

mod calibration;
mod simulation;
mod study;

use std::path::{Path, PathBuf};

use serde::Serialize;
use serde::de::DeserializeOwned;
use serde_json::Value;

pub use simulation::{MeasurementInfo, SimulationRecord, Source, sidecar_path};
pub use study::{SceneRecord, StudySetup, SummaryRecord};

/// A record kind: its header and its shape before the header existed. The
/// header's keys share the record's object, so no record has a field named
/// `format` or `version`.
pub trait Record: Serialize + DeserializeOwned {
    /// The header's `format` name, e.g. `"cassi-calibration"`.
    const FORMAT: &'static str;
    /// The version this build writes, and the newest it reads.
    const VERSION: u64;
    /// Keys every file of this kind has had, header or not: how a file
    /// written before the header (version 0) is recognised.
    const KEYS: &'static [&'static str];
}

/// Every kind, to name the kind of a file read as another.
const KINDS: [(&str, &[&str]); 4] = [
    (
        cassi_core::calib::Calibration::FORMAT,
        <cassi_core::calib::Calibration as Record>::KEYS,
    ),
    (SimulationRecord::FORMAT, SimulationRecord::KEYS),
    (SceneRecord::FORMAT, SceneRecord::KEYS),
    (SummaryRecord::FORMAT, SummaryRecord::KEYS),
];

/// Why a file is not the record asked for; every message names the file
/// and holds the whole reason (no separate error source).
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    #[error("cannot read {}: {error}", path.display())]
    Read {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{}: not valid JSON ({error})", path.display())]
    NotJson {
        path: PathBuf,
        error: serde_json::Error,
    },
    #[error("{}: not a {expected} file: it holds {found}, not a JSON object", path.display())]
    NotObject {
        path: PathBuf,
        expected: &'static str,
        found: &'static str,
    },
    #[error("{} is a {found} record, not a {expected} file", path.display())]
    OtherKind {
        path: PathBuf,
        found: String,
        expected: &'static str,
    },
    #[error("{}: invalid record header: {detail}", path.display())]
    BadHeader { path: PathBuf, detail: String },
    #[error(
        "{} is a {format} file of version {version}, written by a newer cassi; \
         this build reads versions up to {supported}",
        path.display()
    )]
    Newer {
        path: PathBuf,
        format: &'static str,
        version: u64,
        supported: u64,
    },
    #[error("{}: invalid {format} file (version {version}): {error}", path.display())]
    Invalid {
        path: PathBuf,
        format: &'static str,
        version: u64,
        error: serde_json::Error,
    },
    #[error(
        "{}: not a {expected} file: it has no \"format\" header, and as one written \
         before headers existed: {error}",
        path.display()
    )]
    Unrecognised {
        path: PathBuf,
        expected: &'static str,
        error: serde_json::Error,
    },
}

impl RecordError {
    /// The file does not exist (as opposed to existing and being wrong).
    pub fn is_missing(&self) -> bool {
        matches!(self, Self::Read { error, .. } if error.kind() == std::io::ErrorKind::NotFound)
    }
}

/// A record and the version it was read as (0: written before headers).
#[derive(Debug, Clone)]
pub struct Versioned<R> {
    pub version: u64,
    pub record: R,
}

/// A JSON file, read once, to be identified ([`JsonFile::format`]) and
/// then parsed as a record ([`JsonFile::parse`]).
#[derive(Debug, Clone)]
pub struct JsonFile {
    path: PathBuf,
    value: Value,
}

impl JsonFile {
    pub fn read(path: impl AsRef<Path>) -> Result<Self, RecordError> {
        let path = path.as_ref().to_path_buf();
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(error) => return Err(RecordError::Read { path, error }),
        };
        match serde_json::from_str(&text) {
            Ok(value) => Ok(Self { path, value }),
            Err(error) => Err(RecordError::NotJson { path, error }),
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    pub fn value(&self) -> &Value {
        &self.value
    }

    /// The record kind: the header's `format`, or for a file without one,
    /// the kind whose keys it has; `None` when neither (or not an object).
    /// A `format` that is not a string is an error.
    pub fn format(&self) -> Result<Option<&str>, RecordError> {
        let Some(object) = self.value.as_object() else {
            return Ok(None);
        };
        match object.get("format") {
            Some(Value::String(f)) => Ok(Some(f)),
            Some(other) => Err(RecordError::BadHeader {
                path: self.path.clone(),
                detail: format!("\"format\" must be a string, got {}", json_kind(other)),
            }),
            None => Ok(KINDS
                .iter()
                .find(|(_, keys)| keys.iter().all(|k| object.contains_key(*k)))
                .map(|(format, _)| *format)),
        }
    }

    /// The file as an `R`, with the version it was written as.
    pub fn parse<R: Record>(&self) -> Result<Versioned<R>, RecordError> {
        let path = || self.path.clone();
        let Some(object) = self.value.as_object() else {
            return Err(RecordError::NotObject {
                path: path(),
                expected: R::FORMAT,
                found: json_kind(&self.value),
            });
        };
        let headed = object.contains_key("format");
        let format = self.format()?;
        if let Some(found) = format
            && found != R::FORMAT
        {
            return Err(RecordError::OtherKind {
                path: path(),
                found: found.to_string(),
                expected: R::FORMAT,
            });
        }
        let version = if headed {
            header_version(object).map_err(|detail| RecordError::BadHeader {
                path: path(),
                detail,
            })?
        } else {
            0
        };
        if version > R::VERSION {
            return Err(RecordError::Newer {
                path: path(),
                format: R::FORMAT,
                version,
                supported: R::VERSION,
            });
        }
        let mut fields = object.clone();
        if headed {
            fields.remove("format");
            fields.remove("version");
        }
        match serde_json::from_value(Value::Object(fields)) {
            Ok(record) => Ok(Versioned { version, record }),
            Err(error) if format.is_some() => Err(RecordError::Invalid {
                path: path(),
                format: R::FORMAT,
                version,
                error,
            }),
            Err(error) => Err(RecordError::Unrecognised {
                path: path(),
                expected: R::FORMAT,
                error,
            }),
        }
    }
}

/// The header's `version` (its `format` is checked by [`JsonFile::format`]).
fn header_version(object: &serde_json::Map<String, Value>) -> Result<u64, String> {
    match object.get("version") {
        Some(v) => v
            .as_u64()
            .ok_or_else(|| format!("\"version\" must be a whole number ≥ 0, got {v}")),
        None => Err("\"format\" is given but \"version\" is missing".into()),
    }
}

/// The record at `path`, of any version this build reads.
pub fn read_record<R: Record>(path: impl AsRef<Path>) -> Result<R, RecordError> {
    Ok(JsonFile::read(path)?.parse()?.record)
}

/// The record at `path` and the version it was written as.
pub fn read_versioned<R: Record>(path: impl AsRef<Path>) -> Result<Versioned<R>, RecordError> {
    JsonFile::read(path)?.parse()
}

/// The header and the record's fields in one object.
#[derive(Serialize)]
struct Headed<'a, R> {
    format: &'static str,
    version: u64,
    #[serde(flatten)]
    record: &'a R,
}

/// The record as written: pretty JSON with its header, and a final newline.
pub fn to_json<R: Record>(record: &R) -> serde_json::Result<String> {
    let headed = Headed {
        format: R::FORMAT,
        version: R::VERSION,
        record,
    };
    Ok(serde_json::to_string_pretty(&headed)? + "\n")
}

/// Writes the record with its header, atomically.
pub fn write_record<R: Record>(path: impl AsRef<Path>, record: &R) -> anyhow::Result<()> {
    let path = path.as_ref();
    let text = to_json(record).map_err(|e| {
        anyhow::anyhow!(
            "serialising the {} record for {}: {e}",
            R::FORMAT,
            path.display()
        )
    })?;
    cassi_io::write_atomic(path, text.as_bytes())?;
    Ok(())
}

/// "an array", "a string", … for messages.
pub fn json_kind(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}
