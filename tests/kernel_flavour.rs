//! "The same table on any x86-64" as README.md promises it: the AVX2+FMA and the generic
//! kernels round differently, so a checkpoint records which computed its rows, and a merge or a
//! resume that would mix the two is refused with one line naming both; rows of one flavour
//! merge into that flavour's single-process table, bit for bit. The generic flavour is forced
//! on this CPU through the test hooks binary (`OESWEEP_FAILPOINT=kernels:generic`); a CPU
//! without AVX2 and FMA cannot run the other flavour, and the test fails there under `CI=true`.

mod common;

use oesweep::kernels::{Flavour, flavour};
use std::path::Path;
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
        return common::cannot_run("this CPU runs the generic kernels only, so there is no other flavour to mix");
    }
    let dir = tempfile::tempdir().unwrap();
    let (file, out) =
        (common::piezo_job(dir.path(), "out", "flavour", 2000, ([2, 4], [2, 4]), (0.1, 3)), dir.path().join("out"));
    let file = file.to_str().unwrap();

    // Shard 0 on a "generic" node, shard 1 on this AVX2 one.
    let o = generic(&["run", file, "--shard", "0/2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = oesweep(&["run", file, "--shard", "1/2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    // Each with advice that command can follow: merge has no --force, run has.
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    refused_as_a_mix(&o, &out);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("run that folder's cells again") && !err.contains("rerun with --force"), "{err}");
    // A whole run here would resume from the generic shard's rows: refused too.
    let o = oesweep(&["run", file, "--quiet"]);
    refused_as_a_mix(&o, &out);
    assert!(String::from_utf8_lossy(&o.stderr).contains("rerun with --force"), "{}", text(&o));

    // Shard 1 again on the generic kernels: the merge is the generic single-process table.
    let o = generic(&["run", file, "--shard", "1/2", "--quiet", "--force"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = generic(&[
        "run",
        common::piezo_job(dir.path(), "generic", "flavour", 2000, ([2, 4], [2, 4]), (0.1, 3)).to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(
        common::table_without_seconds(&out) == common::table_without_seconds(&dir.path().join("generic")),
        "generic shards differ from the generic run"
    );

    // The reason for all this: the flavours' tables differ (and the hook did force the other).
    let o = oesweep(&[
        "run",
        common::piezo_job(dir.path(), "avx2", "flavour", 2000, ([2, 4], [2, 4]), (0.1, 3)).to_str().unwrap(),
        "--quiet",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(
        common::table_without_seconds(&out) != common::table_without_seconds(&dir.path().join("avx2")),
        "the two flavours gave the same table"
    );
}

/// A checkpoint written before manifests recorded the kernels (no `kernels` field) is refused
/// by a resume and by a merge with one line that says what to do, not serde's "missing field".
#[test]
fn a_checkpoint_without_its_kernels_says_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let (file, out) =
        (common::piezo_job(dir.path(), "out", "old", 1000, ([1, 2], [1, 2]), (0.5, 2)), dir.path().join("out"));
    let file = file.to_str().unwrap();
    let o = oesweep(&["run", file, "--shard", "0/2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let mut manifests = Vec::new();
    let mut stack = vec![out.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().unwrap() == "manifest.json" {
                manifests.push(p);
            }
        }
    }
    assert_eq!(manifests.len(), 1, "{manifests:?}");
    let mut m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&manifests[0]).unwrap()).unwrap();
    m.as_object_mut().unwrap().remove("kernels").expect("a manifest records its kernels");
    std::fs::write(&manifests[0], m.to_string()).unwrap();

    for (args, advice) in [
        (vec!["merge", out.to_str().unwrap()], "merge with the build that wrote it, or run the job again with --force"),
        (
            vec!["run", file, "--quiet"],
            "start again with --force (deletes the checkpoint) or resume with the build that wrote it",
        ),
    ] {
        let o = oesweep(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(err.lines().count(), 1, "{}", text(&o));
        assert!(
            err.contains("manifest.json") && err.contains("did not record which kernels computed its rows"),
            "{err}"
        );
        assert!(err.contains(advice) && !err.contains("missing field"), "{err}");
    }
    assert!(!out.join("cells.parquet").exists());
}
