//! The nested check (METHOD.md 5.6) runs in two places: a whole run checks each cell as a task
//! of the sweep's graph, after its sub-models' checks at the same k; a merge of shards (whose plans each lack
//! sub-models) checks the rows in waves of nB + nF. On the demo job, where the check refits
//! cells, both give the same table bit for bit (every column but `seconds`), and so does a
//! whole run that resumes a shard's rows on another thread count: the checkpoint holds the
//! walks' rows, and the check of a cell reads only its row and its sub-models' final rows.

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
