//! Jobs, readers and the command line of several inputs (issue 46, landing 2): a job whose
//! `data.u` is a list of columns and whose grid gives one range per input validates into the
//! grids the planner will take and writes a job.json that reads back the same; the records are
//! read with the job's columns in the job's order (the DaISy dryer's layout); every bad input of
//! several inputs is one line and exit 2; a one-input job writes the job.json it always wrote;
//! and what is still one input's (the band fit) refuses several with one line.
//! The job-file cases with their data are in the bad-input corpus (`tests/bad_inputs/inputs_*`).

mod common;

use oesweep::data::{ColumnRef, Offset, Record};
use oesweep::job::{self, InputGrid};
use oesweep::oe::{Orders, Structure};
use std::path::Path;
use std::time::Duration;

const LIMIT: Duration = Duration::from_secs(120);

/// The dryer's layout: three inputs and the temperature, 300 rows, with a header.
fn dryer_csv(dir: &Path) -> std::path::PathBuf {
    let rows: Vec<String> = (0..300)
        .map(|t| {
            let t = t as f64;
            let (fuel, fan, feed) = ((0.13 * t).sin(), (0.41 * t).cos() + 2.0, ((0.07 * t).sin() * 3.0).round());
            format!("{fuel:.6},{fan:.6},{feed},{:.6}", 50.0 + fuel + 0.5 * fan - 0.2 * feed)
        })
        .collect();
    let path = dir.join("dryer.csv");
    std::fs::write(&path, format!("fuel,fan,feed,temp\n{}\n", rows.join("\n"))).unwrap();
    path
}

fn write_job(dir: &Path, job: &serde_json::Value) -> std::path::PathBuf {
    let path = dir.join("job.json");
    std::fs::write(&path, serde_json::to_string_pretty(job).unwrap()).unwrap();
    path
}

fn dryer_job() -> serde_json::Value {
    serde_json::json!({
        "name": "dryer",
        "data": {"path": "dryer.csv", "u": ["fuel", "fan", "feed"], "y": "temp", "ts": 10, "rows": [1, 150]},
        "validation": {"rows": [151, 300]},
        "delay": [1, 0, 2],
        "grid": {"nb": [[1, 2], [1, 1], [2, 3]], "nf": [1, 2], "k": [0.5, 1.0]},
        "output": "out"
    })
}

#[test]
fn a_job_of_three_inputs_validates_into_one_grid_per_input_and_reads_back_as_written() {
    let dir = tempfile::tempdir().unwrap();
    dryer_csv(dir.path());
    let vj = job::load(&write_job(dir.path(), &dryer_job())).unwrap();
    assert_eq!(vj.m, 3);
    let grid = |nb: &[usize], nf: &[usize], d: usize| InputGrid { nb: nb.to_vec(), nf: nf.to_vec(), delays: vec![d] };
    assert_eq!(vj.grids, vec![grid(&[1, 2], &[1, 2], 1), grid(&[1], &[1, 2], 0), grid(&[2, 3], &[1, 2], 2)]);
    // The product over the inputs: (2 x 2) (1 x 2) (2 x 2) structures, each with 2 values of k.
    assert_eq!(vj.n_pairs(), 32);
    assert_eq!(vj.n_cells(), 64);
    let o = |nb, nf, delay| Orders { nb, nf, delay };
    assert_eq!(vj.largest_structure(), Structure::new(&[o(2, 2, 1), o(1, 2, 0), o(3, 2, 2)]).unwrap());
    // The validation record takes the estimation record's inputs.
    let cols = |names: &[&str]| names.iter().map(|n| ColumnRef::name(n)).collect::<Vec<_>>();
    let v = vj.job.validation.as_ref().unwrap().first();
    assert_eq!(v.u_cols(), cols(&["fuel", "fan", "feed"]));
    // Normalised: the delays as the grid's ranges, in the form they were given (a list).
    let written = serde_json::to_value(&vj.job).unwrap();
    assert_eq!(written["data"]["u"], serde_json::json!(["fuel", "fan", "feed"]));
    assert_eq!(written["grid"]["delay"], serde_json::json!([[1, 1], [0, 0], [2, 2]]));
    assert_eq!(written["grid"]["nf"], serde_json::json!([1, 2]));
    assert_eq!(written["delay"], serde_json::Value::Null);
    // job.json of a results folder reads back as the same job, with the same grids.
    let as_run = dir.path().join("as-run.json");
    vj.write_as_run(&as_run).unwrap();
    let (back, _) = job::read_as_run(&as_run).unwrap();
    assert_eq!(serde_json::to_value(&back.job).unwrap(), written);
    assert_eq!((back.m, &back.grids), (3, &vj.grids));
}

#[test]
fn a_results_folders_job_json_of_several_inputs_is_checked_as_the_job_file() {
    let dir = tempfile::tempdir().unwrap();
    dryer_csv(dir.path());
    let vj = job::load(&write_job(dir.path(), &dryer_job())).unwrap();
    let as_run = dir.path().join("as-run.json");
    vj.write_as_run(&as_run).unwrap();
    let good: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&as_run).unwrap()).unwrap();
    let edited = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = good.clone();
        edit(&mut v);
        std::fs::write(&as_run, v.to_string()).unwrap();
        job::read_as_run(&as_run).map(|_| ()).unwrap_err().to_string()
    };
    let m = edited(&|v| v["grid"]["nb"] = serde_json::json!([[1, 2], [1, 1]]));
    assert!(m.contains("field 'grid.nb': has 2 ranges for 3 inputs"), "{m}");
    let m = edited(&|v| v["grid"]["delay"] = serde_json::json!([[1, 1], [2, 0], [0, 0]]));
    assert!(m.contains("field 'grid.delay[1]': [2, 0] is not a range"), "{m}");
    let m = edited(&|v| v["validation"]["u"] = serde_json::json!(["fuel", "fan"]));
    assert!(m.contains("field 'validation.u': 2 input columns where the estimation record has 3"), "{m}");
    let m = edited(&|v| v["data"]["u"][1] = serde_json::json!(true));
    assert!(m.contains("field 'data.u[1]': invalid type: boolean `true`, expected a column name"), "{m}");
    assert_eq!(m.lines().count(), 1);
}

#[test]
fn the_dryer_record_is_read_with_the_jobs_columns_in_the_jobs_order() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dryer_csv(dir.path());
    let file = oesweep::data::read_columns(&csv, &["fuel", "fan", "feed", "temp"]).unwrap();
    let mut job = dryer_job();
    job["data"]["u"] = serde_json::json!(["feed", "fuel", 2]);
    let vj = job::load(&write_job(dir.path(), &job)).unwrap();
    let (est, val) = job::read_records(&vj.job.data, vj.job.validation.as_ref()).unwrap();
    assert_eq!(est.u_names, vec!["feed", "fuel", "fan"]);
    assert_eq!((est.inputs(), est.len(), est.y_name.as_str()), (3, 150, "temp"));
    for (i, col) in [2, 0, 1].into_iter().enumerate() {
        assert_eq!(est.input(i), &file[col][..150], "input {i}");
    }
    assert_eq!(est.y, file[3][..150]);
    let val = val.unwrap();
    assert_eq!(val.input(2), &file[1][150..]);
    // As the run reads them: checked, one level per input taken out.
    job["offset"] = serde_json::json!("mean");
    let vj = job::load(&write_job(dir.path(), &job)).unwrap();
    let inputs = job::load_inputs(&vj).unwrap();
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    assert_eq!(inputs.levels.u0, vec![mean(&file[2][..150]), mean(&file[0][..150]), mean(&file[1][..150])]);
    assert!(inputs.est.input(1).iter().zip(&file[0]).all(|(a, b)| *a == b - inputs.levels.u0[1]));
    // The Python package's `read` of one record names its columns alike.
    let spec = &vj.job.data.first().clone();
    assert_eq!(job::read_record(spec).unwrap().u_names, vec!["feed", "fuel", "fan"]);
}

#[test]
fn arrays_of_several_inputs_must_be_as_long_as_the_output() {
    let y = vec![0.0, 1.0, 2.0, 3.0];
    let rec =
        Record::from_input_arrays("<arrays>", vec![vec![1.0, 2.0, 3.0, 5.0], vec![0.0, 1.0, 0.0, 1.0]], y.clone())
            .unwrap();
    assert_eq!((rec.inputs(), rec.input(1)), (2, &[0.0, 1.0, 0.0, 1.0][..]));
    assert_eq!(rec.u_names, vec!["u1", "u2"]);
    let e = Record::from_input_arrays("<arrays>", vec![vec![1.0; 4], vec![1.0; 3]], y.clone()).unwrap_err();
    assert!(e.is_bad_input());
    assert_eq!(e.to_string(), "<arrays>: u2 has 3 samples and y 4: they must be equal");
    let e = Record::from_input_arrays("<arrays>", vec![vec![1.0; 4], vec![1.0, f64::INFINITY, 0.0, 0.0]], y.clone())
        .unwrap_err();
    assert_eq!(e.to_string(), "<arrays>: sample 1 of u2 is inf, not a finite number (NaN marks a missing sample)");
    // One input as before.
    let e = Record::from_arrays("<arrays>", vec![1.0; 3], y).unwrap_err();
    assert_eq!(e.to_string(), "<arrays>: u has 3 samples and y 4: they must be equal");
    // Inputs of arrays are checked as a file's: a collinear pair is named.
    let n = 100;
    let a: Vec<f64> = (0..n).map(|t| (t as f64 * 0.3).sin()).collect();
    let b: Vec<f64> = a.iter().map(|v| 1.0 - 4.0 * v).collect();
    let y: Vec<f64> = (0..n).map(|t| (t as f64 * 0.11).cos()).collect();
    let rec = Record::from_input_arrays("<arrays>", vec![a, b], y).unwrap();
    let two = Structure::new(&[Orders { nb: 1, nf: 1, delay: 1 }; 2]).unwrap();
    let e = job::inputs_of_records(rec, None, Offset::Estimate, &two, &[1, 1]).err().unwrap().to_string();
    assert!(e.contains("input columns 'u1' and 'u2' are perfectly collinear"), "{e}");
}

/// The job.json that oesweep wrote for this job before several inputs (taken from the binary
/// of commit 8b28e50), `DIR` standing for the job's folder.
const ONE_INPUT_JOB_JSON: &str = r#"{
  "format_version": 1,
  "oesweep_version": "0.1.0",
  "name": "ref",
  "data": {
    "path": "DIR/data.csv",
    "u": "u",
    "y": 3,
    "ts": 0.001,
    "delimiter": null,
    "header": null,
    "rows": [
      1,
      70
    ]
  },
  "validation": {
    "path": "DIR/val.csv",
    "u": "u",
    "y": 3,
    "ts": 0.001,
    "delimiter": null,
    "header": "auto",
    "rows": null
  },
  "delay": null,
  "offset": "mean",
  "initial_state": "estimate",
  "spectrum": "robust",
  "grid": {
    "nb": [
      1,
      2
    ],
    "nf": [
      0,
      1
    ],
    "k": [
      0.5,
      1.0
    ],
    "delay": [
      1,
      1
    ]
  },
  "band_hz": null,
  "solver": {
    "max_iterations": 300,
    "ftol": 1e-10,
    "xtol": 1e-10,
    "gtol": 1e-9,
    "lambda0": 0.001,
    "warm_lambda0": 1e-8,
    "huber_hessian": "gauss_newton",
    "huber_tol": 1e-8,
    "huber_extra_starts": 2,
    "method": "lm",
    "explore_rows": 16384,
    "nested_starts": true
  },
  "start": "chains",
  "selection": {
    "min_tolerance": 0.001,
    "fit_tolerance": 0.05
  },
  "output": "DIR/out"
}"#;

#[test]
fn a_one_input_job_writes_the_job_json_it_always_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().canonicalize().unwrap();
    for f in ["data.csv", "val.csv"] {
        std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_inputs/_valid").join(f), root.join(f))
            .unwrap();
    }
    let job = serde_json::json!({
        "name": "ref", "data": {"path": "data.csv", "u": "u", "y": 3, "ts": 0.001, "rows": [1, 70]},
        "validation": {"path": "val.csv"}, "delay": 1, "offset": "mean",
        "grid": {"nb": [1, 2], "nf": [0, 1], "k": {"from": 0.5, "to": 1.0, "count": 2}}, "output": "out"
    });
    let vj = job::load(&write_job(&root, &job)).unwrap();
    assert_eq!((vj.m, vj.nb.clone(), vj.nf.clone(), vj.delays.clone()), (1, vec![1, 2], vec![0, 1], vec![1]));
    let out = root.join("as-run.json");
    vj.write_as_run(&out).unwrap();
    let expected = ONE_INPUT_JOB_JSON
        .replace("DIR", &root.display().to_string())
        .replace("\"0.1.0\"", &format!("\"{}\"", env!("CARGO_PKG_VERSION")));
    assert_eq!(std::fs::read_to_string(&out).unwrap().trim_end(), expected);
}

/// `oesweep ARGS` in `dir`: (exit code, stderr); a failure's stdout must be empty.
fn oesweep(dir: &Path, args: &[&str]) -> (Option<i32>, String) {
    let o = common::run_oesweep(dir, args, LIMIT);
    assert!(o.code == Some(0) || o.stdout.is_empty(), "{args:?}: {}", o.stdout);
    (o.code, o.stderr)
}

/// A record with two independent inputs `u`, `v`, a copy of `u` scaled and shifted (`w`), a
/// constant column `c` and the output.
fn inputs_csv(dir: &Path) {
    let rows: Vec<String> = (0..400)
        .map(|t| {
            let t = t as f64;
            let (u, v) = ((0.3 * t).sin() + (0.05 * t).cos(), (0.17 * t).cos() * (0.021 * t).sin());
            format!("{u:.9},{v:.9},{:.9},4,{:.9}", 2.0 - 3.0 * u, u + 0.5 * v + 0.01 * (1.3 * t).sin())
        })
        .collect();
    std::fs::write(dir.join("d.csv"), format!("u,v,w,c,y\n{}\n", rows.join("\n"))).unwrap();
}

#[test]
fn fit_reads_lists_of_inputs_and_orders_and_names_each_bad_one() {
    let dir = tempfile::tempdir().unwrap();
    inputs_csv(dir.path());
    let fit = |extra: &[&str]| {
        let mut args = vec!["fit", "--data", "d.csv", "--k", "1"];
        args.extend_from_slice(extra);
        oesweep(dir.path(), &args)
    };
    let cases: &[(&[&str], &str)] = &[
        (
            &["--u", "u,v", "--nb", "2,1,1", "--nf", "1"],
            "error: --nb has 3 values for 2 inputs: give one for every input",
        ),
        (&["--u", "u,v", "--nb", "2", "--nf", "1", "--delay", "1,0,0"], "error: --delay has 3 values for 2 inputs"),
        (&["--u", "u,v", "--nb", "2,0", "--nf", "1"], "error: --nb (input 2) must be at least 1, got 0"),
        (&["--u", "u,v,u", "--nb", "1", "--nf", "1"], "d.csv: input column 'u' is named twice"),
        (&["--u", "u,1", "--nb", "1", "--nf", "1"], "d.csv: input column 'u' is named twice (as 'u' and as 1)"),
        (&["--u", "u,y", "--nb", "1", "--nf", "1"], "d.csv: the input and the output column are both 'y'"),
        (&["--u", "u,c", "--nb", "1", "--nf", "1"], "d.csv: input column 'c' is constant (value 4)"),
        (&["--u", "u,v,w", "--nb", "1", "--nf", "1"], "d.csv: input columns 'u' and 'w' are perfectly collinear"),
    ];
    for (extra, want) in cases {
        let (code, err) = fit(extra);
        assert_eq!(code, Some(2), "{extra:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{extra:?}: {err}");
        assert!(err.contains(want), "{extra:?}: expected '{want}' in: {err}");
    }
    // Several inputs are fitted: the report holds one entry per input.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .current_dir(dir.path())
        .args(["fit", "--data", "d.csv", "--k", "1", "--u", "u,v", "--nb", "2,1", "--nf", "1", "--delay", "1,0"])
        .args(["--rows", "1:300", "--val-rows", "301:400", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["nb"], serde_json::json!([2, 1]), "{report}");
    assert_eq!(report["delay"], serde_json::json!([1, 0]));
    assert_eq!(
        report["b"].as_array().map(|b| b.iter().map(|x| x.as_array().unwrap().len()).collect::<Vec<_>>()),
        Some(vec![2, 1])
    );
    assert_eq!(
        report["ls"]["f"].as_array().map(Vec::len),
        Some(2),
        "one F list per input in the least-squares fit too"
    );
    assert_eq!(report["parameters"][0], "u1.b1");
    // One input keeps its meaning: a single value of each, the column as before.
    let (code, err) = fit(&["--u", "u", "--nb", "2", "--nf", "1", "--delay", "0"]);
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn a_job_of_several_inputs_runs_and_what_is_one_input_s_refuses_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().canonicalize().unwrap();
    inputs_csv(&root);
    let job = serde_json::json!({
        "name": "two", "data": {"path": "d.csv", "u": ["u", "v"], "ts": 1},
        "grid": {"nb": [[1, 2], [1, 1]], "nf": [1, 1], "k": [1.0]}, "delay": [1, 0], "output": "out"
    });
    let file = write_job(&root, &job);
    let path = file.to_str().unwrap();
    // The plan names each input's ranges and their product, and counts samples, not values.
    let plan = common::run_oesweep(&root, &["plan", path], LIMIT);
    assert_eq!(plan.code, Some(0), "{}", plan.stderr);
    assert!(plan.stdout.contains("(400 samples"), "{}", plan.stdout);
    assert!(
        plan.stdout.contains("u1: nB 1..2 x nF 1 x delay 1; u2: nB 1 x nF 1 x delay 0; their product: 2 structures"),
        "{}",
        plan.stdout
    );
    let (code, err) = oesweep(&root, &["run", path, "--quiet"]);
    assert_eq!(code, Some(0), "{err}");
    // The product of the grids: nB 1..2 of input 1 times one structure of input 2.
    let table = polars_rows(&root.join("out/cells.parquet"));
    assert_eq!(table, vec![(1, 1), (1, 1), (2, 1), (2, 1)], "(nb_1, nb_2) of the ls and huber rows");
    let selection: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("out/selection.json")).unwrap()).unwrap();
    assert_eq!(selection["input_levels"].as_array().map(Vec::len), Some(2), "one level per input");
    // M1's covariance over every input's parameters and the offset: nB_1 + nF_1 + nB_2 + nF_2 + 1.
    let m1 = &selection["m1"];
    let dim = m1["nb_1"].as_u64().unwrap() + 1 + 1 + 1 + 1;
    assert_eq!(m1["covariance"].as_array().map(|c| c.len() as u64), Some(dim * dim), "{m1}: d x d, row-major");
    // The report and the export take several inputs (tests/several_inputs_export.rs).
    for args in [vec!["report", "out"], vec!["export", "out", "--to", "json"]] {
        let (code, err) = oesweep(&root, &args);
        assert_eq!(code, Some(0), "{args:?}: {err}");
    }
    // A band fit runs: tests/several_inputs_band.rs.
}

/// (nb_1, nb_2) of every row of a two-input table, as polars reads the file.
fn polars_rows(path: &std::path::Path) -> Vec<(u32, u32)> {
    use polars::prelude::*;
    let df = ParquetReader::new(std::fs::File::open(path).unwrap()).finish().unwrap();
    let column =
        |name: &str| -> Vec<u32> { df.column(name).unwrap().u32().unwrap().iter().map(Option::unwrap).collect() };
    let mut rows: Vec<(u32, u32)> = column("nb_1").into_iter().zip(column("nb_2")).collect();
    rows.sort();
    rows
}
