//! Interrupted sweeps through the binary: SIGKILL at random instants followed by resumes gives
//! exactly the table of an uninterrupted run (one row per cell, same numbers); SIGINT/SIGTERM
//! stop cleanly with exit 130 and a resumable folder; a checkpoint of a different job or of
//! changed data is refused (exit 2) unless --force. Unix only: the tests send signals.
#![cfg(unix)]

mod common;

use oesweep::export::parquet::read_cells;
use oesweep::table::CellRow;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The tests here time their interruptions against a measured run; running them one at a
/// time keeps those measurements meaningful on a small machine.
static SERIAL: Mutex<()> = Mutex::new(());

const PAIRS: usize = 6 * 9;
/// k values per pair: a `chains` pair hands out its rows together once its walk is complete,
/// and with this many per pair the 500-row checkpoint batches split some pairs, so kills
/// leave pairs with some of their k values done.
const KS: usize = 30;
const CELLS: usize = PAIRS * KS;

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("binary runs")
}

fn spawn_run(job: &Path, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["run", job.to_str().unwrap(), "--threads", "2", "--quiet", "--checkpoint-every", "0.2"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary starts")
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
    (r.method.as_str().to_string(), r.nb, r.nf, r.k_index)
}

/// The table without the wall-clock column, checked to hold one row per key.
fn table(path: &Path) -> Vec<CellRow> {
    let mut rows = read_cells(path).unwrap();
    let keys: HashSet<_> = rows.iter().map(key).collect();
    assert_eq!(keys.len(), rows.len(), "{}: a cell has two rows", path.display());
    for r in &mut rows {
        r.seconds = 0.0;
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

/// Huber rows in the checkpoint. Also read while a run is going, which may merge and delete
/// its parts at any moment: a part that vanished between listing and reading counts nothing.
fn huber_rows(parts: &Path) -> usize {
    part_files(parts)
        .iter()
        .filter_map(|p| read_cells(p).ok())
        .map(|rows| rows.iter().filter(|r| r.k_index.is_some()).count())
        .sum()
}

/// Order pairs with some but not all of their Huber cells in the checkpoint.
fn partial_pairs(parts: &Path) -> usize {
    let mut per_pair = std::collections::HashMap::new();
    for p in part_files(parts) {
        for r in read_cells(&p).unwrap().iter().filter(|r| r.k_index.is_some()) {
            *per_pair.entry((r.nb, r.nf)).or_insert(0) += 1;
        }
    }
    per_pair.values().filter(|&&n| n < KS).count()
}

/// Run a job to completion, returning the wall time.
fn reference(job: &Path) -> f64 {
    let t = Instant::now();
    let o = oesweep(&["run", job.to_str().unwrap(), "--threads", "2", "--quiet"]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    t.elapsed().as_secs_f64()
}

fn kill_and_resume(start: &str) {
    let _guard = serial();
    let dir = tempfile::tempdir().unwrap();
    make_data(dir.path());
    let reference_job = write_job(dir.path(), "ref.json", "est.csv", start, KS, "ref");
    let secs = reference(&reference_job);
    let expected = table(&dir.path().join("ref/cells.parquet"));
    assert_eq!(expected.len(), PAIRS + CELLS);

    let job = write_job(dir.path(), "job.json", "est.csv", start, KS, "out");
    let out = dir.path().join("out");
    let parts = out.join("parts");
    let mut rng = common::Lcg(0x5eed ^ start.len() as u64);
    let (mut kills, mut saved_before, mut partial_chains) = (0, 0, 0);
    let (mut completed, mut merged_then_killed) = (None, false);
    for round in 0..8 {
        let mut child = spawn_run(&job, &[]);
        // Even rounds: 5 .. 25 % of an uninterrupted run's time after the (re)start, so kills
        // land anywhere from start-up on. Odd rounds: 0 .. 10 % after this run saved its first
        // Huber row, so on a slow machine too, and however long the least-squares phase
        // takes, some kills land amid the Huber cells and every other round makes progress.
        let t = Instant::now();
        if round % 2 == 1 {
            let before = huber_rows(&parts);
            while huber_rows(&parts) == before && child.try_wait().unwrap().is_none() {
                assert!(t.elapsed() < Duration::from_secs(30), "no Huber row saved after 30 s");
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        let fraction = if round % 2 == 1 { 0.1 * rng.next() } else { 0.05 + 0.2 * rng.next() };
        std::thread::sleep(Duration::from_secs_f64(secs * fraction));
        let delay = t.elapsed().as_secs_f64();
        if child.try_wait().unwrap().is_some() {
            // Finished before the kill: this was the completing resume.
            completed = Some(child.wait_with_output().unwrap());
            break;
        }
        child.kill().unwrap();
        wait_at_most(&mut child, Duration::from_secs(10));
        kills += 1;
        if out.join("cells.parquet").exists() {
            // Killed in the merge, after cells.parquet was written (see below).
            eprintln!("{start}: killed after {delay:.2} s, after the merge");
            merged_then_killed = true;
            break;
        }
        let saved = saved_rows(&parts);
        partial_chains += partial_pairs(&parts);
        assert!(saved >= saved_before, "round {round}: the checkpoint lost rows ({saved_before} -> {saved})");
        eprintln!("{start}: killed after {delay:.2} s, {saved} of {} rows saved", PAIRS + CELLS);
        saved_before = saved;
    }
    assert!(kills >= 3, "only {kills} kills hit a running sweep");
    assert!(partial_chains > 0, "no kill left a pair with only some of its k values done");
    assert!(saved_before > 0 && saved_before < PAIRS + CELLS, "the resume must start from a partial checkpoint");

    // Killed after writing cells.parquet but before deleting the checkpoint: a rerun resumes
    // every cell and merges again.
    if !merged_then_killed || parts.exists() {
        let o = completed.unwrap_or_else(|| {
            let mut child = spawn_run(&job, &[]);
            wait_at_most(&mut child, Duration::from_secs(60));
            child.wait_with_output().unwrap()
        });
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        assert!(String::from_utf8_lossy(&o.stdout).contains("resumed from the checkpoint"), "{}", text(&o));
        assert!(!parts.exists(), "the checkpoint is deleted after the merge");
    }
    let got = table(&out.join("cells.parquet"));
    assert_eq!(got.len(), PAIRS + CELLS);
    assert!(got == expected, "start = {start}: the resumed table differs from the uninterrupted one");
    let sel = |d: &str| std::fs::read_to_string(dir.path().join(d).join("selection.json")).unwrap();
    assert_eq!(sel("out"), sel("ref"));
}

#[test]
fn sigkill_at_random_instants_then_resume_gives_the_uninterrupted_table() {
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

/// Start a run and send `signal` once the checkpoint holds Huber cells; returns the output.
fn interrupt(job: &Path, signal: libc::c_int, extra: &[&str]) -> Output {
    let parts = job.parent().unwrap().join("out/parts");
    let mut child = spawn_run(job, extra);
    let t = Instant::now();
    while huber_rows(&parts) == 0 {
        assert!(child.try_wait().unwrap().is_none(), "the run ended before its first checkpoint");
        assert!(t.elapsed() < Duration::from_secs(30), "no checkpoint part after 30 s");
        std::thread::sleep(Duration::from_millis(5));
    }
    // SAFETY: plain kill(2) on the pid of our own child, which has not been reaped yet.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
    wait_at_most(&mut child, Duration::from_secs(30));
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
    let _guard = serial();
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
