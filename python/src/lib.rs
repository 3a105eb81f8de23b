//! The Python package's native module `oesweep._oesweep`: thin calls into the oesweep library
//! that exchange JSON text and float64 arrays (through the buffer protocol), so the pure-Python
//! layer (`oesweep/`) owns the Python types and the binding stays independent of numpy's and
//! polars' versions. Every call releases the GIL while the engine works.

use oesweep::data::{Offset, Raw, Record};
use oesweep::engine::{self, FitRequest, RunEnd, RunOptions, Watch};
use oesweep::estimate::InitialState;
use oesweep::oe::{MAX_INPUTS, Orders, Structure};
use oesweep::spectral::SpectrumMethod;
use pyo3::buffer::PyBuffer;
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{RecvTimeoutError, TryRecvError};
use std::time::Duration;

create_exception!(_oesweep, JobError, PyValueError, "A job, a setting or a results folder that is wrong.");
create_exception!(_oesweep, DataError, PyValueError, "A data file or array that is wrong.");
create_exception!(_oesweep, OutputError, PyOSError, "An output file or folder that cannot be written.");
create_exception!(_oesweep, LockError, OutputError, "An output folder that another run holds.");

/// The engine's error as the Python exception of its kind, with the CLI's one-line message.
fn to_py(e: oesweep::Error) -> PyErr {
    let msg = e.to_string();
    match e {
        oesweep::Error::Input { .. } | oesweep::Error::Invalid(_) => JobError::new_err(msg),
        oesweep::Error::Data { .. } => DataError::new_err(msg),
        oesweep::Error::Locked { .. } => LockError::new_err(msg),
        oesweep::Error::Output { .. } => OutputError::new_err(msg),
    }
}

/// The samples of a one-dimensional float64 array, copied (in the caller's thread, holding the
/// GIL) through the buffer protocol, which checks the element type, size and strides: the
/// engine only ever reads memory the array exports. The Python layer converts other arrays,
/// lists and Series to float64 first (`oesweep._f64`).
fn floats(name: &str, array: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let not_floats = |why: String| DataError::new_err(format!("{name}: expected a 1-D float64 array ({why})"));
    let buf = PyBuffer::<f64>::get(array).map_err(|e| not_floats(e.value(array.py()).to_string()))?;
    if buf.dimensions() != 1 {
        return Err(not_floats(format!("got {} dimensions", buf.dimensions())));
    }
    buf.to_vec(array.py())
}

/// One float64 array per input, named `label` (one input) or `label[i]` in errors.
fn input_floats(label: &str, arrays: &[Bound<'_, PyAny>]) -> PyResult<Vec<Vec<f64>>> {
    let one = arrays.len() == 1;
    arrays
        .iter()
        .enumerate()
        .map(|(i, a)| floats(&if one { label.to_string() } else { format!("{label}[{i}]") }, a))
        .collect()
}

fn parse<T: serde::de::DeserializeOwned>(what: &str, v: &str) -> PyResult<T> {
    serde_json::from_value(serde_json::Value::String(v.into()))
        .map_err(|e| JobError::new_err(format!("{what} {v:?}: {e}")))
}

/// A record of float64 arrays shaped as a job's record of the model `structure` (METHOD.md
/// 21.1): NaN is a missing sample, input gaps of at most `interpolate_inputs` samples filled,
/// the other input gaps cutting the record into segments (those shorter than the model needs
/// left out), missing outputs kept for the fit to leave out.
fn record_of_arrays(
    label: &str,
    inputs: Vec<Vec<f64>>,
    y: Vec<f64>,
    interpolate_inputs: usize,
    structure: &Structure,
) -> PyResult<Record> {
    let raw = Raw::from_arrays(label, inputs, y).map_err(to_py)?;
    let shortest = oesweep::data::min_samples_of(structure);
    oesweep::data::gaps::shape(raw, interpolate_inputs, shortest).map(|(rec, _)| rec).map_err(to_py)
}

/// One model (`oesweep fit --json`'s report as JSON text) from float64 arrays: `u` one array
/// per input, `nb`, `nf`, `delay` one entry per input (the Python side broadcasts them); NaN
/// marks a missing sample.
#[pyfunction]
#[pyo3(signature = (u, y, nb, nf, k, delay, ts, offset, initial_state, val_u=None, val_y=None, interpolate_inputs=0))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    u: Vec<Bound<'_, PyAny>>,
    y: &Bound<'_, PyAny>,
    nb: Vec<usize>,
    nf: Vec<usize>,
    k: f64,
    delay: Vec<usize>,
    ts: f64,
    offset: &str,
    initial_state: &str,
    val_u: Option<Vec<Bound<'_, PyAny>>>,
    val_y: Option<&Bound<'_, PyAny>>,
    interpolate_inputs: usize,
) -> PyResult<String> {
    if nb.len() != u.len() || nf.len() != u.len() || delay.len() != u.len() {
        return Err(JobError::new_err(format!(
            "{} inputs, but nb, nf and delay have {}, {} and {} entries: give one per input",
            u.len(),
            nb.len(),
            nf.len(),
            delay.len()
        )));
    }
    let orders: Vec<Orders> = (0..u.len()).map(|i| Orders { nb: nb[i], nf: nf[i], delay: delay[i] }).collect();
    let structure = Structure::new(&orders).ok_or_else(|| {
        JobError::new_err(format!("{} inputs: between 1 and {MAX_INPUTS} are supported", orders.len()))
    })?;
    oesweep::job::check_interpolate(interpolate_inputs)
        .map_err(|m| JobError::new_err(format!("interpolate_inputs {m}")))?;
    let est =
        record_of_arrays("<u, y arrays>", input_floats("u", &u)?, floats("y", y)?, interpolate_inputs, &structure)?;
    let val = match (val_u, val_y) {
        (Some(vu), Some(vy)) => Some(record_of_arrays(
            "<validation arrays>",
            input_floats("validation u", &vu)?,
            floats("validation y", vy)?,
            interpolate_inputs,
            &structure,
        )?),
        (None, None) => None,
        _ => return Err(DataError::new_err("validation needs both u and y")),
    };
    let req = FitRequest::for_arrays(
        structure,
        k,
        ts,
        parse::<Offset>("offset", offset)?,
        parse::<InitialState>("initial_state", initial_state)?,
    );
    let report = py.detach(|| engine::fit_arrays(&req, est, val)).map_err(to_py)?;
    Ok(report.to_json())
}

/// How often a running sweep looks at Python's signals (and calls the progress callback) while
/// no cell finishes.
const POLL: Duration = Duration::from_millis(100);

/// Finished cells the engine's workers may report ahead of the calling thread, which takes
/// each report before it calls the progress callback: beyond this a worker waits (before its
/// next cell) until the thread has caught up. A slow callback or a wait for the GIL costs the
/// workers nothing below it, and a stop raised by the callback lands within it.
const AHEAD: usize = 32;

/// Run a job (`oesweep run`): the job file `job`, or, with `text`, the job given as JSON text
/// that `job` only names and locates relative paths from (nothing is written for it); returns
/// the results folder. The engine runs on a thread of its own while this one, without the GIL,
/// waits for it and lets Python handle its signals every [`POLL`]. With `on_progress`, the
/// engine tells this thread of every finished cell and `on_progress(done, total)` is called
/// as cells finish (those that finish together in one call) and once at the end, its workers
/// never more than [`AHEAD`] cells ahead of it. Ctrl-C (or any exception the callback raises)
/// stops the run with the checkpoint kept and is raised here once the cells in flight are
/// saved, so the same call resumes. Python's own SIGINT handler stays in place.
#[pyfunction]
#[pyo3(signature = (job, text=None, threads=None, progress=true, force=false, on_progress=None))]
#[allow(clippy::too_many_arguments)]
fn run(
    py: Python<'_>,
    job: PathBuf,
    text: Option<String>,
    threads: Option<usize>,
    progress: bool,
    force: bool,
    on_progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let watch = Watch::default();
    // Reports of finished cells (only when someone listens) and the engine's end: the engine's
    // thread owns every sender, so the channel closes when the engine returns or panics.
    let (report, reports) = std::sync::mpsc::sync_channel::<()>(AHEAD);
    let engine_watch = Watch { finished: on_progress.is_some().then(|| report.clone()), ..watch.clone() };
    let mut opts = RunOptions { quiet: !progress, force, watch: Some(engine_watch), ..RunOptions::default() };
    if let Some(t) = threads {
        opts.threads = t;
    }
    // The callback, then Python's pending signals (a KeyboardInterrupt).
    let poll = || -> PyResult<()> {
        Python::attach(|py| {
            if let Some(cb) = &on_progress {
                cb.call1(py, (watch.done.load(Ordering::Relaxed), watch.total.load(Ordering::Relaxed)))?;
            }
            py.check_signals()
        })
    };
    let (outcome, raised) = py.detach(|| {
        // Owned here: a receiver may not be shared between threads.
        let reports = reports;
        std::thread::scope(|s| {
            let (job, text) = (&job, &text);
            let engine = s.spawn(move || {
                // Dropped, with the options' clone, when the engine returns: the channel closes.
                let _report = report;
                match text {
                    Some(text) => engine::run_text(job, text, &opts, &|_| {}),
                    None => engine::run(job, &opts, &|_| {}),
                }
            });
            let mut raised = None;
            loop {
                let ended = match reports.recv_timeout(POLL) {
                    Err(RecvTimeoutError::Disconnected) => true,
                    Err(RecvTimeoutError::Timeout) => false,
                    // Reports that came together make one call.
                    Ok(()) => loop {
                        match reports.try_recv() {
                            Ok(()) => {}
                            Err(TryRecvError::Empty) => break false,
                            Err(TryRecvError::Disconnected) => break true,
                        }
                    },
                };
                if ended {
                    break;
                }
                // Once raised, the thread only takes the reports of the cells in flight.
                if raised.is_none()
                    && let Err(e) = poll()
                {
                    watch.stop.store(true, Ordering::Relaxed);
                    raised = Some(e);
                }
            }
            // The last word: a run that ended between two polls still reports its end, and a
            // Ctrl-C that came with it is not lost.
            if raised.is_none() {
                raised = poll().err();
            }
            (engine.join(), raised)
        })
    });
    let outcome = outcome.map_err(|_| PyRuntimeError::new_err("the oesweep engine panicked"))?.map_err(to_py)?;
    let saved = || {
        format!(
            "{} of {} cells finished, saved in {}; the same call resumes",
            outcome.finished,
            outcome.cells,
            outcome.checkpoint.display()
        )
    };
    match (raised, &outcome.end) {
        (Some(e), RunEnd::Interrupted) if e.is_instance_of::<PyKeyboardInterrupt>(py) => {
            Err(PyKeyboardInterrupt::new_err(format!("interrupted: {}", saved())))
        }
        (Some(e), _) => Err(e),
        (None, RunEnd::Interrupted) => Err(PyKeyboardInterrupt::new_err(format!("interrupted: {}", saved()))),
        (None, _) => Ok(outcome.out.display().to_string()),
    }
}

/// The spectral estimate of float64 arrays, `u` one array per input (`oesweep spectrum --json`'s
/// report as JSON text: several inputs' `re`, `im`, `mag_lower`, `mag_upper` one list each).
#[pyfunction]
fn spectrum(py: Python<'_>, u: Vec<Bound<'_, PyAny>>, y: &Bound<'_, PyAny>, ts: f64, method: &str) -> PyResult<String> {
    let rec = Record::from_input_arrays("<u, y arrays>", input_floats("u", &u)?, floats("y", y)?).map_err(to_py)?;
    let method = parse::<SpectrumMethod>("method", method)?;
    let report = py.detach(|| engine::spectrum_arrays(&rec, ts, method)).map_err(to_py)?;
    serde_json::to_string(&report).map_err(|e| PyRuntimeError::new_err(e.to_string()))
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

/// A model document (`oesweep export --to json`'s form) as `to` = "json" or "matlab" text, or
/// with "mat" written to `out` as a MAT-file; returns the text ("" for "mat").
#[pyfunction]
#[pyo3(signature = (doc, to, out=None))]
fn write_model(py: Python<'_>, doc: &str, to: &str, out: Option<PathBuf>) -> PyResult<String> {
    py.detach(|| {
        let model = oesweep::export::model::ModelOut::from_json_text(doc).map_err(JobError::new_err)?;
        match (to, out) {
            ("json", _) => Ok(model.to_json_text()),
            ("matlab", _) => Ok(model.to_matlab()),
            ("mat", Some(out)) => model.write_mat(&out).map(|_| String::new()).map_err(to_py),
            ("mat", None) => Err(JobError::new_err("to=\"mat\" writes a binary file: give its path")),
            (other, _) => Err(JobError::new_err(format!("to {other:?}: expected json, matlab or mat"))),
        }
    })
}

/// The continuous-time equivalent (`oesweep export --continuous`) of a model document (`oesweep
/// export --to json`'s form) by `method` = "zoh" or "tustin", as JSON text: `method`, `num`,
/// `den` (descending powers of s), `input_delay` (seconds), `delay_samples`, `zeros`, `poles`
/// (`[re, im]` pairs), `gain`, `state_space` (`a`, `b`, `c`, `d`); a model of several inputs
/// gives a list of one such object per input. A model without an equivalent raises ValueError
/// naming the pole (and the input).
#[pyfunction]
fn to_continuous(py: Python<'_>, doc: &str, method: &str) -> PyResult<String> {
    py.detach(|| {
        let model = oesweep::export::model::ModelOut::from_json_text(doc).map_err(JobError::new_err)?;
        let method = method.parse::<oesweep::export::continuous::Method>().map_err(JobError::new_err)?;
        let c = model.to_continuous(method).map_err(PyValueError::new_err)?;
        // One input: its equivalent; several: a list of one per input.
        let text = if c.len() == 1 { serde_json::to_string(&c[0]) } else { serde_json::to_string(&c) };
        text.map_err(|e| PyRuntimeError::new_err(e.to_string()))
    })
}

/// The u and y columns of a data file named as a job file names a record (JSON text of its
/// fields), as little-endian float64 bytes: the rows as the file has them, a missing sample
/// (empty, NaN, a marker of the record's `missing`) NaN.
#[pyfunction]
fn read(py: Python<'_>, spec: &str) -> PyResult<(Py<PyBytes>, Py<PyBytes>)> {
    let (_, u, y) = read_inputs(py, spec)?;
    Ok((u, y))
}

/// [`read`] of a record of several inputs (`u` a list of columns in the record's JSON): the
/// input columns' names, their samples input after input (m x N float64, C order) and the
/// output, as little-endian float64 bytes.
#[pyfunction]
fn read_inputs(py: Python<'_>, spec: &str) -> PyResult<(Vec<String>, Py<PyBytes>, Py<PyBytes>)> {
    let spec: oesweep::job::DataSpec =
        serde_json::from_str(spec).map_err(|e| JobError::new_err(format!("record: {e}")))?;
    let rec = py.detach(|| oesweep::job::read_raw(&spec)).map_err(to_py)?;
    let bytes = |v: &[f64]| -> Py<PyBytes> {
        let raw: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
        PyBytes::new(py, &raw).unbind()
    };
    Ok((rec.u_names.clone(), bytes(&rec.u), bytes(&rec.y)))
}

/// The `oesweep` command in this process (the wheel's console script): `argv` as
/// `sys.argv`, the program's name first; returns the exit code. Runs without the GIL, with
/// Rust's standard streams flushed before it returns (the process ends in Python, where Rust's
/// exit-time flush does not run). A panic is reported as the binary reports it: its message,
/// then exit code 101.
#[pyfunction]
fn cli(py: Python<'_>, argv: Vec<OsString>) -> i32 {
    py.detach(|| {
        let code = std::panic::catch_unwind(|| oesweep::cli::main_with_args(argv)).map_or(101, i32::from);
        use std::io::Write;
        let _ = std::io::stdout().flush();
        let _ = std::io::stderr().flush();
        code
    })
}

#[pymodule]
fn _oesweep(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("JobError", m.py().get_type::<JobError>())?;
    m.add("DataError", m.py().get_type::<DataError>())?;
    m.add("OutputError", m.py().get_type::<OutputError>())?;
    m.add("LockError", m.py().get_type::<LockError>())?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    m.add_function(wrap_pyfunction!(report, m)?)?;
    m.add_function(wrap_pyfunction!(spectrum, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add_function(wrap_pyfunction!(write_model, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(read_inputs, m)?)?;
    m.add_function(wrap_pyfunction!(to_continuous, m)?)?;
    m.add_function(wrap_pyfunction!(cli, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
