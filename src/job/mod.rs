//! The job file: read, default, validate -> [`ValidJob`], the only thing the planner accepts.
//!
//! A job is JSON (unknown fields are rejected). Relative paths resolve against the job file's
//! folder. Grid values of k are built from integer indices (`from + (to-from) i/(count-1)` or
//! its logarithmic twin), never by repeated float addition, so the same job always gives the
//! same k values bit for bit. Every field, default and allowed range is documented in docs/JOBS.md.

use crate::data::{self, ColumnRef, Delimiter, Header, Offset, ReadOptions};
use crate::error::{Error, Result};
use crate::estimate::InitialState;
use crate::estimate::SolverOptions;

mod grid;
mod inputs;
mod parse;
mod per_input;
mod uncertainty;
mod validate;

pub use crate::reduce::SelectionSettings;
pub use grid::{Grid, KGrid, KRange, SearchMode, Spacing};
pub use inputs::{
    Inputs, inputs_of_records, load_inputs, load_inputs_gaps, read_inputs, read_inputs_gaps, read_records,
    read_records_for,
};
pub use per_input::{Delays, InputColumns, InputGrid, Ranges, check_count, structure_of};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
pub use uncertainty::{Uncertainty, UncertaintyMethod};
use validate::{check_as_run, resolve_validation, validate};
pub use validate::{check_band, check_interpolate, check_k, check_order, check_sampling_period, check_solver};

/// Largest number of Huber cells a job may ask for.
pub const MAX_CELLS: usize = 200_000;
/// Largest order (nB or nF) a job may ask for: above any model of a SISO actuator worth
/// fitting (the paper's grid ends at 15), and below the order up to which pole reflection
/// works without allocation ([`crate::oe::STACK_ORDER`], checked at compile time).
pub const MAX_ORDER: usize = 60;
const _: () = assert!(MAX_ORDER <= crate::oe::STACK_ORDER);
/// The delay of a job that names none.
pub const DEFAULT_DELAY: usize = 1;

/// A data record as named in the job file.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DataSpec {
    /// Data file (text, Parquet or MAT). Required for the estimation record; the validation
    /// record defaults to the estimation record's file (then `rows` tells them apart).
    #[serde(default)]
    pub path: PathBuf,
    /// Input column: a name, or a 1-based position (default "u"; for the validation record,
    /// the estimation record's); or a list of them, one per input (several inputs).
    #[serde(default)]
    pub u: Option<InputColumns>,
    /// Output column. Default: "y" for the estimation record; for the validation record
    /// "y0" (noise-free output written by `oesweep simulate`) when the file has it, else the
    /// estimation record's.
    #[serde(default)]
    pub y: Option<ColumnRef>,
    /// Sampling period in seconds (required for the estimation record; the validation
    /// record's, when given, must be equal).
    #[serde(default)]
    pub ts: Option<f64>,
    /// Text files: `","`, `";"`, `"tab"` or `"whitespace"`; default: sniffed from the file.
    #[serde(default)]
    pub delimiter: Option<String>,
    /// Text files: `true`, `false` or `"auto"` (default; a first line of numbers is data).
    /// The validation record defaults to the estimation record's setting.
    #[serde(default)]
    pub header: Option<Header>,
    /// Data rows `[first, last]` (1-based, inclusive; the header is not a row). Default: all.
    #[serde(default)]
    pub rows: Option<[usize; 2]>,
    /// Markers of missing samples besides `NaN` and empty fields (`["NA", -999]`,
    /// [`data::Marker`]). Records 2.. of a list and the validation record default to the
    /// first record's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub missing: Option<Vec<data::Marker>>,
    /// Input gaps of at most this many samples between two present ones are filled by linear
    /// interpolation, and said (METHOD.md 21.1); default 0: none, every input gap splits the
    /// record. Defaults as `missing`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interpolate_inputs: Option<usize>,
}

impl DataSpec {
    /// The reader's options (the spec is checked by [`load`]).
    pub fn read_options(&self) -> ReadOptions {
        ReadOptions {
            delimiter: self.delimiter.as_deref().and_then(|d| Delimiter::parse(d).ok()),
            header: self.header.unwrap_or_default(),
            rows: self.rows,
            missing: self.missing.clone().unwrap_or_default(),
            interpolate_inputs: self.interpolate_inputs.unwrap_or(0),
        }
    }

    /// The input columns, one per input (validated specs always have them; default "u").
    pub fn u_cols(&self) -> Vec<ColumnRef> {
        self.u.as_ref().map_or_else(|| vec![ColumnRef::name("u")], |u| u.cols.clone())
    }

    /// The output column (validated specs always have one).
    pub fn y_col(&self) -> ColumnRef {
        self.y.clone().unwrap_or_else(|| ColumnRef::name("y"))
    }
}

/// One record named as the job file names it (path, columns, rows, delimiter, header,
/// missing), read on its own. The reader fields are checked as the job's, named `field 'rows'`
/// and so on.
pub fn read_record(spec: &DataSpec) -> Result<data::Record> {
    let raw = read_raw(spec)?;
    data::gaps::shape(raw, spec.read_options().interpolate_inputs, data::gaps::SHORTEST_SEGMENT).map(|(r, _)| r)
}

/// [`read_record`] as the file has it, missing samples NaN and nothing cut: the Python
/// package's `oesweep.read`, whose arrays `oesweep.fit` shapes as a job's record.
pub fn read_raw(spec: &DataSpec) -> Result<data::Raw> {
    validate::check_data_spec(spec, "data")
        .map_err(|(f, m)| Error::Invalid(format!("field '{}': {m}", f.trim_start_matches("data."))))?;
    data::read_raw(&spec.path, &spec.u_cols(), &spec.y_col(), &spec.read_options())
}

/// The records of `data` or `validation`: one object (the usual job) or a list of them, one per
/// experiment (METHOD.md 16). Written back in the form it was read, so the job.json of a
/// one-object job is what it always was.
#[derive(Clone, Debug, PartialEq)]
pub struct Records {
    /// At least one.
    pub specs: Vec<DataSpec>,
    /// Given as a list (even of one record).
    pub list: bool,
}

impl Records {
    /// One record as an object.
    pub fn one(spec: DataSpec) -> Records {
        Records { specs: vec![spec], list: false }
    }

    /// The first record: the one whose settings the others default to.
    pub fn first(&self) -> &DataSpec {
        &self.specs[0]
    }

    pub fn first_mut(&mut self) -> &mut DataSpec {
        &mut self.specs[0]
    }

    /// The records with their field names in messages: `data` for an object, `data[i]` in a
    /// list.
    pub fn named<'a>(&'a self, field: &'a str) -> impl Iterator<Item = (String, &'a DataSpec)> + 'a {
        let list = self.list;
        self.specs
            .iter()
            .enumerate()
            .map(move |(i, s)| (if list { format!("{field}[{i}]") } else { field.to_string() }, s))
    }
}

impl Serialize for Records {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        if self.list { self.specs.serialize(s) } else { self.specs[0].serialize(s) }
    }
}

/// One record (an object) or a list of them; a bad record is named by its place
/// (`data[1].rows`, [`parse`]).
impl<'de> Deserialize<'de> for Records {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = Records;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a record {\"path\": ...} or a list of them")
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> std::result::Result<Records, A::Error> {
                DataSpec::deserialize(serde::de::value::MapAccessDeserializer::new(map)).map(Records::one)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> std::result::Result<Records, A::Error> {
                let mut specs = Vec::new();
                while let Some(spec) = seq.next_element::<DataSpec>()? {
                    specs.push(spec);
                }
                if specs.is_empty() {
                    return Err(serde::de::Error::custom(
                        "an empty list, expected one record {\"path\": ...} or a list of them",
                    ));
                }
                Ok(Records { specs, list: true })
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// Where each Huber fit starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum StartStrategy {
    /// Continuation chains along increasing k, one per start (theta_LS and the pair's extra
    /// starts), merged when they reach the same minimum; each cell keeps the best chain
    /// ([`crate::estimate::Chains`]). As good as `ls` against an independent solver at about a
    /// third of its cost.
    #[default]
    Chains,
    /// From the order pair's least-squares fit (METHOD.md 5), every cell independent.
    Ls,
    /// Continuation along k: from the solution at the next larger k (the largest k from the
    /// least-squares fit). About half the iterations, but it may end in another local minimum.
    Neighbour,
    /// Both starts; keep the lower criterion. Never worse than `ls`.
    Best,
}

crate::names::names!(StartStrategy { Chains = "chains", Ls = "ls", Neighbour = "neighbour", Best = "best" });

/// Smallest `solver.explore_rows`: a shorter head says too little about lightly damped modes.
const MIN_EXPLORE_ROWS: usize = 1000;

/// The job file as written (before validation).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Job {
    pub name: String,
    /// The estimation record, or a list of records (experiments).
    pub data: Records,
    /// The validation record, or a list of records.
    #[serde(default)]
    pub validation: Option<Records>,
    /// One input delay for the whole grid (shorthand of `grid.delay` = [d, d]), or a list of
    /// them, one per input.
    #[serde(default)]
    pub delay: Option<Delays>,
    /// Offsets of the signals ([`data::levels`]).
    #[serde(default)]
    pub offset: Offset,
    /// The initial state the fits are judged with ([`InitialState`]).
    #[serde(default)]
    pub initial_state: InitialState,
    /// The spectral estimate `fit_band` compares with ([`crate::spectral::SpectrumMethod`]).
    #[serde(default)]
    pub spectrum: crate::spectral::SpectrumMethod,
    pub grid: Grid,
    #[serde(default)]
    pub band_hz: Option<[f64; 2]>,
    #[serde(default)]
    pub solver: SolverOptions,
    #[serde(default)]
    pub start: StartStrategy,
    #[serde(default)]
    pub selection: SelectionSettings,
    /// The picks' uncertainty ([`Uncertainty`]).
    #[serde(default, skip_serializing_if = "Uncertainty::is_local")]
    pub uncertainty: Uncertainty,
    /// Output folder.
    pub output: PathBuf,
}

/// A checked job: every field in range, paths resolved, the validation record's output column
/// and sampling period filled in, the k grid expanded. Built once ([`load`], or [`read_as_run`]
/// for the job a run wrote) and never changed afterwards; the records are read beside it
/// ([`load_inputs`]).
#[derive(Clone, Debug)]
pub struct ValidJob {
    /// The job file (or the job.json it was read back from).
    pub file: PathBuf,
    /// Normalised job (resolved paths and columns, k as an explicit list): written as job.json.
    pub job: Job,
    /// Number of inputs m (the input columns of every record).
    pub m: usize,
    /// Each input's grid, in the order of the input columns.
    pub grids: Vec<InputGrid>,
    /// The first input's grid (`grids[0]`: all of it for one input, which the single-input
    /// planner reads).
    pub nb: Vec<usize>,
    pub nf: Vec<usize>,
    pub delays: Vec<usize>,
    pub ks: Vec<f64>,
}

/// `job.json` of a run: the normalised job and the program that ran it.
#[derive(Serialize)]
struct JobAsRun<'a> {
    format_version: u32,
    oesweep_version: &'static str,
    #[serde(flatten)]
    job: &'a Job,
}

impl ValidJob {
    /// The grid of a normalised job (`grid.delay` set, k a list; [`validate`] made it so):
    /// the one expansion of the grid into its values.
    fn of_normalised(file: &Path, job: Job) -> ValidJob {
        let m = job.data.first().u_cols().len();
        let range = |[a, b]: [usize; 2]| (a..=b).collect::<Vec<usize>>();
        let each = |r: &Ranges| -> Vec<Vec<usize>> {
            r.per_input("", m).expect("validated").into_iter().map(|(_, r)| range(r)).collect()
        };
        let delay = job.grid.delay.clone().unwrap_or(Ranges::One([DEFAULT_DELAY; 2]));
        let (nb, nf, delays) = (each(&job.grid.nb), each(&job.grid.nf), each(&delay));
        let grids: Vec<InputGrid> =
            (0..m).map(|i| InputGrid { nb: nb[i].clone(), nf: nf[i].clone(), delays: delays[i].clone() }).collect();
        let first = grids[0].clone();
        ValidJob {
            file: file.to_path_buf(),
            m,
            grids,
            nb: first.nb,
            nf: first.nf,
            delays: first.delays,
            ks: k_values(&job.grid.k),
            job,
        }
    }

    /// Write the job as run (`job.json` of an output or a checkpoint folder), for
    /// [`read_as_run`].
    pub fn write_as_run(&self, path: &Path) -> Result<()> {
        crate::export::json::write_json(
            path,
            &JobAsRun {
                format_version: crate::export::FORMAT_VERSION,
                oesweep_version: env!("CARGO_PKG_VERSION"),
                job: &self.job,
            },
        )
    }

    /// The largest orders and delay of the first input's grid (all of it for one input).
    pub fn largest(&self) -> (usize, usize, usize) {
        (*self.nb.last().unwrap(), *self.nf.last().unwrap(), *self.delays.last().unwrap())
    }

    /// The largest model of the grid, every input at its largest orders and delay: the records
    /// must be long enough for it.
    pub fn largest_structure(&self) -> crate::oe::Structure {
        let last = |v: &[usize]| *v.last().expect("validated");
        let orders: Vec<crate::oe::Orders> = self
            .grids
            .iter()
            .map(|g| crate::oe::Orders { nb: last(&g.nb), nf: last(&g.nf), delay: last(&g.delays) })
            .collect();
        crate::oe::Structure::new(&orders).expect("validated: 1 to MAX_INPUTS inputs")
    }

    /// The structures of the grid: the product over the inputs of each input's (nB, nF, d).
    pub fn n_pairs(&self) -> usize {
        self.grids.iter().map(InputGrid::len).product()
    }
    pub fn n_cells(&self) -> usize {
        self.n_pairs() * self.ks.len()
    }
    pub fn output(&self) -> &Path {
        &self.job.output
    }
    pub fn ts(&self) -> f64 {
        self.job.data.first().ts.expect("validated")
    }
}

/// Expand a k grid (index-based, endpoints exact).
pub fn k_values(k: &KGrid) -> Vec<f64> {
    match k {
        KGrid::List(v) => v.clone(),
        KGrid::Range(r) => {
            if r.count == 1 {
                return vec![r.from];
            }
            let last = (r.count - 1) as f64;
            (0..r.count)
                .map(|i| {
                    if i == 0 {
                        r.from
                    } else if i == r.count - 1 {
                        r.to
                    } else {
                        let s = i as f64 / last;
                        match r.spacing {
                            Spacing::Linear => r.from + (r.to - r.from) * s,
                            Spacing::Log => (r.from.ln() + (r.to.ln() - r.from.ln()) * s).exp(),
                        }
                    }
                })
                .collect()
        }
    }
}

/// Read and validate a job file. Does not touch the data files (see [`load_inputs`]).
pub fn load(path: &Path) -> Result<ValidJob> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot read job file: {e}")))?;
    from_text(path, &text)
}

/// Validate a job given as JSON text rather than read from a file (the Python package's jobs
/// built in memory): `path` names the job in messages and its folder is the base of relative
/// paths, as for the job file [`load`] reads; nothing is read at `path` itself.
pub fn from_text(path: &Path, text: &str) -> Result<ValidJob> {
    // A byte-order mark (written by some Windows editors) is not JSON but is no error either.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    // serde would read a top-level array positionally and complain about its first element.
    if let Ok(v) = serde_json::from_str::<serde_json::Value>(text)
        && !v.is_object()
    {
        return Err(Error::input(path, "invalid job: the file must hold one JSON object { ... }"));
    }
    let job: Job = parse::from_text(text).map_err(|e| Error::input(path, format!("invalid job: {e}")))?;
    let job = resolve_validation(validate(path, job)?)?;
    Ok(ValidJob::of_normalised(path, job))
}

/// Read back the job a run wrote ([`ValidJob::write_as_run`]: `job.json` of an output or a
/// checkpoint folder), for `oesweep merge`, `export` and the report: the same [`Job`] type,
/// checked by the job file's rules but for the files ([`validate::check_as_run`]). Files of versions before the
/// `offset`, `initial_state` and `spectrum` fields ran the paper's model: absent, they read as
/// "none", "zero" and "welch". Relative data paths (a hand-made file) are taken from `path`'s
/// folder.
pub fn read_as_run(path: &Path) -> Result<(ValidJob, Option<String>)> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    let bad = |e: String| Error::input(path, format!("not the job.json `oesweep run` writes: {}", data::one_line(&e)));
    let mut v: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let obj = v.as_object_mut().ok_or_else(|| bad("not a JSON object".into()))?;
    crate::export::json::take_format(obj).map_err(|m| Error::input(path, m))?;
    let version = obj.remove("oesweep_version").and_then(|v| v.as_str().map(str::to_string));
    for (field, paper) in [("offset", "none"), ("initial_state", "zero"), ("spectrum", "welch")] {
        obj.entry(field).or_insert_with(|| paper.into());
    }
    let mut job: Job = parse::from_value(v).map_err(bad)?;
    let folder = path.parent().unwrap_or(Path::new("."));
    let resolve = |p: &Path| if p.is_absolute() { p.to_path_buf() } else { folder.join(p) };
    for spec in job.data.specs.iter_mut().chain(job.validation.iter_mut().flat_map(|v| v.specs.iter_mut())) {
        spec.path = resolve(&spec.path);
    }
    // Edited by hand or not, the file is input: the job file's rules, so that an order range
    // [2, 1] or a k count of 1e15 is this error rather than a panic or an abort further on.
    check_as_run(&mut job).map_err(|(f, m)| Error::input(path, data::one_line(&format!("field '{f}': {m}"))))?;
    Ok((ValidJob::of_normalised(path, job), version))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn k_grid_is_index_based_with_exact_ends() {
        let r = KGrid::Range(KRange { from: 0.05, to: 2.0, count: 40, spacing: Spacing::Log });
        let k = k_values(&r);
        assert_eq!(k.len(), 40);
        assert_eq!(k[0], 0.05);
        assert_eq!(k[39], 2.0);
        assert!(k.windows(2).all(|w| w[1] > w[0]));
        let lin = k_values(&KGrid::Range(KRange { from: 0.1, to: 1.0, count: 10, spacing: Spacing::Linear }));
        assert_eq!(lin[3], 0.1 + 0.9 * (3.0 / 9.0));
    }

    #[test]
    fn byte_order_mark_is_accepted_and_output_probe_leaves_no_trace() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("job.json");
        let job = r#"{"name": "x", "data": {"path": "d.csv", "ts": 1}, "grid": {"nb": [1, 1], "nf": [0, 0], "k": [1]},
            "output": "a/b"}"#;
        std::fs::write(&p, format!("\u{feff}{job}")).unwrap();
        let vj = load(&p).unwrap();
        assert!(vj.output().ends_with("a/b"));
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(left, vec![std::ffi::OsString::from("job.json")]);
    }

    #[test]
    fn a_run_reads_back_the_job_it_wrote() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("job.json");
        let job = r#"{"name": "x", "data": {"path": "d.csv", "ts": 0.5}, "delay": 2, "offset": "mean",
            "grid": {"nb": [1, 3], "nf": [0, 2], "k": {"from": 0.05, "to": 2, "count": 7}}, "output": "out"}"#;
        std::fs::write(&p, job).unwrap();
        let vj = load(&p).unwrap();
        let written = dir.path().join("as-run.json");
        vj.write_as_run(&written).unwrap();
        let (back, version) = read_as_run(&written).unwrap();
        assert_eq!(version.as_deref(), Some(env!("CARGO_PKG_VERSION")));
        assert_eq!(serde_json::to_value(&back.job).unwrap(), serde_json::to_value(&vj.job).unwrap());
        // The grid bit for bit: merge's plan must name the cells the run computed.
        assert_eq!((&back.nb, &back.nf, &back.delays), (&vj.nb, &vj.nf, &vj.delays));
        let bits = |ks: &[f64]| ks.iter().map(|k| k.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&back.ks), bits(&vj.ks));
        assert_eq!(vj.delays, vec![2]);
        assert_eq!(back.ts(), 0.5);
    }

    #[test]
    fn a_job_given_as_text_is_the_job_file_it_names_and_nothing_is_read_there() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("job.json");
        let job = r#"{"name": "x", "data": {"path": "d.csv", "ts": 0.5}, "grid": {"nb": [1, 2], "nf": [1, 2],
            "k": [1]}, "output": "out"}"#;
        std::fs::write(&p, job).unwrap();
        let from_file = load(&p).unwrap();
        let named = dir.path().join("never-written.json");
        let given = from_text(&named, job).unwrap();
        assert_eq!(serde_json::to_value(&given.job).unwrap(), serde_json::to_value(&from_file.job).unwrap());
        assert_eq!(given.file, named);
        assert!(!named.exists());
        let e = from_text(&named, r#"{"name": "x", "grdi": {}}"#).unwrap_err();
        assert!(matches!(e, Error::Input { .. }) && e.to_string().starts_with(&named.display().to_string()), "{e}");
    }

    #[test]
    fn an_older_job_json_reads_with_the_paper_model() {
        // Written before `offset`, `initial_state` and `spectrum` existed, and before
        // `oesweep_version`: those runs took no offset out, judged from a zero state and drew
        // plain Welch, which are not today's defaults.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("job.json");
        let job = r#"{"name": "x", "data": {"path": "d.csv", "ts": 1}, "grid": {"nb": [2, 2], "nf": [1, 1],
            "k": [0.5, 1], "delay": [1, 1]}, "output": "out"}"#;
        std::fs::write(&p, job).unwrap();
        let (vj, version) = read_as_run(&p).unwrap();
        assert_eq!(version, None);
        assert_eq!(vj.job.offset, Offset::None);
        assert_eq!(vj.job.initial_state, InitialState::Zero);
        assert_eq!(vj.job.spectrum, crate::spectral::SpectrumMethod::Welch);
        assert_eq!(vj.job.data.first().path, dir.path().join("d.csv"));
        assert_eq!(vj.ks, vec![0.5, 1.0]);
        assert_eq!(vj.largest(), (2, 1, 1));
    }
}
