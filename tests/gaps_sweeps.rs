//! Records with gaps through a whole sweep's machinery (METHOD.md 21.1): a job of two
//! experiments with missing outputs (empty fields and a number marker) and an input gap gives
//! the same table and `selection.json` run whole, in two shards merged, and killed after a
//! checkpoint part and resumed; `selection.json`'s `gaps` adds the experiments' counts; a
//! number marker in a Parquet file marks a missing sample by value.
#![cfg(unix)]

mod common;

use common::Draws;
use oesweep::checkpoint::BATCH_ROWS;
use oesweep::data::{ColumnRef, Marker, ReadOptions};
use oesweep::export::parquet::read_cells;
use oesweep::table::CellRow;
use polars::prelude::{Column, DataFrame, ParquetWriter};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const PAIRS: usize = 9;
/// k values per pair: 9 + 9 x 60 = 549 rows, more than one checkpoint part.
const KS: usize = 60;
const N: usize = 1500;

fn text(o: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// What each experiment's file misses, to check the counts against.
struct Made {
    outputs_missing: usize,
    rows_cut: usize,
}

/// An OE(2,2) record with noise and 3 % spikes; output samples missing (4 %: bursts and single
/// samples), written as empty fields and as the marker -999; `input_gap` rows of the input
/// left empty.
fn write_record(path: &Path, seed: u64, input_gap: &[usize]) -> Made {
    let u = common::binary_input(N, 4, 1.0, seed);
    let f = common::f_from_poles(&[(0.9, 0.3)], &[]);
    let mut r = Draws(seed + 7);
    let mut y: Vec<f64> = oesweep::oe::simulate_vec(&[0.4, 0.2], &f, 1, &u)
        .iter()
        .map(|v| v + 0.03 * r.gauss() + if r.uniform() < 0.03 { 0.5 } else { 0.0 })
        .collect();
    let gone = common::output_gaps(N, 0.04, &mut r);
    for &t in &gone {
        y[t] = f64::NAN;
    }
    let mut s = String::from("u,y\n");
    for t in 0..N {
        let uf = if input_gap.contains(&t) { String::new() } else { format!("{:e}", u[t]) };
        let yf = if !y[t].is_nan() {
            format!("{:e}", y[t])
        } else if t % 2 == 0 {
            String::new()
        } else {
            "-999".to_string()
        };
        s.push_str(&format!("{uf},{yf}\n"));
    }
    std::fs::write(path, s).unwrap();
    let outputs_missing = gone.iter().filter(|t| !input_gap.contains(t)).count();
    Made { outputs_missing, rows_cut: input_gap.len() }
}

/// Two experiments (the second with an input gap) and a validation record, and a job writing
/// to `output`.
fn setup(dir: &Path) -> (Made, Made) {
    let a = write_record(&dir.join("e0.csv"), 1, &[]);
    let b = write_record(&dir.join("e1.csv"), 2, &[700, 701]);
    write_record(&dir.join("val.csv"), 3, &[]);
    (a, b)
}

fn write_job(dir: &Path, file: &str, output: &str) -> PathBuf {
    let job = serde_json::json!({
        "name": "gaps",
        "data": [{"path": "e0.csv", "ts": 0.01, "missing": [-999]}, {"path": "e1.csv"}],
        "validation": {"path": "val.csv", "y": "y"},
        "delay": 1,
        "grid": {"nb": [1, 3], "nf": [1, 3], "k": {"from": 0.1, "to": 2.0, "count": KS, "spacing": "log"}},
        "start": "chains",
        "output": output,
    });
    let p = dir.join(file);
    std::fs::write(&p, serde_json::to_string_pretty(&job).unwrap()).unwrap();
    p
}

fn table(path: &Path) -> Vec<CellRow> {
    let mut rows = read_cells(path).unwrap();
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

fn selection(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("selection.json")).unwrap()).unwrap()
}

fn run(bin: &str, args: &[&str], failpoint: Option<&str>) -> Child {
    let mut cmd = Command::new(bin);
    cmd.args(args);
    if let Some(f) = failpoint {
        cmd.env("OESWEEP_FAILPOINT", f);
    }
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("binary starts")
}

fn finish(child: Child) -> Output {
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    o
}

#[test]
fn a_job_with_gaps_gives_one_table_whole_sharded_and_resumed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (a, b) = setup(d);
    let oesweep = env!("CARGO_BIN_EXE_oesweep");

    // Whole.
    let whole = write_job(d, "whole.json", "whole");
    finish(run(oesweep, &["run", whole.to_str().unwrap(), "--threads", "2", "--quiet"], None));
    let expected = table(&d.join("whole/cells.parquet"));
    assert_eq!(expected.len(), PAIRS + PAIRS * KS);

    // The counts add the experiments': rows of both, the outputs each misses, the cut rows.
    let gaps = &selection(&d.join("whole"))["gaps"]["data"];
    assert_eq!(gaps["rows"], 2 * N, "{gaps}");
    assert_eq!(gaps["rows_cut"], a.rows_cut + b.rows_cut, "{gaps}");
    assert_eq!(gaps["samples"], 2 * N - b.rows_cut, "{gaps}");
    assert_eq!(gaps["outputs_missing"], a.outputs_missing + b.outputs_missing, "{gaps}");
    assert_eq!(gaps["segments"], 3, "{gaps}");
    assert!(selection(&d.join("whole"))["gaps"]["validation"]["outputs_missing"].as_u64().unwrap() > 0);

    // Two shards side by side, then merge.
    let sharded = write_job(d, "sharded.json", "sharded");
    let s = sharded.to_str().unwrap();
    let shards: Vec<Child> = (0..2)
        .map(|i| run(oesweep, &["run", s, "--shard", &format!("{i}/2"), "--threads", "1", "--quiet"], None))
        .collect();
    for c in shards {
        finish(c);
    }
    finish(run(oesweep, &["merge", d.join("sharded").to_str().unwrap()], None));
    assert!(table(&d.join("sharded/cells.parquet")) == expected, "sharded table differs from the whole run's");
    assert_eq!(selection(&d.join("sharded")), selection(&d.join("whole")));

    // Killed right after the first checkpoint part (the pause point of the test-hooks build),
    // then resumed.
    let resumed = write_job(d, "resumed.json", "resumed");
    let marker = d.join("paused");
    let failpoint = format!("pause_part:1:{}", marker.display());
    let hooks = env!("CARGO_BIN_EXE_oesweep-testhooks");
    let r = resumed.to_str().unwrap();
    let mut child = run(hooks, &["run", r, "--threads", "2", "--quiet", "--checkpoint-every", "1e6"], Some(&failpoint));
    let t = Instant::now();
    while !marker.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the run ended ({status}) before its pause point");
        }
        assert!(t.elapsed() < Duration::from_secs(600), "no pause after 600 s");
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let saved: usize = std::fs::read_dir(d.join("resumed/parts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "parquet"))
        .map(|p| read_cells(&p).unwrap().len())
        .sum();
    assert_eq!(saved, BATCH_ROWS);
    let o = finish(run(oesweep, &["run", r, "--threads", "2", "--quiet"], None));
    assert!(String::from_utf8_lossy(&o.stdout).contains("resumed from the checkpoint"), "{}", text(&o));
    assert!(table(&d.join("resumed/cells.parquet")) == expected, "resumed table differs from the whole run's");
    assert_eq!(selection(&d.join("resumed")), selection(&d.join("whole")));
}

#[test]
fn a_number_marker_marks_a_parquet_sample_by_value() {
    let dir = tempfile::tempdir().unwrap();
    let u: Vec<f64> = (0..30).map(|t| ((t * 5) % 7) as f64).collect();
    let y: Vec<f64> = (0..30).map(|t| if t == 4 || t == 17 { -999.0 } else { t as f64 * 0.1 }).collect();
    let yi: Vec<i64> = (0..30).map(|t| if t == 8 { -999 } else { t }).collect();
    let pq = dir.path().join("r.parquet");
    let mut df = DataFrame::new(
        30,
        vec![Column::new("u".into(), u.clone()), Column::new("y".into(), y), Column::new("yi".into(), yi)],
    )
    .unwrap();
    ParquetWriter::new(std::fs::File::create(&pq).unwrap()).finish(&mut df).unwrap();
    let read = |col: &str, markers: Vec<Marker>| {
        oesweep::data::read_record_inputs(
            &pq,
            &[ColumnRef::name("u")],
            &ColumnRef::name(col),
            &ReadOptions { missing: markers, ..ReadOptions::default() },
        )
    };
    let r = read("y", vec![Marker::Number(-999.0)]).unwrap();
    assert_eq!(r.missing, vec![4, 17]);
    assert!(r.y[4].is_nan() && r.y[17].is_nan() && r.y[5] == 0.5);
    // An integer column matches by value too.
    let r = read("yi", vec![Marker::Number(-999.0)]).unwrap();
    assert_eq!(r.missing, vec![8]);
    // Without the marker, -999 is a number like any other.
    let r = read("y", vec![]).unwrap();
    assert!(r.missing.is_empty() && r.y[4] == -999.0);
}
