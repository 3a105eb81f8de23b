//! The picks of a two-input sweep (METHOD.md 7.2, 17.3, 19): the look beyond the grid's edge
//! grows the order of the input on the edge and finds the truth there; the job's bootstrap
//! gives each picked model's parameter intervals, of the spread its sandwich std predicts, and
//! each input's response intervals.

mod common;

use std::path::Path;
use std::time::Duration;

const LIMIT: Duration = Duration::from_secs(600);

/// Input 1 OE(2,2) d = 1, input 2 OE(1,1) d = 2.
const SYSTEM: &str = r#"{"inputs": [
  {"b": [0.5, 0.3], "f": [-1.2, 0.5], "delay": 1},
  {"b": [0.4], "f": [-0.8], "delay": 2}
]}"#;

fn run(dir: &Path, args: &[&str]) -> String {
    let o = common::run_oesweep(dir, args, LIMIT);
    assert_eq!(o.code, Some(0), "{args:?}: {}", o.stderr);
    o.stdout
}

/// A record of the system with output noise of std 0.1 (the PRBS and the random binary input
/// of level 1), and the selection of the job `grid` on it (`extra`: more of the job's fields).
fn selection(dir: &Path, grid: serde_json::Value, extra: serde_json::Value) -> serde_json::Value {
    std::fs::write(dir.join("sys.json"), SYSTEM).unwrap();
    run(
        dir,
        &[
            "simulate",
            "--system",
            "sys.json",
            "--out",
            "d.csv",
            "--n",
            "3000",
            "--amplitude",
            "1",
            "--noise-std",
            "0.1",
        ],
    );
    let mut job = serde_json::json!({
        "name": "picks", "data": {"path": "d.csv", "u": ["u1", "u2"], "ts": 1},
        "grid": grid, "delay": [1, 2], "output": "out"
    });
    job.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    std::fs::write(dir.join("job.json"), serde_json::to_string_pretty(&job).unwrap()).unwrap();
    run(dir, &["run", "job.json", "--quiet"]);
    serde_json::from_str(&std::fs::read_to_string(dir.join("out/selection.json")).unwrap()).unwrap()
}

#[test]
fn the_look_beyond_the_edge_grows_the_input_on_the_edge() {
    let dir = tempfile::tempdir().unwrap();
    // Input 1's nF stops at 1, below the truth's 2.
    let grid = serde_json::json!({"nb": [[1, 2], [1, 1]], "nf": [[0, 1], [1, 1]], "k": [1.0]});
    let sel = selection(dir.path(), grid, serde_json::json!({}));
    let rbic = &sel["picks"]["rbic"]["model"];
    assert_eq!((&rbic["nb_1"], &rbic["nf_1"]), (&serde_json::json!(2), &serde_json::json!(1)), "{rbic}");
    let warnings: Vec<&str> = sel["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap()).collect();
    let edge = warnings.iter().find(|w| w.contains("input 1's largest nF")).unwrap_or_else(|| panic!("{warnings:?}"));
    // The truth, one step beyond input 1's nF edge, has a lower RBIC: widen the grid.
    assert!(edge.contains("OE(2,2 d1; 1,1 d2) (-") && edge.contains("lower RBIC still"), "{edge}");
    assert!(edge.contains("widen the grid"), "{edge}");
    assert!(!edge.contains("were not fitted"), "{edge}");
}

#[test]
fn the_bootstrap_of_two_input_picks_matches_their_sandwich_std() {
    let dir = tempfile::tempdir().unwrap();
    let grid = serde_json::json!({"nb": [[1, 2], [1, 1]], "nf": [[1, 2], [1, 1]], "k": [1.0]});
    let extra = serde_json::json!({"uncertainty": {"method": "bootstrap", "replicates": 60}});
    let sel = selection(dir.path(), grid, extra);
    let warnings = sel["warnings"].to_string();
    assert!(!warnings.contains("not computed for several inputs"), "{warnings}");
    let boots = sel["bootstrap"].as_array().unwrap_or_else(|| panic!("no bootstrap: {sel}"));
    let truth = [0.5, 0.3, -1.2, 0.5, 0.4, -0.8];
    let mut checked = 0;
    for boot in boots {
        if boot["nb"] != serde_json::json!([2, 1]) || boot["nf"] != serde_json::json!([2, 1]) {
            continue;
        }
        assert_eq!(boot["delay"], serde_json::json!([1, 2]));
        let names: Vec<&str> = boot["parameters"].as_array().unwrap().iter().map(|n| n.as_str().unwrap()).collect();
        assert_eq!(&names[..6], ["u1.b1", "u1.b2", "u1.f1", "u1.f2", "u2.b1", "u2.f1"]);
        let intervals = boot["intervals"]["parameters"].as_array().unwrap();
        assert_eq!(intervals.len(), names.len());
        for (i, t) in truth.iter().enumerate() {
            let value = boot["values"][i].as_f64().unwrap();
            let sandwich = boot["sandwich_std"][i].as_f64().unwrap();
            let spread = intervals[i]["std"].as_f64().unwrap();
            assert!((value - t).abs() < 5.0 * sandwich, "{}: {value} against the truth {t} (std {sandwich})", names[i]);
            let ratio = spread / sandwich;
            assert!((0.5..2.0).contains(&ratio), "{}: bootstrap std {spread}, sandwich {sandwich}", names[i]);
            let (lo, hi) = (intervals[i]["lower"].as_f64().unwrap(), intervals[i]["upper"].as_f64().unwrap());
            assert!(lo < value && value < hi, "{}: {value} outside [{lo}, {hi}]", names[i]);
        }
        // One list of response intervals per input, each holding that input's true |G_i| at
        // the lowest frequency (near the static gains 2.67 and 2).
        let magnitude = boot["intervals"]["magnitude"].as_array().unwrap();
        let w = boot["intervals"]["frequencies"][0].as_f64().unwrap();
        assert_eq!(magnitude.len(), 2, "{}", boot["intervals"]);
        let paths: [(&[f64], &[f64], usize); 2] = [(&[0.5, 0.3], &[-1.2, 0.5], 1), (&[0.4], &[-0.8], 2)];
        for (list, (b, f, d)) in magnitude.iter().zip(paths) {
            let (re, im) = oesweep::oe::freq_response(b, f, d, w);
            let gain = re.hypot(im);
            let low = &list.as_array().unwrap()[0];
            let (lo, hi) = (low["lower"].as_f64().unwrap(), low["upper"].as_f64().unwrap());
            assert!(lo < gain * 1.01 && gain * 0.99 < hi, "|G| at {w}: [{lo}, {hi}], true {gain}");
        }
        checked += 1;
    }
    assert!(checked > 0, "the true structure is a watched pick: {}", sel["bootstrap"]);
}
