//! The coordinate search of several inputs (METHOD.md 20, `src/search.rs`): on a three-input
//! record it reaches the full product's lead pick (the true orders) with a fraction of its
//! fits; a search stopped after any of its rows and resumed gives the table of a run that was
//! never stopped, on another thread count; sharded round by round (every shard, then the merge,
//! until the merge finds the search finished) it gives the whole run's table bit for bit at two
//! shard counts; a merge tells the round that waits with none of its cells (exit 3) from a round
//! with cells missing (exit 1); `oesweep slurm` submits it round by round against a stand-in
//! `sbatch`, each `--next-round` (what a merge job runs on exit 3) submitting the next round's
//! array and merge until the search is finished, and stops without progress or at its bound.

mod common;

use common::*;
use oesweep::engine::{self, MergeEnd, Prepared, RunEnd, RunOptions};
use oesweep::oe::{self, Orders, Structure};
use oesweep::progress::Progress;
use oesweep::search::{self, Search};
use oesweep::shard::Shard;
use oesweep::sweep::{self, Control};
use oesweep::table::CellRow;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

/// Per input (b, f, delay).
fn system() -> Vec<(Vec<f64>, Vec<f64>, usize)> {
    vec![(vec![1.0, 0.5], vec![-1.5, 0.7], 1), (vec![0.8], vec![-0.9], 2), (vec![0.6, 0.5], vec![-0.5], 0)]
}

/// A CSV of the three inputs and their summed responses with low noise and a few spikes.
fn write_record(path: &Path, n: usize, seed: u64) {
    let us: Vec<Vec<f64>> = (0..3).map(|i| binary_input(n, 4 + 3 * i, 1.0, seed * 10 + i as u64)).collect();
    let mut y = vec![0.0; n];
    for ((b, f, d), u) in system().iter().zip(&us) {
        for (t, v) in oe::simulate_vec(b, f, *d, u).into_iter().enumerate() {
            y[t] += v;
        }
    }
    let mut rng = Lcg(seed + 100);
    let lines: Vec<String> = (0..n)
        .map(|t| {
            let e = 0.01 * rng.normal() + if t % 97 == 13 { 1.0 } else { 0.0 };
            format!("{},{},{},{}", us[0][t], us[1][t], us[2][t], y[t] + e)
        })
        .collect();
    std::fs::write(path, format!("u1,u2,u3,y\n{}\n", lines.join("\n"))).unwrap();
}

/// nB, nF in 1..2 per input at the true delays (a product of 64 structures), two k.
fn job(dir: &Path, search: &str) -> PathBuf {
    write_record(&dir.join("est.csv"), 1500, 1);
    write_record(&dir.join("val.csv"), 1500, 2);
    let job = serde_json::json!({
        "name": "search",
        "data": {"path": "est.csv", "u": ["u1", "u2", "u3"], "y": "y", "ts": 1},
        "validation": {"path": "val.csv"},
        "delay": [1, 2, 0],
        "grid": {"nb": [1, 2], "nf": [1, 2], "k": [0.5, 1.5], "search": search},
        "offset": "none",
        "output": "out"
    });
    let path = dir.join("job.json");
    std::fs::write(&path, serde_json::to_string_pretty(&job).unwrap()).unwrap();
    path
}

fn truth() -> Structure {
    let o: Vec<Orders> = system().iter().map(|(b, f, d)| Orders { nb: b.len(), nf: f.len(), delay: *d }).collect();
    Structure::new(&o).unwrap()
}

/// The search's rows (wall times zeroed) and the rows it reported as they finished.
fn search_rows(p: &Prepared, threads: usize, done: Vec<CellRow>) -> (Vec<CellRow>, Vec<CellRow>, search::Rounds) {
    let Search::Coordinate(c) = &p.search else { panic!("a coordinate search") };
    let reported = Mutex::new(Vec::new());
    let on_row = |r: &CellRow| reported.lock().unwrap().push(r.clone());
    let control = Control { done, on_row: &on_row, ..Control::none() };
    let lead = |rows: &[CellRow]| engine::lead_structure(&p.job, rows);
    let guide = search::Guide { lead: &lead, grow: &|_| (), step: search::Step::Whole };
    let (out, rounds) = search::coordinate(c, &p.plan, &p.context(), threads, &Progress::new(0, true), control, guide)
        .expect("the search runs");
    assert!(!out.interrupted);
    (zero_seconds(out.rows), reported.into_inner().unwrap(), rounds)
}

fn zero_seconds(mut rows: Vec<CellRow>) -> Vec<CellRow> {
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

#[test]
fn the_search_reaches_the_products_lead_with_a_fraction_of_its_fits() {
    let dir = tempfile::tempdir().unwrap();
    let p = engine::prepare(&job(dir.path(), "coordinate")).unwrap();
    let (rows, _, rounds) = search_rows(&p, 2, Vec::new());
    let full = engine::prepare(&job(dir.path(), "product")).unwrap();
    assert_eq!(full.search, Search::Product);
    let product = sweep::run(&full.plan, &full.context(), 2, &Progress::new(0, true), Control::none()).unwrap();
    let lead = engine::lead_structure(&p.job, &product.rows).expect("the product has a lead pick");
    assert_eq!(lead, truth(), "the product's lead pick");
    assert_eq!(engine::lead_structure(&p.job, &rows), Some(lead), "the search's lead pick: rounds {:?}", rounds);
    // Its last round went through the lead, and each round swept one input's 4 orders.
    assert_eq!(rounds.rounds.last().unwrap().2, lead);
    let structures = rows.iter().filter(|r| !r.is_huber()).count();
    assert_eq!(structures, rounds.structures);
    assert!(
        structures * 2 <= full.plan.pairs.len(),
        "{structures} structures of the product's {}",
        full.plan.pairs.len()
    );
    assert_eq!(rows.len(), structures * 3, "one least-squares and two Huber rows per structure");
}

#[test]
fn a_search_stopped_after_any_of_its_rows_resumes_to_the_same_table() {
    let dir = tempfile::tempdir().unwrap();
    let p = engine::prepare(&job(dir.path(), "coordinate")).unwrap();
    let (whole, reported, _) = search_rows(&p, 1, Vec::new());
    // What a checkpoint holds after a stop: some of the rows the walks reported (the nested
    // check's refits never reach it): every third, which cuts across rounds and pairs.
    let saved: Vec<CellRow> = reported.iter().step_by(3).cloned().collect();
    assert!(saved.len() > 4 && saved.len() < reported.len());
    let (resumed, _, _) = search_rows(&p, 2, saved);
    assert_eq!(resumed.len(), whole.len());
    for (a, b) in whole.iter().zip(&resumed) {
        assert_eq!(a.key, b.key);
        assert_eq!(a.fit.criterion.map(f64::to_bits), b.fit.criterion.map(f64::to_bits), "{:?}", a.key);
        assert_eq!(a.fit.b, b.fit.b, "{:?}", a.key);
    }
}

#[test]
fn a_stopped_search_merges_to_its_next_round() {
    let dir = tempfile::tempdir().unwrap();
    let path = job(dir.path(), "coordinate");
    // A run stopped before its first cell leaves a checkpoint whose merge names the first round...
    let watch = engine::Watch {
        stop: Arc::new(AtomicBool::new(true)),
        done: Default::default(),
        total: Default::default(),
        finished: None,
    };
    let opts = RunOptions { quiet: true, watch: Some(watch), ..RunOptions::default() };
    let o = engine::run(&path, &opts, &|_| ()).unwrap();
    assert!(matches!(o.end, engine::RunEnd::Interrupted));
    let out = dir.path().join("out");
    let m = engine::merge(&out, false, false).unwrap();
    assert!(matches!(m.end, MergeEnd::Incomplete) && m.exit_code() == engine::NEXT_ROUND, "{m:?}");
    let pending = m.next_round().expect("the round to run, none of its cells there");
    assert_eq!((pending.round, pending.input), (1, 0));
    assert_eq!(pending.structures.len(), 4, "input 1's line through the start");
    // One of its two shards run: cells are missing, not a round (exit 1, the other shard named).
    let shard = Some(Shard { index: 0, count: 2 });
    engine::run(&path, &RunOptions { quiet: true, shard, ..RunOptions::default() }, &|_| ()).unwrap();
    let m = engine::merge(&out, false, false).unwrap();
    assert!(m.next_round().is_none() && m.exit_code() == 1, "{m:?}");
    assert_eq!(m.owners, Some((2, vec![1])));
    // ... and the run resumes it to the results of the rows it fitted.
    let opts = RunOptions { quiet: true, ..RunOptions::default() };
    let o = engine::run(&path, &opts, &|_| ()).unwrap();
    assert!(matches!(o.end, engine::RunEnd::Merged { .. }));
    assert!(o.cells > 0 && o.cells < 64 * 2, "{} cells", o.cells);
}

/// A job of `job`'s record with another output folder (for the whole run beside the shards).
fn job_with_output(dir: &Path, search: &str, output: &str) -> PathBuf {
    let text = std::fs::read_to_string(job(dir, search)).unwrap().replace("\"out\"", &format!("\"{output}\""));
    let path = dir.join(format!("{output}.json"));
    std::fs::write(&path, text).unwrap();
    path
}

fn cells(folder: &Path) -> Vec<CellRow> {
    zero_seconds(oesweep::export::parquet::read_cells(&folder.join("cells.parquet")).unwrap())
}

#[test]
fn a_search_sharded_round_by_round_merges_to_the_table_of_a_whole_run() {
    let dir = tempfile::tempdir().unwrap();
    let reference = job_with_output(dir.path(), "coordinate", "ref");
    let path = job(dir.path(), "coordinate");
    let whole = engine::run(&reference, &RunOptions { quiet: true, ..RunOptions::default() }, &|_| ()).unwrap();
    let rounds = whole.search.clone().expect("a coordinate search");
    let expected = cells(&dir.path().join("ref"));
    let selection = std::fs::read_to_string(dir.path().join("ref/selection.json")).unwrap();
    let out = dir.path().join("out");
    for n in [2, 3] {
        let _ = std::fs::remove_dir_all(&out);
        // Every shard of the round, then the merge: the next round, or the results.
        let mut merges = Vec::new();
        loop {
            for index in 0..n {
                let shard = Some(Shard { index, count: n });
                let o = engine::run(
                    &path,
                    &RunOptions { quiet: true, threads: 1, shard, ..RunOptions::default() },
                    &|_| (),
                )
                .unwrap();
                assert!(matches!(o.end, RunEnd::ShardSaved), "{o:?}");
                let pending = o.search.as_ref().and_then(|r| r.pending.as_ref()).expect("the shard's round");
                assert_eq!(o.pairs, pending.share.len());
                assert!(pending.share.iter().all(|s| pending.structures.contains(s)));
            }
            let m = engine::merge(&out, false, false).unwrap();
            let replayed = m.search.clone().expect("the rounds replayed");
            if let MergeEnd::Merged { .. } = m.end {
                assert_eq!(replayed, rounds, "N = {n}: the rounds of the whole run");
                break;
            }
            assert!(matches!(m.end, MergeEnd::Incomplete) && m.exit_code() == engine::NEXT_ROUND, "{m:?}");
            let pending = replayed.pending.expect("the round the shards run next");
            assert!(merges.last().is_none_or(|&r| r < pending.round), "each round once: {merges:?}, {}", pending.round);
            assert_eq!(m.missing.pairs.len(), pending.structures.len(), "no row of the next round yet");
            merges.push(pending.round);
            assert!(merges.len() <= rounds.rounds.len(), "N = {n}: more rounds than the whole run's");
        }
        assert!(merges.len() >= 2, "N = {n}: the search took several rounds of shards: {merges:?}");
        assert!(cells(&out) == expected, "N = {n}: the merged table differs from the whole run's");
        assert_eq!(std::fs::read_to_string(out.join("selection.json")).unwrap(), selection, "N = {n}");
        assert!(!out.join("parts").exists(), "a finished merge deletes the checkpoint");
    }
}

#[test]
fn plan_says_which_search_runs_and_estimates_its_time() {
    let dir = tempfile::tempdir().unwrap();
    let path = job(dir.path(), "coordinate");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep")).arg("plan").arg(&path).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}{}", String::from_utf8_lossy(&out.stderr));
    // Three inputs of 4 orders each: 1 + 3 x 3 structures per cycle, of the product's 64.
    assert!(text.contains("search     coordinate (grid.search)"), "{text}");
    assert!(text.contains("10 structures (20 cells) per cycle over the inputs, of the product's 64"), "{text}");
    assert!(text.contains("time       about "), "{text}");
    let path = job(dir.path(), "auto");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep")).arg("plan").arg(&path).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("cells      128 Huber cells + 64 least-squares fits"), "{text}");
    assert!(!text.contains("search     coordinate"), "{text}");
}

#[test]
fn slurm_submits_the_search_round_by_round_until_a_merge_finds_it_finished() {
    let dir = tempfile::tempdir().unwrap();
    let reference = job_with_output(dir.path(), "coordinate", "ref");
    engine::run(&reference, &RunOptions { quiet: true, ..RunOptions::default() }, &|_| ()).unwrap();
    let expected = cells(&dir.path().join("ref"));
    let (path_env, log) = fake_sbatch(dir.path());
    let slurm = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
            .arg("slurm")
            .args(args)
            .env("PATH", &path_env)
            .output()
            .unwrap();
        let text = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
        (o.status.code(), text)
    };
    let shards = |job: &Path| {
        for index in 0..2 {
            let shard = Some(Shard { index, count: 2 });
            engine::run(job, &RunOptions { quiet: true, threads: 1, shard, ..RunOptions::default() }, &|_| ()).unwrap();
        }
    };
    let s = |p: &Path| p.to_str().unwrap().to_string();

    // Bad input: a product takes no bound; a merge script of the user's that does not go on.
    let (code, text) = slurm(&[&s(&job_with_output(dir.path(), "product", "product")), "--shards=2", "--max-rounds=2"]);
    assert_eq!(code, Some(2), "{text}");
    let own = dir.path().join("own");
    std::fs::create_dir(&own).unwrap();
    std::fs::write(own.join("sweep.sbatch"), "#!/bin/bash\n").unwrap();
    std::fs::write(own.join("merge.sbatch"), "#!/bin/bash\nexec oesweep merge \"$@\"\n").unwrap();
    let (code, text) = slurm(&[&s(&job(dir.path(), "coordinate")), "--shards=2", "--sbatch", &s(&own)]);
    assert!(code == Some(2) && text.contains("does not go on with a coordinate search"), "{text}");

    // The bound: one array, then the next round is not submitted.
    let bounded = job_with_output(dir.path(), "coordinate", "bounded");
    let (code, text) = slurm(&[&s(&bounded), "--shards=2", "--max-rounds=1"]);
    assert!(code == Some(0) && text.contains("at most 1 round)"), "{text}");
    shards(&bounded);
    let (code, text) = slurm(&["--next-round", &s(&dir.path().join("bounded"))]);
    assert!(code == Some(1) && text.contains("round 2 waits after 1 array, the most --max-rounds allows"), "{text}");

    let path = job(dir.path(), "coordinate");
    let out = dir.path().join("out");
    let (code, text) = slurm(&[&s(&path), "--shards=2"]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("array of 2 shards: round 1 of the coordinate search") && text.contains("at most 30 rounds"));
    let first = 4100 + std::fs::read_to_string(&log).unwrap().lines().count() - 1;
    let mut rounds = vec![1];
    loop {
        shards(&path);
        let (code, text) = slurm(&["--next-round", &s(&out)]);
        assert_eq!(code, Some(0), "{text}");
        if text.contains("the coordinate search is finished") {
            break;
        }
        let round = oesweep::slurm::Loop::read(&out).unwrap().arrays.last().unwrap().round.unwrap();
        assert!(text.contains(&format!("round {round} of the coordinate search: sweep job")), "{text}");
        assert!(round > *rounds.last().unwrap() && rounds.len() < 30, "{rounds:?} then {round}");
        rounds.push(round);
        if rounds.len() == 2 {
            // Before the array's shards ran, the round still waits: the loop stops rather than
            // submit it again.
            let (code, text) = slurm(&["--next-round", &s(&out)]);
            let id = first + 2;
            let stop =
                format!("round {round} still waits after the array submitted for round {round} (Slurm job {id})");
            assert!(code == Some(1) && text.contains(&stop), "{text}");
        }
    }
    assert!(rounds.len() >= 2, "several rounds: {rounds:?}");
    assert!(cells(&out) == expected, "the table of the rounds submitted differs from the whole run's");
    // Each array of two shards, then its merge after it; the state lists them with Slurm's ids.
    let calls: Vec<String> = std::fs::read_to_string(&log).unwrap().lines().map(str::to_string).collect();
    let calls = &calls[first - 4101..];
    assert_eq!(calls.len(), 2 * rounds.len(), "{calls:?}");
    let state = oesweep::slurm::Loop::read(&out).unwrap();
    for (i, (pair, array)) in calls.chunks(2).zip(&state.arrays).enumerate() {
        let id = first + 2 * i;
        assert!(
            pair[0].contains("--array=0-1")
                && pair[0].ends_with(&format!("{} 2", path.canonicalize().unwrap().display()))
        );
        assert!(
            pair[1].contains(&format!("--dependency=afterok:{id}")) && pair[1].contains("merge.sbatch"),
            "{pair:?}"
        );
        assert_eq!((array.round, array.sweep_job.clone()), (Some(rounds[i]), Some(id.to_string())));
    }
}
