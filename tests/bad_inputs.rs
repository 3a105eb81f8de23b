//! The bad-input corpus (`tests/bad_inputs/`): every case is a job that is wrong in exactly one
//! way, and both `oesweep plan` and `oesweep run` must reject it the same way: exit code 2, one
//! line on stderr that names the offending file and says what is wrong, and nothing written.
//!
//! A case is a folder with `job.json`, its data files and `expect.txt`:
//!
//! ```text
//! file: data.csv                      <- the file the message must name (path as resolved)
//! message: line 17, column 'y': ...   <- a substring of the message
//! ```
//!
//! Each command runs on a fresh copy of the case in a temporary folder, so the repository is
//! never written. "Nothing written" is checked on the whole copy (every path and every byte is
//! the same afterwards), which covers both a job whose output folder does not exist (it must
//! still not exist) and one whose output folder holds results of an earlier run (`out/` with a
//! sentinel file: it must be untouched). Folders starting with `_` are not cases (`_valid` is
//! the well-formed job all cases are derived from; it shows that the checks would notice a
//! write).

mod common;

use std::fs;
use std::path::{Path, PathBuf};
use std::time::Duration;

const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/bad_inputs");

/// Every command must answer within this time: validation reads small files only, and a case
/// that gets past validation would start estimating (or allocating) instead of failing.
const TIMEOUT: Duration = Duration::from_secs(60);

struct Case {
    name: String,
    dir: PathBuf,
    /// File the message must name, relative to the case folder.
    file: String,
    /// Substring of the message.
    message: String,
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    for entry in fs::read_dir(CORPUS).expect("corpus folder") {
        let dir = entry.unwrap().path();
        let name = dir.file_name().unwrap().to_str().unwrap().to_string();
        if !dir.is_dir() || name.starts_with('_') {
            continue;
        }
        let expect = fs::read_to_string(dir.join("expect.txt")).unwrap_or_else(|e| panic!("{name}/expect.txt: {e}"));
        let field = |key: &str| {
            expect
                .lines()
                .find_map(|l| l.strip_prefix(key))
                .map(|v| v.trim().to_string())
                .unwrap_or_else(|| panic!("{name}/expect.txt: no '{key}' line"))
        };
        let (file, message) = (field("file:"), field("message:"));
        assert!(!message.is_empty(), "{name}/expect.txt: empty message");
        out.push(Case { name, dir, file, message });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    out
}

/// Runs the binary in `cwd`, killed after [`TIMEOUT`].
fn oesweep(cwd: &Path, args: &[&str]) -> common::Outcome {
    common::run_oesweep(cwd, args, TIMEOUT)
}

/// Checks one case under both commands; returns the problems found (empty when it passes).
fn check(case: &Case) -> Vec<String> {
    let tmp = tempfile::tempdir().unwrap();
    // Canonical, because the program resolves the job's folder to an absolute path.
    let root = tmp.path().canonicalize().unwrap();
    let dir = root.join(&case.name);
    common::copy_tree(&case.dir, &dir);
    let job = dir.join("job.json");
    let named = format!("{}: ", dir.join(&case.file).display());
    let before = common::snapshot(&root, false);
    let had_output = dir.join("out").exists();
    let mut problems = Vec::new();
    for args in [vec!["plan", job.to_str().unwrap()], vec!["run", job.to_str().unwrap(), "--quiet"]] {
        let o = oesweep(&root, &args);
        let what = format!("{} `oesweep {}`", case.name, args[0]);
        let mut fail = |msg: String| problems.push(format!("{what}: {msg}\n    stderr: {:?}", o.stderr));
        if o.code != Some(2) {
            fail(format!("exit code {:?}, expected 2", o.code));
        }
        let lines: Vec<&str> = o.stderr.lines().collect();
        if lines.len() != 1 || !o.stderr.ends_with('\n') {
            fail(format!("{} lines on stderr, expected exactly one", lines.len()));
        }
        if !o.stderr.contains(&named) {
            fail(format!("the message does not name the file: expected '{named}'"));
        }
        if !o.stderr.contains(&case.message) {
            fail(format!("the message lacks '{}'", case.message));
        }
        if !o.stdout.is_empty() {
            fail(format!("unexpected output on stdout: {:?}", o.stdout));
        }
        if common::snapshot(&root, false) != before {
            fail("files were written, changed or removed".into());
        }
        if !had_output && dir.join("out").exists() {
            fail("the output folder was created".into());
        }
        if Path::new("/proc/oesweep-test").exists() {
            fail("/proc/oesweep-test exists".into());
        }
    }
    problems
}

#[test]
fn every_bad_input_is_exit_2_one_line_and_writes_nothing() {
    let cases = cases();
    assert!(cases.len() >= 20, "the corpus has only {} cases", cases.len());
    assert!(
        cases.iter().any(|c| c.dir.join("out").join("sentinel.txt").is_file()),
        "no case has an existing output folder with a sentinel file"
    );
    let problems: Vec<String> = cases.iter().flat_map(check).collect();
    assert!(problems.is_empty(), "{} problem(s):\n{}", problems.len(), problems.join("\n"));
}

/// The control: the job every case is derived from passes `plan`, and `run` writes its output
/// folder, so the checks above would see a write if validation let a case through.
#[test]
fn the_valid_job_passes_and_its_run_is_visible() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().canonicalize().unwrap();
    let dir = root.join("_valid");
    common::copy_tree(&Path::new(CORPUS).join("_valid"), &dir);
    let job = dir.join("job.json");
    let before = common::snapshot(&root, false);
    let plan = oesweep(&root, &["plan", job.to_str().unwrap()]);
    assert_eq!(plan.code, Some(0), "{}", plan.stderr);
    assert!(plan.stderr.is_empty(), "{}", plan.stderr);
    assert_eq!(common::snapshot(&root, false), before, "plan wrote files");
    let run = oesweep(&root, &["run", job.to_str().unwrap(), "--quiet"]);
    assert!(matches!(run.code, Some(0 | 1)), "exit {:?}: {}", run.code, run.stderr);
    assert!(dir.join("out").join("cells.parquet").is_file());
    assert_ne!(common::snapshot(&root, false), before);
}
