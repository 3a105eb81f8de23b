//! The warnings that say when the answer is doubtful (METHOD.md 7.2), on cases made for them:
//! a true order outside the grid (the pick on the grid's edge, "widen the grid"), an integrating
//! plant (a low-order fit's pole that may be 1, and picks on the stability boundary), a stable
//! plant whose output drifts (the drift of the stable picks' residuals, no integrating plant);
//! none on a plant the grid contains, and from one record the lead rule `rbic` without a
//! "widen" warning.

mod common;

use common::*;
use std::path::Path;
use std::process::Command;

/// Write `u`, `y` as CSV and a job over nB, nF in 1..=`max` into `dir`; run `oesweep run`;
/// return its stderr and selection.json's warnings.
fn run(dir: &Path, u: &[f64], y: &[f64], max: usize) -> (String, Vec<String>) {
    let mut csv = String::from("u,y\n");
    for (a, b) in u.iter().zip(y) {
        csv.push_str(&format!("{a},{b}\n"));
    }
    std::fs::write(dir.join("data.csv"), csv).unwrap();
    let job = serde_json::json!({
        "name": "doubts",
        "data": { "path": "data.csv", "u": "u", "y": "y", "ts": 1.0 },
        "grid": { "nb": [1, max], "nf": [1, max], "k": [0.5, 1.5] },
        "output": "out"
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["run", dir.join("job.json").to_str().unwrap(), "--quiet"])
        .output()
        .expect("oesweep runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sel: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/selection.json")).unwrap()).unwrap();
    let warnings = sel["warnings"].as_array().unwrap().iter().map(|w| w.as_str().unwrap().to_string()).collect();
    (String::from_utf8_lossy(&o.stderr).into_owned(), warnings)
}

/// A 3rd-order OE system with noise of 2 % of the output's scale.
fn third_order(n: usize) -> (Vec<f64>, Vec<f64>) {
    let b = [1.0, 0.5, 0.3];
    let f = f_from_poles(&[(0.78, 0.69)], &[0.85]);
    let u = binary_input(n, 3, 1.0, 7);
    let mut rng = Lcg(11);
    let y = oesweep::oe::simulate_vec(&b, &f, 1, &u).iter().map(|v| v + 0.2 * rng.normal()).collect();
    (u, y)
}

#[test]
fn a_true_order_outside_the_grid_puts_the_pick_on_the_edge_and_says_so() {
    let (u, y) = third_order(2000);
    let dir = tempfile::tempdir().unwrap();
    let (stderr, warnings) = run(dir.path(), &u, &y, 2);
    let edge: Vec<&String> = warnings.iter().filter(|w| w.contains("widen the grid")).collect();
    assert!(!edge.is_empty(), "{warnings:?}");
    // The lead rule's pick is among them.
    assert!(edge.iter().any(|w| w.contains("paper_m2") && w.contains("the largest")), "{edge:?}");
    assert!(stderr.contains("widen the grid"), "{stderr}");
    // The grid that contains the plant: no edge, no integrator.
    let dir = tempfile::tempdir().unwrap();
    let (_, warnings) = run(dir.path(), &u, &y, 4);
    assert!(warnings.is_empty(), "{warnings:?}");
}

/// One record with spikes, no validation record, the grid containing the plant: the summary
/// leads with RBIC, which finds the orders; the paper's picks say their basis grows with the
/// orders; no warning tells the user to widen the grid.
#[test]
fn one_record_leads_with_rbic_and_does_not_ask_to_widen_a_grid_that_holds_the_plant() {
    let (b, f) = oe22();
    let n = 2000;
    let u = binary_input(n, 3, 1.0, 17);
    let mut rng = Lcg(23);
    let y0 = oesweep::oe::simulate_vec(&b, &f, 1, &u);
    let sd = 0.2 * (y0.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let y: Vec<f64> = y0
        .iter()
        .map(|v| {
            let spike = if rng.next() < 0.15 { (5.0 + 5.0 * rng.next()) * sd * rng.normal().signum() } else { 0.0 };
            v + sd * rng.normal() + spike
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let (_, warnings) = run(dir.path(), &u, &y, 4);
    assert!(!warnings.iter().any(|w| w.contains("widen the grid")), "{warnings:?}");
    let sel: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/selection.json")).unwrap()).unwrap();
    assert_eq!(sel["rule"], "rbic");
    assert!(sel["rule_why"].as_str().unwrap().contains("without a validation record"), "{}", sel["rule_why"]);
    let lead = &sel["picks"]["rbic"]["model"];
    assert_eq!((lead["nb"].as_u64(), lead["nf"].as_u64()), (Some(2), Some(2)), "{lead}");
    let why = sel["picks"]["paper_m2"]["why"].as_str().unwrap();
    assert!(why.contains("estimation fit, which grows with the orders"), "{why}");
    // The summary names the lead and why.
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["report", dir.path().join("out").to_str().unwrap()])
        .output()
        .expect("oesweep runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(dir.path().join("out/report.html")).unwrap();
    assert!(page.contains("<b>rbic</b> (lead)") && page.contains("Lead rule."), "the report names the lead");
}

#[test]
fn an_integrating_plant_is_named_by_its_low_order_fit_and_its_poles() {
    // y_t = y_{t-1} + 0.05 u_{t-1} + noise: a pole at 1.
    let n = 3000;
    let u = binary_input(n, 5, 1.0, 3);
    let mut rng = Lcg(5);
    let mut y = vec![0.0; n];
    for t in 1..n {
        y[t] = y[t - 1] + 0.05 * u[t - 1];
    }
    let y: Vec<f64> = y.iter().map(|v| v + 0.01 * rng.normal()).collect();
    let dir = tempfile::tempdir().unwrap();
    let (stderr, warnings) = run(dir.path(), &u, &y, 2);
    assert!(warnings.iter().any(|w| w.contains("has a pole at") && w.contains("integrating")), "{warnings:?}");
    assert!(warnings.iter().any(|w| w.contains("stability boundary")), "{warnings:?}");
    assert!(stderr.contains("integrating"), "{stderr}");
}

/// The heat exchanger (`common::drifting_exchanger`): the low-order IV fit finds a
/// pole that may be 1, every pick is stable; the run names the drift of the picks' residuals,
/// not an integrating plant.
#[test]
fn a_stable_plant_whose_output_drifts_is_warned_of_as_a_drift() {
    let (u, y) = drifting_exchanger(27);
    let dir = tempfile::tempdir().unwrap();
    let (stderr, warnings) = run(dir.path(), &u, &y, 2);
    let integrating = |w: &&String| w.contains("integrating (or unstable)") || w.contains("stability boundary");
    assert!(!warnings.iter().any(|w| integrating(&w)), "{warnings:?}");
    let drift: Vec<&String> = warnings.iter().filter(|w| w.starts_with("the residuals of OE(")).collect();
    assert_eq!(drift.len(), 1, "{warnings:?}");
    assert!(
        drift[0].contains("(picked by ") && drift[0].contains("rbic") && drift[0].contains(" drift (above 0.463"),
        "{}",
        drift[0]
    );
    assert!(
        drift[0].contains("a slow disturbance") && drift[0].contains("data.csv has a pole at 0.99"),
        "{}",
        drift[0]
    );
    assert!(stderr.contains("warning: the residuals of OE("), "{stderr}");
}
