//! The Python package's native module `oesweep._oesweep`: thin calls into the oesweep library
//! that exchange JSON text and raw float64 bytes, so the pure-Python layer (`oesweep/`) owns
//! the Python types and the binding stays independent of numpy's and polars' versions. Every
//! call releases the GIL while the engine works.

use oesweep::data::{ColumnRef, Offset, Record};
use oesweep::engine::{self, FitRequest, RunEnd, RunOptions};
use oesweep::estimate::{InitialState, SolverOptions};
use oesweep::spectral::SpectrumMethod;
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use std::path::{Path, PathBuf};

create_exception!(_oesweep, JobError, PyValueError, "A job, a setting or a results folder that is wrong.");
create_exception!(_oesweep, DataError, PyValueError, "A data file or array that is wrong.");

/// The engine's error as the typed Python exception, with the CLI's one-line message.
fn to_py(e: oesweep::Error) -> PyErr {
    let msg = e.to_string();
    match &e {
        oesweep::Error::Input { path, .. } if path.extension().is_some_and(|x| x == "json") => JobError::new_err(msg),
        oesweep::Error::Input { .. } => DataError::new_err(msg),
        oesweep::Error::Invalid(_) => JobError::new_err(msg),
        _ => PyRuntimeError::new_err(msg),
    }
}

fn floats(name: &str, bytes: &[u8]) -> PyResult<Vec<f64>> {
    if !bytes.len().is_multiple_of(8) {
        return Err(DataError::new_err(format!("{name}: not float64 data")));
    }
    Ok(bytes.chunks_exact(8).map(|c| f64::from_ne_bytes(c.try_into().expect("8 bytes"))).collect())
}

fn parse<T: serde::de::DeserializeOwned>(what: &str, v: &str) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(v.into()))
        .map_err(|e| JobError::new_err(format!("{what} {v:?}: {e}")))
}

/// One model (`oesweep fit --json`'s report as JSON text) from float64 bytes.
#[pyfunction]
#[pyo3(signature = (u, y, nb, nf, k, delay, ts, offset, initial_state, val_u=None, val_y=None))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    u: &[u8],
    y: &[u8],
    nb: usize,
    nf: usize,
    k: f64,
    delay: usize,
    ts: f64,
    offset: &str,
    initial_state: &str,
    val_u: Option<&[u8]>,
    val_y: Option<&[u8]>,
) -> PyResult<String> {
    let est = Record::from_arrays("<u, y arrays>", floats("u", u)?, floats("y", y)?).map_err(to_py)?;
    let val = match (val_u, val_y) {
        (Some(vu), Some(vy)) => Some(
            Record::from_arrays("<validation arrays>", floats("validation u", vu)?, floats("validation y", vy)?)
                .map_err(to_py)?,
        ),
        (None, None) => None,
        _ => return Err(DataError::new_err("validation needs both u and y")),
    };
    let req = FitRequest {
        data: PathBuf::from("<u, y arrays>"),
        u: ColumnRef::Name("u".into()),
        y: ColumnRef::Name("y".into()),
        rows: None,
        validation: None,
        val_y: None,
        val_rows: None,
        offset: parse::<Offset>("offset", offset)?,
        initial_state: parse::<InitialState>("initial_state", initial_state)?,
        spectrum: SpectrumMethod::default(),
        nb,
        nf,
        k,
        delay,
        ts: Some(ts),
        band: None,
        solver: SolverOptions::default(),
    };
    let report = py.detach(|| engine::fit_arrays(&req, est, val)).map_err(to_py)?;
    serde_json::to_string(&report).map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

/// Run a job file (`oesweep run`); returns the results folder. An interrupted run raises
/// KeyboardInterrupt with the checkpoint kept (the same call resumes).
#[pyfunction]
#[pyo3(signature = (job, threads=None, progress=true, force=false))]
fn run(py: Python<'_>, job: PathBuf, threads: Option<usize>, progress: bool, force: bool) -> PyResult<String> {
    let mut opts = RunOptions { quiet: !progress, force, ..RunOptions::default() };
    if let Some(t) = threads {
        opts.threads = t;
    }
    let outcome = py.detach(|| engine::run(&job, &opts, &|_| {})).map_err(to_py)?;
    match outcome.end {
        RunEnd::Interrupted => Err(PyKeyboardInterrupt::new_err(format!(
            "interrupted: {} of {} cells finished, saved in {}; the same call resumes",
            outcome.finished,
            outcome.cells,
            outcome.checkpoint.display()
        ))),
        _ => Ok(outcome.out.display().to_string()),
    }
}

/// Write the review report of a results folder; returns the page's path.
#[pyfunction]
fn report(py: Python<'_>, folder: PathBuf) -> PyResult<String> {
    let page = py.detach(|| oesweep::report::write_report(&folder)).map_err(to_py)?;
    Ok(page.display().to_string())
}

/// One model of a results folder (`oesweep export --to json`) as JSON text.
#[pyfunction]
#[pyo3(signature = (folder, pick=None))]
fn export(py: Python<'_>, folder: PathBuf, pick: Option<&str>) -> PyResult<String> {
    let spec = pick.map(|p| p.parse::<engine::PickSpec>().map_err(JobError::new_err)).transpose()?;
    let (model, _notes) = py.detach(|| engine::export_model(Path::new(&folder), spec.as_ref())).map_err(to_py)?;
    Ok(model.to_json_text())
}

#[pymodule]
fn _oesweep(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("JobError", m.py().get_type::<JobError>())?;
    m.add("DataError", m.py().get_type::<DataError>())?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(report, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
