//! The whole operations through the library ([`oesweep::engine`]), without the binary: a run
//! that resumes from a partial checkpoint, and the merge of shards, each giving the table of an
//! uninterrupted run bit for bit (but `seconds`).

mod common;

use oesweep::engine::{self, MergeEnd, RunEnd, RunOptions};
use oesweep::shard::Shard;
use oesweep::table::CellRow;
use std::cell::Cell;
use std::path::{Path, PathBuf};

const PAIRS: usize = 3 * 3;
const KS: usize = 4;

/// Simulated piezo data (noise and spikes) and a job over a small grid writing to `out`.
fn job(dir: &Path, out: &str) -> PathBuf {
    common::piezo_job(dir, out, "engine", 3000, ([5, 7], [4, 6]), (0.1, KS))
}

fn table(out: &Path) -> Vec<CellRow> {
    common::table_without_seconds(out)
}

fn shard(index: usize, count: usize) -> RunOptions {
    RunOptions { threads: 2, shard: Some(Shard { index, count }), ..Default::default() }
}

fn whole() -> RunOptions {
    RunOptions { threads: 2, ..Default::default() }
}

/// The uninterrupted run's table.
fn reference(dir: &Path) -> Vec<CellRow> {
    let o = engine::run(&job(dir, "ref"), &whole(), &|_| {}).unwrap();
    assert!(matches!(o.end, RunEnd::Merged { .. }) && o.exit_code() == 0, "{o:?}");
    assert_eq!((o.computed, o.resumed), (PAIRS * KS, 0));
    table(&dir.join("ref"))
}

#[test]
fn a_run_resumes_from_a_partial_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let expected = reference(dir.path());
    let job = job(dir.path(), "out");
    // Half the pairs done: the checkpoint a shard leaves, which a whole run resumes from.
    let o = engine::run(&job, &shard(0, 2), &|_| {}).unwrap();
    assert!(matches!(o.end, RunEnd::ShardSaved), "{o:?}");
    let saved = o.cells;
    assert!(saved > 0 && saved < PAIRS * KS);

    let heard = Cell::new(None);
    let o = engine::run(&job, &whole(), &|r| heard.set(Some((r.cells, r.ls, r.plan_cells)))).unwrap();
    assert_eq!(heard.get(), Some((saved, saved / KS, PAIRS * KS)));
    assert!(matches!(o.end, RunEnd::Merged { .. }), "{o:?}");
    assert_eq!((o.resumed, o.computed), (saved, PAIRS * KS - saved));
    assert!(!dir.path().join("out/parts").exists(), "the checkpoint is deleted after the merge");
    assert!(table(&dir.path().join("out")) == expected, "the resumed table differs from the uninterrupted one");
}

#[test]
fn shards_merge_into_the_uninterrupted_table() {
    let dir = tempfile::tempdir().unwrap();
    let expected = reference(dir.path());
    let job = job(dir.path(), "out");
    let out = dir.path().join("out");
    for i in [0, 1] {
        assert!(matches!(engine::run(&job, &shard(i, 3), &|_| {}).unwrap().end, RunEnd::ShardSaved));
    }
    // One shard missing: nothing written, and the merge names the shard to run.
    let m = engine::merge(&out, false, false).unwrap();
    assert!(matches!(m.end, MergeEnd::Incomplete) && m.exit_code() == 1, "{m:?}");
    assert_eq!(m.owners, Some((3, vec![2])));
    assert!(m.missing.cells > 0 && !out.join("cells.parquet").exists());
    // --partial writes what there is and keeps the checkpoint.
    let m = engine::merge(&out, true, false).unwrap();
    assert!(matches!(m.end, MergeEnd::Merged { .. }), "{m:?}");
    assert_eq!(m.huber, PAIRS * KS - m.missing.cells);
    assert!(out.join("parts").exists());

    assert!(matches!(engine::run(&job, &shard(2, 3), &|_| {}).unwrap().end, RunEnd::ShardSaved));
    let m = engine::merge(&out, false, false).unwrap();
    assert!(matches!(m.end, MergeEnd::Merged { .. }) && m.exit_code() == 0, "{m:?}");
    assert!(m.missing.is_empty() && !out.join("parts").exists());
    assert!(table(&out) == expected, "the merged table differs from the uninterrupted one");
    assert_eq!(
        std::fs::read_to_string(out.join("selection.json")).unwrap(),
        std::fs::read_to_string(dir.path().join("ref/selection.json")).unwrap()
    );
    // A merge job that runs twice succeeds twice.
    assert!(matches!(engine::merge(&out, false, false).unwrap().end, MergeEnd::AlreadyMerged));
}

/// A watched run (the Python package's): the caller's stop switch instead of signal handlers,
/// and the progress counts. Stopped before the first cell, it saves nothing and says so; the
/// same call then resumes to the uninterrupted table, counting every cell.
#[test]
fn a_watched_run_stops_on_the_callers_switch_and_counts_its_cells() {
    use std::sync::atomic::Ordering;
    let dir = tempfile::tempdir().unwrap();
    let expected = reference(dir.path());
    let job = job(dir.path(), "out");
    let watch = engine::Watch::default();
    watch.stop.store(true, Ordering::Relaxed);
    let opts = RunOptions { watch: Some(watch.clone()), ..whole() };
    let o = engine::run(&job, &opts, &|_| {}).unwrap();
    assert!(matches!(o.end, RunEnd::Interrupted) && o.exit_code() == 130, "{o:?}");
    assert_eq!(
        (o.finished, watch.done.load(Ordering::Relaxed), watch.total.load(Ordering::Relaxed)),
        (0, 0, PAIRS * KS)
    );
    assert!(!dir.path().join("out/cells.parquet").exists());

    let watch = engine::Watch::default();
    let o = engine::run(&job, &RunOptions { watch: Some(watch.clone()), ..whole() }, &|_| {}).unwrap();
    assert!(matches!(o.end, RunEnd::Merged { .. }), "{o:?}");
    assert_eq!(watch.done.load(Ordering::Relaxed), PAIRS * KS);
    assert!(table(&dir.path().join("out")) == expected, "the watched table differs from the uninterrupted one");
}

/// A caller told of each finished cell (the Python package's progress callback) that stops the
/// run on the first message: the worker cannot run ahead of it, so the run stops within the
/// first pair's cells and one more, never at its end, and the same call resumes to the
/// uninterrupted table.
#[test]
fn a_caller_told_of_each_cell_stops_the_run_within_the_cells_it_was_told_of() {
    use std::sync::atomic::Ordering;
    let dir = tempfile::tempdir().unwrap();
    let expected = reference(dir.path());
    let job = job(dir.path(), "out");
    // Capacity 0: each message waits until the caller takes it.
    let (tx, rx) = std::sync::mpsc::sync_channel(0);
    let watch = engine::Watch { finished: Some(tx), ..Default::default() };
    let stop = watch.stop.clone();
    let opts = RunOptions { threads: 1, watch: Some(watch), ..whole() };
    let o = std::thread::scope(|s| {
        // The thread owns the options (and so the sender), which go when the run returns.
        let job = job.clone();
        let run = s.spawn(move || engine::run(&job, &opts, &|_| {}).unwrap());
        rx.recv().expect("a first finished cell");
        stop.store(true, Ordering::Relaxed);
        // The cells in flight, until the channel closes.
        assert!(rx.iter().count() <= KS);
        run.join().unwrap()
    });
    assert!(matches!(o.end, RunEnd::Interrupted), "{o:?}");
    assert!(o.finished >= 1 && o.finished <= KS + 1, "{} cells finished after the stop", o.finished);
    let o = engine::run(&job, &whole(), &|_| {}).unwrap();
    assert_eq!((o.resumed + o.computed, o.finished), (PAIRS * KS, PAIRS * KS));
    assert!(table(&dir.path().join("out")) == expected, "the resumed table differs from the uninterrupted one");
}

/// `--profile`: every minimisation is counted by its role, the counts do not depend on the
/// thread count (each pair is one sequential task), they hold at least the iterations the table
/// reports (the winners'), and an unprofiled run carries no profile.
#[test]
fn a_profiled_run_counts_every_fit_by_role() {
    let dir = tempfile::tempdir().unwrap();
    let job = job(dir.path(), "prof");
    let plain = engine::run(&job, &RunOptions { force: true, ..whole() }, &|_| {}).unwrap();
    assert!(plain.profile.is_none());
    let profiled = |threads| {
        let opts = RunOptions { threads, force: true, profile: true, ..Default::default() };
        engine::run(&job, &opts, &|_| {}).unwrap().profile.expect("asked for")
    };
    let (one, two) = (profiled(1), profiled(2));
    let counts = |p: &oesweep::profile::ProfileReport| {
        p.roles.iter().map(|r| (r.role, r.fits, r.iterations)).collect::<Vec<_>>()
    };
    assert_eq!(counts(&one), counts(&two));
    let rows = table(&dir.path().join("prof"));
    let reported: u64 = rows.iter().map(|r| u64::from(r.fit.iterations.unwrap_or(0))).sum();
    assert!(two.iterations() >= reported, "{} < {reported}", two.iterations());
    let role = |name: &str| two.roles.iter().find(|r| r.role == name).unwrap().clone();
    // Every Huber cell is at least one chain fit; every pair at least one least-squares fit
    // and one top-cell fit from theta_LS.
    assert!(role("chain").fits >= (PAIRS * KS) as u64);
    assert!(role("least_squares").fits >= PAIRS as u64);
    assert!(role("top").fits >= PAIRS as u64);
    // Every phase is reported; only the whole sweep (hundreds of fits) is asserted to have
    // taken any time, which holds on the coarsest clock.
    for phase in ["read", "spectrum", "least_squares_phase", "huber_phase", "evidence", "judge", "sweep", "write"] {
        assert!(two.phases.iter().any(|p| p.phase == phase && p.seconds >= 0.0), "{phase}: {two:?}");
    }
    assert!(two.seconds(oesweep::profile::Phase::Sweep) > 0.0, "{two:?}");

    // The tasks the pool ran: the same list whatever the thread count, apart from the times;
    // per pair its own least-squares minima, its least-squares finish and its Huber walk, per
    // cell its nested check (METHOD.md 5.6), each task after tasks listed in it; the serial parts
    // in run order (the nested check is no serial part of a whole run).
    let (s1, s2) = (&one.schedule, &two.schedule);
    let untimed = |s: &oesweep::profile::Schedule| {
        s.tasks.iter().map(|t| oesweep::profile::TaskTime { seconds: 0.0, ..t.clone() }).collect::<Vec<_>>()
    };
    assert_eq!(untimed(s1), untimed(s2));
    assert_eq!(s2.tasks.len(), 3 * PAIRS + PAIRS * KS);
    for kind in ["least_squares_own", "least_squares", "chains"] {
        assert_eq!(s2.tasks.iter().filter(|t| t.kind == kind).count(), PAIRS, "{kind}");
    }
    assert_eq!(s2.tasks.iter().filter(|t| t.kind == "nested" && t.k_index.is_some()).count(), PAIRS * KS);
    for t in &s2.tasks {
        assert!(t.after.iter().all(|&j| j < s2.tasks.len() && j != t.id), "{t:?}");
        assert!(t.seconds >= 0.0);
    }
    let (w1, w2) = (s1.workers.unwrap(), s2.workers.unwrap());
    assert_eq!((w1.threads, w1.live, w2.threads, w2.live), (1, 1, 2, 2));
    let parts: Vec<&str> = s2.serial.iter().map(|p| p.part).collect();
    assert_eq!(parts, ["read", "setup", "sweep_serial", "write"]);
}

/// With `band_hz` the spectral estimate is a task of the sweep, not a serial part: one task of
/// kind `spectrum` that every least-squares finish (the first fits judged) comes after and
/// nothing else waits for; and the band fits it gave are those of the robust estimate of the
/// record made before the run, whatever the thread count.
#[test]
fn the_spectral_estimate_is_a_task_of_the_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let path = job(dir.path(), "band");
    let mut doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    doc["band_hz"] = serde_json::json!([0, 1500]);
    std::fs::write(&path, doc.to_string()).unwrap();
    let run = |threads| {
        let opts = RunOptions { threads, force: true, profile: true, ..Default::default() };
        let p = engine::run(&path, &opts, &|_| {}).unwrap().profile.expect("asked for");
        (p, table(&dir.path().join("band")))
    };
    let ((one, rows1), (two, rows2)) = (run(1), run(2));
    assert!(rows1 == rows2, "the table depends on the thread count");
    for p in [&one, &two] {
        let s = &p.schedule;
        let spectrum: Vec<_> = s.tasks.iter().filter(|t| t.kind == "spectrum").collect();
        assert_eq!(spectrum.len(), 1);
        let id = spectrum[0].id;
        assert!(spectrum[0].after.is_empty());
        for t in &s.tasks {
            assert_eq!(t.after.contains(&id), t.kind == "least_squares", "{t:?}");
        }
        assert!(!s.serial.iter().any(|p| p.part == "spectrum"), "{:?}", s.serial);
    }
    // The robust estimate of the record, made here up front, gives every row's band fit.
    let prepared = engine::prepare(&path).unwrap();
    let est = &prepared.inputs.est;
    let ests = oesweep::spectral::estimate_inputs(
        &est.u,
        1,
        &est.y,
        &est.seams,
        &est.missing,
        1e-4,
        oesweep::spectral::SpectrumMethod::Robust,
    )
    .unwrap();
    let bins = ests[0].band(0.0, 1500.0);
    assert_eq!(bins, prepared.spectral.as_ref().unwrap().bins);
    assert!(ests[0].replaced > 0, "the record's spikes are cleaned");
    for r in &rows2 {
        let delay = r.key.structure().inputs()[0].delay;
        let expected =
            oesweep::spectral::band_fit(&ests[0], &bins, &r.fit.b, &r.fit.f, delay).filter(|v| v.is_finite());
        assert_eq!(r.fit.fit_band.map(f64::to_bits), expected.map(f64::to_bits), "{:?}", r.key);
    }
}
