//! Reading input/output records (METHOD.md section 1) from CSV or Parquet files.
//!
//! A record is two equally long numeric columns, the input `u` and the measured output `y`,
//! taken from one file. The file format is chosen by extension: `.parquet` / `.pq` are read
//! with polars, anything else is parsed as CSV by the small parser below.
//!
//! CSV dialect, deliberately strict so that a malformed file is reported rather than guessed at:
//! a header row is required, fields are separated by `,`, whitespace around fields and names is
//! trimmed, lines end in `\n` or `\r\n`, a final line break (and a UTF-8 byte-order mark, which
//! spreadsheet programs write) is accepted; nothing else is skipped, so a blank or short line in
//! the middle of the data is an error. Quoting is not supported (numeric data never needs it).
//!
//! Every problem is one [`Error::Input`] naming the file and, where it applies, the line (CSV,
//! 1-based, the header is line 1) or row (Parquet, 1-based data row) and the column: the user
//! should be able to open the file at the right place from the message alone. NaN, infinite and
//! missing values are rejected because every estimator downstream would silently propagate them.

use std::fs;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// One identification record: the input and output columns of a data file.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// The file the record was read from (used in later error messages).
    pub path: PathBuf,
    /// Input samples `u_1..u_N`.
    pub u: Vec<f64>,
    /// Output samples `y_1..y_N` (same length as `u`).
    pub y: Vec<f64>,
    /// Name of the input column in the file.
    pub u_name: String,
    /// Name of the output column in the file.
    pub y_name: String,
}

impl Record {
    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.u.len()
    }

    /// True when the record holds no sample (never the case for a record read from a file).
    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }
}

/// Column names of a CSV file (its header row) or of a Parquet file (its schema), in file order.
pub fn column_names(path: &Path) -> Result<Vec<String>> {
    if is_parquet(path) {
        parquet::guarded(path, || parquet::column_names(path))
    } else {
        let text = read_text(path)?;
        let header = csv_header(path, &text, &[])?;
        Ok(header.names.into_iter().map(str::to_string).collect())
    }
}

/// The output column of a validation record: `given` when set; otherwise `y0` (the noise-free
/// output `oesweep simulate` writes) when the file has that column, else `otherwise`. The one
/// home of this default, for the job file, `oesweep fit` and the report.
pub fn validation_column(path: &Path, given: Option<&str>, otherwise: &str) -> Result<String> {
    Ok(match given {
        Some(c) => c.to_string(),
        None if column_names(path)?.iter().any(|c| c == "y0") => "y0".to_string(),
        None => otherwise.to_string(),
    })
}

/// Reads the input column `u_col` and the output column `y_col` of a CSV or Parquet file.
///
/// All checks of [`read_columns`] apply; in addition the two columns must differ.
pub fn read_record(path: &Path, u_col: &str, y_col: &str) -> Result<Record> {
    if u_col == y_col {
        return Err(input_error(path, format!("the input and the output column are both '{u_col}'")));
    }
    let mut cols = read_columns(path, &[u_col, y_col])?;
    let y = cols.pop().expect("two columns were read");
    let u = cols.pop().expect("two columns were read");
    Ok(Record { path: path.to_path_buf(), u, y, u_name: u_col.to_string(), y_name: y_col.to_string() })
}

/// Reads the named numeric columns of a CSV or Parquet file (format chosen by extension:
/// `.parquet` and `.pq` are Parquet, anything else CSV), in the order of `names`.
///
/// Fails with one [`Error::Input`] when the file cannot be read, a column is missing, the file
/// has no data row, or any requested value is not a finite number.
pub fn read_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
    if is_parquet(path) {
        parquet::guarded(path, || parquet::read_columns(path, names))
    } else {
        let text = read_text(path)?;
        parse_csv(path, &text, names)
    }
}

/// Smallest record length accepted for OE(nb, nf) with delay `delay`:
/// `max(20, delay + max(nb, nf) + 4 (nb + nf))`.
///
/// The first `delay + max(nb, nf)` samples are dominated by the zero initial conditions (the
/// ARX initialisation cannot even form its regressors there); after them we ask for at least
/// four samples per parameter so that the least-squares problems of the initialisation and the
/// L2 phase are clearly overdetermined. This is a floor against nonsense, not a guarantee of a
/// good fit: the paper uses N = 5000 for 24 parameters.
pub fn min_samples(nb: usize, nf: usize, delay: usize) -> usize {
    // Saturating: a job may ask for any delay up to usize::MAX, and a wrapped sum would
    // let it through.
    delay.saturating_add(nb.max(nf)).saturating_add(4usize.saturating_mul(nb.saturating_add(nf))).max(20)
}

/// An input error whose message is kept on one line: it quotes names and values taken from
/// job and data files (and messages of the Parquet reader), any of which may hold a line break.
fn input_error(path: &Path, msg: impl Into<String>) -> Error {
    Error::input(path, one_line(&msg.into()))
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

/// Checks that `rec` can identify OE(nb, nf) with delay `delay`: at least
/// [`min_samples`] samples, and neither the input nor the output is constant (a constant input
/// does not excite the system; a constant output leaves nothing to fit).
pub fn check_for_model(rec: &Record, nb: usize, nf: usize, delay: usize) -> Result<()> {
    debug_assert_eq!(rec.u.len(), rec.y.len());
    let n = rec.len();
    let need = min_samples(nb, nf, delay);
    if n < need {
        return Err(input_error(
            &rec.path,
            format!("{n} samples are too few for OE(nb={nb}, nf={nf}) with delay {delay}: need at least {need}"),
        ));
    }
    if let Some(v) = constant_value(&rec.u) {
        return Err(input_error(
            &rec.path,
            format!("input column '{}' is constant (value {v}): it does not excite the system", rec.u_name),
        ));
    }
    if let Some(v) = constant_value(&rec.y) {
        return Err(input_error(
            &rec.path,
            format!("output column '{}' is constant (value {v}): there is nothing to fit", rec.y_name),
        ));
    }
    Ok(())
}

/// `Some(mean)` when the spread of `x` is negligible relative to its level
/// (max - min <= 1e-12 max(1, |mean|)): such a column carries no information, only round-off.
fn constant_value(x: &[f64]) -> Option<f64> {
    if x.is_empty() {
        return None;
    }
    let (mut lo, mut hi, mut sum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
    for &v in x {
        lo = lo.min(v);
        hi = hi.max(v);
        sum += v;
    }
    let mean = sum / x.len() as f64;
    (hi - lo <= 1e-12 * mean.abs().max(1.0)).then_some(mean)
}

fn is_parquet(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("parquet") || e.eq_ignore_ascii_case("pq"))
}

/// The whole file as text. Reading it at once and splitting in memory is what makes a
/// 20000-line file take a few milliseconds.
fn read_text(path: &Path) -> Result<String> {
    let bytes = fs::read(path).map_err(|e| input_error(path, format!("cannot open file: {e}")))?;
    match String::from_utf8(bytes) {
        Ok(s) => Ok(s),
        Err(e) => {
            let good = e.utf8_error().valid_up_to();
            let line = 1 + e.as_bytes()[..good].iter().filter(|&&b| b == b'\n').count();
            Err(input_error(path, format!("line {line}: not valid UTF-8 text (is this a CSV file?)")))
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

/// Validates one parsed value; `place` is "line 7" or "row 7".
fn check_finite(path: &Path, place: &str, col: &str, v: f64) -> Result<f64> {
    if v.is_nan() {
        Err(input_error(path, format!("{place}, column '{col}': NaN is not allowed")))
    } else if v.is_infinite() {
        Err(input_error(path, format!("{place}, column '{col}': infinite value")))
    } else {
        Ok(v)
    }
}

struct CsvHeader<'a> {
    names: Vec<&'a str>,
    /// Byte offset of the first data line in the text.
    body_start: usize,
}

/// Parses the header row. `wanted` only shapes the empty-file message.
fn csv_header<'a>(path: &Path, text: &'a str, wanted: &[&str]) -> Result<CsvHeader<'a>> {
    let bom = if text.starts_with('\u{feff}') { 3 } else { 0 };
    let text_nobom = &text[bom..];
    if text_nobom.trim().is_empty() {
        let expected = if wanted.is_empty() {
            "expected a header row".to_string()
        } else {
            format!("expected a header row with columns {}", wanted.join(", "))
        };
        return Err(input_error(path, format!("file is empty ({expected})")));
    }
    let (line, body_start) = match text_nobom.find('\n') {
        Some(i) => (&text_nobom[..i], bom + i + 1),
        None => (text_nobom, text.len()),
    };
    let line = line.strip_suffix('\r').unwrap_or(line);
    let names: Vec<&str> = line.split(',').map(str::trim).collect();
    for (i, name) in names.iter().enumerate() {
        if name.is_empty() {
            let hint = if line.trim().is_empty() { " (the header row is blank)" } else { "" };
            return Err(input_error(path, format!("line 1: column {} has an empty name{hint}", i + 1)));
        }
        if names[..i].contains(name) {
            return Err(input_error(path, format!("column '{name}' appears twice in the header")));
        }
    }
    Ok(CsvHeader { names, body_start })
}

/// A hint for headers that are a single field because another separator was used.
fn separator_hint(names: &[&str]) -> &'static str {
    match names {
        [only] if only.contains(';') => " (the file seems to use ';' as separator; only ',' is supported)",
        [only] if only.contains('\t') => " (the file seems to use tabs as separator; only ',' is supported)",
        _ => "",
    }
}

fn parse_csv(path: &Path, text: &str, wanted: &[&str]) -> Result<Vec<Vec<f64>>> {
    let header = csv_header(path, text, wanted)?;
    let width = header.names.len();
    // slot[j] = which output column header column j feeds (a name may be requested twice).
    let mut slots: Vec<Vec<usize>> = vec![Vec::new(); width];
    for (k, name) in wanted.iter().enumerate() {
        match header.names.iter().position(|h| h == name) {
            Some(j) => slots[j].push(k),
            None => {
                let mut err = missing_column(path, name, &header.names);
                if let Error::Input { msg, .. } = &mut err {
                    msg.push_str(separator_hint(&header.names));
                }
                return Err(err);
            }
        }
    }
    let body = &text[header.body_start..];
    let estimate = body.len() / (2 * width).max(1) + 1;
    let mut out: Vec<Vec<f64>> = (0..wanted.len()).map(|_| Vec::with_capacity(estimate.min(1 << 24))).collect();

    let mut lines = body.split('\n').peekable();
    let mut lineno = 1usize;
    let mut rows = 0usize;
    while let Some(raw) = lines.next() {
        lineno += 1;
        let line = raw.strip_suffix('\r').unwrap_or(raw);
        if line.trim().is_empty() {
            // Only the piece after the final line break may be blank.
            if lines.peek().is_none() {
                break;
            }
            return Err(input_error(path, format!("line {lineno}: empty line")));
        }
        let fields = 1 + line.bytes().filter(|&b| b == b',').count();
        if fields != width {
            return Err(input_error(
                path,
                format!(
                    "line {lineno}: {fields} field{}, but the header has {width}",
                    if fields == 1 { "" } else { "s" }
                ),
            ));
        }
        for (j, field) in line.split(',').enumerate() {
            if slots[j].is_empty() {
                continue;
            }
            let col = header.names[j];
            let v = parse_field(path, lineno, col, field)?;
            for &k in &slots[j] {
                out[k].push(v);
            }
        }
        rows += 1;
    }
    if rows == 0 {
        return Err(input_error(path, "no data rows"));
    }
    Ok(out)
}

fn parse_field(path: &Path, lineno: usize, col: &str, field: &str) -> Result<f64> {
    let s = field.trim();
    if s.is_empty() {
        return Err(input_error(path, format!("line {lineno}, column '{col}': empty value")));
    }
    match s.parse::<f64>() {
        Ok(v) => check_finite(path, &format!("line {lineno}"), col, v),
        Err(_) => Err(input_error(path, format!("line {lineno}, column '{col}': '{s}' is not a number"))),
    }
}

/// Parquet access through polars (only the `parquet` feature is enabled, so everything here
/// sticks to the eager `ParquetReader` API).
mod parquet {
    use std::fs::File;
    use std::panic::{self, AssertUnwindSafe};
    use std::path::Path;
    use std::sync::Once;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use polars::prelude::{DataType, ParquetReader, SerReader};

    use super::{check_finite, input_error, missing_column};
    use crate::error::Result;

    /// Panics of the reader while `guarded` runs are caught and not printed.
    static QUIET: AtomicUsize = AtomicUsize::new(0);
    static HOOK: Once = Once::new();

    /// Runs `read` and turns a panic into an input error. The Parquet decoder trusts the
    /// file's metadata and panics on some corrupt files (an `unwrap` on a missing statistic,
    /// found by mutating a valid file), and a bad file must be exit 2 and one line, not a
    /// panic with a backtrace. The panic hook is wrapped once so it stays silent while any
    /// guarded read runs (any thread: the decoder may panic on a pool thread); other panics
    /// are still reported by the previous hook.
    pub(super) fn guarded<T>(path: &Path, read: impl FnOnce() -> Result<T>) -> Result<T> {
        HOOK.call_once(|| {
            let previous = panic::take_hook();
            panic::set_hook(Box::new(move |info| {
                if QUIET.load(Ordering::SeqCst) == 0 {
                    previous(info);
                }
            }));
        });
        QUIET.fetch_add(1, Ordering::SeqCst);
        let outcome = panic::catch_unwind(AssertUnwindSafe(read));
        QUIET.fetch_sub(1, Ordering::SeqCst);
        outcome.unwrap_or_else(|payload| {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown failure".into());
            Err(input_error(path, format!("not a readable Parquet file: the reader failed ({what})")))
        })
    }

    fn open(path: &Path) -> Result<ParquetReader<File>> {
        let file = File::open(path).map_err(|e| input_error(path, format!("cannot open file: {e}")))?;
        Ok(ParquetReader::new(file))
    }

    fn schema_names(path: &Path, reader: &mut ParquetReader<File>) -> Result<Vec<String>> {
        let schema = reader.schema().map_err(|e| input_error(path, format!("not a readable Parquet file: {e}")))?;
        Ok(schema.iter_names().map(|n| n.to_string()).collect())
    }

    pub(super) fn column_names(path: &Path) -> Result<Vec<String>> {
        let mut reader = open(path)?;
        schema_names(path, &mut reader)
    }

    pub(super) fn read_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>> {
        let mut reader = open(path)?;
        let all = schema_names(path, &mut reader)?;
        for name in names {
            if !all.iter().any(|c| c == name) {
                return Err(missing_column(path, name, &all));
            }
        }
        // Project onto the requested columns: other columns may have types this build of
        // polars cannot decode, and they are none of our business.
        let mut unique: Vec<String> = Vec::new();
        for n in names {
            if !unique.iter().any(|u| u == n) {
                unique.push(n.to_string());
            }
        }
        let df = reader
            .with_columns(Some(unique))
            .finish()
            .map_err(|e| input_error(path, format!("cannot read Parquet data: {e}")))?;
        if df.height() == 0 {
            return Err(input_error(path, "no data rows"));
        }
        let mut out = Vec::with_capacity(names.len());
        for &name in names {
            let col = df.column(name).map_err(|e| input_error(path, format!("cannot read column '{name}': {e}")))?;
            let dtype = col.dtype();
            if !dtype.is_primitive_numeric() {
                return Err(input_error(path, format!("column '{name}' has type {dtype:?}, expected numbers")));
            }
            let cast = col.cast(&DataType::Float64).map_err(|e| input_error(path, format!("column '{name}': {e}")))?;
            let ca = cast.f64().map_err(|e| input_error(path, format!("column '{name}': {e}")))?;
            let mut v = Vec::with_capacity(ca.len());
            for (i, x) in ca.iter().enumerate() {
                let row = i + 1;
                match x {
                    Some(x) => v.push(check_finite(path, &format!("row {row}"), name, x)?),
                    None => {
                        return Err(input_error(path, format!("row {row}, column '{name}': missing value (null)")));
                    }
                }
            }
            // A corrupt page header can make the decoder return fewer values than the file's
            // row count (found by fuzzing), which would pair u and y samples wrongly.
            if v.len() != df.height() {
                return Err(input_error(
                    path,
                    format!(
                        "column '{name}' has {} values but the file has {} rows (corrupt file?)",
                        v.len(),
                        df.height()
                    ),
                ));
            }
            out.push(v);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::fmt::Write as _;

    fn parse(text: &str, names: &[&str]) -> Result<Vec<Vec<f64>>> {
        parse_csv(Path::new("mem.csv"), text, names)
    }

    fn msg(r: Result<Vec<Vec<f64>>>) -> String {
        r.expect_err("expected an error").to_string()
    }

    #[test]
    fn crlf_whitespace_bom_and_final_newline() {
        let text = "\u{feff} t , u ,y\r\n0, 1.5 ,-2\r\n1,2.5e-3,  +3 \r\n";
        let c = parse(text, &["y", "u"]).unwrap();
        assert_eq!(c, vec![vec![-2.0, 3.0], vec![1.5, 2.5e-3]]);
        let c = parse("u,y\n1,2\n3,4", &["u", "y"]).unwrap();
        assert_eq!(c, vec![vec![1.0, 3.0], vec![2.0, 4.0]]);
    }

    #[test]
    fn same_column_twice_is_returned_twice() {
        let c = parse("u,y\n1,2\n", &["u", "u"]).unwrap();
        assert_eq!(c, vec![vec![1.0], vec![1.0]]);
    }

    #[test]
    fn blank_line_inside_data_is_an_error() {
        assert!(msg(parse("u,y\n1,2\n\n3,4\n", &["u"])).contains("line 3: empty line"));
        assert!(msg(parse("u,y\n1,2\n\n\n", &["u"])).contains("line 3: empty line"));
        assert!(msg(parse("u,y\n1,2\n3\n", &["u"])).contains("line 3: 1 field, but"));
    }

    #[test]
    fn header_problems() {
        assert!(msg(parse("u,,y\n1,2,3\n", &["u"])).contains("line 1: column 2 has an empty name"));
        let m = msg(parse("u;y\n1;2\n", &["u"]));
        assert!(m.contains("no column 'u' (columns: u;y)"), "{m}");
        assert!(m.contains("';' as separator"), "{m}");
        assert!(msg(parse("  \n \n", &["u", "y"])).contains("file is empty"));
    }

    #[test]
    fn long_headers_are_abbreviated() {
        let names: Vec<String> = (0..30).map(|i| format!("c{i}")).collect();
        let text = format!("{}\n", names.join(","));
        let m = msg(parse(&text, &["u"]));
        assert!(m.contains("c19, ... (30 in all)"), "{m}");
    }

    #[test]
    fn overflow_is_reported_as_infinite() {
        assert!(msg(parse("u\n1e999\n", &["u"])).contains("line 2, column 'u': infinite value"));
        assert!(msg(parse("u\n-inf\n", &["u"])).contains("infinite value"));
        assert!(msg(parse("u\nnan\n", &["u"])).contains("NaN is not allowed"));
    }

    #[test]
    fn invalid_utf8_names_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bin.csv");
        fs::write(&p, b"u,y\n1,2\n\xff\xfe,3\n").unwrap();
        let m = read_columns(&p, &["u"]).unwrap_err().to_string();
        assert!(m.contains("line 3: not valid UTF-8"), "{m}");
    }

    #[test]
    fn extension_picks_the_format() {
        assert!(is_parquet(Path::new("a/b.parquet")));
        assert!(is_parquet(Path::new("b.PQ")));
        assert!(!is_parquet(Path::new("b.csv")));
        assert!(!is_parquet(Path::new("parquet")));
    }

    #[test]
    fn min_samples_rule() {
        assert_eq!(min_samples(1, 1, 1), 20);
        assert_eq!(min_samples(12, 12, 1), 1 + 12 + 96);
        assert_eq!(min_samples(9, 12, 2), 2 + 12 + 84);
    }

    #[test]
    fn constant_detection_is_relative() {
        assert_eq!(constant_value(&[3.0, 3.0, 3.0]), Some(3.0));
        assert!(constant_value(&[1e6, 1e6 + 1e-7]).is_some());
        assert!(constant_value(&[0.0, 1e-9]).is_none());
        assert!(constant_value(&[1e6, 1e6 + 1e-3]).is_none());
    }

    #[test]
    fn reads_20000_lines_quickly() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.csv");
        let mut s = String::from("t,u,y\n");
        for i in 0..20000 {
            let x = i as f64 * 1e-4;
            writeln!(s, "{x},{},{}", (x * 7.0).sin() * 10.0, (x * 3.0).cos() * 1.234_567_89).unwrap();
        }
        fs::write(&p, s).unwrap();
        // Warm the page cache, then time the real read.
        read_record(&p, "u", "y").unwrap();
        let t0 = std::time::Instant::now();
        let rec = read_record(&p, "u", "y").unwrap();
        let dt = t0.elapsed();
        assert_eq!(rec.len(), 20000);
        assert!(dt.as_millis() < 100, "reading 20000 lines took {dt:?}");
    }
}
