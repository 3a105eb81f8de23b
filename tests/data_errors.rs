//! Every way a data file can be wrong gives one clear message naming the file (and the line or
//! row and the column where that applies). These tests pin the wording that users and the docs
//! rely on, for CSV and Parquet, and the model-size checks of `check_for_model`.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use oesweep::data::{ColumnRef, ReadOptions, Record, check_for_model, column_names, read_columns, read_record};
use polars::prelude::{Column, DataFrame, ParquetWriter};
use tempfile::TempDir;

/// Writes `text` to `name` in a fresh temporary folder.
fn csv(name: &str, text: &str) -> (TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    fs::write(&p, text).unwrap();
    (dir, p)
}

/// The error of reading columns u and y, checked to name the file and contain `want`.
fn err_uy(path: &Path, want: &str) -> String {
    let e = read_record(path, "u", "y").unwrap_err();
    let msg = e.to_string();
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(msg.contains(name), "message does not name the file: {msg}");
    assert!(msg.contains(want), "message lacks '{want}': {msg}");
    assert!(e.is_bad_input());
    // Of the data's kind, whatever the file is called (the Python package's DataError).
    assert!(matches!(e, oesweep::Error::Data { .. }), "{e:?}");
    msg
}

fn csv_err(name: &str, text: &str, want: &str) -> String {
    let (_dir, p) = csv(name, text);
    err_uy(&p, want)
}

#[test]
fn missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let msg = err_uy(&dir.path().join("absent.csv"), "cannot open file");
    assert!(msg.contains("absent.csv: cannot open file"), "{msg}");
    err_uy(&dir.path().join("absent.parquet"), "cannot open file");
}

#[test]
fn empty_file() {
    csv_err("empty.csv", "", "file is empty");
    csv_err("blank.csv", "\n  \r\n", "file is empty");
}

#[test]
fn header_only() {
    csv_err("header_only.csv", "u,y\n", "no data rows");
    csv_err("header_only_no_newline.csv", "u,y", "no data rows");
}

#[test]
fn missing_column() {
    csv_err("missing.csv", "t,x,y\n0,1,2\n", "no column 'u' (columns: t, x, y)");
}

#[test]
fn duplicate_column() {
    csv_err("dup.csv", "u,y,u\n1,2,3\n", "column 'u' appears twice in the header");
}

#[test]
fn wrong_field_count() {
    let text = "t,u,y\n0,1,2\n1,1,2\n2,1,2\n3,1,2\n4,1,2\n5,1\n";
    csv_err("fields.csv", text, "line 7: 2 fields, but the header has 3");
    csv_err("too_many.csv", "u,y\n1,2,3\n", "line 2: 3 fields, but the header has 2");
}

#[test]
fn non_numeric() {
    let text = "t,u,y\n0,1,2\n1,1,2\n2,1,2\n3,1,2\n4,1,2\n5,1,abc\n";
    csv_err("text.csv", text, "line 7, column 'y': 'abc' is not a number");
}

#[test]
fn nan_and_empty_are_missing_and_infinity_an_error() {
    // A missing output is kept and listed (METHOD.md 21.1); tests/gaps_data.rs has the rest.
    for (name, text) in [("nan.csv", "u,y\n1,2\n1,NaN\n"), ("hole.csv", "u,y\n1,2\n1, \n")] {
        let (_dir, p) = csv(name, text);
        let r = read_record(&p, "u", "y").unwrap();
        assert_eq!((r.len(), r.missing.clone()), (2, vec![1]));
        assert!(r.y[1].is_nan());
    }
    csv_err("inf.csv", "u,y\n1,2\n1,2\ninf,2\n", "line 4, column 'u': infinite value");
}

#[test]
fn same_input_and_output_column() {
    let (_dir, p) = csv("same.csv", "u,y\n1,2\n");
    let msg = read_record(&p, "y", "y").unwrap_err().to_string();
    assert!(msg.contains("same.csv") && msg.contains("both 'y'"), "{msg}");
}

#[test]
fn csv_reads_values_and_names() {
    let (_dir, p) = csv("ok.csv", "t, u ,y\r\n0,1.5,-2\r\n1,2.5e-3,3\r\n");
    assert_eq!(column_names(&p, &ReadOptions::default()).unwrap(), vec!["t", "u", "y"]);
    let r = read_record(&p, "u", "y").unwrap();
    assert_eq!(r.u, vec![1.5, 2.5e-3]);
    assert_eq!(r.y, vec![-2.0, 3.0]);
    assert_eq!((r.u_names[0].as_str(), r.y_name.as_str()), ("u", "y"));
    assert_eq!(r.path, p);
}

fn write_parquet(path: &Path, columns: Vec<Column>) {
    let height = columns[0].len();
    let mut df = DataFrame::new(height, columns).unwrap();
    let file = fs::File::create(path).unwrap();
    ParquetWriter::new(file).finish(&mut df).unwrap();
}

#[test]
fn parquet_roundtrip() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("rec.parquet");
    let u: Vec<f64> = (0..100).map(|i| if i % 3 == 0 { 10.0 } else { -10.0 }).collect();
    let y: Vec<f64> = (0..100).map(|i| (i as f64 * 0.1).sin() * 1e-3 + 1.0 / 3.0).collect();
    // An integer column must be accepted and converted; an unrelated text column ignored.
    let k: Vec<i64> = (0..100).collect();
    let note: Vec<&str> = (0..100).map(|_| "x").collect();
    write_parquet(
        &p,
        vec![
            Column::new("note".into(), note),
            Column::new("u".into(), u.clone()),
            Column::new("k".into(), k),
            Column::new("y".into(), y.clone()),
        ],
    );
    assert_eq!(column_names(&p, &ReadOptions::default()).unwrap(), vec!["note", "u", "k", "y"]);
    let r = read_record(&p, "u", "y").unwrap();
    assert_eq!(r.u, u);
    assert_eq!(r.y, y); // bit-exact: Parquet stores doubles as they are
    let cols = read_columns(&p, &["k", "u"]).unwrap();
    assert_eq!(cols[0], (0..100).map(|i| i as f64).collect::<Vec<_>>());
    assert_eq!(cols[1], u);
    // `.pq` is Parquet too.
    let pq = dir.path().join("rec.pq");
    fs::copy(&p, &pq).unwrap();
    assert_eq!(read_record(&pq, "u", "y").unwrap().y, y);
    // Several inputs, in the order asked for (an integer column among them), input after input.
    let cols = [ColumnRef::name("u"), ColumnRef::name("k")];
    let r = oesweep::data::read_record_inputs(&p, &cols, &ColumnRef::name("y"), &ReadOptions::default()).unwrap();
    assert_eq!((r.inputs(), r.u_names.clone()), (2, vec!["u".to_string(), "k".to_string()]));
    assert_eq!((r.input(0), r.input(1)), (&u[..], &cols_k()[..]));
    let cols = [ColumnRef::name("k"), ColumnRef::Position(3)];
    let e = oesweep::data::read_record_inputs(&p, &cols, &ColumnRef::name("y"), &ReadOptions::default()).unwrap_err();
    assert!(e.to_string().ends_with("input column 'k' is named twice (as 'k' and as 3)"), "{e}");
}

fn cols_k() -> Vec<f64> {
    (0..100).map(|i| i as f64).collect()
}

#[test]
fn parquet_missing_column() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nou.parquet");
    write_parquet(
        &p,
        vec![
            Column::new("t".into(), vec![0.0, 1.0]),
            Column::new("x".into(), vec![0.0, 1.0]),
            Column::new("y".into(), vec![0.0, 1.0]),
        ],
    );
    err_uy(&p, "no column 'u' (columns: t, x, y)");
}

#[test]
fn parquet_null_value() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nulls.parquet");
    let mut y: Vec<Option<f64>> = (0..20).map(|i| Some(i as f64)).collect();
    y[11] = None;
    write_parquet(&p, vec![Column::new("u".into(), vec![1.0; 20]), Column::new("y".into(), y)]);
    // A null is a missing sample (METHOD.md 21.1).
    assert_eq!(read_record(&p, "u", "y").unwrap().missing, vec![11]);
}

#[test]
fn parquet_non_numeric_type() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("text.parquet");
    write_parquet(&p, vec![Column::new("u".into(), vec![1.0, 2.0]), Column::new("y".into(), vec!["a", "b"])]);
    err_uy(&p, "column 'y' has type String, expected numbers");
}

#[test]
fn parquet_nan_and_infinity() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.parquet");
    write_parquet(
        &p,
        vec![Column::new("u".into(), vec![1.0, 2.0, 3.0]), Column::new("y".into(), vec![1.0, 2.0, f64::NAN])],
    );
    assert_eq!(read_record(&p, "u", "y").unwrap().missing, vec![2]);
    let p = dir.path().join("inf.parquet");
    write_parquet(
        &p,
        vec![Column::new("u".into(), vec![1.0, f64::NEG_INFINITY]), Column::new("y".into(), vec![1.0, 2.0])],
    );
    err_uy(&p, "row 2, column 'u': infinite value");
}

#[test]
fn parquet_no_rows_and_garbage() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("norows.parquet");
    write_parquet(&p, vec![Column::new("u".into(), Vec::<f64>::new()), Column::new("y".into(), Vec::<f64>::new())]);
    err_uy(&p, "no data rows");
    let p = dir.path().join("garbage.parquet");
    fs::write(&p, "u,y\n1,2\n").unwrap();
    err_uy(&p, "not a readable Parquet file");
}

/// A data page header that declares a negative value count (polars 0.55 reserved 2^61 bytes for
/// it and aborted the process) is refused before polars decodes the page, for each column read.
#[test]
fn parquet_page_header_with_a_negative_count() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.parquet");
    write_parquet(&good, vec![Column::new("u".into(), ramp(64)), Column::new("y".into(), ramp(64))]);
    let bytes = fs::read(&good).unwrap();
    for column in ["u", "y"] {
        let p = dir.path().join(format!("page-{column}.parquet"));
        fs::write(&p, common::negate_page_values(&bytes, column)).unwrap();
        err_uy(
            &p,
            &format!("a page of column '{column}' in row group 0 declares a value count of -65 where at most 64 fit"),
        );
    }
}

fn record(name: &str, u: Vec<f64>, y: Vec<f64>) -> Record {
    Record {
        path: PathBuf::from(name),
        u,
        y,
        u_names: vec!["u".into()],
        y_name: "y".into(),
        seams: Vec::new(),
        missing: Vec::new(),
    }
}

fn model_err(rec: &Record, nb: usize, nf: usize, delay: usize, want: &str) {
    let msg = check_for_model(rec, nb, nf, delay).unwrap_err().to_string();
    assert!(msg.contains(&*rec.path.to_string_lossy()), "{msg}");
    assert!(msg.contains(want), "message lacks '{want}': {msg}");
}

fn ramp(n: usize) -> Vec<f64> {
    (0..n).map(|i| (i as f64 * 0.37).sin()).collect()
}

#[test]
fn too_few_samples() {
    let rec = record("short.csv", ramp(50), ramp(50));
    model_err(&rec, 12, 12, 1, "50 samples are too few for OE(nb=12, nf=12) with delay 1: need at least 109");
    let rec = record("enough.csv", ramp(109), ramp(109));
    check_for_model(&rec, 12, 12, 1).unwrap();
    // Tiny models still need 20 samples.
    let rec = record("tiny.csv", ramp(19), ramp(19));
    model_err(&rec, 1, 1, 1, "need at least 20");
}

#[test]
fn constant_input() {
    let rec = record("flat_u.csv", vec![3.0; 500], ramp(500));
    model_err(&rec, 2, 2, 1, "input column 'u' is constant (value 3): it does not excite the system");
}

#[test]
fn constant_output() {
    let rec = record("flat_y.csv", ramp(500), vec![0.0; 500]);
    model_err(&rec, 2, 2, 1, "output column 'y' is constant (value 0)");
}
