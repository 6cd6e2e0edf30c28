//! `--band-offsets FILE`: a table of each band's position along the
//! dispersion (a monochromator scan of the camera, or the shape the
//! band-shift bench measured), read as [`BandOffsets`] — its own line
//! through band 0 removed, which the calibration's dx and a1 carry.

use std::path::Path;

use anyhow::{Context, bail};
use cassi_core::optics::BandOffsets;

/// The table in `path` (.npy, .npz or .mat: a vector, `var` naming it where
/// the file holds several; .txt or .csv: numbers separated by spaces,
/// commas or new lines, `#` starting a comment), one value per band of
/// `bands`; `stride` the nominal dispersion its slope is checked against.
pub fn load_band_offsets(
    path: &Path,
    var: Option<&str>,
    bands: usize,
    stride: f64,
) -> anyhow::Result<BandOffsets> {
    let text = matches!(
        path.extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref(),
        Some("txt" | "csv")
    );
    let (values, what) = if text {
        if var.is_some() {
            bail!(
                "{}: --band-offsets-var names a variable; a text table has none",
                path.display()
            );
        }
        (read_text(path)?, "the table".to_string())
    } else {
        let a = cassi_io::load_array(path, var)?;
        let vector = match a.shape.as_slice() {
            [_] => true,
            [r, c] => *r == 1 || *c == 1,
            _ => false,
        };
        if !vector {
            bail!(
                "{}: variable {:?} has shape {:?}, expected a vector of {bands} values (one \
                 position per band)",
                path.display(),
                a.name,
                a.shape
            );
        }
        let values = a.data.iter().map(|&v| v as f64).collect();
        (values, format!("variable {:?}", a.name))
    };
    if values.len() != bands {
        // a table with a band-index column reads as twice the bands
        let columns = if text && values.len() == 2 * bands {
            "; a text table is the positions alone, no band-index column"
        } else {
            ""
        };
        bail!(
            "{}: {what} holds {} values, expected {bands} (one position per band of the \
             cube{columns})",
            path.display(),
            values.len()
        );
    }
    BandOffsets::from_table(&values, stride).with_context(|| format!("{}: {what}", path.display()))
}

fn read_text(path: &Path) -> anyhow::Result<Vec<f64>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read the band table", path.display()))?;
    let mut values = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for word in line
            .split(|c: char| c == ',' || c.is_whitespace())
            .filter(|w| !w.is_empty())
        {
            let v: f64 = word.parse().with_context(|| {
                format!(
                    "{}: line {}: {word:?} is not a number",
                    path.display(),
                    i + 1
                )
            })?;
            values.push(v);
        }
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn tables_are_read_in_each_format_and_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("cassi-band-table-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let positions: Vec<f64> = (0..4).map(|k| 2.0 * k as f64).collect();
        let txt = write(
            dir.as_path(),
            "t.txt",
            "# band positions, px\n0, 2.0\n4.3 # bowed\n6\n",
        );
        let o = load_band_offsets(&txt, None, 4, 2.0).unwrap();
        assert_eq!(o.bands(), 4);
        assert!(o.rms() > 0.05);
        let npy = dir.as_path().join("t.npy");
        let data: Vec<f32> = positions.iter().map(|&v| v as f32).collect();
        cassi_io::save_array(&npy, "t", &[1, 4], &data).unwrap();
        let straight = load_band_offsets(&npy, None, 4, 2.0).unwrap();
        assert!(straight.rms() < 1e-6);
        let refused = |p: &Path, bands| load_band_offsets(p, None, bands, 2.0).unwrap_err();
        let e = format!("{:#}", refused(&npy, 28));
        assert!(
            e.contains("t.npy") && e.contains("4 values, expected 28"),
            "{e}"
        );
        let cube = dir.as_path().join("c.npy");
        cassi_io::save_array(&cube, "c", &[2, 2, 2], &[0.0; 8]).unwrap();
        let e = format!("{:#}", refused(&cube, 8));
        assert!(e.contains("c.npy") && e.contains("[2, 2, 2]"), "{e}");
        let bad = write(dir.as_path(), "b.csv", "0, 2, x\n");
        let e = format!("{:#}", refused(&bad, 3));
        assert!(e.contains("b.csv: line 1") && e.contains("\"x\""), "{e}");
        let indexed = write(dir.as_path(), "i.csv", "0, 0\n1, 2\n2, 4.3\n3, 6\n");
        let e = format!("{:#}", refused(&indexed, 4));
        assert!(
            e.contains("8 values, expected 4") && e.contains("band-index column"),
            "{e}"
        );
        let nm = write(dir.as_path(), "nm.txt", "450 457 464 471\n");
        let e = format!("{:#}", refused(&nm, 4));
        assert!(e.contains("nm.txt") && e.contains("wavelengths"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
