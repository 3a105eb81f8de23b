//! One pathological cell must not take the sweep down (issue 5): a cell that panics becomes a
//! row with `status = "failed"` and a reason, the other cells complete, everything is
//! written, and the process exits 1.
//!
//! The panic is injected with the `OESWEEP_FAILPOINT` hook (`panic:NB,NF,K_INDEX`), which
//! makes exactly that Huber cell panic inside the worker, as a bug in the numerics would. The
//! hook lives only in the `oesweep-testhooks` binary, which the test suite builds
//! (src/failpoint.rs). The `oesweep` binary the same `cargo test` builds ignores it (checked
//! here), and so does a user's build (`tests/release_binary.sh`).

mod common;

use oesweep::export::parquet::read_cells;

use std::path::Path;
use std::process::Command;

/// An OE(2,2) record and a 2 x 2 x 2 job over it (`job.json`, output `out`) in `d`.
fn small_job(d: &Path) {
    let (b, f) = common::oe22();
    std::fs::write(d.join("sys.json"), serde_json::json!({"b": b, "f": f, "delay": 1}).to_string()).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["simulate", "--system", "sys.json", "--out", "est.csv", "--n", "1500", "--noise-std", "0.05"])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(o.status.success());
    let job = serde_json::json!({
        "name": "fault", "data": {"path": "est.csv", "ts": 1e-3},
        "grid": {"nb": [1, 2], "nf": [1, 2], "k": [0.1, 1.0]}, "output": "out"
    });
    std::fs::write(d.join("job.json"), job.to_string()).unwrap();
}

#[test]
fn a_panicking_cell_becomes_a_failed_row_and_the_sweep_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    small_job(d);
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep-testhooks"))
        .args(["run", "job.json", "--quiet"])
        .env("OESWEEP_FAILPOINT", "panic:2,2,1")
        .current_dir(d)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = read_cells(&d.join("out/cells.parquet")).unwrap();
    let huber: Vec<_> = rows.iter().filter(|r| r.is_huber()).collect();
    assert_eq!(huber.len(), 8);
    let failed: Vec<_> = huber.iter().filter(|r| !r.ok()).collect();
    assert_eq!(failed.len(), 1);
    let bad = failed[0];
    assert_eq!((bad.key.nb, bad.key.nf, bad.key.k_index), (2, 2, Some(1)));
    assert!(bad.reason.as_deref().unwrap_or("").contains("panicked"), "{:?}", bad.reason);
    assert!(bad.fit.criterion.is_none());
    assert!(huber.iter().filter(|r| r.ok()).all(|r| r.fit.criterion.is_some()));
    assert!(d.join("out/selection.json").exists());
    let summary = String::from_utf8_lossy(&o.stdout);
    assert!(summary.contains("1 failed"), "{summary}");
}

/// After `cargo test` (which builds the library with the `failpoints` feature), the `oesweep`
/// binary in the target folder is still a user's binary: the variable does nothing.
#[test]
fn the_oesweep_binary_ignores_the_failpoint_variable() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    small_job(d);
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["run", "job.json", "--quiet"])
        .env("OESWEEP_FAILPOINT", "panic:2,2,1")
        .current_dir(d)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("(0 failed)"));
    let rows = read_cells(&d.join("out/cells.parquet")).unwrap();
    assert!(rows.iter().all(|r| r.ok()), "no failed row");
}
