//! The result table on disk (`cells.parquet`), JSON output, and model choice from a read-back table.

mod common;

use oesweep::Error;
use oesweep::estimate::evidence::Evidence;
use oesweep::export::json::write_json;
use oesweep::export::parquet::{read_cells, write_cells};
use oesweep::reduce::{FitBasis, ReduceOptions, Selection, select};
use oesweep::table::{CellRow, Fit, FitKind, RowKey, Status};
use polars::prelude::*;
use std::fs::File;
use std::path::Path;

fn key(kind: FitKind, nb: u32, nf: u32, delay: u32, k_index: Option<u32>) -> RowKey {
    RowKey::siso(kind, nb, nf, delay, k_index)
}

fn huber_row(nb: u32, nf: u32, k_index: u32, criterion: f64, fit_val: f64) -> CellRow {
    CellRow {
        key: key(FitKind::Huber, nb, nf, 1, Some(k_index)),
        k: Some(0.0625),
        status: Status::Ok,
        reason: None,
        fit: Fit {
            sigma: Some(3.608),
            gamma: Some(0.0625 * 3.608),
            criterion: Some(criterion),
            l1c: Some(0.942),
            fit: Some(95.22),
            fit_val: Some(fit_val),
            fit_band: Some(0.1 + 0.2),
            iterations: Some(17),
            termination: Some("converged".into()),
            converged: true,
            max_pole_radius: Some(0.984),
            reflections: Some(0),
            start: "ls".into(),
            seconds: 0.0731,
            b: (0..nb).map(|i| 0.1 * i as f64 - 0.35).collect(),
            f: (0..nf).map(|i| (-1.0f64).powi(i as i32) / (i + 2) as f64).collect(),
            // The rest (a model without offset) as a new table column starts: empty.
            ..Fit::default()
        },
        evidence: Evidence {
            b_std: (0..nb).map(|i| 0.01 * (i + 1) as f64).collect(),
            f_std: (0..nf).map(|i| 0.02 * (i + 1) as f64).collect(),
            max_rel_std: Some(f64::INFINITY),
            resid_white_p: Some(0.5),
            ..Evidence::default()
        },
    }
}

fn ls_row() -> CellRow {
    let mut r = huber_row(9, 12, 0, 12.5, 82.5);
    r.key = key(FitKind::Ls, 9, 12, 1, None);
    r.k = None;
    r.fit = Fit {
        gamma: None,
        l1c: None,
        fit_val: None,
        fit_band: None,
        termination: Some("small_step".into()),
        start: "init".into(),
        ..r.fit
    };
    r
}

/// A handful of rows covering every kind: huber ok, ls, failed (nulls, empty b/f), and awkward
/// floats (negative zero, subnormal, huge, non-terminating binary fractions).
fn sample_rows() -> Vec<CellRow> {
    let mut odd = huber_row(4, 0, 3, f64::MIN_POSITIVE / 8.0, 1e300);
    odd.fit.b = vec![-0.0, 0.0, f64::EPSILON, -1.0 / 3.0];
    odd.fit.f = vec![];
    odd.fit.sigma = Some(-0.0);
    odd.fit.converged = false;
    odd.fit.termination = Some("max_iterations".into());
    odd.reason = Some("unused reason, with unicode: \u{3c3} \u{2264} 1".into());
    vec![
        huber_row(9, 12, 1, 0.2255, 82.5),
        ls_row(),
        CellRow::failed(key(FitKind::Huber, 14, 15, 1, Some(39)), Some(2.0), "Huber fit ended non_finite".into()),
        CellRow::failed(key(FitKind::Ls, 14, 15, 2, None), None, "least-squares fit ended non_finite".into()),
        odd,
    ]
}

/// Bit-exact comparison: `{:?}` prints the shortest roundtrip form of every f64 and keeps the
/// sign of zero, which `==` on f64 would not distinguish (the rows are NaN-free).
fn assert_rows_identical(got: &[CellRow], want: &[CellRow]) {
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        assert_eq!(format!("{g:?}"), format!("{w:?}"));
    }
}

fn dir_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

#[test]
fn parquet_roundtrip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    let rows = sample_rows();
    write_cells(&path, &rows).unwrap();
    assert_rows_identical(&read_cells(&path).unwrap(), &rows);
    assert_eq!(dir_entries(dir.path()), vec!["cells.parquet"]);
}

#[test]
fn parquet_roundtrip_of_a_large_repetitive_table() {
    // Enough rows with repeated values that the writer dictionary-encodes the float columns;
    // 0.0 and -0.0 must stay distinct through the dictionary.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    let rows: Vec<CellRow> = (0..1000u32)
        .map(|i| {
            let mut r = huber_row(7 + i % 8, 4 + i % 12, i % 40, 0.1 * (i % 5) as f64, 80.0 + (i % 7) as f64);
            r.fit.fit_band = Some(if i % 2 == 0 { 0.0 } else { -0.0 });
            r.fit.seconds = if i % 3 == 0 { -0.0 } else { 0.0 };
            r.fit.b[0] = if i % 2 == 0 { -0.0 } else { 0.0 };
            if i % 10 == 0 {
                r = CellRow::failed(key(FitKind::Huber, 7, 4 + i % 12, 1, Some(i % 40)), Some(0.05), "x".into());
            }
            r
        })
        .collect();
    write_cells(&path, &rows).unwrap();
    assert_rows_identical(&read_cells(&path).unwrap(), &rows);
}

#[test]
fn parquet_file_has_the_documented_schema() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    write_cells(&path, &sample_rows()).unwrap();
    let df = ParquetReader::new(File::open(&path).unwrap()).finish().unwrap();
    // The published layout (docs/JOBS.md "Columns of cells.parquet"), written out here rather than
    // derived from `COLUMNS`, so that a renamed, retyped, moved or dropped column fails.
    let (s, u, f, b) = (DataType::String, DataType::UInt32, DataType::Float64, DataType::Boolean);
    let l = DataType::List(Box::new(DataType::Float64));
    #[rustfmt::skip]
    let published = [
        ("method", &s), ("nb", &u), ("nf", &u), ("delay", &u), ("k_index", &u), ("k", &f), ("sigma", &f),
        ("gamma", &f), ("criterion", &f), ("l1c", &f), ("fit", &f), ("fit_val", &f), ("fit_band", &f),
        ("iterations", &u), ("termination", &s), ("converged", &b), ("status", &s), ("reason", &s),
        ("max_pole_radius", &f), ("reflections", &u), ("start", &s), ("seconds", &f), ("b", &l), ("f", &l),
        ("offset", &f), ("b_std", &l), ("f_std", &l), ("offset_std", &f), ("max_rel_std", &f),
        ("resid_white_p", &f), ("resid_indep_p", &f), ("cancellations", &u), ("aic", &f), ("aicc", &f),
        ("bic", &f), ("fpe", &f), ("raic", &f), ("rbic", &f), ("fit_exp", &l), ("fit_val_exp", &l),
    ];
    let want: Vec<(String, DataType)> = published.iter().map(|(n, d)| (n.to_string(), (*d).clone())).collect();
    let got: Vec<(String, DataType)> = df.schema().iter().map(|(n, d)| (n.to_string(), d.clone())).collect();
    assert_eq!(got, want);
    assert_eq!(df.height(), 5);
    // Nulls are real Parquet nulls, not sentinels.
    assert_eq!(df.column("k_index").unwrap().null_count(), 2);
    assert_eq!(df.column("method").unwrap().str().unwrap().get(1), Some("ls"));
    assert_eq!(df.column("status").unwrap().str().unwrap().get(2), Some("failed"));
    assert_eq!(df.column("b").unwrap().list().unwrap().null_count(), 0);
}

#[test]
fn overwrite_replaces_the_file_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    write_cells(&path, &sample_rows()).unwrap();
    let second = vec![huber_row(3, 3, 0, 1.0, 50.0)];
    write_cells(&path, &second).unwrap();
    assert_rows_identical(&read_cells(&path).unwrap(), &second);
    assert_eq!(dir_entries(dir.path()), vec!["cells.parquet"], "no temporary file left behind");
}

#[test]
fn write_failure_is_an_output_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing-folder").join("cells.parquet");
    let err = write_cells(&path, &sample_rows()).unwrap_err();
    assert!(matches!(err, Error::Output { .. }), "{err:?}");
    assert!(!err.is_bad_input());
    assert!(err.to_string().contains("cells.parquet"), "{err}");
}

#[test]
fn read_errors_name_the_file_and_column() {
    let dir = tempfile::tempdir().unwrap();

    let missing = dir.path().join("nope.parquet");
    let err = read_cells(&missing).unwrap_err();
    assert!(err.is_bad_input() && err.to_string().contains("nope.parquet"), "{err}");

    let garbage = dir.path().join("garbage.parquet");
    std::fs::write(&garbage, "method,nb\nls,3\n").unwrap();
    let err = read_cells(&garbage).unwrap_err();
    assert!(err.is_bad_input() && err.to_string().contains("garbage.parquet"), "{err}");

    // A Parquet file that lacks a column.
    let partial = dir.path().join("partial.parquet");
    write_cells(&partial, &sample_rows()).unwrap();
    let mut df = ParquetReader::new(File::open(&partial).unwrap()).finish().unwrap();
    df.drop_in_place("fit_band").unwrap();
    ParquetWriter::new(File::create(&partial).unwrap()).finish(&mut df).unwrap();
    let err = read_cells(&partial).unwrap_err();
    let msg = err.to_string();
    assert!(err.is_bad_input() && msg.contains("partial.parquet") && msg.contains("`fit_band`"), "{msg}");
}

/// A row whose parameters do not fit its orders (an edited checkpoint part or cells.parquet) is
/// refused when read, naming the row and the column: the nested pass and the exports embed
/// the parameters by the orders.
#[test]
fn a_row_whose_parameters_do_not_fit_its_orders_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    let mut rows = sample_rows();
    rows[1].fit.f.pop();
    write_cells(&path, &rows).unwrap();
    let err = read_cells(&path).unwrap_err();
    let msg = err.to_string();
    assert!(
        err.is_bad_input() && msg.contains("cells.parquet") && msg.contains("row 1") && msg.contains("`f`"),
        "{msg}"
    );
    // Standard deviations may be absent, not of another length.
    let mut rows = sample_rows();
    rows[0].evidence.b_std.clear();
    write_cells(&path, &rows).unwrap();
    assert!(read_cells(&path).is_ok());
    rows[0].evidence.b_std.push(1.0);
    write_cells(&path, &rows).unwrap();
    assert!(read_cells(&path).unwrap_err().to_string().contains("`b_std`"));
}

#[test]
fn selection_from_a_written_table_to_json() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    // One W curve over nf = 4..8 with its minimum at nf = 6, plus a failed cell and an ls row.
    let mut rows: Vec<CellRow> = [3.0, 2.5, 2.0, 2.2, 2.4]
        .iter()
        .enumerate()
        .map(|(i, &w)| huber_row(9, 4 + i as u32, 2, w, 80.0 + i as f64))
        .collect();
    rows.push(CellRow::failed(key(FitKind::Huber, 9, 9, 1, Some(2)), Some(0.0625), "diverged".into()));
    rows.push(ls_row());
    write_cells(&path, &rows).unwrap();
    let back = read_cells(&path).unwrap();
    let sel = select(&back, &ReduceOptions::new(FitBasis::Validation));
    assert_eq!((sel.cells, sel.failed), (6, 1));
    let m1 = sel.m1.as_ref().unwrap();
    assert_eq!((m1.model.key.nb, m1.model.key.nf, m1.model.k_index()), (9, 6, 2));
    assert_eq!(m1.model.fit.b, rows[2].fit.b);

    let json = dir.path().join("selection.json");
    write_json(&json, &sel).unwrap();
    let text = std::fs::read_to_string(&json).unwrap();
    // The file is exactly the pretty serialisation (serde_json writes the shortest exact form of
    // every f64). Parsing back may differ by an ulp unless serde_json's `float_roundtrip` feature
    // is on, so the parsed document is compared on structure, not bit by bit.
    assert_eq!(text, serde_json::to_string_pretty(&sel).unwrap() + "\n");
    let parsed: Selection = serde_json::from_str(&text).unwrap();
    let m1p = parsed.m1.as_ref().unwrap();
    assert_eq!((m1p.model.key.nb, m1p.model.key.nf, m1p.model.k_index(), &m1p.rule), (9, 6, 2, &m1.rule));
    assert_eq!(m1p.candidates.len(), m1.candidates.len());
    assert_eq!(parsed.m2.as_ref().map(|p| p.model.key.nf), sel.m2.as_ref().map(|p| p.model.key.nf));
    assert_eq!(dir_entries(dir.path()), vec!["cells.parquet", "selection.json"]);
}

#[test]
fn extra_columns_are_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    let rows = sample_rows();
    write_cells(&path, &rows).unwrap();
    let mut df = ParquetReader::new(File::open(&path).unwrap()).finish().unwrap();
    df.with_column(Column::new("note".into(), vec!["a", "b", "c", "d", "e"])).unwrap();
    ParquetWriter::new(File::create(&path).unwrap()).finish(&mut df).unwrap();
    assert_rows_identical(&read_cells(&path).unwrap(), &rows);
}

#[test]
fn corrupt_files_are_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.parquet");
    write_cells(&good, &sample_rows()).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let bad = dir.path().join("bad.parquet");
    // Every byte damaged in turn, the page headers inside the column chunks as well as the footer
    // (its length and the magic): polars 0.55.2 trusts a page header's counts and could attempt
    // a huge allocation and abort this process; the checks before polars refuse them.
    let n = bytes.len();
    let mut errors = 0;
    for i in 0..n {
        let mut b = bytes.clone();
        b[i] = b[i].wrapping_add(0x5b);
        std::fs::write(&bad, &b).unwrap();
        if let Err(e) = read_cells(&bad) {
            assert!(e.is_bad_input() && e.to_string().contains("bad.parquet"), "{e}");
            errors += 1;
        }
    }
    for len in [0, 4, n / 2, n - 1] {
        std::fs::write(&bad, &bytes[..len]).unwrap();
        assert!(read_cells(&bad).unwrap_err().is_bad_input());
    }
    assert!(errors > 0);
}

/// The page header damage that aborted the process before (a negative value count, see
/// `common::negate_page_values`) in a column of each type: one clear error naming the file.
#[test]
fn a_page_header_with_a_negative_count_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.parquet");
    write_cells(&good, &sample_rows()).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let bad = dir.path().join("bad.parquet");
    for column in ["method", "nb", "k", "converged", "b.list.element"] {
        std::fs::write(&bad, common::negate_page_values(&bytes, column)).unwrap();
        let e = read_cells(&bad).unwrap_err();
        let msg = e.to_string();
        assert!(e.is_bad_input() && msg.contains("bad.parquet"), "{msg}");
        assert!(
            msg.contains(&format!("a page of column '{column}' in row group 0 declares a value count of -")),
            "{msg}"
        );
    }
}
