//! The sweep engine end to end through the binary: job file -> cells.parquet, selection.json,
//! job.json; determinism across thread counts; picks on low-noise data.

mod common;

use oesweep::export::parquet::read_cells;
use oesweep::table::{CellRow, FitKind};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("binary runs")
}

/// Simulated OE(2,2) data (low noise, a few spikes) and a job over a small grid around it.
fn setup(dir: &Path, out: &str, start: &str) -> PathBuf {
    let (b, f) = common::oe22();
    std::fs::write(dir.join("sys.json"), serde_json::json!({"b": b, "f": f, "delay": 1}).to_string()).unwrap();
    for (name, seed) in [("est.csv", 1), ("val.csv", 2)] {
        if !dir.join(name).exists() {
            let noise = common::Noise { amplitude: 10.0, std: 0.01, spike_probability: 0.03, spike_range: "1,3" };
            common::simulate(&dir.join("sys.json"), &dir.join(name), 2000, seed, &noise);
        }
    }
    let job = serde_json::json!({
        "name": "small",
        "data": {"path": "est.csv", "ts": 1e-3},
        "validation": {"path": "val.csv"},
        "grid": {"nb": [1, 3], "nf": [1, 4], "k": [0.1, 0.5, 1.5]},
        "band_hz": [0, 200],
        "start": start,
        "output": out,
    });
    let p = dir.join(format!("{out}.json"));
    std::fs::write(&p, serde_json::to_string_pretty(&job).unwrap()).unwrap();
    p
}

fn run(job: &Path, threads: &str) -> Vec<CellRow> {
    let o = oesweep(&["run", job.to_str().unwrap(), "--threads", threads, "--quiet"]);
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    let out = job.parent().unwrap().join(job.file_stem().unwrap());
    read_cells(&out.join("cells.parquet")).unwrap()
}

/// Everything but the wall-clock column.
fn strip_seconds(mut rows: Vec<CellRow>) -> Vec<CellRow> {
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

#[test]
fn small_sweep_writes_one_row_per_cell_and_picks_true_orders() {
    let dir = tempfile::tempdir().unwrap();
    let job = setup(dir.path(), "out", "ls");
    let o = oesweep(&["plan", job.to_str().unwrap()]);
    let plan = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && plan.contains("36 Huber cells") && plan.contains("12 least-squares"), "{plan}");
    assert!(!dir.path().join("out").exists(), "plan must not write anything");

    let rows = run(&job, "2");
    let huber: Vec<&CellRow> = rows.iter().filter(|r| r.key.kind == FitKind::Huber).collect();
    assert_eq!(huber.len(), 3 * 4 * 3);
    assert_eq!(rows.iter().filter(|r| r.key.kind == FitKind::Ls).count(), 12);
    let mut keys: Vec<(u32, u32, u32)> = huber.iter().map(|r| (r.key.nb, r.key.nf, r.key.k_index.unwrap())).collect();
    keys.sort();
    keys.dedup();
    assert_eq!(keys.len(), 36, "one row per cell");
    for r in &huber {
        assert!(r.ok(), "{r:?}");
        assert!(
            r.fit.criterion.is_some() && r.fit.l1c.is_some() && r.fit.fit_val.is_some() && r.fit.fit_band.is_some()
        );
        assert_eq!(r.fit.b.len(), r.key.nb as usize);
        assert_eq!(r.fit.f.len(), r.key.nf as usize);
        assert!((r.fit.gamma.unwrap() - r.k.unwrap() * r.fit.sigma.unwrap()).abs() < 1e-12);
    }

    let out = dir.path().join("out");
    let sel: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("selection.json")).unwrap()).unwrap();
    for pick in ["m1", "m2"] {
        assert_eq!((sel[pick]["nb"].as_u64(), sel[pick]["nf"].as_u64()), (Some(2), Some(2)), "{pick}: {sel}");
        assert!(!sel[pick]["candidates"].as_array().unwrap().is_empty());
    }
    let job_as_run: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("job.json")).unwrap()).unwrap();
    assert_eq!(job_as_run["validation"]["y"], "y0");
    assert_eq!(job_as_run["grid"]["k"], serde_json::json!([0.1, 0.5, 1.5]));
}

#[test]
fn thread_count_does_not_change_the_table() {
    let dir = tempfile::tempdir().unwrap();
    for start in ["chains", "ls", "best"] {
        let job = setup(dir.path(), &format!("out_{start}"), start);
        let one = strip_seconds(run(&job, "1"));
        let two = strip_seconds(run(&job, "2"));
        assert_eq!(one, two, "start = {start}");
    }
}

/// The least-squares criterion of a larger model is never above its sub-models' (nested
/// starts, METHOD.md 5.2 step 2): on the bundled piezo data, OE(8..9, 7..8) with the paper's
/// model, where the independently fitted pairs break this twice.
#[test]
fn a_larger_model_never_fits_worse_in_least_squares() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data");
    let ls_criteria = |nested: bool| -> std::collections::HashMap<(u32, u32), f64> {
        let out = format!("nested-{nested}");
        let job = serde_json::json!({
            "name": "nested",
            "data": {"path": data.join("piezo_est.csv"), "ts": 1e-4},
            "validation": {"path": data.join("piezo_val.csv"), "y": "y0"},
            "offset": "none",
            "initial_state": "zero",
            "grid": {"nb": [8, 9], "nf": [7, 8], "k": [1.0]},
            "solver": {"nested_starts": nested},
            "output": out,
        });
        let p = dir.path().join(format!("{out}.json"));
        std::fs::write(&p, job.to_string()).unwrap();
        run(&p, "2")
            .into_iter()
            .filter(|r| r.key.kind == FitKind::Ls)
            .map(|r| ((r.key.nb, r.key.nf), r.fit.criterion.unwrap()))
            .collect()
    };
    let rises = |v: &std::collections::HashMap<(u32, u32), f64>| -> usize {
        let mut n = 0;
        for (&(nb, nf), &c) in v {
            for larger in [(nb + 1, nf), (nb, nf + 1)] {
                n += v.get(&larger).is_some_and(|&l| l > c * (1.0 + 1e-12)) as usize;
            }
        }
        n
    };
    let independent = ls_criteria(false);
    let nested = ls_criteria(true);
    assert_eq!(independent.len(), 4);
    assert!(rises(&independent) > 0, "the case no longer exercises the nested starts: {independent:?}");
    assert_eq!(rises(&nested), 0, "{nested:?}");
    for (pair, c) in &nested {
        assert!(*c <= independent[pair], "{pair:?}: {c} nested, {} independent", independent[pair]);
    }
}

/// No Huber cell is left above a sub-model's cell at the same k (the nested pass, METHOD.md
/// 5.6): on the demo job the pairs' own walks left 59 of 540 cells above a sub-model's W by
/// more than a relative 1e-6; the pass refits them from the sub-models' solutions.
#[test]
fn a_larger_model_is_never_left_above_its_sub_model_at_the_same_k() {
    let dir = tempfile::tempdir().unwrap();
    let mut job = common::demo_job();
    job["output"] = serde_json::json!("demo");
    let p = dir.path().join("demo.json");
    std::fs::write(&p, job.to_string()).unwrap();
    let rows: Vec<CellRow> = run(&p, "2").into_iter().filter(|r| r.key.kind == FitKind::Huber && r.ok()).collect();
    let w: std::collections::HashMap<_, f64> =
        rows.iter().map(|r| ((r.key.nb, r.key.nf, r.key.k_index), r.fit.criterion.unwrap())).collect();
    let above: Vec<_> = w
        .iter()
        .filter(|&(&(nb, nf, k), &c)| {
            [(nb - 1, nf, k), (nb, nf - 1, k)].iter().any(|s| w.get(s).is_some_and(|&sub| c > sub * (1.0 + 1e-6)))
        })
        .collect();
    assert!(above.is_empty(), "{} cells above a sub-model: {above:?}", above.len());
    let nested = rows.iter().filter(|r| r.fit.start == "nested").count();
    assert!(nested > 0, "the case no longer exercises the nested pass");
}

/// `run --profile FILE` prints the table and writes the JSON (every role with its fits and
/// iterations, every phase); a FILE in a folder that does not exist is refused before the run
/// (exit 2, nothing written).
#[test]
fn run_profile_writes_the_breakdown_or_refuses_a_missing_folder() {
    let dir = tempfile::tempdir().unwrap();
    let job = setup(dir.path(), "prof", "chains");
    let bad = dir.path().join("no/such/folder/p.json");
    let o = oesweep(&["run", job.to_str().unwrap(), "--quiet", "--profile", bad.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--profile") && err.contains("does not exist"), "{err}");
    assert!(!dir.path().join("prof").exists(), "nothing is written");

    let file = dir.path().join("profile.json");
    let o = oesweep(&["run", job.to_str().unwrap(), "--quiet", "--profile", file.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("solver work by role") && err.contains("time by phase"), "{err}");
    let p: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    let roles = p["roles"].as_array().unwrap();
    let count = |role: &str, key: &str| {
        roles.iter().find(|r| r["role"] == role).and_then(|r| r[key].as_u64()).unwrap_or_else(|| panic!("{role}"))
    };
    // 12 pairs x 3 k: every cell at least one chain fit, every pair a least-squares phase.
    assert!(count("chain", "fits") >= 36 && count("least_squares", "fits") >= 12, "{p}");
    assert!(count("chain", "iterations") > 0);
    let phases: Vec<&str> = p["phases"].as_array().unwrap().iter().map(|x| x["phase"].as_str().unwrap()).collect();
    for want in ["read", "spectrum", "least_squares_phase", "huber_phase", "evidence", "judge", "sweep", "write"] {
        assert!(phases.contains(&want), "{phases:?}");
    }
}
