//! "The same table on any x86-64" as README.md promises it: the AVX2+FMA and the generic
//! kernels round differently, so a checkpoint records which computed its rows, and a merge or a
//! resume that would mix the two is refused with one line naming both; rows of one flavour
//! merge into that flavour's single-process table, bit for bit. The generic flavour is forced
//! on this CPU through the test hooks binary (`OESWEEP_FAILPOINT=kernels:generic`).

mod common;

use oesweep::export::parquet::read_cells;
use oesweep::kernels::{Flavour, flavour};
use oesweep::table::CellRow;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("binary runs")
}

/// `oesweep` on the generic kernels whatever the CPU.
fn generic(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep-testhooks"))
        .env("OESWEEP_FAILPOINT", "kernels:generic")
        .args(args)
        .output()
        .expect("binary runs")
}

fn text(o: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Simulated piezo data and a small job writing to `out`.
fn job(dir: &Path, out: &str) -> PathBuf {
    if !dir.join("est.csv").exists() {
        let noise = common::Noise { amplitude: 1.0, std: 0.05, spike_probability: 0.03, spike_range: "1,3" };
        common::simulate(&common::piezo_system(), &dir.join("est.csv"), 2000, 1, &noise);
    }
    let job = serde_json::json!({
        "name": "flavour",
        "data": {"path": "est.csv", "ts": 1e-4},
        "grid": {"nb": [2, 4], "nf": [2, 4], "k": {"from": 0.1, "to": 2.0, "count": 3, "spacing": "log"}},
        "output": out,
    });
    let p = dir.join(format!("{out}.json"));
    std::fs::write(&p, job.to_string()).unwrap();
    p
}

/// The table without the wall-clock column.
fn table(out: &Path) -> Vec<CellRow> {
    let mut rows = read_cells(&out.join("cells.parquet")).unwrap();
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

/// Exit 2 and one line on stderr naming both flavours, nothing merged.
fn refused_as_a_mix(o: &Output, out: &Path) {
    assert_eq!(o.status.code(), Some(2), "{}", text(o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{}", text(o));
    assert!(err.contains("generic kernels") && err.contains("avx2-fma kernels"), "{}", text(o));
    assert!(!out.join("cells.parquet").exists(), "a refused mix wrote a table");
}

#[test]
fn a_table_takes_rows_of_one_kernel_flavour() {
    if flavour() != Flavour::Avx2Fma {
        eprintln!("skipped: this CPU runs the generic kernels only, so there is no other flavour to mix");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (file, out) = (job(dir.path(), "out"), dir.path().join("out"));
    let file = file.to_str().unwrap();

    // Shard 0 on a "generic" node, shard 1 on this AVX2 one.
    let o = generic(&["run", file, "--shard", "0/2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = oesweep(&["run", file, "--shard", "1/2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    refused_as_a_mix(&oesweep(&["merge", out.to_str().unwrap()]), &out);
    // A whole run here would resume from the generic shard's rows: refused too.
    refused_as_a_mix(&oesweep(&["run", file, "--quiet"]), &out);

    // Shard 1 again on the generic kernels: the merge is the generic single-process table.
    let o = generic(&["run", file, "--shard", "1/2", "--quiet", "--force"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = generic(&["run", job(dir.path(), "generic").to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(table(&out) == table(&dir.path().join("generic")), "generic shards differ from the generic run");

    // The reason for all this: the flavours' tables differ (and the hook did force the other).
    let o = oesweep(&["run", job(dir.path(), "avx2").to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(table(&out) != table(&dir.path().join("avx2")), "the two flavours gave the same table");
}
