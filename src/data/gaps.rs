//! Records with gaps (METHOD.md 21.1): what a missing sample is in a data file, and the shape a
//! record with missing samples takes before anything downstream sees it.
//!
//! A selected value is missing when it is `NaN` (any case), an empty field of a text file, a
//! Parquet null, or equal to one of the record's markers (`data.missing`: a number such as
//! -999, compared by value in every format, or a text such as `"NA"`, compared with a text
//! field as it reads). Infinite values and other text stay errors.
//!
//! An output-error model needs no output history to predict, so a missing **output** costs only
//! its own residual: the row is kept, `y` holds NaN there and its index goes to
//! [`Record::missing`]. A missing **input** breaks the simulation: the row is cut, and the
//! record is split there into segments that are fitted together as several experiments (each
//! from its own initial state, METHOD.md 16), exactly the record the segments would give as a
//! `data` list. A segment shorter than the shortest useful one (the largest model's
//! [`super::min_samples_of`]) is left out and counted. Input gaps of at most
//! `interpolate_inputs` samples between two present samples are filled linearly instead, only
//! when the job asks, and then said in a warning. Nothing is ever interpolated silently.

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

use super::{ColumnRef, ReadOptions, Record, input_error};
use crate::error::Result;

/// Most of a record's rows that may miss a value (an output or an input, as read): beyond this
/// the record is more hole than data, which is a wrong column or file far more often than a
/// measurement, and is refused with the counts.
pub const MAX_MISSING_SHARE: f64 = 0.5;

/// Largest `interpolate_inputs`: a linear fill across more samples invents the input.
pub const MAX_INTERPOLATE: usize = 1000;

/// The shortest segment kept where no model is known (a record read without a grid:
/// `oesweep spectrum`, the report's plots): the floor of [`super::min_samples_of`].
pub const SHORTEST_SEGMENT: usize = 20;

/// A value that stands for a missing sample (`data.missing`): a number, which a field or value
/// matches when it equals it (`-999` matches `-999`, `-999.0` and a Parquet or MAT value of
/// -999), or a text, which a text file's field matches when it reads exactly so once the
/// whitespace around it is trimmed (`"NA"`, `"n/a"`). A text that reads as a number matches
/// both ways.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Marker {
    Number(f64),
    Text(String),
}

/// By hand, to say what a marker may be when it is something else (`true`, an object).
impl<'de> Deserialize<'de> for Marker {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl serde::de::Visitor<'_> for Visitor {
            type Value = Marker;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a missing-value marker: a text such as \"NA\" or a number such as -999")
            }
            fn visit_f64<E: serde::de::Error>(self, v: f64) -> std::result::Result<Marker, E> {
                Ok(Marker::Number(v))
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Marker, E> {
                Ok(Marker::Number(v as f64))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Marker, E> {
                Ok(Marker::Number(v as f64))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<Marker, E> {
                Ok(Marker::Text(v.to_string()))
            }
        }
        d.deserialize_any(Visitor)
    }
}

impl Marker {
    /// A command-line marker (`--missing -999`): always a text, which matches by value too when
    /// it reads as a number.
    pub fn parse(s: &str) -> Marker {
        Marker::Text(s.to_string())
    }

    /// The number this marker stands for, if any.
    fn value(&self) -> Option<f64> {
        match self {
            Marker::Number(v) => Some(*v),
            Marker::Text(s) => s.trim().parse::<f64>().ok().filter(|v| v.is_finite()),
        }
    }
}

/// The markers of a record, as the readers match them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Markers {
    texts: Vec<String>,
    values: Vec<f64>,
}

impl Markers {
    pub fn of(markers: &[Marker]) -> Markers {
        Markers {
            texts: markers
                .iter()
                .filter_map(|m| if let Marker::Text(s) = m { Some(s.trim().to_string()) } else { None })
                .collect(),
            values: markers.iter().filter_map(Marker::value).collect(),
        }
    }

    /// True when a text field (trimmed) is a declared marker.
    pub(super) fn is_text(&self, field: &[u8]) -> bool {
        !self.texts.is_empty() && self.texts.iter().any(|t| t.as_bytes() == field)
    }

    /// True when a finite value is a declared marker.
    pub(super) fn is_value(&self, v: f64) -> bool {
        self.values.contains(&v)
    }
}

/// What was missing in a record and what became of it: the counts `selection.json` (`gaps`),
/// the summaries and `plan` report. Several experiments add up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Gaps {
    /// Data rows read (the record's `rows`).
    pub rows: usize,
    /// Samples of the record as fitted: the rows kept.
    pub samples: usize,
    /// Kept rows whose output is missing: simulated through, their residuals left out.
    pub outputs_missing: usize,
    /// Input samples filled by linear interpolation (`interpolate_inputs`).
    pub inputs_interpolated: usize,
    /// Rows cut because an input was missing.
    pub rows_cut: usize,
    /// Segments between input gaps kept (each experiment of a list counts one at least).
    pub segments: usize,
    /// Segments left out as shorter than the shortest useful one, and their rows.
    pub segments_dropped: usize,
    pub rows_dropped: usize,
}

impl Gaps {
    /// The counts of a record that missed nothing.
    pub fn complete(rows: usize) -> Gaps {
        Gaps { rows, samples: rows, segments: 1, ..Gaps::default() }
    }

    /// True when anything was missing (complete records write no `gaps`).
    pub fn any(&self) -> bool {
        self.outputs_missing + self.inputs_interpolated + self.rows_cut + self.rows_dropped > 0
    }

    /// The counts of several experiments together.
    pub fn sum(all: impl IntoIterator<Item = Gaps>) -> Gaps {
        all.into_iter().fold(Gaps::default(), |a, g| Gaps {
            rows: a.rows + g.rows,
            samples: a.samples + g.samples,
            outputs_missing: a.outputs_missing + g.outputs_missing,
            inputs_interpolated: a.inputs_interpolated + g.inputs_interpolated,
            rows_cut: a.rows_cut + g.rows_cut,
            segments: a.segments + g.segments,
            segments_dropped: a.segments_dropped + g.segments_dropped,
            rows_dropped: a.rows_dropped + g.rows_dropped,
        })
    }

    /// One line for a summary: "3000 rows: 150 outputs missing, 40 rows cut at input gaps (3
    /// segments), ...".
    pub fn describe(&self) -> String {
        let mut parts = vec![format!("{} outputs missing (left out of every criterion)", self.outputs_missing)];
        if self.rows_cut > 0 {
            parts.push(format!(
                "{} rows cut at input gaps ({} segments fitted as experiments)",
                self.rows_cut, self.segments
            ));
        }
        if self.segments_dropped > 0 {
            parts.push(format!("{} segments of {} rows too short, left out", self.segments_dropped, self.rows_dropped));
        }
        if self.inputs_interpolated > 0 {
            parts.push(format!("{} input samples interpolated", self.inputs_interpolated));
        }
        format!("{} of {} rows fitted: {}", self.samples, self.rows, parts.join(", "))
    }

    /// What the user must be told about a record's gaps beside the counts (kept in
    /// selection.json's warnings): interpolated inputs and segments left out.
    pub fn warnings(&self, path: &Path, interpolate: usize) -> Vec<String> {
        let mut out = Vec::new();
        if self.inputs_interpolated > 0 {
            out.push(format!(
                "{}: {} missing input samples were filled by linear interpolation (interpolate_inputs {interpolate}: \
                 gaps of at most {interpolate} samples between two present ones)",
                path.display(),
                self.inputs_interpolated
            ));
        }
        if self.segments_dropped > 0 {
            let (what, are) = match self.segments_dropped {
                1 => ("1 segment".to_string(), "is"),
                n => (format!("{n} segments"), "are"),
            };
            out.push(format!(
                "{}: {what} between input gaps ({} rows) {are} shorter than the shortest useful segment and left out",
                path.display(),
                self.rows_dropped
            ));
        }
        out
    }
}

/// The gaps of a job's records, as `selection.json` keeps them: a record that missed nothing
/// is absent.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RecordGaps {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub data: Option<Gaps>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validation: Option<Gaps>,
}

impl RecordGaps {
    /// The gaps of the estimation record and of the validation record (None: none), each kept
    /// only when something was missing.
    pub fn of(data: Gaps, validation: Option<Gaps>) -> RecordGaps {
        RecordGaps { data: Some(data).filter(Gaps::any), validation: validation.filter(Gaps::any) }
    }

    /// None when no record missed anything.
    pub fn any(&self) -> bool {
        self.data.is_some() || self.validation.is_some()
    }
}

/// A record as read, before its gaps are handled: inputs and output with NaN where a value is
/// missing ([`shape`] makes it a [`Record`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Raw {
    pub path: PathBuf,
    /// Input after input, as [`Record::u`].
    pub u: Vec<f64>,
    pub y: Vec<f64>,
    pub u_names: Vec<String>,
    pub y_name: String,
}

impl Raw {
    /// Samples in memory (the Python package's arrays), `label` standing for the file in
    /// messages, inputs named `u` (one) or `u1`, `u2`, ...: every input as long as `y`, NaN a
    /// missing sample, an infinite value an error.
    pub fn from_arrays(label: &str, inputs: Vec<Vec<f64>>, y: Vec<f64>) -> Result<Raw> {
        let path = PathBuf::from(label);
        if inputs.is_empty() {
            return Err(input_error(&path, "no input array: give at least one"));
        }
        let u_names: Vec<String> =
            if inputs.len() == 1 { vec!["u".into()] } else { (1..=inputs.len()).map(|i| format!("u{i}")).collect() };
        for (name, x) in u_names.iter().zip(&inputs) {
            if x.len() != y.len() {
                return Err(input_error(
                    &path,
                    format!("{name} has {} samples and y {}: they must be equal", x.len(), y.len()),
                ));
            }
        }
        for (name, x) in u_names.iter().map(String::as_str).zip(&inputs).chain([("y", &y)]) {
            if let Some(i) = x.iter().position(|v| v.is_infinite()) {
                return Err(input_error(
                    &path,
                    format!("sample {i} of {name} is {}, not a finite number (NaN marks a missing sample)", x[i]),
                ));
            }
        }
        Ok(Raw { path, u: inputs.concat(), y, u_names, y_name: "y".into() })
    }

    fn len(&self) -> usize {
        self.y.len()
    }
}

/// The record of `raw` (see the module docs): input gaps of at most `interpolate` samples
/// filled, the rows with a missing input cut and the record split there into segments (seams),
/// segments shorter than `shortest` left out when there are input gaps, missing outputs in
/// [`Record::missing`]. Exactly [`Record::concat`] of the segments' records. Errors, naming the
/// counts: every output missing, more than [`MAX_MISSING_SHARE`] of the rows missing a value,
/// no segment of `shortest` samples.
pub fn shape(raw: Raw, interpolate: usize, shortest: usize) -> Result<(Record, Gaps)> {
    let n = raw.len();
    let m = raw.u_names.len();
    debug_assert_eq!(raw.u.len(), m * n);
    let whole = |raw: Raw| Record {
        path: raw.path,
        u: raw.u,
        y: raw.y,
        u_names: raw.u_names,
        y_name: raw.y_name,
        seams: Vec::new(),
        missing: Vec::new(),
    };
    if !raw.u.iter().chain(&raw.y).any(|v| v.is_nan()) {
        return Ok((whole(raw), Gaps::complete(n)));
    }
    let path = raw.path.clone();
    let outputs = raw.y.iter().filter(|v| v.is_nan()).count();
    if outputs == n {
        return Err(input_error(&path, format!("every output of column '{}' is missing ({n} rows)", raw.y_name)));
    }
    let input_missing = |u: &[f64], t: usize| (0..m).any(|i| u[i * n + t].is_nan());
    let incomplete = (0..n).filter(|&t| raw.y[t].is_nan() || input_missing(&raw.u, t)).count();
    if incomplete as f64 > MAX_MISSING_SHARE * n as f64 {
        let inputs = raw.u.iter().filter(|v| v.is_nan()).count();
        return Err(input_error(
            &path,
            format!(
                "{incomplete} of {n} rows ({:.0} %) miss a value ({outputs} outputs, {inputs} input samples): more than \
                 the {:.0} % a record may miss",
                100.0 * incomplete as f64 / n as f64,
                100.0 * MAX_MISSING_SHARE
            ),
        ));
    }
    let mut raw = raw;
    let mut gaps = Gaps { rows: n, ..Gaps::default() };
    if interpolate > 0 {
        for i in 0..m {
            gaps.inputs_interpolated += fill(&mut raw.u[i * n..(i + 1) * n], interpolate);
        }
    }
    // The stretches of rows whose inputs are all present.
    let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
    let mut start = None;
    for t in 0..=n {
        let present = t < n && !input_missing(&raw.u, t);
        match (present, start) {
            (true, None) => start = Some(t),
            (false, Some(s)) => {
                runs.push(s..t);
                start = None;
            }
            _ => {}
        }
    }
    gaps.rows_cut = n - runs.iter().map(|r| r.len()).sum::<usize>();
    if gaps.rows_cut == 0 {
        // No input gap: the record as read; its length is the model's business
        // ([`super::check_for_structure`]), as for a complete record.
        let mut rec = whole(raw);
        rec.missing = (0..n).filter(|&t| rec.y[t].is_nan()).collect();
        gaps.samples = n;
        gaps.segments = 1;
        gaps.outputs_missing = rec.missing.len();
        return Ok((rec, gaps));
    }
    let longest = runs.iter().map(|r| r.len()).max().unwrap_or(0);
    let (kept, dropped): (Vec<_>, Vec<_>) = runs.into_iter().partition(|r| r.len() >= shortest);
    if kept.is_empty() {
        let (cut, leave) = match gaps.rows_cut {
            1 => ("the 1 row".to_string(), "leaves"),
            n => (format!("the {n} rows"), "leave"),
        };
        let segments = if dropped.len() == 1 { "1 segment".to_string() } else { format!("{} segments", dropped.len()) };
        return Err(input_error(
            &path,
            format!(
                "no segment between input gaps is long enough: {cut} with a missing input {leave} {segments} of at \
                 most {longest} rows, and a segment needs at least {shortest} samples"
            ),
        ));
    }
    gaps.segments = kept.len();
    gaps.segments_dropped = dropped.len();
    gaps.rows_dropped = dropped.iter().map(|r| r.len()).sum();
    let records: Vec<Record> = kept
        .iter()
        .map(|r| Record {
            path: raw.path.clone(),
            u: (0..m).flat_map(|i| raw.u[i * n + r.start..i * n + r.end].iter().copied()).collect(),
            y: raw.y[r.clone()].to_vec(),
            u_names: raw.u_names.clone(),
            y_name: raw.y_name.clone(),
            seams: Vec::new(),
            missing: (0..r.len()).filter(|&t| raw.y[r.start + t].is_nan()).collect(),
        })
        .collect();
    let rec = Record::concat(records);
    gaps.samples = rec.len();
    gaps.outputs_missing = rec.missing.len();
    if gaps.outputs_missing == gaps.samples {
        return Err(input_error(
            &path,
            format!(
                "every output of column '{}' in the {} rows between input gaps is missing",
                rec.y_name, gaps.samples
            ),
        ));
    }
    Ok((rec, gaps))
}

/// [`super::read_raw`] shaped by [`shape`] (input gaps of at most `opts.interpolate_inputs`
/// filled, the others cutting the record into segments, those shorter than `shortest` left
/// out), with the counts.
pub fn read_record_gaps(
    path: &Path,
    u: &[ColumnRef],
    y: &ColumnRef,
    opts: &ReadOptions,
    shortest: usize,
) -> Result<(Record, Gaps)> {
    shape(super::read_raw(path, u, y, opts)?, opts.interpolate_inputs, shortest)
}

/// Fills the runs of NaN of at most `longest` samples that have a present sample on both sides
/// by the straight line between them; returns the samples filled.
fn fill(x: &mut [f64], longest: usize) -> usize {
    let n = x.len();
    let mut filled = 0;
    let mut t = 0;
    while t < n {
        if !x[t].is_nan() {
            t += 1;
            continue;
        }
        let a = t;
        while t < n && x[t].is_nan() {
            t += 1;
        }
        // x[a..t] is missing; x[a - 1] and x[t] are present when they exist.
        if a > 0 && t < n && t - a <= longest {
            let (x0, x1, span) = (x[a - 1], x[t], (t - a + 1) as f64);
            for (j, v) in x[a..t].iter_mut().enumerate() {
                *v = x0 + (x1 - x0) * ((j + 1) as f64 / span);
            }
            filled += t - a;
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    const NAN: f64 = f64::NAN;

    fn raw(u: Vec<Vec<f64>>, y: Vec<f64>) -> Raw {
        Raw {
            path: "r.csv".into(),
            u_names: (0..u.len()).map(|i| format!("u{i}")).collect(),
            u: u.concat(),
            y,
            y_name: "y".into(),
        }
    }

    fn part(r: &Raw, rows: std::ops::Range<usize>) -> Record {
        let n = r.y.len();
        let m = r.u_names.len();
        Record {
            path: r.path.clone(),
            u: (0..m).flat_map(|i| r.u[i * n + rows.start..i * n + rows.end].to_vec()).collect(),
            y: r.y[rows.clone()].to_vec(),
            u_names: r.u_names.clone(),
            y_name: r.y_name.clone(),
            seams: Vec::new(),
            missing: (rows.clone()).filter(|&t| r.y[t].is_nan()).map(|t| t - rows.start).collect(),
        }
    }

    fn same(a: &Record, b: &Record) {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.u), bits(&b.u));
        assert_eq!(bits(&a.y), bits(&b.y));
        assert_eq!((&a.seams, &a.missing, &a.u_names), (&b.seams, &b.missing, &b.u_names));
    }

    #[test]
    fn a_complete_record_is_read_as_it_is() {
        let r = raw(vec![(0..30).map(f64::from).collect()], (0..30).map(|t| f64::from(t) * 0.5).collect());
        let (rec, gaps) = shape(r.clone(), 0, 20).unwrap();
        assert_eq!((rec.u, rec.y), (r.u, r.y));
        assert!(rec.seams.is_empty() && rec.missing.is_empty());
        assert_eq!(gaps, Gaps::complete(30));
        assert!(!gaps.any());
    }

    #[test]
    fn missing_outputs_stay_in_the_record_and_are_listed() {
        let mut y: Vec<f64> = (0..30).map(f64::from).collect();
        y[0] = NAN;
        y[17] = NAN;
        let (rec, gaps) = shape(raw(vec![(0..30).map(f64::from).collect()], y), 0, 20).unwrap();
        assert_eq!(rec.len(), 30);
        assert_eq!(rec.missing, vec![0, 17]);
        assert!(rec.y[17].is_nan() && rec.seams.is_empty());
        assert_eq!((gaps.outputs_missing, gaps.segments, gaps.samples), (2, 1, 30));
        assert!(gaps.any());
    }

    #[test]
    fn input_gaps_split_the_record_as_a_list_of_its_segments_would() {
        // Two inputs; a gap in the second at rows 25..27, one in the first at 60, a short
        // stretch 61..70 between 60 and 70 (too short for 20), outputs missing here and there.
        let n = 120;
        let mut a: Vec<f64> = (0..n).map(|t| (t as f64 * 0.3).sin()).collect();
        let mut b: Vec<f64> = (0..n).map(|t| (t as f64 * 0.7).cos()).collect();
        let mut y: Vec<f64> = (0..n).map(|t| t as f64).collect();
        b[25] = NAN;
        b[26] = NAN;
        a[60] = NAN;
        a[70] = NAN;
        for t in [3, 26, 40, 65, 119] {
            y[t] = NAN;
        }
        let r = raw(vec![a, b], y);
        let (rec, gaps) = shape(r.clone(), 0, 20).unwrap();
        let list = Record::concat(vec![part(&r, 0..25), part(&r, 27..60), part(&r, 71..n)]);
        same(&rec, &list);
        assert_eq!(rec.seams, vec![25, 58]);
        assert_eq!(
            gaps,
            Gaps {
                rows: n,
                samples: n - 4 - 9,
                outputs_missing: 3,
                inputs_interpolated: 0,
                rows_cut: 4,
                segments: 3,
                segments_dropped: 1,
                rows_dropped: 9
            }
        );
        // A gap at the first row: the record starts after it, without a seam.
        let mut first = r.clone();
        first.u[0] = NAN;
        let (rec, _) = shape(first.clone(), 0, 20).unwrap();
        same(&rec, &Record::concat(vec![part(&first, 1..25), part(&first, 27..60), part(&first, 71..n)]));
    }

    #[test]
    fn short_input_gaps_are_interpolated_only_when_asked() {
        let n = 50;
        let mut u: Vec<f64> = (0..n).map(|t| 2.0 * t as f64).collect();
        u[0] = NAN; // no sample before: cut, never extrapolated
        u[10] = NAN;
        u[11] = NAN;
        u[30] = NAN;
        u[31] = NAN;
        u[32] = NAN;
        let r = raw(vec![u], (0..n).map(|t| t as f64).collect());
        let (rec, gaps) = shape(r.clone(), 2, 5).unwrap();
        assert_eq!(gaps.inputs_interpolated, 2);
        assert_eq!(gaps.rows_cut, 4);
        // Row 10 and 11 filled on the line from u[9] = 18 to u[12] = 24; the gap of three cut.
        assert_eq!(&rec.u[8..12], &[18.0, 20.0, 22.0, 24.0]);
        assert_eq!(rec.seams, vec![29]);
        let w = gaps.warnings(Path::new("r.csv"), 2);
        assert!(w[0].contains("2 missing input samples were filled by linear interpolation"), "{w:?}");
        let (_, none) = shape(r, 0, 5).unwrap();
        assert_eq!((none.inputs_interpolated, none.rows_cut, none.segments), (0, 6, 3));
    }

    #[test]
    fn bad_records_are_named_with_their_counts() {
        let n = 40;
        let u: Vec<f64> = (0..n).map(f64::from).collect();
        let e = shape(raw(vec![u.clone()], vec![NAN; 40]), 0, 20).unwrap_err().to_string();
        assert!(e.contains("every output of column 'y' is missing (40 rows)"), "{e}");
        let y: Vec<f64> = (0..n).map(|t| if t % 3 == 0 { f64::from(t) } else { NAN }).collect();
        let e = shape(raw(vec![u.clone()], y), 0, 20).unwrap_err().to_string();
        assert!(e.contains("26 of 40 rows (65 %) miss a value (26 outputs, 0 input samples)"), "{e}");
        let gappy: Vec<f64> = (0..n).map(|t| if t % 15 == 14 { NAN } else { f64::from(t) }).collect();
        let e = shape(raw(vec![gappy], u.clone()), 0, 20).unwrap_err().to_string();
        assert!(e.contains("the 2 rows with a missing input leave 3 segments of at most 14 rows"), "{e}");
        assert!(e.contains("needs at least 20 samples"), "{e}");
    }

    #[test]
    fn markers_match_by_value_and_by_text() {
        let m = Markers::of(&[Marker::Number(-999.0), Marker::Text(" NA ".into()), Marker::Text("-1e3".into())]);
        assert!(m.is_value(-999.0) && m.is_value(-1000.0) && !m.is_value(0.0));
        assert!(m.is_text(b"NA") && !m.is_text(b"na"));
        let parsed: Vec<Marker> = serde_json::from_str(r#"["NA", -999, 1.5]"#).unwrap();
        assert_eq!(parsed, vec![Marker::Text("NA".into()), Marker::Number(-999.0), Marker::Number(1.5)]);
        assert_eq!(serde_json::to_string(&parsed).unwrap(), r#"["NA",-999.0,1.5]"#);
        let e = serde_json::from_str::<Vec<Marker>>("[true]").unwrap_err().to_string();
        assert!(e.contains("expected a missing-value marker"), "{e}");
    }
}
