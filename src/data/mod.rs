//! Reading input/output records (METHOD.md section 1) from the files people publish.
//!
//! A record is two equally long numeric columns, the input `u` and the measured output `y`,
//! taken from one file, optionally restricted to a range of its data rows (so one experiment
//! can give both the estimation and the validation record). The format is chosen by extension:
//!
//! - `.parquet` / `.pq`: Parquet, read with polars ([`parquet`]);
//! - `.mat`: MATLAB level-5 MAT-file (the default of `save` up to `-v7`), read with the
//!   `matfile` crate; `u` and `y` name numeric vector variables ([`mat`]). A `-v7.3` file is
//!   HDF5 and is refused with a hint how to re-save it;
//! - anything else: delimited text read with the `csv` crate ([`text`]): RFC 4180 quoting,
//!   fields separated by `,`, `;`, tabs or runs of whitespace (sniffed from the first lines
//!   unless given), a header row or none (`header`: true, false or auto-detected), a byte-order
//!   mark, CRLF line ends, a trailing delimiter on every line and blank lines at the end.
//!
//! Columns are chosen by name or by 1-based position ([`ColumnRef`]). Columns that are not
//! selected are not looked at (they may be empty, text or have missing values); in the selected
//! ones every value is a finite number or a missing sample (NaN, an empty field, a null, a
//! declared marker), and a record with missing samples takes its shape in [`gaps`] (METHOD.md
//! 21.1).
//!
//! Every problem is one [`Error::Data`] naming the file and, where it applies, the line (text,
//! 1-based, counting the header) or row (Parquet and MAT, 1-based data row) and the column: the
//! user should be able to open the file at the right place from the message alone.

mod checks;
pub mod gaps;
pub mod levels;
mod mat;
pub(crate) mod parquet;
mod text;

pub use checks::{check_for_model, check_for_structure, check_inputs_distinct, min_samples, min_samples_of};
pub use gaps::{Gaps, Marker, Raw, RecordGaps, read_record_gaps};
pub use levels::{Levels, Offset};

use std::cell::Cell;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// One identification record: the input and output columns of a data file.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// The file the record was read from (used in later error messages).
    pub path: PathBuf,
    /// Input samples, input after input: `u[i N .. (i+1) N]` is input i's `u_1..u_N`
    /// ([`Record::input`]; one input: the whole vector).
    pub u: Vec<f64>,
    /// Output samples `y_1..y_N` (same length as `u`).
    pub y: Vec<f64>,
    /// Names of the input columns in the file (header names, or "column 3" without one), one
    /// per input.
    pub u_names: Vec<String>,
    /// Name of the output column in the file.
    pub y_name: String,
    /// Where the experiments after the first begin, when the record is several experiments
    /// concatenated ([`Record::concat`]; METHOD.md 16): empty for one experiment. Simulations
    /// restart from zero there and no lag reaches across.
    pub seams: Vec<usize>,
    /// The samples whose output is missing (sorted; `y` holds NaN there): the model is
    /// simulated through them and their residuals are left out of every criterion, fit and
    /// test (METHOD.md 21). Empty for a complete record.
    pub missing: Vec<usize>,
}

/// The ranges `[0, s_1), [s_1, s_2), ..., [s_k, n)` of experiments separated by `seams`.
pub fn experiment_ranges(n: usize, seams: &[usize]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::with_capacity(seams.len() + 1);
    let mut start = 0;
    for &s in seams {
        out.push(start..s);
        start = s;
    }
    out.push(start..n);
    out
}

/// The stretches of consecutive observed outputs: the experiments separated by `seams`, cut
/// at every missing sample of `missing` (sorted), empty stretches left out. What methods that
/// need an unbroken output history (ARX starts, spectral segments, lagged residual
/// correlations) work on (METHOD.md 21).
pub fn observed_ranges(n: usize, seams: &[usize], missing: &[usize]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::with_capacity(seams.len() + missing.len() + 1);
    let mut gaps = missing.iter().copied().peekable();
    for e in experiment_ranges(n, seams) {
        let mut start = e.start;
        while let Some(&t) = gaps.peek() {
            if t >= e.end {
                break;
            }
            gaps.next();
            if t >= start {
                if t > start {
                    out.push(start..t);
                }
                start = t + 1;
            }
        }
        if start < e.end {
            out.push(start..e.end);
        }
    }
    out
}

impl Record {
    /// A record from samples in memory (the Python package's arrays), `label` standing for the
    /// file in messages: the same rules as a file's numbers (equal lengths, every sample finite
    /// or NaN, a missing sample, [`gaps`]).
    pub fn from_arrays(label: &str, u: Vec<f64>, y: Vec<f64>) -> Result<Record> {
        Record::from_input_arrays(label, vec![u], y)
    }

    /// [`Record::from_arrays`] of several inputs, one array each, named `u1`, `u2`, ... in
    /// messages (one input: `u`): every input as long as `y`. Shaped as a record read without a
    /// grid ([`gaps::SHORTEST_SEGMENT`]); [`Raw::from_arrays`] and [`gaps::shape`] shape it for
    /// a model.
    pub fn from_input_arrays(label: &str, inputs: Vec<Vec<f64>>, y: Vec<f64>) -> Result<Record> {
        let raw = Raw::from_arrays(label, inputs, y)?;
        gaps::shape(raw, 0, gaps::SHORTEST_SEGMENT).map(|(rec, _)| rec)
    }

    /// Several experiments as one record: the samples one after the other, with a seam where
    /// each experiment after the first begins. The path and column names are the first's. One
    /// record is returned as it is.
    pub fn concat(mut records: Vec<Record>) -> Record {
        assert!(!records.is_empty(), "no record to concatenate");
        if records.len() == 1 {
            return records.remove(0);
        }
        let m = records[0].inputs();
        let n: usize = records.iter().map(Record::len).sum();
        let mut u = Vec::with_capacity(m * n);
        for i in 0..m {
            for r in &records {
                u.extend_from_slice(r.input(i));
            }
        }
        let mut all = records.remove(0);
        for r in records {
            let at = all.y.len();
            all.seams.push(at);
            all.missing.extend(r.missing.iter().map(|t| t + at));
            all.y.extend_from_slice(&r.y);
        }
        all.u = u;
        all
    }

    /// Number of inputs m.
    pub fn inputs(&self) -> usize {
        self.u_names.len()
    }

    /// Input i's samples `u_i,1..u_i,N`.
    pub fn input(&self, i: usize) -> &[f64] {
        let n = self.len();
        &self.u[i * n..(i + 1) * n]
    }

    /// The sample ranges of the experiments (one range for a single experiment).
    pub fn experiments(&self) -> Vec<std::ops::Range<usize>> {
        experiment_ranges(self.len(), &self.seams)
    }

    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// True when the record holds no sample (never the case for a record read from a file).
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }
}

/// A column of a data file: its name (header name, Parquet column, MAT variable) or its
/// 1-based position (a JSON integer in the job file; digits on the command line).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(untagged)]
pub enum ColumnRef {
    Position(usize),
    Name(String),
}

/// By hand rather than `untagged`, whose error names neither form.
impl<'de> Deserialize<'de> for ColumnRef {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = ColumnRef;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a column name or a 1-based column index")
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<ColumnRef, E> {
                usize::try_from(v)
                    .map(ColumnRef::Position)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(v), &self))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<ColumnRef, E> {
                u64::try_from(v)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(v), &self))
                    .and_then(|v| self.visit_u64(v))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<ColumnRef, E> {
                Ok(ColumnRef::Name(v.to_string()))
            }
        }
        d.deserialize_any(Visitor)
    }
}

impl ColumnRef {
    /// A command-line column: digits are a position, anything else a name.
    pub fn parse(s: &str) -> ColumnRef {
        match s.parse::<usize>() {
            Ok(p) if !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) => ColumnRef::Position(p),
            _ => ColumnRef::Name(s.to_string()),
        }
    }

    pub fn name(s: &str) -> ColumnRef {
        ColumnRef::Name(s.to_string())
    }
}

impl std::fmt::Display for ColumnRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ColumnRef::Name(n) => write!(f, "'{}'", one_line(n)),
            ColumnRef::Position(p) => write!(f, "{p}"),
        }
    }
}

/// Whether a text file starts with a header row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Header {
    Yes,
    No,
    /// A first line whose fields all parse as numbers is data; otherwise it is the header.
    #[default]
    Auto,
}

impl Serialize for Header {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self {
            Header::Yes => s.serialize_bool(true),
            Header::No => s.serialize_bool(false),
            Header::Auto => s.serialize_str("auto"),
        }
    }
}

impl<'de> Deserialize<'de> for Header {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Header;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("true, false or \"auto\"")
            }
            fn visit_bool<E: serde::de::Error>(self, v: bool) -> std::result::Result<Header, E> {
                Ok(if v { Header::Yes } else { Header::No })
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<Header, E> {
                match v {
                    "auto" => Ok(Header::Auto),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
        }
        d.deserialize_any(Visitor)
    }
}

/// The field separator of a text file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    /// One byte: `,`, `;` or a tab.
    Byte(u8),
    /// Runs of spaces and tabs (leading and trailing ones ignored), as in DaISy files.
    Whitespace,
}

impl Delimiter {
    /// The job file's spelling: `","`, `";"`, `"tab"` (or a tab character), `"whitespace"`.
    pub fn parse(s: &str) -> std::result::Result<Delimiter, String> {
        match s {
            "," => Ok(Delimiter::Byte(b',')),
            ";" => Ok(Delimiter::Byte(b';')),
            "\t" | "tab" => Ok(Delimiter::Byte(b'\t')),
            "whitespace" | " " => Ok(Delimiter::Whitespace),
            other => Err(format!("\"{}\" is not one of \",\", \";\", \"tab\", \"whitespace\"", one_line(other))),
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Delimiter::Byte(b',') => ",",
            Delimiter::Byte(b';') => ";",
            Delimiter::Byte(b'\t') => "tab",
            Delimiter::Byte(_) => "?",
            Delimiter::Whitespace => "whitespace",
        }
    }
}

/// How to read a file besides which columns: the text dialect and the row range.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadOptions {
    /// Text files: the separator; `None` = sniffed from the first lines.
    pub delimiter: Option<Delimiter>,
    /// Text files: whether the first line is a header.
    pub header: Header,
    /// Data rows `[first, last]`, 1-based and inclusive (the header is not a row); `None` =
    /// all rows.
    pub rows: Option<[usize; 2]>,
    /// Markers of a missing sample besides NaN and empty fields ([`Marker`]).
    pub missing: Vec<Marker>,
    /// Input gaps of at most this many samples filled by linear interpolation ([`gaps::shape`]);
    /// 0: none.
    pub interpolate_inputs: usize,
}

/// The rule for a row range, shared by the job file and `oesweep fit` (the caller names the
/// field or flag).
pub fn check_rows([first, last]: [usize; 2]) -> std::result::Result<(), String> {
    if first >= 1 && first <= last {
        Ok(())
    } else {
        Err(format!("[{first}, {last}] is not a range [first, last] of data rows with 1 <= first <= last"))
    }
}

/// Column names of a file (text header, Parquet schema or numeric MAT variables), in file
/// order; empty for a text file without a header.
pub fn column_names(path: &Path, opts: &ReadOptions) -> Result<Vec<String>> {
    match Format::of(path) {
        Format::Parquet => guarded(path, "Parquet", || parquet::column_names(path)),
        Format::Mat => mat::column_names(path),
        Format::Text => text::column_names(path, opts),
    }
}

/// The output column of a validation record: `given` when set; otherwise `y0` (the noise-free
/// output `oesweep simulate` writes) when the file has that column, else `otherwise`. The one
/// home of this default, for the job file, `oesweep fit` and the report.
pub fn validation_column(
    path: &Path,
    given: Option<&ColumnRef>,
    otherwise: &ColumnRef,
    opts: &ReadOptions,
) -> Result<ColumnRef> {
    Ok(match given {
        Some(c) => c.clone(),
        None if column_names(path, opts)?.iter().any(|c| c == "y0") => ColumnRef::name("y0"),
        None => otherwise.clone(),
    })
}

/// Reads the columns named `u_col` and `y_col` of a file, all rows, default dialect.
pub fn read_record(path: &Path, u_col: &str, y_col: &str) -> Result<Record> {
    read_record_with(path, &ColumnRef::name(u_col), &ColumnRef::name(y_col), &ReadOptions::default())
}

/// Reads the input column `u` and the output column `y` of a file, as `opts` says
/// ([`read_record_inputs`] of one input).
pub fn read_record_with(path: &Path, u: &ColumnRef, y: &ColumnRef, opts: &ReadOptions) -> Result<Record> {
    read_record_inputs(path, std::slice::from_ref(u), y, opts)
}

/// Reads the input columns `u` (one per input, in the model's order) and the output column `y`
/// of a file, as `opts` says: one record, its inputs one after the other, shaped as a record read
/// without a grid ([`read_record_gaps`] with [`gaps::SHORTEST_SEGMENT`]).
pub fn read_record_inputs(path: &Path, u: &[ColumnRef], y: &ColumnRef, opts: &ReadOptions) -> Result<Record> {
    read_record_gaps(path, u, y, opts, gaps::SHORTEST_SEGMENT).map(|(rec, _)| rec)
}

/// The input columns `u` and the output column `y` of a file as `opts` says, every row of the
/// range, a missing sample NaN ([`gaps`]).
///
/// All checks of [`read_columns_with`] apply; in addition no column may be named twice, nor be
/// both an input and the output (by its reference or by the column it resolves to).
pub fn read_raw(path: &Path, u: &[ColumnRef], y: &ColumnRef, opts: &ReadOptions) -> Result<Raw> {
    if u.is_empty() {
        return Err(input_error(path, "no input column: give at least one"));
    }
    if let Some(c) = u.iter().find(|&c| c == y) {
        return Err(input_error(path, format!("the input and the output column are both {c}")));
    }
    for (i, c) in u.iter().enumerate() {
        if u[..i].contains(c) {
            return Err(input_error(path, format!("input column {c} is named twice")));
        }
    }
    let cols: Vec<ColumnRef> = u.iter().chain([y]).cloned().collect();
    let Columns { mut names, mut values } = read_columns_with(path, &cols, opts)?;
    let (y, y_name) = (values.pop().expect("the output column"), names.pop().expect("the output column"));
    if let Some(n) = names.iter().find(|&n| *n == y_name) {
        return Err(input_error(path, format!("the input and the output column are both '{n}'")));
    }
    for (i, n) in names.iter().enumerate() {
        if let Some(j) = names[..i].iter().position(|m| m == n) {
            return Err(input_error(path, format!("input column '{n}' is named twice (as {} and as {})", u[j], u[i])));
        }
    }
    Ok(Raw { path: path.to_path_buf(), u: values.concat(), y, u_names: names, y_name })
}

/// Reads the named numeric columns of a file, all rows, default dialect, in the order of
/// `names`.
pub fn read_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    let cols: Vec<ColumnRef> = names.iter().map(|n| ColumnRef::name(n)).collect();
    Ok(read_columns_with(path, &cols, &ReadOptions::default())?.values)
}

/// Columns read from a file: their names (as the file calls them) and values.
#[derive(Debug, Clone, PartialEq)]
pub struct Columns {
    pub names: Vec<String>,
    pub values: Vec<Vec<f64>>,
}

/// Reads the numeric columns `cols` of a file (format chosen by extension, see the module
/// docs), in the order of `cols`, restricted to `opts.rows`.
///
/// Fails with one [`Error::Data`] when the file cannot be read, a column is missing, the file
/// has no data row, the row range reaches past the file, or any selected value is neither a
/// finite number nor a missing sample (which is NaN, [`gaps`]).
pub fn read_columns_with(path: &Path, cols: &[ColumnRef], opts: &ReadOptions) -> Result<Columns> {
    if let Some(rows) = opts.rows {
        check_rows(rows).map_err(|m| input_error(path, format!("rows {m}")))?;
    }
    match Format::of(path) {
        Format::Parquet => {
            guarded(path, "Parquet", || parquet::read_columns(path, cols, opts.rows, &gaps::Markers::of(&opts.missing)))
        }
        Format::Mat => mat::read_columns(path, cols, opts.rows, &gaps::Markers::of(&opts.missing)),
        Format::Text => text::read_columns(path, cols, opts),
    }
}

/// A data error whose message is kept on one line: it quotes names and values taken from
/// job and data files (and messages of the readers), any of which may hold a line break.
fn input_error(path: &Path, msg: impl Into<String>) -> Error {
    Error::data(path, one_line(&msg.into()))
}

/// `s` with control characters escaped (`\n`, `\u{1b}`): names taken from job or data files
/// are quoted in messages, and a message must stay on one line.
pub(crate) fn one_line(s: &str) -> String {
    s.chars().fold(String::with_capacity(s.len()), |mut out, c| {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
        out
    })
}

thread_local! {
    /// Depth of [`guarded`] calls on this thread.
    static READING: Cell<usize> = const { Cell::new(0) };
}

/// True while this thread runs a data reader inside [`guarded`], whose panic becomes an input
/// error. For a program's own panic hook that wants to leave such panics unprinted (the
/// `oesweep` binary's, [`crate::cli::quiet_reader_panics`]); the library installs no hook.
pub fn reading_data() -> bool {
    READING.with(|r| r.get() > 0)
}

/// Runs `read` and turns a panic into an input error. The Parquet decoder (and the MAT parser)
/// trusts the file's metadata and panics on some corrupt files (an `unwrap` on a missing
/// statistic, found by mutating a valid file), and a bad file must be an input error, not a
/// crash. Caught here, on the calling thread (the readers decode there: see
/// `parquet::read_columns`); whether the panic message is printed is the process's panic
/// hook's business ([`reading_data`]).
fn guarded<T>(path: &Path, format: &str, read: impl FnOnce() -> Result<T>) -> Result<T> {
    READING.with(|r| r.set(r.get() + 1));
    let outcome = panic::catch_unwind(AssertUnwindSafe(read));
    READING.with(|r| r.set(r.get() - 1));
    outcome.unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown failure".into());
        Err(input_error(path, format!("not a readable {format} file: the reader failed ({what})")))
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Parquet,
    Mat,
    Text,
}

impl Format {
    fn of(path: &Path) -> Format {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        if ext.eq_ignore_ascii_case("parquet") || ext.eq_ignore_ascii_case("pq") {
            Format::Parquet
        } else if ext.eq_ignore_ascii_case("mat") {
            Format::Mat
        } else {
            Format::Text
        }
    }
}

/// The columns of a file, listed for a "no column" message; long headers are abbreviated.
fn list_columns(all: &[impl AsRef<str>]) -> String {
    const SHOWN: usize = 20;
    let mut s = all.iter().take(SHOWN).map(|c| c.as_ref()).collect::<Vec<_>>().join(", ");
    if all.len() > SHOWN {
        s.push_str(&format!(", ... ({} in all)", all.len()));
    }
    s
}

fn missing_column(path: &Path, name: &str, all: &[impl AsRef<str>]) -> Error {
    input_error(path, format!("no column '{name}' (columns: {})", list_columns(all)))
}

/// One value of a selected column: itself, NaN for a missing sample (NaN, a marker), or the
/// error of an infinite value; `place` is "line 7" or "row 7".
fn sample(path: &Path, place: &str, col: &str, v: f64, markers: &gaps::Markers) -> Result<f64> {
    if v.is_nan() || markers.is_value(v) {
        Ok(f64::NAN)
    } else if v.is_infinite() {
        Err(input_error(path, format!("{place}, column '{col}': infinite value")))
    } else {
        Ok(v)
    }
}

/// The 0-based index range of `rows` in a file of `n` data rows (all of them for `None`), or
/// the error naming what is outside.
fn row_range(path: &Path, rows: Option<[usize; 2]>, n: usize) -> Result<std::ops::Range<usize>> {
    if n == 0 {
        return Err(input_error(path, "no data rows"));
    }
    match rows {
        None => Ok(0..n),
        Some([first, last]) if last <= n => Ok(first - 1..last),
        Some([first, last]) => Err(input_error(
            path,
            format!("rows [{first}, {last}] reach past the end of the file: it has {n} data rows"),
        )),
    }
}

/// Resolves `cols` against a file's column `names` (in file order): the 0-based index of each,
/// or one error naming what is missing, ambiguous or out of range. `kind` is "column" or
/// "variable" for the messages.
fn resolve_columns(path: &Path, cols: &[ColumnRef], names: &[String], width: usize) -> Result<Vec<usize>> {
    cols.iter()
        .map(|c| match c {
            ColumnRef::Position(0) => {
                Err(input_error(path, "column position 0: positions count from 1 (the first column is 1)"))
            }
            ColumnRef::Position(p) if *p > width => {
                Err(input_error(path, format!("column position {p}: the file has {width} columns")))
            }
            ColumnRef::Position(p) => Ok(p - 1),
            ColumnRef::Name(n) => {
                let mut hits = names.iter().enumerate().filter(|(_, h)| *h == n).map(|(i, _)| i);
                match (hits.next(), hits.next()) {
                    (Some(i), None) => Ok(i),
                    (Some(_), Some(_)) => Err(input_error(path, format!("column '{n}' appears twice in the header"))),
                    (None, _) => Err(missing_column(path, n, names)),
                }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
