//! The mismatch ψ and the dispersion model from Python arguments. Names come
//! from the library's one registry ([`Parameter::ALL`] and its keys), never
//! from a list kept here.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyMapping, PyString};

use cassi_core::optics::DispersionModel;
use cassi_core::{Mismatch, Parameter};

use crate::calibration::PyCalibration;
use crate::errors::{type_error, value_error};

/// The registry's keys, for messages: `dx, dy, theta_deg, …`.
pub fn known_keys() -> String {
    Parameter::ALL
        .iter()
        .map(|p| p.key())
        .collect::<Vec<_>>()
        .join(", ")
}

fn set_by_key(
    py: Python<'_>,
    m: &mut Mismatch,
    key: &Bound<'_, PyAny>,
    value: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let key: String = key
        .extract()
        .map_err(|_| type_error(py, "mismatch parameter names are strings"))?;
    let Some(p) = Parameter::ALL.iter().find(|p| p.key() == key) else {
        return Err(value_error(
            py,
            format!(
                "unknown mismatch parameter '{key}' (known: {}; angles in degrees)",
                known_keys()
            ),
        ));
    };
    let v: f64 = value.extract().map_err(|_| {
        type_error(
            py,
            format!("mismatch parameter {key} must be a number, got {value:?}"),
        )
    })?;
    p.set(m, v);
    Ok(())
}

/// ψ from `mismatch` (None, "nominal", "paper", a mapping of registry keys,
/// or a `Calibration`) and then the keyword `params`, starting from the
/// nominal instrument of `stride`; validated.
pub fn mismatch(
    py: Python<'_>,
    stride: f64,
    mismatch: Option<&Bound<'_, PyAny>>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<Mismatch> {
    let mut m = Mismatch::nominal(stride);
    if let Some(obj) = mismatch {
        if let Ok(s) = obj.cast::<PyString>() {
            m = match s.to_cow()?.as_ref() {
                "nominal" => Mismatch::nominal(stride),
                "paper" => Mismatch::paper(),
                other => {
                    return Err(value_error(
                        py,
                        format!(
                            "mismatch '{other}' is not a preset ('nominal' or 'paper'); give a \
                             dict of {}",
                            known_keys()
                        ),
                    ));
                }
            };
        } else if let Ok(cal) = obj.cast::<PyCalibration>() {
            // the calibrated model's operator: its reconstruction parameters
            m = cal.get().inner.reconstruction_parameters();
        } else if let Ok(map) = obj.cast::<PyMapping>() {
            for item in map.items()?.iter() {
                let (k, v): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item.extract()?;
                set_by_key(py, &mut m, &k, &v)?;
            }
        } else {
            return Err(type_error(
                py,
                format!(
                    "mismatch must be None, 'nominal', 'paper', a dict of {} or a Calibration",
                    known_keys()
                ),
            ));
        }
    }
    if let Some(kw) = params {
        for (k, v) in kw.iter() {
            set_by_key(py, &mut m, &k, &v)?;
        }
    }
    m.validate().map_err(|e| value_error(py, e.to_string()))?;
    Ok(m)
}

/// ψ as `{key: value}` in registry order.
pub fn to_dict<'py>(py: Python<'py>, m: &Mismatch) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for p in Parameter::ALL {
        d.set_item(p.key(), p.get(m))?;
    }
    Ok(d)
}

pub fn model(py: Python<'_>, name: &str) -> PyResult<DispersionModel> {
    name.parse::<DispersionModel>()
        .map_err(|e| value_error(py, format!("model: {e}")))
}

/// The dispersion model: `name`, else a `Calibration` mismatch's own, else
/// rounded; a name that contradicts the calibration's model is refused
/// rather than silently fitting another instrument.
pub fn model_for(
    py: Python<'_>,
    name: Option<&str>,
    mismatch: Option<&Bound<'_, PyAny>>,
) -> PyResult<DispersionModel> {
    let calibrated = mismatch
        .and_then(|m| m.cast::<PyCalibration>().ok())
        .map(|c| c.get().inner.model);
    match (name, calibrated) {
        (None, Some(m)) => Ok(m),
        (None, None) => Ok(DispersionModel::default()),
        (Some(n), None) => model(py, n),
        (Some(n), Some(m)) => {
            let chosen = model(py, n)?;
            if chosen != m {
                return Err(value_error(
                    py,
                    format!(
                        "model '{n}' differs from the calibration's model '{}'; leave model out \
                         to use the calibrated one",
                        m.name()
                    ),
                ));
            }
            Ok(chosen)
        }
    }
}
