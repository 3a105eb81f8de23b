//! Interrupted sweeps through the binary: SIGKILL followed by resumes gives exactly the table of
//! an uninterrupted run (one row per cell, same numbers); SIGINT/SIGTERM stop cleanly with exit
//! 130 and a resumable folder; a checkpoint of a different job or of changed data is refused
//! (exit 2) unless --force; one run per output folder. Unix only: the tests send signals.
//!
//! Nothing here depends on timing. The states the tests assert on are reached through the
//! pause points of the `oesweep-testhooks` binary (src/failpoint.rs): a test waits until the
//! binary says it is paused (a marker file), then kills or signals it. Every kill lands at
//! such a point (after a chosen checkpoint part, between the result files and the deletion of
//! the checkpoint), never at a moment chosen by a clock.
#![cfg(unix)]

mod common;

use oesweep::checkpoint::BATCH_ROWS;
use oesweep::export::parquet::read_cells;
use oesweep::table::CellRow;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

const PAIRS: usize = 6 * 9;
/// k values per pair: a `chains` pair hands out its rows together once its walk is complete,
/// and with this many per pair the 500-row checkpoint batches split some pairs, so kills
/// leave pairs with some of their k values done.
const KS: usize = 30;
const CELLS: usize = PAIRS * KS;

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("binary runs")
}

/// `oesweep run JOB --threads 2 --quiet EXTRA...`, with `OESWEEP_FAILPOINT` when given (the
/// hooks live in the `oesweep-testhooks` build of the same command).
fn spawn_run(job: &Path, extra: &[&str], failpoint: Option<&str>) -> Child {
    let bin = if failpoint.is_some() { env!("CARGO_BIN_EXE_oesweep-testhooks") } else { env!("CARGO_BIN_EXE_oesweep") };
    let mut cmd = Command::new(bin);
    cmd.args(["run", job.to_str().unwrap(), "--threads", "2", "--quiet"]).args(extra);
    if let Some(f) = failpoint {
        cmd.env("OESWEEP_FAILPOINT", f);
    }
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().expect("binary starts")
}

/// Wait until the paused run has created `marker`. The limit only keeps a broken build from
/// hanging the suite; the state itself is reached whatever the machine's speed.
fn wait_for_pause(child: &mut Child, marker: &Path) {
    let t = Instant::now();
    while !marker.exists() {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                std::io::Read::read_to_string(&mut e, &mut err).unwrap();
            }
            panic!("the run ended ({status}) before its pause point\n{err}");
        }
        assert!(t.elapsed() < Duration::from_secs(600), "no pause after 600 s");
        std::thread::sleep(Duration::from_millis(2));
    }
}

fn text(o: &Output) -> String {
    format!("stdout:\n{}\nstderr:\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Wait for `child` at most `limit`; a hung run fails the test instead of hanging it.
fn wait_at_most(child: &mut Child, limit: Duration) -> ExitStatus {
    let t = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if t.elapsed() > limit {
            let _ = child.kill();
            panic!("oesweep run did not finish within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Data from the bundled 10th-order piezo model (5000 samples, noise and spikes) in `dir`.
fn make_data(dir: &Path) {
    for (name, seed, spikes) in [("est.csv", 1, 0.03), ("val.csv", 2, 0.0)] {
        let noise = common::Noise { amplitude: 1.0, std: 0.05, spike_probability: spikes, spike_range: "1,3" };
        common::simulate(&common::piezo_system(), &dir.join(name), 5000, seed, &noise);
    }
}

/// A job of PAIRS order pairs and `k_count` k values; `file` names the job file.
fn write_job(dir: &Path, file: &str, data: &str, start: &str, k_count: usize, output: &str) -> PathBuf {
    let job = serde_json::json!({
        "name": "resume",
        "data": {"path": data, "ts": 1e-4},
        "validation": {"path": "val.csv"},
        "grid": {"nb": [5, 10], "nf": [4, 12], "k": {"from": 0.1, "to": 2.0, "count": k_count, "spacing": "log"}},
        "band_hz": [0, 1500],
        "start": start,
        "output": output,
    });
    let p = dir.join(file);
    std::fs::write(&p, serde_json::to_string_pretty(&job).unwrap()).unwrap();
    p
}

fn key(r: &CellRow) -> (String, u32, u32, Option<u32>) {
    (r.key.kind.as_str().to_string(), r.key.nb, r.key.nf, r.key.k_index)
}

/// The table without the wall-clock column, checked to hold one row per key.
fn table(path: &Path) -> Vec<CellRow> {
    let mut rows = read_cells(path).unwrap();
    let keys: HashSet<_> = rows.iter().map(key).collect();
    assert_eq!(keys.len(), rows.len(), "{}: a cell has two rows", path.display());
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

fn part_files(parts: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = match std::fs::read_dir(parts) {
        Ok(entries) => {
            entries.map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|x| x == "parquet")).collect()
        }
        Err(_) => Vec::new(),
    };
    v.sort();
    v
}

/// Rows saved in the checkpoint; asserts no cell is in two parts.
fn saved_rows(parts: &Path) -> usize {
    let mut keys = HashSet::new();
    for p in part_files(parts) {
        for r in read_cells(&p).unwrap() {
            assert!(keys.insert(key(&r)), "{:?} saved twice (again in {})", key(&r), p.display());
        }
    }
    keys.len()
}

/// Huber rows in the checkpoint.
fn huber_rows(parts: &Path) -> usize {
    part_files(parts).iter().map(|p| read_cells(p).unwrap().iter().filter(|r| r.key.k_index.is_some()).count()).sum()
}

/// Order pairs with some but not all of their Huber cells in the checkpoint.
fn partial_pairs(parts: &Path) -> usize {
    let mut per_pair = std::collections::HashMap::new();
    for p in part_files(parts) {
        for r in read_cells(&p).unwrap().iter().filter(|r| r.key.k_index.is_some()) {
            *per_pair.entry((r.key.nb, r.key.nf)).or_insert(0) += 1;
        }
    }
    per_pair.values().filter(|&&n| n < KS).count()
}

/// Run a job to completion.
fn reference(job: &Path) {
    let o = oesweep(&["run", job.to_str().unwrap(), "--threads", "2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
}

/// Run (or resume) `job` until its checkpoint writer has made its first part durable, and
/// SIGKILL it there. Parts are written only when [`BATCH_ROWS`] rows wait (the time trigger is
/// set out of reach), and the writer pauses right after the part, so the checkpoint then holds
/// exactly one more batch than before, whatever the machine's speed.
fn kill_after_one_part(job: &Path, marker: &Path) {
    let failpoint = format!("pause_part:1:{}", marker.display());
    let mut child = spawn_run(job, &["--checkpoint-every", "1e6"], Some(&failpoint));
    wait_for_pause(&mut child, marker);
    child.kill().unwrap();
    wait_at_most(&mut child, Duration::from_secs(600));
    std::fs::remove_file(marker).unwrap();
}

fn kill_and_resume(start: &str) {
    let dir = tempfile::tempdir().unwrap();
    make_data(dir.path());
    let reference_job = write_job(dir.path(), "ref.json", "est.csv", start, KS, "ref");
    reference(&reference_job);
    let expected = table(&dir.path().join("ref/cells.parquet"));
    assert_eq!(expected.len(), PAIRS + CELLS);

    let job = write_job(dir.path(), "job.json", "est.csv", start, KS, "out");
    let out = dir.path().join("out");
    let parts = out.join("parts");
    let marker = dir.path().join("paused");

    // Killed right after the first part: the PAIRS least-squares rows (the first phase ends
    // before any Huber cell starts) and BATCH_ROWS - PAIRS = 446 Huber rows. That is not a
    // multiple of KS, so some pair has only some of its k values saved: the resume must
    // finish a pair whose chain was cut.
    kill_after_one_part(&job, &marker);
    assert_eq!(saved_rows(&parts), BATCH_ROWS);
    assert_eq!(huber_rows(&parts), BATCH_ROWS - PAIRS);
    assert!(!(BATCH_ROWS - PAIRS).is_multiple_of(KS) && partial_pairs(&parts) > 0);
    assert!(!out.join("cells.parquet").exists());
    // Resumed and killed the same way: one more batch, the first one untouched.
    kill_after_one_part(&job, &marker);
    assert_eq!(saved_rows(&parts), 2 * BATCH_ROWS);

    // And a third time: the checkpoint only grows and never holds a cell twice (`saved_rows`
    // checks); 174 rows are left.
    kill_after_one_part(&job, &marker);
    assert_eq!(saved_rows(&parts), 3 * BATCH_ROWS);
    const { assert!(3 * BATCH_ROWS < PAIRS + CELLS) };

    // Killed after the result files are written but before the checkpoint is deleted: the
    // results are complete, and a rerun resumes every saved cell and merges again.
    let failpoint = format!("pause_merge:{}", marker.display());
    let mut child = spawn_run(&job, &[], Some(&failpoint));
    wait_for_pause(&mut child, &marker);
    assert!(out.join("cells.parquet").exists() && parts.exists());
    child.kill().unwrap();
    wait_at_most(&mut child, Duration::from_secs(600));
    std::fs::remove_file(&marker).unwrap();
    assert!(table(&out.join("cells.parquet")) == expected, "start = {start}: the results before the kill");
    let mut child = spawn_run(&job, &[], None);
    wait_at_most(&mut child, Duration::from_secs(600));
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("resumed from the checkpoint"), "{}", text(&o));
    assert!(!parts.exists(), "the checkpoint is deleted after the merge");
    let got = table(&out.join("cells.parquet"));
    assert_eq!(got.len(), PAIRS + CELLS);
    assert!(got == expected, "start = {start}: the resumed table differs from the uninterrupted one");
    let sel = |d: &str| std::fs::read_to_string(dir.path().join(d).join("selection.json")).unwrap();
    assert_eq!(sel("out"), sel("ref"));
    assert!(sel("out").contains("\"rbic\": {"), "every rule's pick is compared");
}

#[test]
fn sigkill_then_resume_gives_the_uninterrupted_table() {
    kill_and_resume("ls");
}

#[test]
fn sigkill_then_resume_walks_the_k_chains_again_exactly() {
    kill_and_resume("chains");
}

#[test]
fn sigkill_then_resume_continues_neighbour_chains_exactly() {
    kill_and_resume("neighbour");
}

/// The first Huber cell of the plan (the first pair, the first k), where `interrupt` pauses.
const FIRST_CELL: &str = "5,4,0";

/// Start a run that pauses before the plan's first Huber cell with every worker held (the
/// least-squares phase is done and saved in the writer's buffer), send `signal` there, and
/// return the output. The pause ends on the signal after the run's stop flag is set, so the
/// paused cells finish and no other cell starts.
fn interrupt(job: &Path, signal: libc::c_int, extra: &[&str]) -> Output {
    let marker = job.parent().unwrap().join("paused");
    let failpoint = format!("pause_cell:{FIRST_CELL}:{}", marker.display());
    let mut child = spawn_run(job, extra, Some(&failpoint));
    wait_for_pause(&mut child, &marker);
    // SAFETY: plain kill(2) on the pid of our own child, which has not been reaped yet.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    wait_at_most(&mut child, Duration::from_secs(600));
    let _ = std::fs::remove_file(&marker);
    child.wait_with_output().unwrap()
}

/// Files of a folder with their sizes and modification times.
fn snapshot(dir: &Path) -> Vec<(PathBuf, u64, std::time::SystemTime)> {
    let mut v: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let m = e.as_ref().unwrap().metadata().unwrap();
            (e.unwrap().path(), m.len(), m.modified().unwrap())
        })
        .collect();
    v.sort();
    v
}

#[test]
fn sigint_stops_cleanly_and_another_job_is_refused_unless_forced() {
    let dir = tempfile::tempdir().unwrap();
    make_data(dir.path());
    let job = write_job(dir.path(), "job.json", "est.csv", "ls", KS, "out");
    let out = dir.path().join("out");
    let parts = out.join("parts");

    // SIGINT: running cells finish, a last part is written, exit 130 with how to resume.
    let o = interrupt(&job, libc::SIGINT, &[]);
    assert_eq!(o.status.code(), Some(130), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("interrupted") && err.contains(&format!("oesweep run {}", job.display())), "{err}");
    let saved = saved_rows(&parts);
    assert!(parts.join("manifest.json").exists() && saved > 0 && saved < PAIRS + CELLS, "{saved}");
    // Every cell it reports finished (the running ones included) is in the checkpoint.
    let finished: usize = err.split("interrupted: ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert_eq!(huber_rows(&parts), finished, "{err}");
    assert!(!out.join("cells.parquet").exists(), "an interrupted run merges nothing");

    // A different k list: refused with one line naming the field; the checkpoint is untouched.
    let before = snapshot(&parts);
    let other = write_job(dir.path(), "other.json", "est.csv", "ls", 11, "out");
    let o = oesweep(&["run", other.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("parts") && err.contains("'grid.k'") && err.contains("--force"), "{err}");
    assert_eq!(snapshot(&parts), before);

    // Changed data under the same job: refused, naming the file.
    let mut csv = std::fs::read_to_string(dir.path().join("est.csv")).unwrap();
    let last = csv.trim_end().rsplit_once(',').unwrap().0.len();
    csv.replace_range(last.., ",0.5\n");
    std::fs::write(dir.path().join("changed.csv"), &csv).unwrap();
    let changed = write_job(dir.path(), "changed.json", "changed.csv", "ls", KS, "out");
    let o = oesweep(&["run", changed.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("estimation data") && err.contains("changed.csv"), "{err}");
    assert_eq!(snapshot(&parts), before);

    // The same bytes under another path are the same data: resumes and completes.
    std::fs::copy(dir.path().join("est.csv"), dir.path().join("moved.csv")).unwrap();
    let moved = write_job(dir.path(), "moved.json", "moved.csv", "ls", KS, "out");
    let o = oesweep(&["run", moved.to_str().unwrap(), "--threads", "2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("resumed from the checkpoint"), "{}", text(&o));
    assert_eq!(table(&out.join("cells.parquet")).len(), PAIRS + CELLS);
    assert!(!parts.exists());

    // SIGTERM behaves like SIGINT; --force then discards that checkpoint for another job.
    let o = interrupt(&job, libc::SIGTERM, &[]);
    assert_eq!(o.status.code(), Some(130), "{}", text(&o));
    assert!(saved_rows(&parts) > 0);
    // A part damaged from outside: refused with one line naming it, not a panic.
    let first = part_files(&parts).remove(0);
    std::fs::write(&first, b"PAR1 not really").unwrap();
    let o = oesweep(&["run", job.to_str().unwrap(), "--quiet"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    let last = err.lines().last().unwrap();
    assert!(last.starts_with("error: ") && last.contains("part-000001.parquet") && last.contains("--force"), "{err}");
    let o = oesweep(&["run", other.to_str().unwrap(), "--threads", "2", "--quiet", "--force"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(!String::from_utf8_lossy(&o.stdout).contains("resumed"), "{}", text(&o));
    assert_eq!(table(&out.join("cells.parquet")).len(), PAIRS + PAIRS * 11);
    assert!(!parts.exists());
}

/// `oesweep ARGS` while another run holds the folder: exit 2, one line naming the folder, what
/// holds it and `holder` (a pid, or the shard with its pid).
fn refused(args: &[&str], folder: &Path, holder: &str) {
    let o = oesweep(args);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains(&folder.display().to_string()) && err.contains("in use by") && err.contains(holder), "{err}");
}

#[test]
fn one_run_per_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    make_data(dir.path());
    let job = write_job(dir.path(), "job.json", "est.csv", "ls", 5, "out");
    let out = dir.path().join("out");
    let marker = dir.path().join("paused");
    let failpoint = format!("pause_cell:{FIRST_CELL}:{}", marker.display());
    let j = job.to_str().unwrap();

    // A run paused mid-sweep holds the folder: a second run and a merge are refused, naming
    // its pid, and change nothing; released, the first run completes alone.
    let mut first = spawn_run(&job, &[], Some(&failpoint));
    wait_for_pause(&mut first, &marker);
    let pid = format!("pid {}", first.id());
    refused(&["run", j, "--quiet"], &out, &pid);
    refused(&["run", j, "--quiet", "--force"], &out, &pid);
    refused(&["merge", out.to_str().unwrap()], &out, &pid);
    refused(&["run", j, "--quiet", "--shard", "0/2"], &out, &pid);
    std::fs::remove_file(&marker).unwrap();
    wait_at_most(&mut first, Duration::from_secs(600));
    let o = first.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert_eq!(table(&out.join("cells.parquet")).len(), PAIRS + PAIRS * 5);

    // A run killed with SIGKILL leaves no lock: the next one runs (and resumes).
    let mut killed = spawn_run(&job, &["--force"], Some(&failpoint));
    wait_for_pause(&mut killed, &marker);
    killed.kill().unwrap();
    wait_at_most(&mut killed, Duration::from_secs(600));
    std::fs::remove_file(&marker).unwrap();
    let o = oesweep(&["run", j, "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert_eq!(table(&out.join("cells.parquet")).len(), PAIRS + PAIRS * 5);

    // Two runs started together into a fresh folder: whichever order they take the lock in,
    // each completes or is refused with the message, at least one completes, and the table
    // has one row per cell.
    let both = write_job(dir.path(), "both.json", "est.csv", "ls", 5, "both");
    let (a, b) = (spawn_run(&both, &[], None), spawn_run(&both, &[], None));
    let outputs = [a.wait_with_output().unwrap(), b.wait_with_output().unwrap()];
    for o in &outputs {
        match o.status.code() {
            Some(0) => {}
            Some(2) => {
                assert!(String::from_utf8_lossy(&o.stderr).contains("in use by another oesweep run"), "{}", text(o))
            }
            _ => panic!("{}", text(o)),
        }
    }
    assert!(outputs.iter().any(|o| o.status.code() == Some(0)));
    assert_eq!(table(&dir.path().join("both/cells.parquet")).len(), PAIRS + PAIRS * 5);
}

#[test]
fn shards_lock_their_own_share_and_keep_whole_runs_and_merges_out() {
    let dir = tempfile::tempdir().unwrap();
    make_data(dir.path());
    let job = write_job(dir.path(), "job.json", "est.csv", "chains", 5, "out");
    let out = dir.path().join("out");
    let marker = dir.path().join("paused");
    let j = job.to_str().unwrap();
    // The shard that holds the plan's first pair pauses there; call it shard 0/2 below.
    let plan = oesweep::plan::Plan::from_job(&oesweep::job::load(&job).unwrap());
    let (s0, s1) = if oesweep::shard::layout(&plan, 2)[0].contains(&0) { ("0/2", "1/2") } else { ("1/2", "0/2") };
    let failpoint = format!("pause_cell:{FIRST_CELL}:{}", marker.display());
    let mut shard0 = spawn_run(&job, &["--shard", s0], Some(&failpoint));
    wait_for_pause(&mut shard0, &marker);
    let pid = format!("shard {s0} (pid {})", shard0.id());
    refused(&["run", j, "--quiet", "--shard", s0], &out, &format!("another run of shard {s0} (pid {})", shard0.id()));
    refused(&["run", j, "--quiet"], &out, &pid);
    refused(&["merge", out.to_str().unwrap()], &out, &pid);
    // The other shard runs beside it.
    let o = oesweep(&["run", j, "--quiet", "--threads", "2", "--shard", s1]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    std::fs::remove_file(&marker).unwrap();
    wait_at_most(&mut shard0, Duration::from_secs(600));
    let o = shard0.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let o = oesweep(&["merge", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert_eq!(table(&out.join("cells.parquet")).len(), PAIRS + PAIRS * 5);
}
