//! Property-based fuzzing of the two parsers that read user files: the job loader
//! (`job::load`, then `job::load_inputs` on what it accepts) and the data reader
//! (`data::read_record`, CSV and Parquet). Whatever the input, they must return `Ok` or a
//! bad-input `Err` whose message is one line; they must never panic, hang or abort.
//!
//! Inputs: arbitrary text and bytes, CSV-like text built from tricky tokens, structured
//! mutations of a valid job (fields removed, replaced by values of the wrong type or out of
//! range, unknown fields added), and byte-level mutations of a valid Parquet file.
//!
//! The default case count (256 per property, a few seconds in release) keeps `cargo test`
//! quick; for a longer campaign: `PROPTEST_CASES=100000 cargo test --release --test
//! fuzz_parsers`. A failure is shrunk to a small input and its seed saved in
//! `tests/fuzz_parsers.proptest-regressions`, which every run replays first.

use oesweep::data::{check_for_model, read_record};
use oesweep::error::Error;
use oesweep::job::{self, MAX_CELLS};
use polars::prelude::{Column, DataFrame, ParquetWriter};
use proptest::prelude::*;
use serde_json::{Value, json};
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const VALID_DATA: &str = include_str!("bad_inputs/_valid/data.csv");
const VALID_VAL: &str = include_str!("bad_inputs/_valid/val.csv");

/// The message of a bad-input error. The path in front of it is printed as given (by the
/// command line or the job) and is not the parsers' to escape.
fn checked_message(e: &Error) -> String {
    assert!(e.is_bad_input(), "not a bad-input error: {e}");
    let msg = match e {
        Error::Input { msg, .. } | Error::Data { msg, .. } => msg.clone(),
        other => other.to_string(),
    };
    assert!(!msg.contains('\n') && !msg.contains('\r'), "message is not one line: {msg:?}");
    msg
}

// ---------------------------------------------------------------------------------------------
// Data reader

/// Fields that have broken or nearly broken parsers elsewhere.
fn tokens() -> Vec<String> {
    let mut t: Vec<String> = [
        "0",
        "1",
        "-2.5e3",
        "+3",
        ".5",
        "5.",
        "1e999",
        "-1e999",
        "1e-400",
        "nan",
        "NaN",
        "inf",
        "-Infinity",
        "",
        " ",
        "abc",
        "0x10",
        "1_000",
        "1,5",
        "\"1\"",
        "\t2\t",
        "1\r",
        "\u{feff}",
        "é",
        "1e",
        "--1",
    ]
    .map(str::to_string)
    .to_vec();
    t.push("9".repeat(400));
    t
}

fn csv_like() -> impl Strategy<Value = String> {
    let field = prop_oneof![4 => prop::sample::select(tokens()), 1 => ".{0,6}"];
    let name = prop::sample::select(&["u", "y", "t", "y0", "", " u ", "u;y", "U"][..]);
    let header = prop::collection::vec(name, 0..5);
    let row = prop::collection::vec(field, 0..5);
    let rows = prop::collection::vec(row, 0..30);
    let sep = prop::sample::select(&[",", ",", ",", ";", "\t"][..]);
    let eol = prop::sample::select(&["\n", "\n", "\r\n", "\r", ""][..]);
    (any::<bool>(), header, rows, sep, eol, any::<bool>()).prop_map(|(bom, header, rows, sep, eol, final_eol)| {
        let mut s = String::from(if bom { "\u{feff}" } else { "" });
        s.push_str(&header.join(sep));
        for r in rows {
            s.push_str(eol);
            s.push_str(&r.join(sep));
        }
        if final_eol {
            s.push_str(eol);
        }
        s
    })
}

fn check_read(path: &Path, u: &str, y: &str) {
    match read_record(path, u, y) {
        Ok(rec) => {
            assert!(!rec.u.is_empty() && rec.u.len() == rec.y.len());
            assert!(rec.u.iter().chain(&rec.y).all(|v| v.is_finite()));
            // Any orders and delay, including absurd ones, are a verdict and not a panic.
            for (nb, nf, d) in [(1, 0, 0), (2, 2, 1), (60, 60, 10_000), (1, 1, usize::MAX)] {
                if let Err(e) = check_for_model(&rec, nb, nf, d) {
                    checked_message(&e);
                }
            }
        }
        Err(e) => {
            checked_message(&e);
        }
    }
}

fn read_text_as_csv(text: &[u8], u: &str, y: &str) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("data.csv");
    fs::write(&p, text).unwrap();
    check_read(&p, u, y);
}

/// A valid Parquet record (t, u, y as f64) to mutate.
fn valid_parquet() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let n = 64;
        let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let u: Vec<f64> = (0..n).map(|i| if (i / 3) % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let cols = vec![Column::new("t".into(), t), Column::new("u".into(), u), Column::new("y".into(), y)];
        let mut df = DataFrame::new(n, cols).unwrap();
        let mut buf = Vec::new();
        ParquetWriter::new(&mut buf).finish(&mut df).unwrap();
        buf
    })
}

#[derive(Clone, Debug)]
enum ByteEdit {
    Set(usize, u8),
    Insert(usize, Vec<u8>),
    Truncate(usize),
}

fn byte_edit() -> impl Strategy<Value = ByteEdit> {
    prop_oneof![
        6 => (any::<usize>(), any::<u8>()).prop_map(|(i, b)| ByteEdit::Set(i, b)),
        1 => (any::<usize>(), prop::collection::vec(any::<u8>(), 1..16)).prop_map(|(i, b)| ByteEdit::Insert(i, b)),
        1 => any::<usize>().prop_map(ByteEdit::Truncate),
    ]
}

proptest! {
    #[test]
    fn csv_arbitrary_text(text in "(?s).{0,300}") {
        read_text_as_csv(text.as_bytes(), "u", "y");
    }

    #[test]
    fn csv_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        read_text_as_csv(&bytes, "u", "y");
    }

    #[test]
    fn csv_tricky_tokens(text in csv_like(), cols in prop::sample::select(&[("u", "y"), ("u", "u"), ("t", "y0"), ("u\n", "y")][..])) {
        read_text_as_csv(text.as_bytes(), cols.0, cols.1);
    }

    #[test]
    fn parquet_mutated(edits in prop::collection::vec(byte_edit(), 1..6)) {
        let mut b = valid_parquet().to_vec();
        for e in edits {
            match e {
                // Most edits land in the data pages; keep some in the footer (metadata), which
                // is where the decoder trusts the file most.
                ByteEdit::Set(i, v) if !b.is_empty() => {
                    let i = if i % 3 == 0 { b.len() - 1 - (i / 3) % b.len().min(200) } else { i % b.len() };
                    b[i] = v;
                }
                ByteEdit::Insert(i, v) => {
                    let i = i % (b.len() + 1);
                    b.splice(i..i, v);
                }
                ByteEdit::Truncate(i) => b.truncate(i % (b.len() + 1)),
                _ => {}
            }
        }
        plan_parquet(&b);
    }
}

/// Validates a job on the Parquet file `bytes` in a child process (`oesweep plan`): exit 0, or
/// exit 2 with one line naming the file. A child, because the failure this property guards
/// against is an abort, which would end the test process itself: polars-parquet 0.55 trusts a
/// page header's value count and reserves memory for it (a negative count became a reservation
/// of 2^61 bytes, about one mutated file in 30000), and a failed allocation aborts.
/// `data::parquet::check_layout` refuses such a file before polars sees it; anything but exit
/// 0 or 2 (a panic, an abort or another signal, a second line) fails the property.
fn plan_parquet(bytes: &[u8]) {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("data.parquet");
    fs::write(&p, bytes).unwrap();
    let job = json!({
        "name": "parquet",
        "data": {"path": "data.parquet", "ts": 1e-3},
        "grid": {"nb": [1, 1], "nf": [1, 1], "k": [1.0]},
        "output": "out"
    });
    fs::write(dir.path().join("job.json"), job.to_string()).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .arg("plan")
        .arg(dir.path().join("job.json"))
        .env("RUST_BACKTRACE", "0")
        .output()
        .expect("binary runs");
    let stderr = String::from_utf8_lossy(&o.stderr);
    match o.status.code() {
        // A file that reads may still earn a warning about its data (METHOD.md 7.2).
        Some(0) => assert!(stderr.lines().all(|l| l.starts_with("warning: ")), "{stderr}"),
        Some(2) => {
            assert_eq!(stderr.lines().count(), 1, "not one line: {stderr}");
            assert!(stderr.contains(&format!("{}: ", p.display())), "file not named: {stderr}");
        }
        _ => panic!("oesweep plan: {:?}\n{stderr}", o.status),
    }
}

// ---------------------------------------------------------------------------------------------
// Job loader

/// A folder with the job's data files (CSV, Parquet, a sub-folder) and a path to write jobs to.
fn job_folder() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("data.csv"), VALID_DATA).unwrap();
    fs::write(dir.path().join("val.csv"), VALID_VAL).unwrap();
    fs::write(dir.path().join("data.parquet"), valid_parquet()).unwrap();
    fs::create_dir(dir.path().join("sub")).unwrap();
    let p = dir.path().join("job.json");
    (dir, p)
}

fn check_job(path: &Path) {
    match job::load(path) {
        Ok(vj) => {
            assert!(vj.n_cells() >= 1 && vj.n_cells() <= MAX_CELLS);
            assert!(vj.ks.iter().all(|k| k.is_finite() && *k > 0.0));
            let mut ks = vj.ks.clone();
            ks.sort_by(f64::total_cmp);
            assert!(ks.windows(2).all(|w| w[0] < w[1]), "duplicate k: {:?}", vj.ks);
            if let Err(e) = job::load_inputs(&vj) {
                checked_message(&e);
            }
        }
        Err(e) => {
            checked_message(&e);
        }
    }
}

fn base_job() -> Value {
    json!({
        "name": "fuzz",
        "data": {"path": "data.csv", "u": "u", "y": "y", "ts": 1e-3},
        "validation": {"path": "val.csv", "u": "u"},
        "delay": 1,
        "grid": {"nb": [1, 2], "nf": [0, 2], "k": {"from": 0.1, "to": 1.0, "count": 3, "spacing": "log"}},
        "band_hz": [0, 200],
        "start": "best",
        "solver": {"max_iterations": 10, "ftol": 1e-10, "huber_hessian": "irls"},
        "selection": {"min_tolerance": 1e-3, "fit_tolerance": 0.05},
        "output": "out"
    })
}

/// Values a field may be replaced by: right and wrong types, edge numbers, names of files
/// that exist, do not exist or are folders, and arbitrary short text.
fn json_value() -> impl Strategy<Value = Value> {
    let numbers = prop::sample::select(
        &[
            0.0,
            -0.0,
            1.0,
            -1.0,
            0.5,
            2.0,
            59.0,
            60.0,
            61.0,
            1e-320,
            1e-12,
            1e12,
            1e15,
            1e308,
            -1e308,
            4.5e15,
            9007199254740993.0,
            18446744073709551615.0,
            1.5,
        ][..],
    );
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        numbers.prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        (0u64..300).prop_map(Value::from),
        any::<f64>().prop_map(Value::from),
        prop::sample::select(
            &[
                "data.csv",
                "val.csv",
                "data.parquet",
                "missing.csv",
                "sub",
                "sub/new",
                "data.csv/x",
                "",
                " ",
                "out",
                "u",
                "y",
                "y0",
                "t",
                "log",
                "linear",
                "ls",
                "neighbour",
                "best",
                "irls",
                "gauss_newton",
                "a\nb",
            ][..]
        )
        .prop_map(Value::from),
        "[^/.]{0,8}".prop_map(Value::from),
    ];
    leaf.prop_recursive(2, 12, 4, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..4).prop_map(Value::Array),
            prop::collection::btree_map(
                prop::sample::select(&["from", "to", "count", "spacing", "path", "ts", "x"][..])
                    .prop_map(str::to_string),
                inner,
                0..4
            )
            .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

#[derive(Clone, Debug)]
enum JobEdit {
    Remove(usize),
    Replace(usize, Value),
    /// Add a key (known somewhere in the schema, or unknown) to an object.
    Insert(usize, String, Value),
}

fn job_edit() -> impl Strategy<Value = JobEdit> {
    let key = prop::sample::select(
        &["name", "ts", "u", "y", "delay", "band_hz", "output", "count", "spacing", "threads", "k", "gtol", "xtol"][..],
    )
    .prop_map(str::to_string);
    prop_oneof![
        1 => any::<usize>().prop_map(JobEdit::Remove),
        4 => (any::<usize>(), json_value()).prop_map(|(i, v)| JobEdit::Replace(i, v)),
        1 => (any::<usize>(), key, json_value()).prop_map(|(i, k, v)| JobEdit::Insert(i, k, v)),
    ]
}

/// JSON pointers of every node below the root.
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, c) in m {
                let p = format!("{at}/{k}");
                out.push(p.clone());
                pointers(c, p, out);
            }
        }
        Value::Array(a) => {
            for (i, c) in a.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                pointers(c, p, out);
            }
        }
        _ => {}
    }
}

fn apply(job: &mut Value, edit: JobEdit) {
    let mut ps = Vec::new();
    pointers(job, String::new(), &mut ps);
    let pick = |i: usize| ps[i % ps.len()].clone();
    match edit {
        JobEdit::Remove(i) => {
            let p = pick(i);
            let (parent, last) = p.rsplit_once('/').unwrap();
            match job.pointer_mut(parent) {
                Some(Value::Object(m)) => {
                    m.remove(last);
                }
                Some(Value::Array(a)) => {
                    a.remove(last.parse::<usize>().unwrap());
                }
                _ => {}
            }
        }
        JobEdit::Replace(i, v) => {
            if let Some(slot) = job.pointer_mut(&pick(i)) {
                *slot = v;
            }
        }
        JobEdit::Insert(i, k, v) => {
            let p = pick(i);
            let target = match job.pointer(&p) {
                Some(Value::Object(_)) => p,
                _ => String::new(),
            };
            if let Some(Value::Object(m)) = job.pointer_mut(&target) {
                m.insert(k, v);
            }
        }
    }
}

proptest! {
    #[test]
    fn job_arbitrary_text(text in "(?s).{0,200}") {
        let (_dir, p) = job_folder();
        fs::write(&p, text).unwrap();
        check_job(&p);
    }

    #[test]
    fn job_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..200)) {
        let (_dir, p) = job_folder();
        fs::write(&p, bytes).unwrap();
        check_job(&p);
    }

    #[test]
    fn job_structured_mutations(edits in prop::collection::vec(job_edit(), 1..5), pretty in any::<bool>()) {
        let mut job = base_job();
        for e in edits {
            apply(&mut job, e);
        }
        let (_dir, p) = job_folder();
        let text = if pretty { serde_json::to_string_pretty(&job) } else { serde_json::to_string(&job) };
        fs::write(&p, text.unwrap()).unwrap();
        check_job(&p);
    }

    /// Cutting a valid job anywhere (the usual result of an editor crash or a bad merge).
    #[test]
    fn job_truncated(cut in any::<usize>()) {
        let text = serde_json::to_string_pretty(&base_job()).unwrap();
        let cut = cut % (text.len() + 1);
        let (_dir, p) = job_folder();
        fs::write(&p, &text.as_bytes()[..cut]).unwrap();
        check_job(&p);
    }
}

/// The base job itself is valid, so the mutations start from a job that gets all the way
/// through validation (a mutation then breaks one thing at a time).
#[test]
fn base_job_is_valid() {
    let (_dir, p) = job_folder();
    fs::write(&p, serde_json::to_string(&base_job()).unwrap()).unwrap();
    let vj = job::load(&p).unwrap();
    job::load_inputs(&vj).unwrap();
}
