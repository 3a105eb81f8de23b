//! The data readers on files as people publish them: every dialect gives the same numbers,
//! columns by name or position, row ranges, MAT-files; and each malformed variant one clear
//! message naming the file, the line or row and the column.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use common::mat::{Var, level5, v73_stub};
use oesweep::data::{ColumnRef, Delimiter, Header, ReadOptions, Record, column_names, read_record_with};
use tempfile::TempDir;

/// 40 samples whose text form round-trips exactly (`{}` of an f64 parses back to it).
fn signals() -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = (0..40).map(|i| if (i / 3) % 2 == 0 { 1.5 } else { -0.25 }).collect();
    let y: Vec<f64> = (0..40).map(|i| 97.0 + (i as f64 * 0.37).sin() / 3.0).collect();
    (u, y)
}

fn write(dir: &TempDir, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.path().join(name);
    fs::write(&p, bytes).unwrap();
    p
}

fn by_name(u: &str, y: &str) -> (ColumnRef, ColumnRef) {
    (ColumnRef::name(u), ColumnRef::name(y))
}

fn read(p: &Path, cols: &(ColumnRef, ColumnRef), opts: &ReadOptions) -> Record {
    read_record_with(p, &cols.0, &cols.1, opts).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn err(p: &Path, cols: &(ColumnRef, ColumnRef), opts: &ReadOptions, want: &str) -> String {
    let e = read_record_with(p, &cols.0, &cols.1, opts).expect_err("expected an error");
    let msg = e.to_string();
    assert!(e.is_bad_input(), "{msg}");
    assert!(msg.contains(p.file_name().unwrap().to_str().unwrap()), "message does not name the file: {msg}");
    assert!(msg.contains(want), "message lacks '{want}': {msg}");
    assert!(!msg.contains('\n'), "{msg}");
    msg
}

/// Text of a table: `head` (or none), then one line per sample from `fields(u, y)`.
fn table(head: Option<&str>, fields: impl Fn(f64, f64) -> String, tail: &str) -> String {
    let (u, y) = signals();
    let mut s = head.map(|h| format!("{h}\n")).unwrap_or_default();
    for (a, b) in u.iter().zip(&y) {
        s.push_str(&fields(*a, *b));
        s.push('\n');
    }
    s.push_str(tail);
    s
}

#[test]
fn every_dialect_gives_the_same_record() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let default = ReadOptions::default();
    let cases: Vec<(&str, String, (ColumnRef, ColumnRef))> = vec![
        ("plain.csv", table(Some("t,u,y"), |a, b| format!("0,{a},{b}"), ""), by_name("u", "y")),
        (
            "quoted_trailing_comma.csv",
            table(Some("\"uEst\",\"yEst\",\"note, quoted\","), |a, b| format!("{a},{b},x,"), "\n"),
            by_name("uEst", "yEst"),
        ),
        ("trailing_comma_data_only.csv", table(Some("u,y"), |a, b| format!("{a},{b},"), ""), by_name("u", "y")),
        ("semicolons.csv", table(Some("u;y;t"), |a, b| format!("{a};{b};1,5"), ""), by_name("u", "y")),
        ("tabs.tsv", table(Some("u\ty"), |a, b| format!("{a}\t{b}"), "\n\n"), by_name("u", "y")),
        (
            "daisy.dat",
            table(None, |a, b| format!("  {:.6e}   {a}  {b}", 0.0), "\n"),
            (ColumnRef::Position(2), ColumnRef::Position(3)),
        ),
        ("crlf_bom.csv", format!("\u{feff}{}", table(Some("u,y"), |a, b| format!("{a},{b}\r"), "")), by_name("u", "y")),
        (
            "positions_with_header.csv",
            table(Some("time,input,output"), |a, b| format!("0,{a},{b}"), ""),
            (ColumnRef::Position(2), ColumnRef::Position(3)),
        ),
        ("unused_holes.csv", table(Some("u,,y,notes"), |a, b| format!("{a},,{b},"), ""), by_name("u", "y")),
    ];
    for (name, text, cols) in &cases {
        let p = write(&dir, name, text);
        let r = read(&p, cols, &default);
        assert_eq!(r.u, u, "{name}");
        assert_eq!(r.y, y, "{name}");
    }
    // Positions name the column in messages and records.
    let p = dir.path().join("daisy.dat");
    let r = read(&p, &(ColumnRef::Position(2), ColumnRef::Position(3)), &default);
    assert_eq!((r.u_names[0].as_str(), r.y_name.as_str()), ("column 2", "column 3"));
    let p = dir.path().join("positions_with_header.csv");
    let r = read(&p, &(ColumnRef::Position(2), ColumnRef::Position(3)), &default);
    assert_eq!((r.u_names[0].as_str(), r.y_name.as_str()), ("input", "output"));
    assert_eq!(column_names(&p, &default).unwrap(), vec!["time", "input", "output"]);
    assert!(column_names(&dir.path().join("daisy.dat"), &default).unwrap().is_empty());
}

#[test]
fn several_input_columns_of_a_text_file_in_the_order_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let p = write(&dir, "three.dat", table(None, |a, b| format!("  {b}  {a}  {}", a * 2.0 + 1.0), "\n"));
    let us = [ColumnRef::Position(3), ColumnRef::Position(2)];
    let r = oesweep::data::read_record_inputs(&p, &us, &ColumnRef::Position(1), &ReadOptions::default()).unwrap();
    let doubled: Vec<f64> = u.iter().map(|a| a * 2.0 + 1.0).collect();
    assert_eq!((r.input(0), r.input(1), &r.y), (&doubled[..], &u[..], &y));
    assert_eq!(r.u_names, vec!["column 3", "column 2"]);
    let e = oesweep::data::read_record_inputs(
        &p,
        &[ColumnRef::Position(2), ColumnRef::Position(2)],
        &ColumnRef::Position(1),
        &ReadOptions::default(),
    );
    assert!(e.unwrap_err().to_string().ends_with("three.dat: input column 2 is named twice"));
}

#[test]
fn dialect_and_header_can_be_given() {
    let dir = tempfile::tempdir().unwrap();
    let (u, _) = signals();
    // A numeric first line that is a header (names that are numbers), and a forced delimiter.
    let p = write(&dir, "numeric_names.txt", table(Some("1;2"), |a, b| format!("{a};{b}"), ""));
    let cols = (ColumnRef::name("1"), ColumnRef::name("2"));
    let opts = ReadOptions { header: Header::Yes, delimiter: Some(Delimiter::Byte(b';')), ..ReadOptions::default() };
    assert_eq!(read(&p, &cols, &opts).u, u);
    // header: false reads the first line as data.
    let p = write(&dir, "no_header.csv", table(None, |a, b| format!("{a},{b}"), ""));
    let opts = ReadOptions { header: Header::No, ..ReadOptions::default() };
    assert_eq!(read(&p, &(ColumnRef::Position(1), ColumnRef::Position(2)), &opts).u, u);
    // Whitespace forced on a file the sniffer would call tab-separated.
    let p = write(&dir, "aligned.txt", table(None, |a, b| format!("\t{a}\t\t{b}"), ""));
    let opts = ReadOptions { delimiter: Some(Delimiter::Whitespace), ..ReadOptions::default() };
    assert_eq!(read(&p, &(ColumnRef::Position(1), ColumnRef::Position(2)), &opts).u, u);
}

#[test]
fn row_ranges_split_one_experiment() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let p = write(&dir, "exp.csv", table(Some("u,y"), |a, b| format!("{a},{b}"), ""));
    let cols = by_name("u", "y");
    let est = read(&p, &cols, &ReadOptions { rows: Some([1, 30]), ..ReadOptions::default() });
    let val = read(&p, &cols, &ReadOptions { rows: Some([31, 40]), ..ReadOptions::default() });
    assert_eq!(est.u, u[..30]);
    assert_eq!(val.y, y[30..]);
    err(
        &p,
        &cols,
        &ReadOptions { rows: Some([31, 41]), ..ReadOptions::default() },
        "rows [31, 41] reach past the end of the file: it has 40 data rows",
    );
    err(&p, &cols, &ReadOptions { rows: Some([0, 4]), ..ReadOptions::default() }, "rows [0, 4] is not a range");
    // A bad value outside the range is not looked at; inside it is named by its line.
    let mut text = table(Some("u,y"), |a, b| format!("{a},{b}"), "");
    text = text.replacen("97.33", "oops", 1);
    let p = write(&dir, "late_typo.csv", &text);
    let line = 1 + text.lines().skip(1).position(|l| l.contains("oops")).unwrap() + 1;
    let before = ReadOptions { rows: Some([1, line - 3]), ..ReadOptions::default() };
    assert_eq!(read(&p, &cols, &before).len(), line - 3);
    err(&p, &cols, &ReadOptions::default(), &format!("line {line}, column 'y': 'oops"));
}

#[test]
fn text_files_that_are_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let d = ReadOptions::default();
    let uy = by_name("u", "y");
    let pos = |a, b| (ColumnRef::Position(a), ColumnRef::Position(b));
    let p = write(&dir, "pos0.csv", "u,y\n1,2\n");
    err(&p, &pos(0, 2), &d, "column position 0: positions count from 1");
    err(&p, &pos(1, 3), &d, "column position 3: the file has 2 columns");
    let p = write(&dir, "noheader.dat", "1 2\n3 4\n");
    err(&p, &uy, &d, "no column 'u': the file has no header row");
    // An empty field is a missing sample, not an error (METHOD.md 21.1, tests/gaps_data.rs).
    let p = write(&dir, "hole.csv", "u,y,z\n1,2,3\n1,,3\n");
    assert_eq!(read(&p, &uy, &d).missing, vec![1]);
    let p = write(&dir, "short.csv", "u,y,z\n1,2,3\n1,2\n");
    err(&p, &uy, &d, "line 3: 2 fields, but the header has 3");
    let p = write(&dir, "blank.csv", "u,y\n1,2\n\n3,4\n");
    err(&p, &uy, &d, "line 3: empty line");
    let p = write(&dir, "dup.csv", "u,y,u\n1,2,3\n");
    err(&p, &uy, &d, "column 'u' appears twice in the header");
    let p = write(&dir, "comma_decimals.csv", "u;y\n1,5;2\n");
    err(&p, &uy, &d, "line 2, column 'u': '1,5' is not a number (a decimal comma?");
    let p = write(&dir, "empty.csv", " \n\n");
    err(&p, &uy, &d, "file is empty");
    let p = write(&dir, "header_only.csv", "u,y\n");
    err(&p, &uy, &d, "no data rows");
    let p = write(&dir, "inf.txt", "1 2\n3 -inf\n");
    err(&p, &pos(1, 2), &d, "line 2, column 'column 2': infinite value");
}

#[test]
fn mat_files() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals();
    let t: Vec<f64> = (0..40).map(|i| i as f64).collect();
    let two: Vec<f64> = u.iter().chain(&y).copied().collect();
    let bytes = level5(&[
        Var::Text { name: "note", text: "piezo, 2026" },
        Var::Double { name: "u", dims: [40, 1], data: &u },
        Var::Double { name: "y", dims: [1, 40], data: &y },
        Var::Double { name: "t", dims: [40, 1], data: &t },
        Var::Double { name: "uy", dims: [40, 2], data: &two },
        Var::Double { name: "short", dims: [39, 1], data: &y[..39] },
    ]);
    let p = write(&dir, "rec.mat", &bytes);
    let d = ReadOptions::default();
    let r = read(&p, &by_name("u", "y"), &d);
    assert_eq!((r.u, r.y), (u.clone(), y.clone()));
    assert_eq!(column_names(&p, &d).unwrap(), vec!["u", "y", "t", "uy", "short"]);
    let r = read(&p, &by_name("u", "y"), &ReadOptions { rows: Some([11, 40]), ..d.clone() });
    assert_eq!(r.y, y[10..]);
    err(&p, &by_name("uy", "y"), &d, "variable 'uy' is a 40x2 matrix: give a vector");
    err(&p, &by_name("note", "y"), &d, "no numeric variable 'note' (numeric variables: u, y, t, uy, short; text");
    err(&p, &by_name("u", "short"), &d, "variables 'u' (40 samples) and 'short' (39 samples) differ in length");
    err(&p, &(ColumnRef::Position(1), ColumnRef::name("y")), &d, "chosen by name");
    // Several inputs: vectors of either orientation, in the order asked for.
    let (us, y_ref) = ([ColumnRef::name("t"), ColumnRef::name("u")], ColumnRef::name("y"));
    let r = oesweep::data::read_record_inputs(&p, &us, &y_ref, &d).unwrap();
    assert_eq!((r.input(0), r.input(1), &r.y), (&t[..], &u[..], &y));
    assert_eq!(r.u_names, vec!["t", "u"]);
    let us = [ColumnRef::name("u"), ColumnRef::name("short")];
    let e = oesweep::data::read_record_inputs(&p, &us, &y_ref, &d).unwrap_err().to_string();
    assert!(e.contains("'short' (39 samples)"), "{e}");
    let p = write(&dir, "new.mat", v73_stub());
    err(&p, &by_name("u", "y"), &d, "MATLAB v7.3 (HDF5) MAT-file");
    err(&p, &by_name("u", "y"), &d, "-v7");
    let p = write(&dir, "garbage.mat", "u,y\n1,2\n");
    err(&p, &by_name("u", "y"), &d, "not a readable MATLAB level-5 MAT-file");
}
