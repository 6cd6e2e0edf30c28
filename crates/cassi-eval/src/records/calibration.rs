//! The calibration file (`cassi calibrate -o`, `cassi demo`): core's
//! [`Calibration`] as it is, under the `cassi-calibration` header.

use cassi_core::calib::Calibration;

use super::Record;

impl Record for Calibration {
    const FORMAT: &'static str = "cassi-calibration";
    const VERSION: u64 = 1;
    const KEYS: &'static [&'static str] = &["preset", "model", "parameters", "stages"];
}
