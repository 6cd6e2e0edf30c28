//! Where the simulation sidecar of a measurement is, and what it says. The
//! record itself is [`cassi_eval::records::SimulationRecord`].

use std::path::{Path, PathBuf};

use cassi_core::optics::BandSpread;
use cassi_eval::records::{JsonFile, Record, SimulationRecord, read_record, sidecar_path};

/// The simulation sidecar beside `measurement`, if there is one: a JSON file
/// of that name holding a simulation record (of any version, so a newer
/// cassi's sidecar is protected too). Commands that read the measurement
/// must not write over it (it describes the measurement).
pub fn existing_sidecar(measurement: &Path) -> Option<PathBuf> {
    let path = sidecar_path(measurement);
    if path == measurement {
        return None;
    }
    let file = JsonFile::read(&path).ok()?;
    (file.format().ok()? == Some(SimulationRecord::FORMAT)).then_some(path)
}

/// The band count the simulation sidecar beside `measurement` records, if
/// there is one this build reads (any other JSON file there says nothing).
pub fn recorded_bands(measurement: &Path) -> Option<usize> {
    let record: SimulationRecord = read_record(sidecar_path(measurement)).ok()?;
    Some(record.instrument.bands).filter(|&b| b > 0)
}

/// Where each band's light lay in the instrument that made `measurement`,
/// as its simulation sidecar records it (one this build reads): the
/// physical simulator's band spread, or a point per band for a discrete
/// model's operator. An instrument's design, as its band count is.
pub fn recorded_band_spread(measurement: &Path) -> Option<BandSpread> {
    let record: SimulationRecord = read_record(sidecar_path(measurement)).ok()?;
    Some(record.physical.map_or(BandSpread::Point, |p| p.band_spread))
}
