//! No crash on any input (issue 38): every number a user gives (flags, job fields, the files of
//! a results or checkpoint folder) ends in exit 0, 1 or 2, never in a panic (101) or an abort
//! (134), and exit 2 is one line on stderr with nothing written.
//!
//! First the crashes reproduced with the release binary before the fix, one test each; then
//! properties over command lines and over mutated results folders (job.json, selection.json,
//! cells.parquet) and checkpoint folders (manifest.json, job.json, a part). Every property
//! runs the binary, so the case counts are modest ([`CASES_CLI`], [`CASES_RESULTS`],
//! [`CASES_CHECKPOINT`]: 180 processes in all) and the seed is fixed: the same cases every run.
//! A damaged Parquet *page header* is refused before polars decodes it (the abort it caused is
//! the regression case `tests/bad_inputs/parquet_page_header_values`).

mod common;

use common::{Outcome, Snapshot};
use polars::prelude::SerReader;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use serde_json::Value;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

const CASES_CLI: u32 = 60;
const CASES_RESULTS: u32 = 80;
const CASES_CHECKPOINT: u32 = 40;

/// A safety net, not a measurement: a command still running after this is killed and fails
/// the test (validation reads small files; a case past it would estimate or allocate).
const TIMEOUT: Duration = Duration::from_secs(120);

const VALID: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/bad_inputs/_valid");

fn config(cases: u32) -> Config {
    Config { cases, rng_seed: RngSeed::Fixed(38), failure_persistence: None, ..Config::default() }
}

fn oesweep(cwd: &Path, args: &[String]) -> Outcome {
    common::run_oesweep(cwd, args, TIMEOUT)
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|s| s.to_string()).collect()
}

/// The verdict any input must get: exit 0, 1 or 2, no signal; on exit 2 exactly one line
/// `error: ...` and `root` as it was. Returns a description of what is wrong.
fn verdict(o: &Outcome, before: &Snapshot, root: &Path) -> Result<(), String> {
    let show = || format!("exit {:?}, signal {:?}, stderr {:?}", o.code, o.signal, o.stderr);
    match o.code {
        Some(0 | 1) => Ok(()),
        Some(2) => {
            if o.stderr.lines().count() != 1 || !o.stderr.starts_with("error: ") || !o.stderr.ends_with('\n') {
                return Err(format!("exit 2 without exactly one error line: {}", show()));
            }
            if common::snapshot(root, true) != *before {
                return Err(format!("exit 2 but files were written, changed or removed: {}", show()));
            }
            Ok(())
        }
        _ => Err(format!("neither 0, 1 nor 2: {}", show())),
    }
}

/// A folder with the valid job of the bad-input corpus (`job.json`, `data.csv`, `val.csv`,
/// output `out`).
fn job_folder(root: &Path) -> PathBuf {
    let dir = root.join("case");
    common::copy_tree(Path::new(VALID), &dir);
    dir
}

/// Made once: a finished results folder (`done/out`) and an unmerged one of two shards
/// (`sharded/out/parts/shard-I-of-2`), both of the valid job.
fn fixtures() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = tempfile::tempdir().unwrap().keep().canonicalize().unwrap();
        for (name, runs) in [("done", vec![vec![]]), ("sharded", vec![vec!["--shard", "0/2"], vec!["--shard", "1/2"]])]
        {
            let dir = root.join(name);
            common::copy_tree(Path::new(VALID), &dir);
            for extra in runs {
                let mut args = strings(&["run", "job.json", "--quiet", "--threads", "1"]);
                args.extend(strings(&extra));
                let o = oesweep(&dir, &args);
                assert!(matches!(o.code, Some(0 | 1)), "{name}: {}", o.stderr);
            }
        }
        assert!(root.join("done/out/cells.parquet").is_file());
        assert!(root.join("sharded/out/parts/shard-1-of-2/manifest.json").is_file());
        root
    })
}

/// Copy of a fixture folder (`done` or `sharded`) in a fresh temporary folder.
fn fresh(name: &str) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().canonicalize().unwrap();
    common::copy_tree(&fixtures().join(name), &root.join(name));
    (tmp, root)
}

/// Runs `args` in `root` and asserts exit 2, one line holding `needle`, nothing written.
fn assert_refused(root: &Path, args: &[&str], needle: &str) {
    let before = common::snapshot(root, true);
    let o = oesweep(root, &strings(args));
    assert_eq!(o.code, Some(2), "{args:?}: {:?} {}", o.signal, o.stderr);
    verdict(&o, &before, root).unwrap();
    assert!(o.stderr.contains(needle), "{args:?}: {}", o.stderr);
}

fn edit_json(path: &Path, edit: impl FnOnce(&mut Value)) {
    let mut v: Value = serde_json::from_str(&fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut v);
    fs::write(path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
}

// ---------------------------------------------------------------------------------------------
// The crashes of issue 38, each now exit 2.

#[test]
fn checkpoint_every_1e20_is_refused_and_leaves_no_parts() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = job_folder(tmp.path());
    assert_refused(&dir, &["run", "job.json", "--checkpoint-every", "1e20"], "--checkpoint-every");
    assert!(!dir.join("out").exists());
}

#[test]
fn threads_100000_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = job_folder(tmp.path());
    assert_refused(&dir, &["run", "job.json", "--threads", "100000"], "--threads must be at most 1024");
}

#[test]
fn absurd_shard_counts_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = job_folder(tmp.path());
    assert_refused(&dir, &["run", "job.json", "--shard", "0/1000000000000"], "at most one shard per cell");
    assert_refused(&dir, &["plan", "job.json", "--shards", "1000000000000"], "at most one shard per cell");
    assert_refused(&dir, &["slurm", "job.json", "--shards", "1000000000000", "--dry-run"], "one shard per cell");
}

#[test]
fn simulate_n_1e15_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let system = concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/data/piezo_system.json");
    let args = ["simulate", "--system", system, "--out", "sim.csv", "--n", "1000000000000000"];
    assert_refused(tmp.path(), &args, "between 1 and 10000000");
}

#[test]
fn fit_bootstrap_1e12_and_orders_above_the_limit_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = job_folder(tmp.path());
    let fit = ["fit", "--data", "data.csv", "--nb", "2", "--nf", "1", "--k", "1"];
    assert_refused(
        &dir,
        &[&fit[..], &["--bootstrap", "1000000000000"]].concat(),
        "--bootstrap must be from 40 to 100000",
    );
    assert_refused(&dir, &[&fit[..5], &["--nf", "61", "--k", "1"]].concat(), "--nf orders above 60");
    assert_refused(&dir, &[&fit[..], &["--ftol=-1"]].concat(), "--ftol must be a non-negative number");
}

#[test]
fn an_edited_job_json_is_refused_by_export_report_and_merge() {
    let (_tmp, root) = fresh("done");
    let out = root.join("done/out");
    edit_json(&out.join("job.json"), |j| j["grid"]["nb"] = serde_json::json!([2, 1]));
    let folder = out.to_str().unwrap();
    assert_refused(&root, &["export", folder, "--pick", "rbic", "--to", "json"], "field 'grid.nb': [2, 1]");
    assert_refused(&root, &["report", folder], "field 'grid.nb'");
    edit_json(&out.join("job.json"), |j| {
        j["grid"]["nb"] = serde_json::json!([1, 2]);
        j["grid"]["k"] = serde_json::json!({"from": 0.1, "to": 1, "count": 1_000_000_000_000_000u64});
    });
    assert_refused(&root, &["export", folder, "--to", "json"], "above the limit of 200000");
    assert_refused(&root, &["report", folder], "above the limit of 200000");

    let (_tmp, root) = fresh("sharded");
    let job = root.join("sharded/out/parts/shard-0-of-2/job.json");
    edit_json(&job, |j| j["grid"]["k"] = serde_json::json!({"from": 0.1, "to": 1, "count": 1_000_000_000_000_000u64}));
    assert_refused(&root, &["merge", root.join("sharded/out").to_str().unwrap()], "above the limit");
}

#[test]
fn a_shard_folder_of_an_absurd_count_is_refused_by_merge() {
    let (_tmp, root) = fresh("sharded");
    let parts = root.join("sharded/out/parts");
    fs::rename(parts.join("shard-1-of-2"), parts.join("shard-1-of-1000000000000")).unwrap();
    assert_refused(&root, &["merge", root.join("sharded/out").to_str().unwrap()], "at most one shard per cell");
}

#[test]
fn a_newer_format_is_refused_in_each_result_file() {
    for file in ["job.json", "selection.json"] {
        let (_tmp, root) = fresh("done");
        let out = root.join("done/out");
        edit_json(&out.join(file), |j| {
            assert_eq!(j["format_version"], 1, "{file} declares its format");
            j["format_version"] = 2.into();
        });
        let needle = format!("{file}: format_version 2 is newer");
        assert_refused(&root, &["export", out.to_str().unwrap(), "--to", "json"], &needle);
    }
    // cells.parquet: the key-value metadata, rewritten by polars with a newer version.
    let (_tmp, root) = fresh("done");
    let cells = root.join("done/out/cells.parquet");
    let meta = |p: &Path| {
        let mut r = polars::prelude::ParquetReader::new(fs::File::open(p).unwrap());
        let m = r.get_metadata().unwrap().key_value_metadata().clone().unwrap_or_default();
        m.into_iter().map(|kv| (kv.key, kv.value)).collect::<Vec<_>>()
    };
    assert!(meta(&cells).contains(&("format_version".into(), Some("1".into()))));
    let mut df = polars::prelude::ParquetReader::new(fs::File::open(&cells).unwrap()).finish().unwrap();
    let kv = polars::prelude::KeyValueMetadata::from_static(vec![("format_version".into(), "3".into())]);
    polars::prelude::ParquetWriter::new(fs::File::create(&cells).unwrap())
        .with_key_value_metadata(Some(kv))
        .finish(&mut df)
        .unwrap();
    assert_refused(&root, &["export", root.join("done/out").to_str().unwrap(), "--to", "json"], "format_version 3");
}

// ---------------------------------------------------------------------------------------------
// A reader that stops early (`oesweep run JOB | head`).

/// Runs `args` in `cwd` with standard output a pipe whose reading end was closed before the
/// binary started: its every write fails with a broken pipe, with no race to time.
fn with_stdout_closed(cwd: &Path, args: &[&str]) -> std::process::Output {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(args)
        .current_dir(cwd)
        .env("RUST_BACKTRACE", "0")
        .stdin(std::process::Stdio::null())
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("binary starts")
}

#[test]
fn a_closed_stdout_ends_the_printing_not_the_command() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().canonicalize().unwrap();
    let (read, closed) = (job_folder(&root.join("read")), job_folder(&root.join("closed")));
    let run = ["run", "job.json", "--quiet", "--threads", "1"];
    let normal = oesweep(&read, &strings(&run));
    assert!(matches!(normal.code, Some(0 | 1)) && !normal.stdout.is_empty(), "{}", normal.stderr);

    let o = with_stdout_closed(&closed, &[&run[..], &["--profile", "profile.json"]].concat());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), normal.code, "{stderr}");
    assert!(!stderr.contains("panicked") && !stderr.contains("error"), "{stderr}");
    // The results, and the profile written after the printing, are all there.
    assert_eq!(common::table_without_seconds(&closed.join("out")), common::table_without_seconds(&read.join("out")));
    assert!(closed.join("out/selection.json").is_file() && closed.join("profile.json").is_file());

    let out = closed.join("out");
    for args in [&["plan", "job.json", "--shards", "2"][..], &["export", out.to_str().unwrap(), "--to", "matlab"]] {
        let o = with_stdout_closed(&closed, args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

// ---------------------------------------------------------------------------------------------
// Properties.

/// Numbers (and non-numbers) a user might type: the edges of every type and typos.
fn number() -> impl Strategy<Value = String> {
    prop::sample::select(
        &[
            "0",
            "1",
            "2",
            "3",
            "-1",
            "0.5",
            "1e-300",
            "1e20",
            "1e308",
            "1000000000000",
            "1000000000000000",
            "18446744073709551615",
            "18446744073709551616",
            "nan",
            "inf",
            "-inf",
            "abc",
            "",
            "60",
            "61",
            "0x10",
            "4294967296",
            "200001",
        ][..],
    )
    .prop_map(str::to_string)
}

fn shard() -> impl Strategy<Value = String> {
    (number(), number()).prop_map(|(i, n)| format!("{i}/{n}"))
}

/// A command line of one of the commands that take numbers, with some flags drawn.
fn command_line() -> impl Strategy<Value = Vec<String>> {
    let opt = |flag: &'static str, v: BoxedStrategy<String>| {
        prop::option::weighted(0.6, v).prop_map(move |v| v.map(|v| vec![flag.to_string(), v]).unwrap_or_default())
    };
    let run = (
        opt("--threads", number().boxed()),
        opt("--checkpoint-every", number().boxed()),
        opt("--shard", shard().boxed()),
    )
        .prop_map(|(a, b, c)| [strings(&["run", "job.json", "--quiet"]), a, b, c].concat());
    let plan = opt("--shards", number().boxed()).prop_map(|a| [strings(&["plan", "job.json"]), a].concat());
    let system = concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/data/piezo_system.json");
    let simulate = (
        number(),
        opt("--bits", number().boxed()),
        opt("--noise-std", number().boxed()),
        opt("--outlier-prob", number().boxed()),
        opt("--student-t", number().boxed()),
    )
        .prop_map(move |(n, a, b, c, d)| {
            // A valid --n costs a file of that many rows: the large ones are refused anyway.
            [strings(&["simulate", "--system", system, "--out", "sim.csv", "--n", &n]), a, b, c, d].concat()
        });
    let fit = (
        number(),
        number(),
        number(),
        opt("--delay", number().boxed()),
        opt("--ts", number().boxed()),
        opt("--max-iterations", number().boxed()),
        opt("--ftol", number().boxed()),
        opt("--bootstrap", number().boxed()),
    )
        .prop_map(|(nb, nf, k, a, b, c, d, e)| {
            let base = strings(&["fit", "--data", "data.csv", "--nb", &nb, "--nf", &nf, "--k", &k]);
            [base, a, b, c, d, e].concat()
        });
    let spectrum = number().prop_map(|ts| strings(&["spectrum", "--data", "data.csv", "--ts", &ts]));
    prop_oneof![3 => run, 1 => plan, 2 => simulate, 3 => fit, 1 => spectrum]
}

/// A JSON value to put in a result file: wrong types, edge numbers, ranges upside down.
fn json_value() -> impl Strategy<Value = Value> {
    use serde_json::json;
    prop::sample::select(vec![
        Value::Null,
        json!(true),
        json!(0),
        json!(1),
        json!(2),
        json!(-1),
        json!(0.5),
        json!(1e300),
        json!(1_000_000_000_000_000u64),
        json!(u64::MAX),
        json!(""),
        json!("x"),
        json!("rbic"),
        json!([]),
        json!([2, 1]),
        json!([0, 0]),
        json!([1, 1_000_000_000_000u64]),
        json!([61, 61]),
        json!({}),
        json!({"from": 0.1, "to": 1, "count": 1_000_000_000_000_000u64}),
        json!({"nb": 1_000_000, "nf": 2, "k": 0.5, "delay": 1}),
    ])
}

/// Every JSON pointer of `v` (objects' fields and arrays' items).
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let p = format!("{at}/{}", k.replace('~', "~0").replace('/', "~1"));
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                let p = format!("{at}/{i}");
                out.push(p.clone());
                pointers(x, p, out);
            }
        }
        _ => {}
    }
}

/// One edit of a file: a JSON value replaced or removed (by an index into its pointers), or
/// bytes set, inserted or cut (by indices into the file).
#[derive(Clone, Debug)]
enum Edit {
    Replace(usize, Value),
    Remove(usize),
    SetByte(usize, u8),
    Insert(usize, Vec<u8>),
    Truncate(usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        4 => (any::<usize>(), json_value()).prop_map(|(i, v)| Edit::Replace(i, v)),
        1 => any::<usize>().prop_map(Edit::Remove),
        2 => (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::SetByte(i, b)),
        1 => (any::<usize>(), prop::collection::vec(any::<u8>(), 1..8)).prop_map(|(i, b)| Edit::Insert(i, b)),
        1 => any::<usize>().prop_map(Edit::Truncate),
    ]
}

/// Applies `edits` to the file at `path`: JSON edits to a JSON file, byte edits to any file
/// (a JSON edit of a file that is not JSON flips a byte at its index).
fn mutate(path: &Path, edits: &[Edit]) {
    let mut bytes = fs::read(path).unwrap();
    for e in edits {
        if let (Edit::Replace(i, _) | Edit::Remove(i), Ok(mut v)) = (e, serde_json::from_slice::<Value>(&bytes)) {
            let mut ps = Vec::new();
            pointers(&v, String::new(), &mut ps);
            if ps.is_empty() {
                continue;
            }
            let p = ps[i % ps.len()].clone();
            match e {
                Edit::Replace(_, x) => *v.pointer_mut(&p).unwrap() = x.clone(),
                _ => {
                    let (parent, last) = p.rsplit_once('/').unwrap();
                    match v.pointer_mut(parent) {
                        Some(Value::Object(m)) => {
                            m.remove(&last.replace("~1", "/").replace("~0", "~"));
                        }
                        Some(Value::Array(a)) => {
                            a.remove(last.parse::<usize>().unwrap());
                        }
                        _ => {}
                    }
                }
            }
            bytes = serde_json::to_vec_pretty(&v).unwrap();
            continue;
        }
        let n = bytes.len();
        match e {
            Edit::Replace(i, _) | Edit::Remove(i) if n > 0 => bytes[i % n] ^= 0x5a,
            Edit::SetByte(i, b) if n > 0 => {
                // Half of the edits land in the last 200 bytes: a Parquet file's footer.
                let at = if i % 2 == 0 { n - 1 - (i / 2) % n.min(200) } else { i % n };
                bytes[at] = *b;
            }
            Edit::Insert(i, b) => {
                let at = i % (n + 1);
                bytes.splice(at..at, b.iter().copied());
            }
            Edit::Truncate(i) => bytes.truncate(i % (n + 1)),
            _ => {}
        }
    }
    fs::write(path, bytes).unwrap();
}

/// The commands that read a results folder.
fn reader() -> impl Strategy<Value = Vec<&'static str>> {
    prop::sample::select(vec![
        vec!["export", "{}", "--to", "json"],
        vec!["export", "{}", "--pick", "rbic", "--to", "matlab"],
        vec!["export", "{}", "--pick", "1,1,0.5", "--to", "json"],
        vec!["report", "{}"],
    ])
}

fn with_folder(args: &[&str], folder: &Path) -> Vec<String> {
    args.iter().map(|a| if *a == "{}" { folder.display().to_string() } else { a.to_string() }).collect()
}

proptest! {
    #![proptest_config(config(CASES_CLI))]
    #[test]
    fn any_command_line_is_0_1_or_2(args in command_line()) {
        let tmp = tempfile::tempdir().unwrap();
        let dir = job_folder(&tmp.path().canonicalize().unwrap());
        let before = common::snapshot(&dir, true);
        let o = oesweep(&dir, &args);
        if let Err(why) = verdict(&o, &before, &dir) {
            return Err(TestCaseError::fail(format!("oesweep {args:?}: {why}")));
        }
        prop_assert!(o.code != Some(2) || o.stdout.is_empty(), "exit 2 with output: {}", o.stdout);
    }
}

proptest! {
    #![proptest_config(config(CASES_RESULTS))]
    #[test]
    fn any_mutated_results_folder_is_0_1_or_2(
        file in prop::sample::select(vec!["job.json", "selection.json", "cells.parquet"]),
        edits in prop::collection::vec(edit(), 1..4),
        args in reader(),
    ) {
        let (_tmp, root) = fresh("done");
        let out = root.join("done/out");
        mutate(&out.join(file), &edits);
        let before = common::snapshot(&root, true);
        let args = with_folder(&args, &out);
        let o = oesweep(&root, &args);
        if let Err(why) = verdict(&o, &before, &root) {
            return Err(TestCaseError::fail(format!("{file} {edits:?}, oesweep {args:?}: {why}")));
        }
    }
}

proptest! {
    #![proptest_config(config(CASES_CHECKPOINT))]
    #[test]
    fn any_mutated_checkpoint_is_0_1_or_2(
        file in prop::sample::select(vec!["manifest.json", "job.json", "part-000001.parquet"]),
        shard in 0..2usize,
        edits in prop::collection::vec(edit(), 1..4),
        resume in any::<bool>(),
    ) {
        let (_tmp, root) = fresh("sharded");
        let path = root.join(format!("sharded/out/parts/shard-{shard}-of-2/{file}"));
        prop_assume!(path.is_file());
        mutate(&path, &edits);
        let before = common::snapshot(&root, true);
        let args = if resume {
            // A whole run resumes from the shards' folders.
            strings(&["run", root.join("sharded/job.json").to_str().unwrap(), "--quiet", "--threads", "1"])
        } else {
            strings(&["merge", root.join("sharded/out").to_str().unwrap()])
        };
        let o = oesweep(&root, &args);
        if let Err(why) = verdict(&o, &before, &root) {
            return Err(TestCaseError::fail(format!("{file} of shard {shard} {edits:?}, oesweep {args:?}: {why}")));
        }
    }
}
