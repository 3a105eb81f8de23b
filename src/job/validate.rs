//! The rules of a job file: every field checked and the job normalised (paths resolved,
//! defaults filled in, the validation record's output column found), with one error naming
//! the file and the field. The rules that `oesweep fit` shares are public.

use super::{
    DEFAULT_DELAY, DataSpec, InputColumns, Job, KGrid, MAX_CELLS, MAX_ORDER, MIN_EXPLORE_ROWS, Ranges, k_values,
};
use crate::data::{self, ColumnRef, Delimiter};
use crate::error::{Error, Result};
use crate::estimate::SolverOptions;
use std::path::{Path, PathBuf};

/// Rules that the job file and `oesweep fit` share. Each returns what is wrong; the caller
/// names the field or flag.
pub fn check_sampling_period(ts: f64) -> std::result::Result<(), String> {
    if ts.is_finite() && ts > 0.0 { Ok(()) } else { Err(format!("must be a positive number of seconds, got {ts}")) }
}

/// A tuning constant k (see [`check_sampling_period`]).
pub fn check_k(k: f64) -> std::result::Result<(), String> {
    if k.is_finite() && k > 0.0 { Ok(()) } else { Err(format!("must be positive, got {k}")) }
}

/// An order: nB (`min` 1) or nF (`min` 0), at most [`MAX_ORDER`] (see [`check_sampling_period`]).
pub fn check_order(n: usize, min: usize) -> std::result::Result<(), String> {
    if n < min {
        Err(format!("must be at least {min}, got {n}"))
    } else if n > MAX_ORDER {
        Err(format!("orders above {MAX_ORDER} are not supported, got {n}"))
    } else {
        Ok(())
    }
}

/// The sampling period `ts` of a record beside the first record's `first` (every experiment is
/// sampled alike; the tolerance absorbs decimal rounding).
fn check_same_ts(ts: f64, first: f64, whose: &str) -> std::result::Result<(), String> {
    check_sampling_period(ts)?;
    if (ts - first).abs() > 1e-9 * first {
        return Err(format!("sampling period {ts} s differs from the {whose} {first} s"));
    }
    Ok(())
}

/// A frequency band [lo, hi] in Hz at sampling period `ts` (see [`check_sampling_period`]).
pub fn check_band(lo: f64, hi: f64, ts: f64) -> std::result::Result<(), String> {
    let nyq = 0.5 / ts;
    // The tolerance lets `hi` be the Nyquist frequency as written in decimal.
    if lo >= 0.0 && hi > lo && hi <= nyq * (1.0 + 1e-12) {
        Ok(())
    } else {
        Err(format!("need 0 <= lo < hi <= Nyquist frequency {nyq} Hz"))
    }
}

/// The rule of `interpolate_inputs` (the job field and `fit --interpolate-inputs`).
pub fn check_interpolate(l: usize) -> std::result::Result<(), String> {
    if l > data::gaps::MAX_INTERPOLATE {
        return Err(format!(
            "{l} samples: at most {} (a longer straight line invents the input)",
            data::gaps::MAX_INTERPOLATE
        ));
    }
    Ok(())
}

/// The reader fields of a data spec (`which` is "data" or "validation"): (field, message).
pub(super) fn check_data_spec(d: &DataSpec, which: &str) -> std::result::Result<(), (String, String)> {
    if let Some(delim) = &d.delimiter {
        Delimiter::parse(delim).map_err(|m| (format!("{which}.delimiter"), m))?;
    }
    if let Some(rows) = d.rows {
        data::check_rows(rows).map_err(|m| (format!("{which}.rows"), m))?;
    }
    if let Some(l) = d.interpolate_inputs {
        check_interpolate(l).map_err(|m| (format!("{which}.interpolate_inputs"), m))?;
    }
    let inputs = d.u.iter().flat_map(|u| u.cols.iter().enumerate().map(|(i, c)| (u.list, i, c)));
    let named = inputs.map(|(list, i, c)| (if list { format!("u[{i}]") } else { "u".into() }, c));
    for (name, c) in named.chain(d.y.iter().map(|c| ("y".to_string(), c))) {
        if c == &ColumnRef::Position(0) {
            return Err((format!("{which}.{name}"), "column position 0: positions count from 1".into()));
        }
    }
    Ok(())
}

/// A record's gap settings (`missing`, `interpolate_inputs`) default to the first record's:
/// the same logger writes the same markers.
fn inherit_gaps(spec: &mut DataSpec, first: &DataSpec) {
    if spec.missing.is_none() {
        spec.missing = first.missing.clone();
    }
    if spec.interpolate_inputs.is_none() {
        spec.interpolate_inputs = first.interpolate_inputs;
    }
}

/// `p` relative to `base`, with `a/../` folded lexically so messages show readable paths.
fn resolve(base: &Path, p: &Path) -> PathBuf {
    use std::path::Component;
    let joined = if p.is_absolute() { p.to_path_buf() } else { base.join(p) };
    let mut out = PathBuf::new();
    for c in joined.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.components().next_back(), Some(Component::Normal(_))) => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    if out.as_os_str().is_empty() { PathBuf::from(".") } else { out }
}

/// The validation record's output column (the file's `y0` when it has one,
/// [`data::validation_column`]) and sampling period, filled in so that the checked job is
/// complete. Reads the header of the validation file when its column is not given.
pub(super) fn resolve_validation(mut job: Job) -> Result<Job> {
    let (data_y, ts) = (job.data.first().y_col(), job.data.first().ts);
    for v in job.validation.iter_mut().flat_map(|v| v.specs.iter_mut()) {
        v.y = Some(data::validation_column(&v.path, v.y.as_ref(), &data_y, &v.read_options())?);
        v.ts = v.ts.or(ts);
    }
    Ok(job)
}

/// Check every field and normalise the job: paths resolved, defaults filled in, the delay as
/// `grid.delay`, k as an explicit list.
pub(super) fn validate(path: &Path, mut job: Job) -> Result<Job> {
    // Messages quote paths and values from the job, which may hold control characters.
    let bad = |field: &str, msg: String| Error::input(path, data::one_line(&format!("field '{field}': {msg}")));
    // Absolute base: job.json in the output folder must locate the data from anywhere.
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let base = parent.canonicalize().unwrap_or_else(|_| parent.to_path_buf());
    // The first record as a job of one record has it; the others of a list default to the
    // first's columns, layout and sampling period (every experiment measures the same signals).
    let names: Vec<String> = job.data.named("data").map(|(n, _)| n).collect();
    for (i, name) in names.iter().enumerate() {
        let first = (i > 0).then(|| job.data.first().clone());
        let spec = &mut job.data.specs[i];
        if spec.path.as_os_str().is_empty() {
            return Err(bad(&format!("{name}.path"), "missing: the data file is required".into()));
        }
        spec.path = resolve(&base, &spec.path);
        match &first {
            None => {
                spec.u.get_or_insert_with(|| InputColumns::one(ColumnRef::name("u")));
                spec.y.get_or_insert_with(|| ColumnRef::name("y"));
            }
            Some(first) => {
                spec.u.get_or_insert_with(|| first.u.clone().expect("filled in above"));
                spec.y.get_or_insert_with(|| first.y_col());
                if spec.delimiter.is_none() && spec.path == first.path {
                    spec.delimiter = first.delimiter.clone();
                }
                if spec.header.is_none() {
                    spec.header = first.header;
                }
                inherit_gaps(spec, first);
            }
        }
        check_data_spec(spec, name).map_err(|(f, m)| bad(&f, m))?;
        match (spec.ts, &first) {
            (Some(ts), None) => check_sampling_period(ts).map_err(|m| bad(&format!("{name}.ts"), m))?,
            (None, None) => {
                return Err(bad(&format!("{name}.ts"), "missing: the sampling period in seconds is required".into()));
            }
            (Some(ts), Some(first)) => {
                check_same_ts(ts, first.ts.unwrap(), "first record's").map_err(|m| bad(&format!("{name}.ts"), m))?
            }
            (None, Some(first)) => spec.ts = first.ts,
        }
    }
    let data0 = job.data.first().clone();
    let vnames: Vec<String> = job.validation.iter().flat_map(|v| v.named("validation").map(|(n, _)| n)).collect();
    for (v, vname) in job.validation.iter_mut().flat_map(|v| v.specs.iter_mut()).zip(&vnames) {
        let vname = vname.as_str();
        // The usual split of one experiment: same file and layout, other rows; or the same
        // rows, other columns (`uVal`, `yVal` beside `uEst`, `yEst`).
        if v.path.as_os_str().is_empty() {
            if v.rows.is_none() && v.u.is_none() && v.y.is_none() {
                return Err(bad(
                    vname,
                    "give its 'path', or the 'rows' or columns ('u', 'y') it takes from the estimation file (as \
                     it is, it would be the estimation record)"
                        .into(),
                ));
            }
            v.path = data0.path.clone();
        } else {
            v.path = resolve(&base, &v.path);
        }
        v.u.get_or_insert_with(|| data0.u.clone().expect("filled in above"));
        if v.delimiter.is_none() && v.path == data0.path {
            v.delimiter = data0.delimiter.clone();
        }
        v.header.get_or_insert(data0.header.unwrap_or_default());
        inherit_gaps(v, &data0);
        check_data_spec(v, vname).map_err(|(f, m)| bad(&f, m))?;
        if let Some(ts) = v.ts {
            check_same_ts(ts, data0.ts.unwrap(), "estimation record's").map_err(|m| bad(&format!("{vname}.ts"), m))?;
        }
    }
    check_grid_and_settings(&mut job).map_err(|(f, m)| bad(&f, m))?;
    job.output = resolve(&base, &job.output);
    check_output_folder(&job.output).map_err(|msg| bad("output", msg))?;
    Ok(job)
}

/// The name, grid and settings of a job (orders, delays, k, band, solver, selection): the
/// rules that need no file, shared by [`validate`] and [`check_as_run`]. Expands k into a
/// list. Returns (field, message).
fn check_grid_and_settings(job: &mut Job) -> std::result::Result<(), (String, String)> {
    let err = |field: &str, msg: String| (field.to_string(), msg);
    if job.name.trim().is_empty() {
        return Err(err("name", "must not be empty".into()));
    }
    let m = check_input_counts(job)?;
    let delay = match (job.grid.delay.take(), job.delay.take()) {
        (Some(_), Some(_)) => {
            return Err(err("delay", "give either 'delay' or 'grid.delay', not both".into()));
        }
        (Some(ranges), None) => ranges,
        (None, Some(d)) => {
            if let super::Delays::PerInput(v) = &d {
                super::check_count("delay", "delays", v.len(), m)?;
            }
            d.as_ranges()
        }
        (None, None) => Ranges::One([DEFAULT_DELAY; 2]),
    };
    let nb = job.grid.nb.per_input("grid.nb", m)?;
    let nf = job.grid.nf.per_input("grid.nf", m)?;
    let delays = delay.per_input("grid.delay", m)?;
    // The structures of the product over the inputs (None: beyond any count).
    let mut structures = Some(1u128);
    for i in 0..m {
        let ((bf, [b0, b1]), (ff, [f0, f1]), (df, [d0, d1])) = (&nb[i], &nf[i], &delays[i]);
        if *b0 < 1 || b0 > b1 {
            return Err(err(bf, format!("[{b0}, {b1}] is not a range [from, to] with 1 <= from <= to")));
        }
        if f0 > f1 {
            return Err(err(ff, format!("[{f0}, {f1}] is not a range [from, to] with from <= to")));
        }
        check_order(*b1.max(f1), 0).map_err(|m| err("grid", m))?;
        if d0 > d1 {
            return Err(err(df, format!("[{d0}, {d1}] is not a range [from, to] with from <= to")));
        }
        let here = ((b1 - b0 + 1) * (f1 - f0 + 1)) as u128 * ((d1 - d0) as u128 + 1);
        structures = structures.and_then(|s| s.checked_mul(here));
    }
    job.grid.delay = Some(delay);
    if let KGrid::Range(r) = &job.grid.k {
        if r.count == 0 {
            return Err(err("grid.k.count", "must be at least 1".into()));
        }
        if !(r.from.is_finite() && r.to.is_finite() && r.from > 0.0 && r.to >= r.from) {
            return Err(err("grid.k", format!("from {} to {}: need 0 < from <= to", r.from, r.to)));
        }
        if r.count > 1 && r.from == r.to {
            return Err(err("grid.k", format!("from == to == {} with count {}: the range is empty", r.from, r.count)));
        }
    }
    // The cell cap is checked before the k grid is expanded: a typo such as a count of 1e15
    // must be an error, not an allocation that aborts the process.
    let n_k = match &job.grid.k {
        KGrid::List(v) => v.len(),
        KGrid::Range(r) => r.count,
    };
    match structures.and_then(|s| s.checked_mul(n_k as u128)) {
        Some(cells) if cells > MAX_CELLS as u128 => {
            return Err(err("grid", format!("{cells} cells is above the limit of {MAX_CELLS}")));
        }
        None => return Err(err("grid", format!("more cells than can be counted: the limit is {MAX_CELLS}"))),
        Some(_) => {}
    }
    let ks = k_values(&job.grid.k);
    if ks.is_empty() {
        return Err(err("grid.k", "the list of k values is empty".into()));
    }
    if let Some(m) = ks.iter().find_map(|&k| check_k(k).err()) {
        return Err(err("grid.k", format!("k {m}")));
    }
    // Duplicates anywhere in the list (not only neighbours) would give two cells with the
    // same (nB, nF, k) and two identical rows in the table.
    let mut sorted = ks.clone();
    sorted.sort_by(f64::total_cmp);
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(err("grid.k", format!("k = {} appears twice", w[0])));
    }
    if let Some([lo, hi]) = job.band_hz {
        check_band(lo, hi, job.data.first().ts.unwrap()).map_err(|m| err("band_hz", format!("[{lo}, {hi}]: {m}")))?;
    }
    check_solver(&job.solver).map_err(|(f, m)| (format!("solver.{f}"), m))?;
    let sel = &job.selection;
    if !(sel.min_tolerance.is_finite() && sel.min_tolerance >= 0.0) {
        return Err(err("selection.min_tolerance", format!("must be >= 0, got {}", sel.min_tolerance)));
    }
    if !(sel.fit_tolerance.is_finite() && sel.fit_tolerance >= 0.0) {
        return Err(err("selection.fit_tolerance", format!("must be >= 0, got {}", sel.fit_tolerance)));
    }
    if !job.uncertainty.is_local() {
        crate::estimate::bootstrap::check_replicates(job.uncertainty.replicates)
            .map_err(|m| err("uncertainty.replicates", m))?;
    }
    job.grid.k = KGrid::List(ks);
    Ok(())
}

/// The number of inputs m of a job: the input columns of its first record, which every other
/// record (experiments, validation) must match. Returns (field, message).
fn check_input_counts(job: &Job) -> std::result::Result<usize, (String, String)> {
    let count = |s: &DataSpec| s.u.as_ref().map_or(1, |u| u.cols.len());
    let m = count(job.data.first());
    if m > crate::oe::MAX_INPUTS {
        return Err((
            "data.u".into(),
            format!("{m} input columns: at most {} inputs are supported", crate::oe::MAX_INPUTS),
        ));
    }
    let named = job.data.named("data").skip(1).chain(job.validation.iter().flat_map(|v| v.named("validation")));
    for (name, spec) in named {
        if count(spec) != m {
            let whose = if name.starts_with("data") { "the first record" } else { "the estimation record" };
            return Err((
                format!("{name}.u"),
                format!(
                    "{} where {whose} has {m}: every record has the same inputs",
                    super::per_input::counted(count(spec), "input columns")
                ),
            ));
        }
    }
    Ok(m)
}

/// The rules of a job a run wrote (`job.json` of a results or checkpoint folder, which anyone
/// may have edited since): every field as [`validate`] checks it, but not the files, which
/// are checked when (and if) they are read. Returns (field, message).
pub(super) fn check_as_run(job: &mut Job) -> std::result::Result<(), (String, String)> {
    let ts_field = |name: &str, m: String| (format!("{name}.ts"), m);
    let Some(ts0) = job.data.first().ts else {
        return Err(("data.ts".into(), "missing: the sampling period in seconds is required".into()));
    };
    check_sampling_period(ts0).map_err(|m| ts_field("data", m))?;
    let named = job.data.named("data").chain(job.validation.iter().flat_map(|v| v.named("validation")));
    for (name, spec) in named {
        check_data_spec(spec, &name)?;
        if let Some(ts) = spec.ts {
            check_same_ts(ts, ts0, "first record's").map_err(|m| ts_field(&name, m))?;
        }
    }
    check_grid_and_settings(job)
}

/// The settings of the solver (`solver.FIELD` in a job, flags of `oesweep fit`): (field, message).
pub fn check_solver(s: &SolverOptions) -> std::result::Result<(), (&'static str, String)> {
    if s.max_iterations == 0 {
        return Err(("max_iterations", "must be at least 1".into()));
    }
    if s.explore_rows != 0 && s.explore_rows < MIN_EXPLORE_ROWS {
        return Err((
            "explore_rows",
            format!("must be 0 (explore on the whole record) or at least {MIN_EXPLORE_ROWS}, got {}", s.explore_rows),
        ));
    }
    for (name, v) in [
        ("ftol", s.ftol),
        ("xtol", s.xtol),
        ("gtol", s.gtol),
        ("lambda0", s.lambda0),
        ("warm_lambda0", s.warm_lambda0),
        ("huber_tol", s.huber_tol),
    ] {
        if !(v.is_finite() && v >= 0.0) {
            return Err((name, format!("must be a non-negative number, got {v}")));
        }
    }
    Ok(())
}

/// Checks, without leaving a trace, that `out` is a folder `run` will be able to create or
/// write into: a typo in `output` must fail in `plan`, before a night of estimation.
///
/// The nearest existing ancestor (the folder itself when it exists) must be a folder in which
/// we can create an entry. That is tested by creating and at once removing a uniquely named
/// empty probe folder, not with `access(W_OK)`: the permission bits are no answer for root
/// (who may write almost anywhere, yet not under `/proc`), nor for read-only mounts, ACLs or
/// full quotas on some file systems, and `libc` is not a dependency.
fn check_output_folder(out: &Path) -> std::result::Result<(), String> {
    use std::io::ErrorKind;
    let mut existing = None;
    for a in out.ancestors() {
        match std::fs::metadata(a) {
            Ok(m) => {
                existing = Some((a, m));
                break;
            }
            // NotADirectory: a component further up is a file; the loop reaches it.
            Err(e) if matches!(e.kind(), ErrorKind::NotFound | ErrorKind::NotADirectory) => {}
            Err(e) => return Err(format!("cannot access {}: {e}", a.display())),
        }
    }
    let Some((dir, meta)) = existing else {
        return Err(format!("{}: no part of this path exists", out.display()));
    };
    if !meta.is_dir() {
        return Err(if dir == out {
            format!("{} is a file, not a folder", out.display())
        } else {
            format!("cannot create {}: {} is a file, not a folder", out.display(), dir.display())
        });
    }
    static PROBES: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let probe = dir.join(format!(
        ".oesweep-probe-{}-{nanos}-{}",
        std::process::id(),
        PROBES.fetch_add(1, std::sync::atomic::Ordering::Relaxed)
    ));
    match std::fs::create_dir(&probe) {
        Ok(()) => {
            // A probe that cannot be removed again would be a trace; say so rather than hide it.
            std::fs::remove_dir(&probe).map_err(|e| format!("cannot remove the probe folder {}: {e}", probe.display()))
        }
        Err(e) if dir == out => Err(format!("cannot write into {} ({e})", out.display())),
        Err(e) => Err(format!("cannot create {}: {} does not accept new folders ({e})", out.display(), dir.display())),
    }
}
