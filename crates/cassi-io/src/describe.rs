//! `cassi info FILE`: what a file holds.

use std::fmt;
use std::path::Path;

use serde::Serialize;

use crate::array::shape_str;
use crate::decode::Stats;
use crate::error::Result;
use crate::escape::esc;
use crate::open::{FileFormat, Opened};

/// One variable of a file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VariableSummary {
    pub name: String,
    /// Shape as the file's own tool shows it (empty for a group/struct in v7.3).
    pub shape: Vec<usize>,
    /// Element type in the file's vocabulary (MATLAB class or NumPy dtype).
    pub dtype: String,
    /// Whether cassi can load it as numbers.
    pub numeric: bool,
    /// Present for numeric variables whose values were read (see [`describe`]).
    pub stats: Option<Stats>,
    /// Why the statistics of a numeric variable were not computed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stats_skipped: Option<String>,
    /// Why a variable is not loadable, if it is not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// What `describe` found in a file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FileSummary {
    pub path: String,
    pub format: FileFormat,
    pub variables: Vec<VariableSummary>,
}

/// Lists the variables of a `.mat` (v5 or v7.3), `.npy` or `.npz` file with
/// shape and element type, from the headers. Statistics (min/max/mean and the
/// count of non-finite values) are computed, streaming, only for numeric
/// variables of at most 2^22 elements that are within the element budget and
/// whose bytes are present; for the others `stats_skipped` says why.
pub fn describe(path: impl AsRef<Path>) -> Result<FileSummary> {
    let path = path.as_ref();
    let mut file = Opened::open(path)?;
    let vars = file.vars();
    let mut out = Vec::with_capacity(vars.len());
    for (i, v) in vars.into_iter().enumerate() {
        let (stats, stats_skipped) = if v.numeric {
            match file.stats(path, i, &v)? {
                Ok(s) => (Some(s), None),
                Err(why) => (None, Some(why)),
            }
        } else {
            (None, None)
        };
        out.push(VariableSummary {
            stats_skipped,
            note: (!v.note.is_empty()).then(|| v.note.clone()),
            name: v.name,
            shape: v.shape,
            dtype: v.dtype,
            numeric: v.numeric,
            stats,
        });
    }
    Ok(FileSummary {
        path: path.display().to_string(),
        format: file.format(),
        variables: out,
    })
}

fn num(x: Option<f64>) -> String {
    match x {
        None => "-".into(),
        Some(v) if v == v.trunc() && v.abs() < 1e15 => format!("{v}"),
        Some(v) if v.abs() >= 1e-3 && v.abs() < 1e6 => format!("{v:.6}")
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string(),
        Some(v) => format!("{v:.4e}"),
    }
}

impl fmt::Display for FileSummary {
    /// ```text
    /// data/mask.mat: MATLAB v5 MAT-file, 2 variables
    ///   name   shape    type    min  max  mean      non-finite
    ///   mask   256×256  single  0    1    0.561234  0
    ///   note   1×6      char    (a MATLAB char is not a numeric array)
    /// ```
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.variables.len();
        writeln!(
            f,
            "{}: {}, {} variable{}",
            esc(&self.path),
            self.format,
            n,
            if n == 1 { "" } else { "s" }
        )?;
        if n == 0 {
            return Ok(());
        }
        let rows: Vec<[String; 7]> = self
            .variables
            .iter()
            .map(|v| {
                let shape = if v.shape.is_empty() && !v.numeric {
                    "-".to_string()
                } else {
                    shape_str(&v.shape)
                };
                let (name, dtype) = (esc(&v.name).into_owned(), esc(&v.dtype).into_owned());
                match &v.stats {
                    Some(s) => [
                        name,
                        shape,
                        dtype,
                        num(s.min),
                        num(s.max),
                        num(s.mean),
                        s.non_finite.to_string(),
                    ],
                    None => [
                        name,
                        shape,
                        dtype,
                        match (&v.stats_skipped, &v.note) {
                            (Some(why), _) => format!("(stats skipped: {})", esc(why)),
                            (None, note) => {
                                format!("({})", esc(note.as_deref().unwrap_or("not numeric")))
                            }
                        },
                        String::new(),
                        String::new(),
                        String::new(),
                    ],
                }
            })
            .collect();
        let head = ["name", "shape", "type", "min", "max", "mean", "non-finite"].map(String::from);
        let mut width = [0usize; 7];
        for r in std::iter::once(&head).chain(rows.iter()) {
            // A non-numeric row's note spans the stats columns: do not widen them.
            let spans = r[4].is_empty() && r[3].starts_with('(');
            for (k, cell) in r.iter().enumerate() {
                if spans && k >= 3 {
                    continue;
                }
                width[k] = width[k].max(cell.chars().count());
            }
        }
        for r in std::iter::once(&head).chain(rows.iter()) {
            let mut line = String::from(" ");
            for (k, cell) in r.iter().enumerate() {
                line.push(' ');
                line.push_str(cell);
                if k + 1 < r.len() {
                    let pad = width[k].saturating_sub(cell.chars().count()) + 1;
                    line.push_str(&" ".repeat(pad));
                }
            }
            writeln!(f, "{}", line.trim_end())?;
        }
        Ok(())
    }
}
