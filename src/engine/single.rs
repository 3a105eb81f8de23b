//! The one-model operations: [`fit`] one cell (`oesweep fit`) and [`simulate`] example data
//! (the nonparametric spectrum of a record: [`super::spectrum`]).

use crate::data::{self, ColumnRef, ReadOptions};
use crate::error::{Error, Result};
use crate::estimate::{self, HuberFit, InitialState, Judge, LsFit, Problem, SolverOptions, Workspace};
use crate::job;
use crate::oe::Structure;
use crate::simulate;
use crate::spectral;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One model, `oesweep fit`: the least-squares fit of (nB, nF) and the Huber fit at k from it.
#[derive(Clone, Debug)]
pub struct FitRequest {
    pub data: PathBuf,
    /// The input columns, one per input (of the estimation and the validation record).
    pub u: Vec<ColumnRef>,
    pub y: ColumnRef,
    /// Data rows of the estimation record (default: all).
    pub rows: Option<[usize; 2]>,
    /// Validation file; with `val_rows` and no file, the estimation file.
    pub validation: Option<PathBuf>,
    /// Validation output column (default: see [`data::validation_column`]).
    pub val_y: Option<ColumnRef>,
    /// Data rows of the validation record (default: all).
    pub val_rows: Option<[usize; 2]>,
    /// Offsets of the signals ([`data::levels`]).
    pub offset: data::Offset,
    /// The initial state `fit` and `fit_val` are computed with.
    pub initial_state: InitialState,
    /// The spectral estimate of `band`.
    pub spectrum: spectral::SpectrumMethod,
    /// Every input's orders and delay, in the order of `u`.
    pub structure: Structure,
    pub k: f64,
    /// Sampling period (needed for `band`).
    pub ts: Option<f64>,
    pub band: Option<(f64, f64)>,
    pub solver: SolverOptions,
    /// Bootstrap replicates of the whole estimation (`--bootstrap B`; None: none,
    /// METHOD.md 17.3).
    pub bootstrap: Option<usize>,
    /// Worker threads of the bootstrap's replicates (0: all cores), on a pool of its own: the
    /// host's rayon pool is left alone. The intervals do not depend on it.
    pub threads: usize,
    /// What else marks a missing sample in the files, besides NaN and empty fields (`--missing`,
    /// the job's `data.missing`; METHOD.md 21.1).
    pub missing: Vec<data::Marker>,
    /// Input gaps of at most this many samples filled by linear interpolation
    /// (`--interpolate-inputs`, the job's `data.interpolate_inputs`; 0: none, the record is cut).
    pub interpolate_inputs: usize,
}

/// Report of [`fit`] (`fit --json` prints it).
#[derive(serde::Serialize)]
pub struct FitReport {
    pub data: PathBuf,
    pub n: usize,
    pub validation: Option<PathBuf>,
    pub validation_column: Option<String>,
    /// The orders (one input; several: lists, one entry per input, see [`FitReport::to_json`]).
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    #[serde(skip)]
    pub structure: Structure,
    /// Sampling period (None: not given).
    pub ts: Option<f64>,
    pub band_hz: Option<(f64, f64)>,
    /// The offset mode, and the input level u0 taken out (the model is `B/F (u - u0) + offset`).
    pub offset_mode: data::Offset,
    #[serde(serialize_with = "data::levels::one_or_list")]
    pub input_level: Vec<f64>,
    pub initial_state: InitialState,
    /// What the user should know about the data.
    pub warnings: Vec<String>,
    pub sigma: f64,
    #[serde(flatten)]
    pub huber: HuberFit,
    pub converged: bool,
    /// The names of the Huber fit's parameters (b1.., f1.., offset when estimated) and their
    /// covariance, one row per parameter (None when it cannot be computed), as `oesweep
    /// export` gives them.
    pub parameters: Vec<String>,
    pub covariance: Option<Vec<Vec<f64>>>,
    /// Where the Huber fit returned started (`ls`, `ls_alt`, or a boundary start:
    /// `contracted`, `guess`, `walk`; METHOD.md 17.1).
    pub start: &'static str,
    /// The check of the criterion over the fit's confidence region (METHOD.md 17.2; None
    /// without a covariance).
    pub quadratic: Option<estimate::quadratic::QuadraticCheck>,
    /// Percentile intervals of the whole estimation (`--bootstrap B`, METHOD.md 17.3).
    pub bootstrap: Option<estimate::bootstrap::Bootstrap>,
    pub seconds: f64,
    pub ls: LsFit,
    /// What was missing in the files and what became of it (METHOD.md 21.1); None for complete
    /// records and for arrays.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gaps: Option<data::RecordGaps>,
}

impl FitReport {
    /// The report as `fit --json` prints it and Python's `fit` reads it: a several-input
    /// model's orders and coefficients one entry per input ([`super::per_input`]).
    pub fn to_json(&self) -> String {
        if self.structure.m() == 1 {
            return serde_json::to_string(self).expect("report serialises");
        }
        let mut v = serde_json::to_value(self).expect("report serialises");
        if let Some(obj) = v.as_object_mut() {
            super::per_input::split_fields(&self.structure, obj, &["ls"]);
        }
        v.to_string()
    }
}

impl FitRequest {
    /// A request for records in memory ([`fit_arrays`]: the Python package's `oesweep.fit`),
    /// the other settings at `oesweep fit`'s defaults.
    pub fn for_arrays(
        structure: Structure,
        k: f64,
        ts: f64,
        offset: data::Offset,
        initial_state: InitialState,
    ) -> FitRequest {
        FitRequest {
            data: PathBuf::from("<u, y arrays>"),
            u: match structure.m() {
                1 => vec![ColumnRef::Name("u".into())],
                m => (1..=m).map(|i| ColumnRef::Name(format!("u{i}"))).collect(),
            },
            y: ColumnRef::Name("y".into()),
            rows: None,
            validation: None,
            val_y: None,
            val_rows: None,
            offset,
            initial_state,
            spectrum: spectral::SpectrumMethod::default(),
            structure,
            k,
            ts: Some(ts),
            band: None,
            solver: SolverOptions::default(),
            bootstrap: None,
            threads: 0,
            missing: Vec::new(),
            interpolate_inputs: 0,
        }
    }

    /// The job file's rules ([`job::check_order`], [`job::check_solver`], ...), named as the
    /// command line names the settings.
    fn check(&self) -> Result<()> {
        let bad = |flag: &str, msg: String| Error::Invalid(format!("{flag} {msg}"));
        if self.u.len() != self.structure.m() {
            let m = self.structure.m();
            return Err(bad("--u", format!("{} input columns for orders of {m} inputs", self.u.len())));
        }
        for o in self.structure.inputs() {
            job::check_order(o.nb, 1).map_err(|m| bad("--nb", m))?;
            job::check_order(o.nf, 0).map_err(|m| bad("--nf", m))?;
        }
        for (flag, rows) in [("--rows", self.rows), ("--val-rows", self.val_rows)] {
            if let Some(r) = rows {
                data::check_rows(r).map_err(|m| bad(flag, m))?;
            }
        }
        job::check_k(self.k).map_err(|m| bad("--k", m))?;
        job::check_interpolate(self.interpolate_inputs).map_err(|m| bad("--interpolate-inputs", m))?;
        if let Some(ts) = self.ts {
            job::check_sampling_period(ts).map_err(|m| bad("--ts", m))?;
        }
        if let Some((lo, hi)) = self.band {
            let Some(ts) = self.ts else {
                return Err(Error::Invalid("--band needs --ts (the sampling period in seconds)".into()));
            };
            job::check_band(lo, hi, ts).map_err(|m| bad(&format!("--band {lo},{hi}:"), m))?;
        }
        job::check_solver(&self.solver).map_err(|(field, m)| match field {
            "max_iterations" => bad("--max-iterations", m),
            "ftol" => bad("--ftol", m),
            other => bad(&format!("solver.{other}"), m),
        })?;
        if let Some(b) = self.bootstrap {
            estimate::bootstrap::check_replicates(b).map_err(|m| Error::Invalid(format!("--bootstrap {m}")))?;
        }
        crate::pool::check_threads(self.threads).map_err(|m| Error::Invalid(format!("--threads {m}")))?;
        Ok(())
    }
}

/// Fit one model (see [`FitRequest`]).
pub fn fit(req: &FitRequest) -> Result<FitReport> {
    req.check()?;
    // The records as a job names them, read by the run's loader.
    let missing = (!req.missing.is_empty()).then(|| req.missing.clone());
    let interpolate_inputs = (req.interpolate_inputs > 0).then_some(req.interpolate_inputs);
    let data = job::DataSpec {
        path: req.data.clone(),
        u: Some(job::InputColumns::list(req.u.clone())),
        y: Some(req.y.clone()),
        rows: req.rows,
        missing: missing.clone(),
        interpolate_inputs,
        ..Default::default()
    };
    let val_path = req.validation.clone().or_else(|| req.val_rows.map(|_| req.data.clone()));
    let validation = match &val_path {
        Some(p) => {
            let opts = ReadOptions { rows: req.val_rows, ..ReadOptions::default() };
            let y = data::validation_column(p, req.val_y.as_ref(), &req.y, &opts)?;
            Some(job::DataSpec {
                path: p.clone(),
                u: Some(job::InputColumns::list(req.u.clone())),
                y: Some(y),
                rows: req.val_rows,
                missing,
                interpolate_inputs,
                ..Default::default()
            })
        }
        None => None,
    };
    let validation = validation.map(job::Records::one);
    let (est, val, gaps) = job::read_records_for(&job::Records::one(data), validation.as_ref(), &req.structure)?;
    let mut report = fit_records(req, est, val, val_path)?;
    report.gaps = (gaps.data.is_some() || gaps.validation.is_some()).then_some(gaps);
    Ok(report)
}

/// [`fit`] of records in memory (the Python package's arrays; `req`'s file fields only name
/// them in the report), the estimation record `est` and an optional validation record.
pub fn fit_arrays(req: &FitRequest, est: data::Record, val: Option<data::Record>) -> Result<FitReport> {
    req.check()?;
    let val_path = val.as_ref().map(|v| v.path.clone());
    fit_records(req, est, val, val_path)
}

fn fit_records(
    req: &FitRequest,
    est: data::Record,
    val: Option<data::Record>,
    val_path: Option<PathBuf>,
) -> Result<FitReport> {
    let largest = &req.structure;
    let delays: Vec<usize> = largest.inputs().iter().map(|o| o.delay).collect();
    let job::Inputs { est, val, levels, warnings, pole_tests } =
        job::inputs_of_records(est, val, req.offset, largest, &delays)?;
    let first = largest.inputs()[0];
    let spec = match (req.band, req.ts) {
        (Some((lo, hi)), Some(ts)) => {
            let s = spectral::estimate_inputs(&est.u, largest.m(), &est.y, &est.seams, &est.missing, ts, req.spectrum)?;
            let bins = s[0].band(lo, hi);
            Some((s, bins))
        }
        _ => None,
    };
    let judge = Judge {
        validation: val.as_ref().map(|v| (&v.u[..], &v.y[..])),
        validation_seams: val.as_ref().map_or(&[][..], |v| &v.seams[..]),
        validation_missing: val.as_ref().map_or(&[][..], |v| &v.missing[..]),
        band: spec.as_ref().map(|(s, bins)| (&s[..], &bins[..])),
        initial_state: req.initial_state,
        criterion_only: false,
    };
    let prob = Problem {
        u: &est.u,
        y: &est.y,
        structure: *largest,
        offset: req.offset.estimated(),
        seams: &est.seams,
        missing: &est.missing,
    };
    let mut ws = Workspace::new();
    let t0 = Instant::now();
    let estimate::OneFit { mut ls, mut huber, start, .. } =
        estimate::fit_one(&prob, req.k, &judge, &req.solver, &mut ws);
    let seconds = t0.elapsed().as_secs_f64();
    let theta = huber.theta();
    let loss = estimate::Loss::Huber { gamma: huber.gamma };
    let dim = theta.len();
    let cov = estimate::evidence::covariance(&prob, &theta, loss, &prob.simulate_vec(&theta));
    let quadratic = cov.as_ref().map(|c| estimate::quadratic::check(&prob, &theta, loss, c));
    let mut warnings = warnings;
    let model = largest.label();
    // The integrating-plant test of each input judged against this fit (METHOD.md 7.3, 19).
    {
        use estimate::integrating::{self, Judged};
        let drift = std::cell::OnceCell::new();
        let record = est.path.display().to_string();
        warnings.extend(integrating::doubts(&pole_tests, &est.u_names, &record, |i| {
            let radius = match largest.m() {
                1 => huber.assessment.max_pole_radius,
                _ => integrating::input_radius(largest, &theta, i),
            };
            let drift = integrating::judged_by_residuals(radius)
                .then(|| *drift.get_or_init(|| integrating::residual_drift(&prob, &theta)));
            vec![Judged { name: model.clone(), radius, drift }]
        }));
    }
    warnings.extend(estimate::quadratic::doubt(
        &model,
        huber.assessment.max_pole_radius,
        quadratic.as_ref(),
        "--bootstrap B",
    ));
    let covariance = cov.map(|c| c.chunks(dim).map(<[f64]>::to_vec).collect());
    let bootstrap = req
        .bootstrap
        .map(|replicates| {
            let settings = estimate::bootstrap::Settings { replicates, ..Default::default() };
            let pool = crate::pool::local(req.threads, "for the bootstrap")?;
            // The offset, when a parameter, is estimated in the data's units: nothing to convert.
            Ok(pool.install(|| estimate::bootstrap::run(&prob, &theta, Some(huber.k), &settings, &req.solver)))
        })
        .transpose()?;
    let parameters = crate::export::model::structure_parameter_names(largest, req.offset.estimated());
    // Reported in the data's units, as in the table.
    ls.offset = levels.offset(ls.offset);
    huber.offset = levels.offset(huber.offset);
    Ok(FitReport {
        data: req.data.clone(),
        n: est.len(),
        validation: val_path,
        validation_column: val.as_ref().map(|v| v.y_name.clone()),
        nb: first.nb,
        nf: first.nf,
        delay: first.delay,
        structure: *largest,
        ts: req.ts,
        band_hz: req.band,
        offset_mode: req.offset,
        input_level: (0..largest.m()).map(|i| levels.u0(i)).collect(),
        initial_state: req.initial_state,
        warnings,
        sigma: ls.sigma,
        converged: huber.termination.converged(),
        huber,
        parameters,
        covariance,
        start,
        quadratic,
        bootstrap,
        seconds,
        ls,
        gaps: None,
    })
}

/// Example data, `oesweep simulate`: the system file's OE model driven by a PRBS, with noise
/// and spikes as `opts` say, written to `out` as CSV (`u,y,y0`; a system of several inputs:
/// `u1,..,um,y,y0`, [`simulate::generate_inputs`]). Returns the samples written.
pub fn simulate(system: &Path, out: &Path, opts: &simulate::SimOptions) -> Result<usize> {
    let systems = simulate::read_systems(system)?;
    let rec = simulate::generate_inputs(&systems, opts)?;
    simulate::write_csv(out, &rec)?;
    Ok(opts.n)
}
