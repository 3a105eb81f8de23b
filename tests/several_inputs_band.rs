//! The band fit, the spectral estimate and example data of several inputs (METHOD.md 19), on
//! a two-input system of known responses: `oesweep simulate` of a two-input system file
//! writes `u1,u2,y,y0` whose fit recovers the system; `oesweep spectrum --u u1,u2` estimates
//! each input's response; `fit --band` and a job's `band_hz` give each input's band fit, near
//! 100 % for the true model, and their mean in `fit_band`.

mod common;

use oesweep::oe::freq_response;
use std::f64::consts::PI;
use std::path::Path;
use std::time::Duration;

const LIMIT: Duration = Duration::from_secs(300);

/// Input 1 OE(2,2) d = 1, input 2 OE(1,1) d = 2.
const SYSTEM: &str = r#"{"inputs": [
  {"b": [0.5, 0.3], "f": [-1.2, 0.5], "delay": 1},
  {"b": [0.4], "f": [-0.8], "delay": 2}
]}"#;

fn truth() -> [(Vec<f64>, Vec<f64>, usize); 2] {
    [(vec![0.5, 0.3], vec![-1.2, 0.5], 1), (vec![0.4], vec![-0.8], 2)]
}

fn run(dir: &Path, args: &[&str]) -> String {
    let o = common::run_oesweep(dir, args, LIMIT);
    assert_eq!(o.code, Some(0), "{args:?}: {}", o.stderr);
    o.stdout
}

/// A noise-free record of the two-input system (a 13-bit PRBS on input 1: its lines fall on
/// Welch's 1024-sample bins, METHOD.md 11).
fn simulate(dir: &Path) {
    std::fs::write(dir.join("sys.json"), SYSTEM).unwrap();
    run(dir, &["simulate", "--system", "sys.json", "--out", "d.csv", "--n", "16384", "--bits", "13"]);
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap_or(f64::NAN)).collect()
}

#[test]
fn simulate_writes_several_inputs_and_fitting_the_record_recovers_the_system() {
    let dir = tempfile::tempdir().unwrap();
    simulate(dir.path());
    let header = std::fs::read_to_string(dir.path().join("d.csv")).unwrap();
    assert!(header.starts_with("u1,u2,y,y0\n"), "{}", &header[..40]);
    let json = run(
        dir.path(),
        &[
            "fit", "--data", "d.csv", "--u", "u1,u2", "--nb", "2,1", "--nf", "2,1", "--delay", "1,2", "--k", "1",
            "--ts", "1", "--band", "0,0.25", "--json",
        ],
    );
    let report: serde_json::Value = serde_json::from_str(&json).unwrap();
    for (i, (b, f, _)) in truth().iter().enumerate() {
        let (got_b, got_f) = (floats(&report["b"][i]), floats(&report["f"][i]));
        for (g, t) in got_b.iter().zip(b).chain(got_f.iter().zip(f)) {
            assert!((g - t).abs() < 1e-6, "input {}: b {got_b:?}, f {got_f:?}", i + 1);
        }
    }
    let per_input = floats(&report["fit_band_inputs"]);
    assert_eq!(per_input.len(), 2, "{report}");
    for (i, v) in per_input.iter().enumerate() {
        assert!(*v > 98.0, "input {}: band fit of the true model {v}", i + 1);
    }
    let mean = report["fit_band"].as_f64().unwrap();
    assert!((mean - (per_input[0] + per_input[1]) / 2.0).abs() < 1e-9, "fit_band {mean} is the mean of {per_input:?}");
    // The summary prints each input's band fit.
    let text = run(
        dir.path(),
        &[
            "fit", "--data", "d.csv", "--u", "u1,u2", "--nb", "2,1", "--nf", "2,1", "--delay", "1,2", "--k", "1",
            "--ts", "1", "--band", "0,0.25",
        ],
    );
    assert!(text.contains("fit (band, input 2)"), "{text}");
}

#[test]
fn spectrum_of_two_inputs_is_each_input_s_response() {
    let dir = tempfile::tempdir().unwrap();
    simulate(dir.path());
    let json = run(dir.path(), &["spectrum", "--data", "d.csv", "--u", "u1,u2", "--ts", "1", "--json"]);
    let r: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(r["u"], serde_json::json!(["u1", "u2"]));
    let freq = floats(&r["freq_hz"]);
    assert_eq!(r["re"].as_array().unwrap().len(), 2, "one list per input");
    for (i, (b, f, d)) in truth().iter().enumerate() {
        let (re, im) = (floats(&r["re"][i]), floats(&r["im"][i]));
        let (lower, upper) = (floats(&r["mag_lower"][i]), floats(&r["mag_upper"][i]));
        let mut checked = 0;
        for k in 0..freq.len() {
            // The DC bin of mean-removed segments holds only their leakage.
            if freq[k] == 0.0 || freq[k] > 0.25 {
                continue;
            }
            let (gr, gi) = freq_response(b, f, *d, 2.0 * PI * freq[k]);
            let rel = (re[k] - gr).hypot(im[k] - gi) / gr.hypot(gi);
            assert!(rel < 0.05, "input {} at {} Hz: relative error {rel}", i + 1, freq[k]);
            assert!(lower[k] <= upper[k]);
            checked += 1;
        }
        assert!(checked > 200, "{checked} bins");
    }
    // The table names each input.
    let text = run(dir.path(), &["spectrum", "--data", "d.csv", "--u", "u1,u2", "--ts", "1"]);
    assert!(text.contains("input 1 (u1):") && text.contains("input 2 (u2):"), "{}", &text[..200]);
}

#[test]
fn a_job_with_a_band_gives_each_input_s_band_fit() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().canonicalize().unwrap();
    simulate(&root);
    let job = serde_json::json!({
        "name": "band", "data": {"path": "d.csv", "u": ["u1", "u2"], "ts": 1}, "band_hz": [0.0, 0.25],
        "grid": {"nb": [[1, 2], [1, 1]], "nf": [[2, 2], [1, 1]], "k": [1.0]}, "delay": [1, 2], "output": "out"
    });
    std::fs::write(root.join("job.json"), serde_json::to_string_pretty(&job).unwrap()).unwrap();
    run(&root, &["run", "job.json", "--quiet"]);
    let rows = oesweep::export::parquet::read_cells(&root.join("out/cells.parquet")).unwrap();
    let truth = rows
        .iter()
        .find(|r| r.is_huber() && r.key.structure().inputs()[0].nb == 2)
        .expect("the true structure's Huber row");
    let per_input = truth.fit.fit_band_inputs.clone().expect("each input's band fit");
    assert!(per_input.iter().all(|v| *v > 98.0), "{per_input:?}");
    assert_eq!(truth.fit.fit_band, Some((per_input[0] + per_input[1]) / 2.0));
    // The file's columns, as polars reads them.
    use polars::prelude::*;
    let df = ParquetReader::new(std::fs::File::open(root.join("out/cells.parquet")).unwrap()).finish().unwrap();
    let names: Vec<String> = df.get_column_names().iter().map(|s| s.to_string()).collect();
    let at = names.iter().position(|n| n == "fit_band").unwrap();
    assert_eq!(&names[at..at + 3], ["fit_band", "fit_band_1", "fit_band_2"]);
    // The smaller model of input 1 fits its response worse, and input 2's as well as the truth.
    let smaller = rows.iter().find(|r| r.is_huber() && r.key.structure().inputs()[0].nb == 1).unwrap();
    let small = smaller.fit.fit_band_inputs.clone().unwrap();
    assert!(small[0] < per_input[0] - 1.0, "{small:?} against {per_input:?}");
    let selection = std::fs::read_to_string(root.join("out/selection.json")).unwrap();
    assert!(selection.contains("\"fit_band_2\""), "the picks carry each input's band fit");
}
