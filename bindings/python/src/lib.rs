//! The native half of the Python package `wheelcal`: drives read from a
//! path or built from in-memory columns, and the calibrator's, the
//! diagnosis's, the info summary's and the odometry evaluation's library
//! functions called on them, each result returned as the JSON text the
//! command-line tools write for it (`--json`). The Python half
//! (`python/wheelcal/`) wraps the text in result objects and tables.
//!
//! Only conversion lives here: every result is what a library function
//! returns; the Rust work runs with the GIL released. An error is a
//! `wheelcal.WheelcalError` carrying the message chain the command-line
//! tool prints (outermost first, joined by `: `).

mod columns;
mod run;

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use std::path::PathBuf;

create_exception!(
    wheelcal._native,
    WheelcalError,
    PyException,
    "A drive that cannot be read, calibrated, diagnosed or evaluated: the message is the command-line tool's."
);

/// An error as the command-line tools print it, for Python.
fn py_err(e: anyhow::Error) -> PyErr {
    WheelcalError::new_err(format!("{e:#}"))
}

/// A drive, read from a path or built from columns, with the warnings
/// its reading produced.
#[pyclass(module = "wheelcal._native", frozen)]
pub struct Drive {
    loaded: drive_io::LoadedDrive,
    /// The name errors and reports give the drive (its path as given).
    name: String,
}

#[pymethods]
impl Drive {
    /// The name the drive goes by in errors (its path, or the name given).
    #[getter]
    fn name(&self) -> String {
        self.name.clone()
    }

    /// The warnings of reading the drive.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.loaded.warnings.clone()
    }

    /// The drive's duration on the wheel clock, s.
    #[getter]
    fn duration_s(&self) -> f64 {
        self.loaded.drive.wheel_duration_s()
    }

    fn __repr__(&self) -> String {
        format!(
            "Drive({:?}, {:.1} s, {} warnings)",
            self.name,
            self.loaded.drive.wheel_duration_s(),
            self.loaded.warnings.len()
        )
    }
}

/// Read a drive folder, an MCAP recording or a ROS 2 bag as the
/// command-line tools do (`--vehicle`, `--topics`, `--topic`,
/// `--skip-corrupt-chunks`, `--allow-truncated`).
#[pyfunction]
#[pyo3(signature = (path, vehicle=None, topics=None, topic=Vec::new(), skip_corrupt_chunks=false, allow_truncated=false))]
fn read_drive(
    py: Python<'_>,
    path: PathBuf,
    vehicle: Option<PathBuf>,
    topics: Option<PathBuf>,
    topic: Vec<String>,
    skip_corrupt_chunks: bool,
    allow_truncated: bool,
) -> PyResult<Drive> {
    let input = drive_io::cli::DriveInput {
        vehicle,
        topic,
        topics,
    };
    let name = path.display().to_string();
    let loaded = py
        .detach(|| run::read(&input, &path, skip_corrupt_chunks, allow_truncated))
        .map_err(py_err)?;
    Ok(Drive { loaded, name })
}

/// Build a drive from columns: `streams` maps a stream name (`wheels`,
/// `gnss`, `imu`, `heading`, `truth`) to its columns (the drive format's
/// names: `t_s`, `rl_rad_s`, `x_m`, `lat_deg`, ...), each the bytes of
/// little-endian float64 values; `vehicle_toml` is `vehicle.toml`'s text.
#[pyfunction]
fn drive_from_columns(
    py: Python<'_>,
    name: String,
    vehicle_toml: String,
    streams: std::collections::BTreeMap<String, std::collections::BTreeMap<String, Vec<u8>>>,
) -> PyResult<Drive> {
    let loaded = py
        .detach(|| columns::drive(&name, &vehicle_toml, &streams))
        .map_err(py_err)?;
    Ok(Drive { loaded, name })
}

/// `calibrator calibrate DRIVE --json` (with `diagnose`: `--diagnose`):
/// the estimate file's JSON text.
#[pyfunction]
#[pyo3(signature = (drive, diagnose=false))]
fn calibrate(py: Python<'_>, drive: &Drive, diagnose: bool) -> PyResult<String> {
    py.detach(|| run::calibrate(&drive.loaded, &drive.name, diagnose))
        .map_err(py_err)
}

/// `calibrator diagnose DRIVE --json` (with `block_s`: `--block`): the
/// diagnosis's JSON text.
#[pyfunction]
#[pyo3(signature = (drive, block_s=None))]
fn diagnose(py: Python<'_>, drive: &Drive, block_s: Option<f64>) -> PyResult<String> {
    py.detach(|| run::diagnose(&drive.loaded, &drive.name, block_s))
        .map_err(py_err)
}

/// `calibrator diagnose DRIVE DRIVE... --json` (with `block_s`:
/// `--block`): several drives of one car, the JSON's text.
#[pyfunction]
#[pyo3(signature = (drives, block_s=None))]
fn diagnose_drives(
    py: Python<'_>,
    drives: Vec<PyRef<'_, Drive>>,
    block_s: Option<f64>,
) -> PyResult<String> {
    let loaded: Vec<&drive_io::LoadedDrive> = drives.iter().map(|d| &d.loaded).collect();
    let names: Vec<String> = drives.iter().map(|d| d.name.clone()).collect();
    py.detach(|| run::diagnose_drives(&loaded, &names, block_s))
        .map_err(py_err)
}

/// `calibrator info DRIVE --json`: the info report's JSON text.
#[pyfunction]
fn info(py: Python<'_>, drive: &Drive) -> PyResult<String> {
    py.detach(|| run::info(&drive.loaded)).map_err(py_err)
}

/// `odometry evaluate DRIVE [--estimate FILE] --outage S --spacing S
/// --json`: the evaluation report's JSON text. `estimate_json` is an
/// estimate file's text (`calibrate`'s), `estimate_source` the name it
/// goes by (its path).
#[pyfunction]
#[pyo3(signature = (drive, estimate_json=None, estimate_source=String::from("estimate"), outage_s=30.0, spacing_s=10.0))]
fn evaluate(
    py: Python<'_>,
    drive: &Drive,
    estimate_json: Option<String>,
    estimate_source: String,
    outage_s: f64,
    spacing_s: f64,
) -> PyResult<String> {
    py.detach(|| {
        run::evaluate(
            &drive.loaded,
            &drive.name,
            estimate_json
                .as_deref()
                .map(|t| (t, estimate_source.as_str())),
            outage_s,
            spacing_s,
        )
    })
    .map_err(py_err)
}

/// The module `wheelcal._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("WheelcalError", m.py().get_type::<WheelcalError>())?;
    m.add_class::<Drive>()?;
    m.add_function(wrap_pyfunction!(read_drive, m)?)?;
    m.add_function(wrap_pyfunction!(drive_from_columns, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose_drives, m)?)?;
    m.add_function(wrap_pyfunction!(info, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    Ok(())
}
