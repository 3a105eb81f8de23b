//! The DaISy industrial dryer (`jobs/dryer.json`, `jobs/data/dryer.csv`; README "Several
//! inputs", METHOD.md 19): the three-input sweep's lead pick validates on the record's second
//! half far better than the lead pick of the same sweep of any one input alone.

mod common;

use std::path::Path;
use std::time::Duration;

const LIMIT: Duration = Duration::from_secs(300);

/// `jobs/dryer.json` with `u` as given and its output in `dir`, run; the lead pick's `fit_val`.
fn lead_fit_val(dir: &Path, u: serde_json::Value) -> f64 {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut job: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("jobs/dryer.json")).unwrap()).unwrap();
    let name = match &u {
        serde_json::Value::String(s) => s.clone(),
        _ => "all".to_string(),
    };
    job["data"]["path"] = root.join("jobs/data/dryer.csv").to_str().unwrap().into();
    job["data"]["u"] = u;
    job["output"] = dir.join(format!("out-{name}")).to_str().unwrap().into();
    let path = dir.join(format!("{name}.json"));
    std::fs::write(&path, serde_json::to_string_pretty(&job).unwrap()).unwrap();
    let out = common::run_oesweep(dir, &["run".as_ref(), path.as_os_str(), "--quiet".as_ref()], LIMIT);
    assert_eq!(out.code, Some(0), "run {name}: {}", out.stderr);
    let sel: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join(format!("out-{name}/selection.json"))).unwrap())
            .unwrap();
    let rule = sel["rule"].as_str().unwrap();
    sel["picks"][rule]["model"]["fit_val"].as_f64().unwrap()
}

#[test]
fn the_three_input_pick_validates_better_than_the_best_single_input() {
    let dir = tempfile::tempdir().unwrap();
    let all = lead_fit_val(dir.path(), serde_json::json!(["fuel", "fan", "feed"]));
    let single: Vec<f64> = ["fuel", "fan", "feed"].iter().map(|u| lead_fit_val(dir.path(), (*u).into())).collect();
    let best = single.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    eprintln!(
        "fit_val: three inputs {all:.2} %, fuel {:.2} %, fan {:.2} %, feed {:.2} %",
        single[0], single[1], single[2]
    );
    // Measured at 3d22ed4: 44.66 % against the fan's -3.34 % (fuel -11.26 %, feed -42.24 %).
    assert!(all > 40.0, "three inputs validate at {all} %");
    assert!(all > best + 30.0, "three inputs {all} % against the best single input's {best} %");
}
