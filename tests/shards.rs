//! Sharded sweeps through the binary, without Slurm: N shard processes started side by side
//! into one output folder and then `oesweep merge` give exactly the table of a single-process
//! run (every column but `seconds`, bit for bit, and the same picks); a merge with a shard
//! missing names the missing cells and their shard and exits 1; `--partial` merges what there
//! is; a whole run finishes the rest from the shard folders. `oesweep slurm` is checked
//! against a stand-in `sbatch` on the PATH (the real cluster test is tests/slurm_cluster.sh).

mod common;

use oesweep::export::parquet::read_cells;
use oesweep::plan::Plan;
use oesweep::table::CellRow;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_oesweep"))
}

fn oesweep(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}

fn text(o: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Data from the bundled piezo model (noise and spikes, so the extra least-squares starts and
/// the continuation chains matter) and a job over 16 order pairs x 4 k in `dir`.
fn setup(dir: &Path, start: &str, delays: [usize; 2]) -> PathBuf {
    for (name, seed, spikes) in [("est.csv", 1, 0.03), ("val.csv", 2, 0.0)] {
        let noise = common::Noise { amplitude: 1.0, std: 0.05, spike_probability: spikes, spike_range: "1,3" };
        common::simulate(&common::piezo_system(), &dir.join(name), 3000, seed, &noise);
    }
    for (file, out) in [("ref.json", "ref"), ("job.json", "out")] {
        let job = serde_json::json!({
            "name": "shards",
            "data": {"path": "est.csv", "ts": 1e-4},
            "validation": {"path": "val.csv"},
            "grid": {"nb": [5, 8], "nf": [4, 7], "delay": delays, "k": {"from": 0.1, "to": 2.0, "count": 4, "spacing": "log"}},
            "band_hz": [0, 1500],
            "start": start,
            "output": out,
        });
        std::fs::write(dir.join(file), serde_json::to_string_pretty(&job).unwrap()).unwrap();
    }
    dir.join("job.json")
}

/// The table without the wall-clock column, checked to hold one row per key.
fn table(path: &Path) -> Vec<CellRow> {
    let mut rows = read_cells(path).unwrap();
    let keys: HashSet<_> = rows.iter().map(|r| r.key).collect();
    assert_eq!(keys.len(), rows.len(), "{}: a cell has two rows", path.display());
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

/// The single-process table of the job (output `ref`).
fn reference(dir: &Path) -> Vec<CellRow> {
    let o = oesweep(&["run", dir.join("ref.json").to_str().unwrap(), "--threads", "2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    table(&dir.join("ref/cells.parquet"))
}

/// Start the given shards of N at once (one thread each) and wait for all.
fn run_shards(job: &Path, shards: &[usize], n: usize) {
    let children: Vec<_> = shards
        .iter()
        .map(|i| {
            let children = bin()
                .args(["run", job.to_str().unwrap(), "--shard", &format!("{i}/{n}"), "--threads", "1", "--quiet"])
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .expect("binary starts");
            (i, children)
        })
        .collect();
    for (i, child) in children {
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(0), "shard {i}/{n}: {}", text(&o));
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(out.contains(&format!("shard {i}/{n}")) && out.contains("oesweep merge"), "{out}");
    }
}

fn file(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap()
}

fn shards_side_by_side(start: &str, delays: [usize; 2]) {
    let dir = tempfile::tempdir().unwrap();
    let job = setup(dir.path(), start, delays);
    let expected = reference(dir.path());
    assert_eq!(expected.len(), (16 + 64) * (delays[1] - delays[0] + 1));

    let out = dir.path().join("out");
    run_shards(&job, &[0, 1, 2], 3);
    assert!(!out.join("cells.parquet").exists(), "a shard does not merge");
    for i in 0..3 {
        let shard = out.join(format!("parts/shard-{i}-of-3"));
        assert!(shard.join("manifest.json").exists() && shard.join("job.json").exists(), "{}", shard.display());
    }
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(table(&out.join("cells.parquet")) == expected, "start = {start}: merged table differs from one process");
    // The same picks of every rule, criteria included (the table holds the criteria columns).
    assert_eq!(file(&out, "selection.json"), file(&dir.path().join("ref"), "selection.json"));
    assert!(file(&out, "selection.json").contains("\"rbic\": {"), "every rule's pick is compared");
    let ref_job = file(&dir.path().join("ref"), "job.json").replace("/ref\"", "/out\"");
    assert_eq!(file(&out, "job.json"), ref_job);
    assert!(!out.join("parts").exists(), "a complete merge deletes the checkpoint");

    // Merging again (say, a requeued merge job) leaves the results as they are.
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("already merged"), "{}", text(&o));
}

#[test]
fn three_shard_processes_and_a_merge_give_the_single_process_table() {
    shards_side_by_side("ls", [1, 1]);
}

#[test]
fn shards_keep_continuation_chains_and_extra_starts_exact() {
    shards_side_by_side("best", [1, 1]);
}

#[test]
fn shards_keep_the_k_chains_exact() {
    shards_side_by_side("chains", [1, 1]);
}

/// The delay as a grid dimension: pairs (nB, nF, d) are dealt to the shards like order pairs.
#[test]
fn shards_split_a_delay_grid() {
    shards_side_by_side("chains", [0, 2]);
}

#[test]
fn merge_names_missing_cells_and_partial_merges_what_there_is() {
    let dir = tempfile::tempdir().unwrap();
    let job = setup(dir.path(), "ls", [1, 1]);
    let expected = reference(dir.path());
    let out = dir.path().join("out");

    // `plan --shards` prints the layout the shards use.
    let o = oesweep(&["plan", job.to_str().unwrap(), "--shards", "3"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let vj = oesweep::job::load(&job).unwrap();
    let plan = Plan::from_job(&vj);
    let layout = oesweep::shard::layout(&plan, 3);
    let plan_out = String::from_utf8_lossy(&o.stdout);
    for (i, pairs) in layout.iter().enumerate() {
        let line = plan_out.lines().find(|l| l.trim_start().starts_with(&format!("{i}/3"))).expect("a line per shard");
        for &p in pairs {
            assert!(line.contains(&format!("({},{})", plan.pairs[p].one().nb, plan.pairs[p].one().nf)), "{line}");
        }
    }

    run_shards(&job, &[0, 2], 3);
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let cells = layout[1].len() * plan.ks.len();
    assert!(err.contains(&format!("{cells} of 64 cells and {} of 16", layout[1].len())), "{err}");
    for &p in &layout[1] {
        assert!(
            err.contains(&format!("OE({}, {}): ls, all 4 k", plan.pairs[p].one().nb, plan.pairs[p].one().nf)),
            "{err}"
        );
    }
    assert!(err.contains("shard 1 of 3"), "{err}");
    assert!(!out.join("cells.parquet").exists() && !out.join("selection.json").exists(), "nothing written");

    // --partial: what the two shards computed, the checkpoint kept.
    let o = oesweep(&["merge", out.to_str().unwrap(), "--partial"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let partial = table(&out.join("cells.parquet"));
    let kept: HashSet<(u32, u32)> =
        layout[1].iter().map(|&p| (plan.pairs[p].one().nb as u32, plan.pairs[p].one().nf as u32)).collect();
    let want: Vec<CellRow> = expected.iter().filter(|r| !kept.contains(&(r.key.nb, r.key.nf))).cloned().collect();
    assert!(partial == want, "the partial table holds exactly the rows of shards 0 and 2");
    assert!(out.join("parts/shard-0-of-3").exists(), "a partial merge keeps the checkpoint");

    // A whole run takes the shards' cells and computes only the rest.
    let o = oesweep(&["run", job.to_str().unwrap(), "--threads", "2"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let done = 64 - cells;
    assert!(err.contains(&format!("{done} of 64 cells")), "{}", text(&o));
    assert!(table(&out.join("cells.parquet")) == expected);
    assert!(!out.join("parts").exists());
}

#[test]
fn slurm_submits_the_array_then_a_merge_that_depends_on_it() {
    let dir = tempfile::tempdir().unwrap();
    let job = setup(dir.path(), "ls", [1, 1]);
    let (path, log) = common::fake_sbatch(dir.path());
    let o = bin()
        .args(["slurm", job.to_str().unwrap(), "--shards", "4", "--cpus-per-task", "2", "--sbatch-arg=--partition=x"])
        .env("PATH", path)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("sweep job 4101") && stdout.contains("merge job 4102"), "{stdout}");
    let calls = std::fs::read_to_string(&log).unwrap();
    let calls: Vec<&str> = calls.lines().collect();
    assert_eq!(calls.len(), 2, "{calls:?}");
    let out = dir.path().join("out");
    let canon_job = job.canonicalize().unwrap();
    assert!(calls[0].starts_with(&format!("OESWEEP={} ", env!("CARGO_BIN_EXE_oesweep"))), "{}", calls[0]);
    for want in ["--parsable", "--array=0-3", "--cpus-per-task=2", "--partition=x", "sweep.sbatch"] {
        assert!(calls[0].contains(want), "{want}: {}", calls[0]);
    }
    assert!(calls[0].ends_with(&format!("{} 4", canon_job.display())), "{}", calls[0]);
    assert!(calls[1].contains("--dependency=afterok:4101") && calls[1].contains("--partition=x"), "{}", calls[1]);
    assert!(calls[1].contains("merge.sbatch") && calls[1].ends_with(&out.display().to_string()), "{}", calls[1]);
    // The templates it submitted are kept next to the Slurm logs.
    let tmpl = |n: &str| std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/slurm").join(n));
    assert_eq!(std::fs::read_to_string(out.join("slurm/sweep.sbatch")).unwrap(), tmpl("sweep.sbatch").unwrap());
    assert_eq!(std::fs::read_to_string(out.join("slurm/merge.sbatch")).unwrap(), tmpl("merge.sbatch").unwrap());
    // A product is one array: no loop state, and no bound on rounds to take.
    assert!(!out.join("slurm/search.json").exists());
    let o = oesweep(&["slurm", job.to_str().unwrap(), "--shards", "4", "--max-rounds", "3", "--dry-run"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--max-rounds: the job runs the full product of its grid in one array"), "{}", text(&o));
}
