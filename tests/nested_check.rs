//! The nested check (METHOD.md 5.6) runs in two places: a whole run checks each cell as a task
//! of the sweep's graph, after its sub-models' checks at the same k; a merge of shards (whose plans each lack
//! sub-models) checks the rows in waves of nB + nF. On the demo job, where the check refits
//! cells, both give the same table bit for bit (every column but `seconds`), and so does a
//! whole run that resumes a shard's rows on another thread count: the checkpoint holds the
//! walks' rows, and the check of a cell reads only its row and its sub-models' final rows.
//! Workers the system refuses are an error, never a table without its check.

mod common;

use common::{demo_job, table_without_seconds as table};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("binary runs")
}

fn ok(o: Output) -> Output {
    let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert_eq!(o.status.code(), Some(0), "{text}");
    o
}

/// The demo job with its records by absolute path and its results in `dir/out`.
fn demo(dir: &Path, out: &str) -> PathBuf {
    let mut job = demo_job();
    job["output"] = serde_json::json!(dir.join(out));
    let p = dir.join(format!("{out}.json"));
    std::fs::write(&p, job.to_string()).unwrap();
    p
}

#[test]
fn the_graphs_check_a_merges_waves_and_a_resumed_run_give_the_same_table() {
    let dir = tempfile::tempdir().unwrap();
    let path = |p: &Path| p.to_str().unwrap().to_owned();

    let whole = demo(dir.path(), "whole");
    ok(oesweep(&["run", &path(&whole), "--threads", "2", "--quiet"]));
    let expected = table(&dir.path().join("whole"));
    let refits = expected.iter().filter(|r| r.fit.start == "nested").count();
    assert!(refits > 0, "the case no longer exercises the nested check");

    // Two shards and a merge: the merge's waves over all rows.
    let sharded = demo(dir.path(), "sharded");
    for shard in ["0/2", "1/2"] {
        ok(oesweep(&["run", &path(&sharded), "--shard", shard, "--threads", "1", "--quiet"]));
    }
    ok(oesweep(&["merge", &path(&dir.path().join("sharded"))]));
    assert!(table(&dir.path().join("sharded")) == expected, "the merge's table differs from the whole run's");

    // One shard, then a whole run on one thread that resumes its rows and computes the rest.
    let resumed = demo(dir.path(), "resumed");
    ok(oesweep(&["run", &path(&resumed), "--shard", "0/2", "--threads", "1", "--quiet"]));
    ok(oesweep(&["run", &path(&resumed), "--threads", "1", "--quiet"]));
    assert!(table(&dir.path().join("resumed")) == expected, "the resumed run's table differs from the whole run's");
}

/// `oesweep-testhooks` with every worker pool refused, as a system at its thread limit refuses
/// it (`OESWEEP_FAILPOINT=threads:refused`): exit 2, one line naming the work, nothing written.
fn refused(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep-testhooks"))
        .env("OESWEEP_FAILPOINT", "threads:refused")
        .args(args)
        .output()
        .expect("binary runs");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains("the system refused them"), "{err}");
    err
}

/// A merge that cannot start the nested check's workers writes nothing, not the walks' table
/// as if checked; a run and `fit --bootstrap` fail alike.
#[test]
fn refused_workers_are_an_error_not_a_table_without_its_check() {
    let dir = tempfile::tempdir().unwrap();
    let job = common::piezo_job(dir.path(), "out", "refused", 1000, ([1, 3], [1, 3]), (0.5, 2));
    let (job, out) = (job.to_str().unwrap(), dir.path().join("out"));
    for shard in ["0/2", "1/2"] {
        ok(oesweep(&["run", job, "--shard", shard, "--threads", "1", "--quiet"]));
    }
    let before = common::snapshot(&out, true);
    let err = refused(&["merge", out.to_str().unwrap()]);
    assert!(err.contains("cannot start a thread per core for the nested check"), "{err}");
    assert!(common::snapshot(&out, true) == before, "a refused merge changed the output folder");
    ok(oesweep(&["merge", out.to_str().unwrap()]));
    assert!(out.join("cells.parquet").is_file());

    let fresh = common::piezo_job(dir.path(), "fresh", "refused", 1000, ([1, 2], [1, 2]), (0.5, 2));
    let err = refused(&["run", fresh.to_str().unwrap(), "--threads", "2", "--quiet"]);
    assert!(err.contains("cannot start 2 threads for the sweep"), "{err}");
    assert!(!dir.path().join("fresh/cells.parquet").exists());
    let data = dir.path().join("est.csv");
    let fit = ["fit", "--data", data.to_str().unwrap(), "--nb", "2", "--nf", "2", "--k", "1", "--bootstrap", "40"];
    let err = refused(&fit);
    assert!(err.contains("cannot start a thread per core for the bootstrap"), "{err}");
}
