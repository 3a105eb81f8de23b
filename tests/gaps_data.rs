//! Records with gaps, the data side (METHOD.md 21.1): every form of a missing sample in every
//! reader (text `NaN`/empty/markers, Parquet nulls and NaN, MAT NaN), a record cut at its input
//! gaps is exactly the `data` list of its segments (the record, and a run's `cells.parquet`,
//! bit for bit), a gap at the first row starts the record later, interpolation only when asked
//! and then said, the counts in `selection.json` (absent for a complete record), the job's
//! fields through a results folder's `job.json`, and `oesweep simulate --missing`.

mod common;

use common::mat::{Var, level5};
use oesweep::data::{ColumnRef, Gaps, Marker, ReadOptions, Record};
use oesweep::engine::{self, RunEnd, RunOptions};
use oesweep::job;
use polars::prelude::{Column, DataFrame, ParquetWriter};
use std::path::{Path, PathBuf};

const NAN: f64 = f64::NAN;

/// The tests of this file one at a time: a run's child processes inherit locks (see
/// tests/experiments.rs).
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// A CSV of `u` and `y`, NaN written as `missing` (an empty field, "NaN", a marker).
fn write_csv(path: &Path, u: &[f64], y: &[f64], missing: &str) {
    let field = |v: f64| if v.is_nan() { missing.to_string() } else { format!("{v:e}") };
    let mut s = String::from("u,y\n");
    for (a, b) in u.iter().zip(y) {
        s.push_str(&format!("{},{}\n", field(*a), field(*b)));
    }
    std::fs::write(path, s).unwrap();
}

fn write_job(dir: &Path, name: &str, job: serde_json::Value) -> PathBuf {
    let p = dir.join(format!("{name}.json"));
    std::fs::write(&p, serde_json::to_string_pretty(&job).unwrap()).unwrap();
    p
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn same_record(a: &Record, b: &Record) {
    assert_eq!(bits(&a.u), bits(&b.u), "u");
    assert_eq!(bits(&a.y), bits(&b.y), "y");
    assert_eq!((&a.seams, &a.missing, &a.u_names, &a.y_name), (&b.seams, &b.missing, &b.u_names, &b.y_name));
}

/// A lightly damped OE(2,2) record with noise, from rest.
fn record(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u = common::binary_input(n, 3, 1.0, seed);
    let f = common::f_from_poles(&[(0.95, 0.4)], &[]);
    let mut r = common::Lcg(seed + 1);
    let y = oesweep::oe::simulate_vec(&[0.3, 0.1], &f, 1, &u).iter().map(|v| v + 0.02 * r.normal()).collect();
    (u, y)
}

#[test]
fn every_reader_reads_each_form_of_a_missing_sample() {
    let dir = tempfile::tempdir().unwrap();
    let u: Vec<f64> = (0..40).map(|t| ((t * 7) % 5) as f64 - 2.0).collect();
    let mut y: Vec<f64> = (0..40).map(|t| (t as f64 * 0.3).sin()).collect();
    for t in [0, 9, 10, 39] {
        y[t] = NAN;
    }
    let opts = |markers: Vec<Marker>| ReadOptions { missing: markers, ..ReadOptions::default() };
    let read = |p: &Path, o: &ReadOptions| {
        oesweep::data::read_record_inputs(p, &[ColumnRef::name("u")], &ColumnRef::name("y"), o)
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let expect = |r: &Record| {
        assert_eq!(r.missing, vec![0, 9, 10, 39]);
        assert_eq!(bits(&r.u), bits(&u));
        assert!(r.missing.iter().all(|&t| r.y[t].is_nan()));
        assert!((0..40).filter(|t| !r.missing.contains(t)).all(|t| r.y[t] == y[t]));
    };
    // Text: empty fields, NaN in any case, a text marker, a number marker matched by value.
    for (i, (form, markers)) in [
        ("", vec![]),
        ("NaN", vec![]),
        ("nan", vec![]),
        ("NAN", vec![]),
        ("NA", vec![Marker::Text("NA".into())]),
        ("-999.0", vec![Marker::Number(-999.0)]),
        ("-999", vec![Marker::Text("-999".into())]),
    ]
    .into_iter()
    .enumerate()
    {
        let p = dir.path().join(format!("r{i}.csv"));
        write_csv(&p, &u, &y, form);
        expect(&read(&p, &opts(markers)));
    }
    // An undeclared text stays an error, and says how to declare it; infinity stays one.
    let p = dir.path().join("na.csv");
    write_csv(&p, &u, &y, "NA");
    let e = oesweep::data::read_record_inputs(&p, &[ColumnRef::name("u")], &ColumnRef::name("y"), &opts(vec![]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 2, column 'y': 'NA' is not a number (a missing sample?"), "{e}");
    write_csv(&p, &u, &y, "inf");
    let e = oesweep::data::read_record(&p, "u", "y").unwrap_err().to_string();
    assert!(e.contains("line 2, column 'y': infinite value"), "{e}");
    // Without a header, a first row whose output is missing still has two columns.
    let p = dir.path().join("bare.csv");
    std::fs::write(&p, "1,\n2,0.5\n3,NaN\n4,0.25\n").unwrap();
    let pos = [ColumnRef::Position(1)];
    let r = oesweep::data::read_record_inputs(&p, &pos, &ColumnRef::Position(2), &opts(vec![])).unwrap();
    assert_eq!((r.u.clone(), r.missing.clone()), (vec![1.0, 2.0, 3.0, 4.0], vec![0, 2]));
    // Parquet: nulls and NaN.
    let pq = dir.path().join("r.parquet");
    let ys: Vec<Option<f64>> = y.iter().enumerate().map(|(t, v)| if t == 9 { None } else { Some(*v) }).collect();
    let mut df = DataFrame::new(40, vec![Column::new("u".into(), u.clone()), Column::new("y".into(), ys)]).unwrap();
    ParquetWriter::new(std::fs::File::create(&pq).unwrap()).finish(&mut df).unwrap();
    expect(&read(&pq, &opts(vec![])));
    // MAT: NaN, and a number marker.
    let mat = dir.path().join("r.mat");
    let ym: Vec<f64> = y.iter().enumerate().map(|(t, v)| if t == 10 { -999.0 } else { *v }).collect();
    let vars =
        [Var::Double { name: "u", dims: [40, 1], data: &u }, Var::Double { name: "y", dims: [40, 1], data: &ym }];
    std::fs::write(&mat, level5(&vars)).unwrap();
    expect(&read(&mat, &opts(vec![Marker::Number(-999.0)])));
    // Arrays (the Python package's): NaN missing, infinity refused.
    let rec = Record::from_input_arrays("<arrays>", vec![u.clone()], y.clone()).unwrap();
    expect(&rec);
    let mut bad = y.clone();
    bad[3] = f64::INFINITY;
    let e = Record::from_input_arrays("<arrays>", vec![u.clone()], bad).unwrap_err().to_string();
    assert!(e.contains("sample 3 of y is inf"), "{e}");
}

/// A record of 1000 rows with input gaps at rows 300-302 (one input) and 640 (the other), and
/// the same record given as the `data` list of its segments: the same record, the same table.
#[test]
fn a_record_cut_at_its_input_gaps_is_the_list_of_its_segments() {
    let _serial = serial();
    let dir = tempfile::tempdir().unwrap();
    let (mut u, y) = record(1000, 3);
    let (mut uv, yv) = record(600, 5);
    for t in [299, 300, 301, 639] {
        u[t] = NAN;
    }
    uv[99] = NAN;
    write_csv(&dir.path().join("est.csv"), &u, &y, "");
    write_csv(&dir.path().join("val.csv"), &uv, &yv, "NaN");
    let grid = serde_json::json!({"nb": [1, 2], "nf": [1, 2], "k": [0.5, 1.5]});
    let gappy = write_job(
        dir.path(),
        "gappy",
        serde_json::json!({"name": "g", "data": {"path": "est.csv", "ts": 0.01}, "validation": {"path": "val.csv", "y": "y"},
            "grid": grid, "output": "gappy"}),
    );
    let list = write_job(
        dir.path(),
        "list",
        serde_json::json!({"name": "g",
            "data": [{"path": "est.csv", "ts": 0.01, "rows": [1, 299]}, {"path": "est.csv", "rows": [303, 639]},
                     {"path": "est.csv", "rows": [641, 1000]}],
            "validation": [{"path": "val.csv", "y": "y", "rows": [1, 99]}, {"path": "val.csv", "rows": [101, 600]}],
            "grid": grid, "output": "list"}),
    );
    let (a, gaps) = job::load_inputs_gaps(&job::load(&gappy).unwrap()).unwrap();
    let (b, none) = job::load_inputs_gaps(&job::load(&list).unwrap()).unwrap();
    same_record(&a.est, &b.est);
    same_record(a.val.as_ref().unwrap(), b.val.as_ref().unwrap());
    assert_eq!(a.est.seams, vec![299, 636]);
    assert_eq!(
        gaps.data,
        Some(Gaps {
            rows: 1000,
            samples: 996,
            outputs_missing: 0,
            inputs_interpolated: 0,
            rows_cut: 4,
            segments: 3,
            segments_dropped: 0,
            rows_dropped: 0
        })
    );
    assert_eq!(gaps.validation.map(|g| (g.rows_cut, g.segments)), Some((1, 2)));
    assert!(!none.any());
    let run = |job: &Path| {
        let o = engine::run(job, &RunOptions { threads: 2, ..Default::default() }, &|_| {}).unwrap();
        assert!(matches!(o.end, RunEnd::Merged { .. }), "{o:?}");
        common::table_without_seconds(&job.with_extension(""))
    };
    let (ta, tb) = (run(&gappy), run(&list));
    assert!(!ta.is_empty());
    assert!(ta == tb, "the record cut at its input gaps gives another table than the list of its segments");
    // The counts reach selection.json only where something was missing.
    let sel = |name: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(name).join("selection.json")).unwrap()).unwrap()
    };
    assert_eq!(sel("gappy")["gaps"]["data"]["rows_cut"], 4);
    assert_eq!(sel("gappy")["gaps"]["validation"]["segments"], 2);
    assert!(sel("list").get("gaps").is_none());
    // `plan` prints them.
    let o = common::run_oesweep(dir.path(), &["plan", gappy.to_str().unwrap()], std::time::Duration::from_secs(120));
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    assert!(o.stdout.contains("gaps       data: 996 of 1000 rows fitted"), "{}", o.stdout);
}

#[test]
fn a_gap_at_the_first_row_starts_the_record_later_and_short_segments_are_left_out() {
    let dir = tempfile::tempdir().unwrap();
    let (mut u, mut y) = record(500, 9);
    u[0] = NAN; // the first row's input
    u[200] = NAN; // ... and a stretch of 10 rows between two input gaps
    u[211] = NAN;
    y[1] = NAN; // the first kept row's output
    write_csv(&dir.path().join("est.csv"), &u, &y, "");
    let j = write_job(
        dir.path(),
        "first",
        serde_json::json!({"name": "f", "data": {"path": "est.csv", "ts": 1}, "grid": {"nb": [1, 3], "nf": [1, 3], "k": [1]},
            "output": "out"}),
    );
    let (inputs, gaps) = job::load_inputs_gaps(&job::load(&j).unwrap()).unwrap();
    let est = &inputs.est;
    assert_eq!(est.len(), 500 - 3 - 10);
    assert_eq!(est.seams, vec![199]);
    assert_eq!(est.missing, vec![0]);
    let g = gaps.data.unwrap();
    assert_eq!((g.rows_cut, g.segments, g.segments_dropped, g.rows_dropped, g.outputs_missing), (3, 2, 1, 10, 1));
    assert!(
        inputs.warnings.iter().any(|w| w.contains("1 segment between input gaps (10 rows)")),
        "{:?}",
        inputs.warnings
    );
}

#[test]
fn input_gaps_are_interpolated_only_when_the_job_asks_and_it_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let (mut u, y) = record(400, 11);
    let before = (u[99], u[102]);
    u[100] = NAN;
    u[101] = NAN;
    u[300] = NAN;
    u[301] = NAN;
    u[302] = NAN;
    write_csv(&dir.path().join("est.csv"), &u, &y, "NaN");
    let j = write_job(
        dir.path(),
        "interp",
        serde_json::json!({"name": "i", "data": {"path": "est.csv", "ts": 1, "interpolate_inputs": 2},
            "grid": {"nb": [1, 2], "nf": [1, 2], "k": [1]}, "output": "out"}),
    );
    let vj = job::load(&j).unwrap();
    let (inputs, gaps) = job::load_inputs_gaps(&vj).unwrap();
    let g = gaps.data.unwrap();
    assert_eq!((g.inputs_interpolated, g.rows_cut, g.segments), (2, 3, 2));
    let line = before.0 + (before.1 - before.0) / 3.0;
    assert!((inputs.est.u[100] + inputs.levels.u0(0) - line).abs() < 1e-12);
    assert!(inputs.warnings.iter().any(|w| w.contains("2 missing input samples were filled by linear interpolation")));
    // The setting goes through a results folder's job.json and its rules.
    let written = dir.path().join("as-run.json");
    vj.write_as_run(&written).unwrap();
    let (back, _) = job::read_as_run(&written).unwrap();
    assert_eq!(back.job.data.first().interpolate_inputs, Some(2));
    let edited =
        std::fs::read_to_string(&written).unwrap().replace("\"interpolate_inputs\": 2", "\"interpolate_inputs\": 5000");
    std::fs::write(&written, edited).unwrap();
    let e = job::read_as_run(&written).unwrap_err().to_string();
    assert!(e.contains("field 'data.interpolate_inputs': 5000 samples: at most 1000"), "{e}");
}

#[test]
fn markers_default_through_lists_and_to_the_validation_record() {
    let dir = tempfile::tempdir().unwrap();
    let (u, mut y) = record(300, 13);
    y[7] = NAN;
    write_csv(&dir.path().join("a.csv"), &u, &y, "-999");
    write_csv(&dir.path().join("b.csv"), &u, &y, "-999");
    let j = write_job(
        dir.path(),
        "m",
        serde_json::json!({"name": "m", "data": [{"path": "a.csv", "ts": 1, "missing": [-999]}, {"path": "b.csv"}],
            "validation": {"path": "b.csv", "y": "y"}, "grid": {"nb": [1, 1], "nf": [1, 1], "k": [1]}, "output": "out"}),
    );
    let vj = job::load(&j).unwrap();
    assert_eq!(vj.job.data.specs[1].missing, Some(vec![Marker::Number(-999.0)]));
    assert_eq!(vj.job.validation.as_ref().unwrap().first().missing, Some(vec![Marker::Number(-999.0)]));
    let (inputs, gaps) = job::load_inputs_gaps(&vj).unwrap();
    assert_eq!(inputs.est.missing, vec![7, 307]);
    assert_eq!(gaps.data.map(|g| (g.outputs_missing, g.segments)), Some((2, 2)));
    assert_eq!(gaps.validation.map(|g| g.outputs_missing), Some(1));
    // A complete job writes no gap field into its job.json.
    let plain = job::load(&write_job(
        dir.path(),
        "plain",
        serde_json::json!({"name": "p", "data": {"path": "a.csv", "ts": 1}, "grid": {"nb": [1, 1], "nf": [1, 1], "k": [1]},
            "output": "out"}),
    ))
    .unwrap();
    let text = serde_json::to_string(&plain.job).unwrap();
    assert!(!text.contains("missing") && !text.contains("interpolate"), "{text}");
}

#[test]
fn simulate_makes_records_with_gaps_from_the_seed() {
    let dir = tempfile::tempdir().unwrap();
    let sys = dir.path().join("sys.json");
    std::fs::write(&sys, r#"{"b": [0.5, 0.2], "f": [-0.6], "delay": 1}"#).unwrap();
    let make = |name: &str, seed: &str| {
        let out = dir.path().join(name);
        let args = [
            "simulate",
            "--system",
            sys.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--n",
            "2000",
            "--seed",
            seed,
            "--noise-std",
            "0.1",
            "--missing",
            "0.05",
            "--missing-burst",
            "20",
            "--missing-inputs",
            "0.01",
        ];
        let o = common::run_oesweep(dir.path(), &args, std::time::Duration::from_secs(60));
        assert_eq!(o.code, Some(0), "{}", o.stderr);
        out
    };
    let (a, b, c) = (make("a.csv", "4"), make("b.csv", "4"), make("c.csv", "5"));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&c).unwrap());
    let cols = oesweep::data::read_columns(&a, &["u", "y", "y0"]).unwrap();
    let out = cols[1].iter().filter(|v| v.is_nan()).count();
    let ins = cols[0].iter().filter(|v| v.is_nan()).count();
    assert!((100..120).contains(&out), "{out}");
    assert!((20..40).contains(&ins), "{ins}");
    assert!(cols[2].iter().all(|v| v.is_finite()));
    // Without gaps, the record is the one simulate always made.
    let plain = dir.path().join("plain.csv");
    let args = ["simulate", "--system", sys.to_str().unwrap(), "--out", plain.to_str().unwrap(), "--n", "300"];
    assert_eq!(common::run_oesweep(dir.path(), &args, std::time::Duration::from_secs(60)).code, Some(0));
    let opts = oesweep::simulate::SimOptions {
        n: 300,
        bits: 10,
        amplitude: 10.0,
        seed: 1,
        noise_std: 0.0,
        noise: oesweep::simulate::NoiseKind::Gaussian,
        outliers: Some(oesweep::simulate::Outliers { probability: 0.0, min: 5.0, max: 10.0 }),
    };
    let direct = dir.path().join("direct.csv");
    engine::simulate(&sys, &direct, &opts).unwrap();
    assert_eq!(std::fs::read(&plain).unwrap(), std::fs::read(&direct).unwrap());
}
