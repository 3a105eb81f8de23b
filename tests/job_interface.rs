//! What a user types and reads about a job, checked over the whole job schema rather than
//! field by field, so a new field or enum cannot be left out:
//!
//! - every field of a complete job, given a value of a wrong type, is one error line naming
//!   the field by its path (`data.u`, `data[1].rows`, `grid.k[1]`) and saying what it accepts
//!   in words (no serde type names such as `usize` or `untagged enum`); the same for every
//!   field of the `job.json` a run writes, which users may edit;
//! - every enum field of a job reads both spellings of each name (`gauss_newton`,
//!   `gauss-newton`) as the same job, and so does every enum argument of the command line;
//! - the summary of `run` labels a pick's score by the fit column that ranked it.

mod common;

use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// A step of a path into a job's JSON.
#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Index(usize),
}

/// `data[1].rows`: the path as the messages write it.
fn show(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) if s.is_empty() => s.push_str(k),
            Seg::Key(k) => s.push_str(&format!(".{k}")),
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

/// Every field and list element below `v`, parents before children.
fn paths(v: &Value, prefix: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    let children: Vec<(Seg, &Value)> = match v {
        Value::Object(m) => m.iter().map(|(k, v)| (Seg::Key(k.clone()), v)).collect(),
        Value::Array(a) => a.iter().enumerate().map(|(i, v)| (Seg::Index(i), v)).collect(),
        _ => return,
    };
    for (seg, child) in children {
        prefix.push(seg);
        out.push(prefix.clone());
        paths(child, prefix, out);
        prefix.pop();
    }
}

fn with(job: &Value, path: &[Seg], value: Value) -> Value {
    let mut job = job.clone();
    let mut at = &mut job;
    for seg in path {
        at = match seg {
            Seg::Key(k) => &mut at[k.as_str()],
            Seg::Index(i) => &mut at[*i],
        };
    }
    *at = value;
    job
}

fn get<'a>(job: &'a Value, path: &[Seg]) -> &'a Value {
    path.iter().fold(job, |at, seg| match seg {
        Seg::Key(k) => &at[k.as_str()],
        Seg::Index(i) => &at[*i],
    })
}

/// The kind of a JSON value, as far as a field's type tells them apart.
fn kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "bool",
        Value::Number(n) if n.is_u64() => "whole",
        Value::Number(n) if n.is_i64() => "negative",
        Value::Number(_) => "fraction",
        Value::String(_) => "string",
        Value::Array(_) => "list",
        Value::Object(_) => "object",
    }
}

/// One value of every kind: those of another kind than a field's are the wrong types tried.
fn every_kind() -> Vec<Value> {
    vec![json!(null), json!(true), json!(7), json!(-1), json!(1.5), json!("text"), json!([]), json!({"wrong": 1})]
}

/// A folder with the data files the fixtures name (two records of 400 rows each, one with a
/// header and one without).
fn data_folder() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let rows: Vec<String> =
        (0..800).map(|i| format!("{},{}", (i % 7) as f64 - 3.0, ((i * 13) % 11) as f64 * 0.1)).collect();
    std::fs::write(dir.path().join("est.csv"), format!("u,y\n{}\n", rows.join("\n"))).unwrap();
    std::fs::write(dir.path().join("raw.csv"), format!("{}\n", rows.join("\n"))).unwrap();
    dir
}

/// Jobs that between them set every field of the job file to a valid value that is not its
/// default (`delay` and `grid.delay` exclude each other; `data` and `validation` are an
/// object in one, a list in the other; `k` a range in one, a list in the other).
/// [`the_fixtures_set_every_field_of_the_job`] checks that no field is left out.
fn fixtures() -> Vec<Value> {
    vec![
        json!({
            "name": "schema",
            "data": {"path": "est.csv", "u": "u", "y": 2, "ts": 0.001, "delimiter": ",", "header": "auto", "rows": [1, 400],
                "missing": ["NA", -999], "interpolate_inputs": 2},
            "validation": {"path": "est.csv", "u": 1, "y": "y", "ts": 0.001, "delimiter": ",", "header": true, "rows": [401, 800],
                "missing": ["n/a"], "interpolate_inputs": 1},
            "offset": "mean",
            "initial_state": "zero",
            "spectrum": "welch",
            "grid": {"nb": [1, 2], "nf": [0, 2], "k": {"from": 0.5, "to": 2.0, "count": 3, "spacing": "linear"}, "delay": [1, 2]},
            "band_hz": [0, 100],
            "solver": {
                "max_iterations": 100, "ftol": 1e-9, "xtol": 1e-9, "gtol": 1e-8, "lambda0": 0.01, "warm_lambda0": 1e-7,
                "huber_hessian": "irls", "huber_tol": 1e-7, "huber_extra_starts": 1, "method": "separable",
                "explore_rows": 0, "nested_starts": false
            },
            "start": "best",
            "selection": {"min_tolerance": 0.01, "fit_tolerance": 0.1, "rule": "paper_m1"},
            "uncertainty": {"method": "bootstrap", "replicates": 50, "seed": 3},
            "output": "out"
        }),
        json!({
            "name": "schema-list",
            "data": [
                {"path": "est.csv", "u": 1, "y": "y", "ts": 0.001, "rows": [1, 400]},
                {"path": "raw.csv", "u": 1, "y": 2, "header": false, "delimiter": ",", "rows": [1, 400]}
            ],
            "validation": [{"path": "est.csv", "rows": [401, 800]}],
            "delay": 2,
            "grid": {"nb": [1, 1], "nf": [1, 1], "k": [0.5, 1.0]},
            "uncertainty": "bootstrap",
            "output": "out"
        }),
    ]
}

/// Parse `job` as the job file `dir/job.json` (written there: the messages name it).
fn parse(dir: &Path, job: &Value) -> Result<oesweep::job::ValidJob, String> {
    let file = dir.join("job.json");
    std::fs::write(&file, serde_json::to_string_pretty(job).unwrap()).unwrap();
    oesweep::job::load(&file).map_err(|e| e.to_string())
}

/// Serde's words a user should never have to read.
const INTERNALS: &[&str] =
    &["usize", "u64", "u32", "f64", "struct ", "untagged", "did not match", "path string", "sequence"];

/// The message of a wrong-typed field: after `prefix`, the field by its path (or a field
/// inside it), and what it accepts. Returns what is wrong with it.
fn check_message(msg: &str, prefix: &str, field: &str) -> Option<String> {
    let head = format!("{prefix}field '{field}");
    let rest = msg.split_once(&head).map(|(_, rest)| rest);
    let named = rest.is_some_and(|r| r.starts_with('\'') || r.starts_with('.') || r.starts_with('['));
    if !named {
        return Some(format!("does not name field '{field}' after '{prefix}'"));
    }
    if !msg.contains("expected ") {
        return Some("does not say what the field accepts ('expected ...')".into());
    }
    if let Some(w) = INTERNALS.iter().find(|w| msg.contains(*w)) {
        return Some(format!("speaks serde ('{w}')"));
    }
    if msg.lines().count() != 1 {
        return Some("is not one line".into());
    }
    None
}

/// Every field of `job` with a value of every other kind: a type the field takes is no error
/// (or a rule's error naming something else), any other is a message as [`check_message`]
/// wants. Every field must refuse at least one kind. Returns the problems.
fn wrong_types(job: &Value, read: &dyn Fn(&Value) -> Result<(), String>, prefix: &str, skip: &[&str]) -> Vec<String> {
    let mut problems = Vec::new();
    let mut all = Vec::new();
    paths(job, &mut Vec::new(), &mut all);
    for path in all {
        let field = show(&path);
        if skip.contains(&field.as_str()) {
            continue;
        }
        let original = get(job, &path);
        let mut refused = 0;
        for wrong in every_kind().into_iter().filter(|w| kind(w) != kind(original)) {
            let Err(msg) = read(&with(job, &path, wrong.clone())) else { continue };
            if !msg.contains(prefix) {
                continue; // a rule of a valid type (a range, a missing file): not this test's
            }
            refused += 1;
            if let Some(what) = check_message(&msg, prefix, &field) {
                problems.push(format!("{field} = {wrong}: the message {what}:\n    {msg}"));
            }
        }
        if refused == 0 {
            problems.push(format!("{field}: no value of another kind was refused as a wrong type"));
        }
    }
    problems
}

#[test]
fn every_field_of_a_job_with_a_wrong_type_is_named_with_what_it_accepts() {
    let dir = data_folder();
    let read = |job: &Value| parse(dir.path(), job).map(|_| ());
    let mut problems = Vec::new();
    for job in fixtures() {
        read(&job).unwrap_or_else(|e| panic!("the fixture is a valid job: {e}"));
        problems.extend(wrong_types(&job, &read, "invalid job: ", &[]));
    }
    assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
}

#[test]
fn every_field_of_a_results_folders_job_json_with_a_wrong_type_is_named_with_what_it_accepts() {
    let dir = data_folder();
    for job in fixtures() {
        let run = parse(dir.path(), &job).unwrap();
        let written = dir.path().join("as-run.json");
        run.write_as_run(&written).unwrap();
        let as_run: Value = serde_json::from_str(&std::fs::read_to_string(&written).unwrap()).unwrap();
        let read = |v: &Value| {
            std::fs::write(&written, v.to_string()).unwrap();
            oesweep::job::read_as_run(&written).map(|_| ()).map_err(|e| e.to_string())
        };
        read(&as_run).unwrap();
        // The format fields are the results folder's, checked by their own rule.
        let problems = wrong_types(
            &as_run,
            &read,
            "not the job.json `oesweep run` writes: ",
            &["format_version", "oesweep_version"],
        );
        assert!(problems.is_empty(), "{} problems:\n{}", problems.len(), problems.join("\n"));
    }
}

/// The field paths of a JSON value, list positions left out (`data.rows`).
fn field_names(v: &Value) -> std::collections::BTreeSet<String> {
    let mut all = Vec::new();
    paths(v, &mut Vec::new(), &mut all);
    all.iter()
        .map(|p| p.iter().filter(|s| matches!(s, Seg::Key(_))).cloned().collect::<Vec<_>>())
        .filter(|p| !p.is_empty())
        .map(|p| show(&p))
        .collect()
}

/// The job as checked and written back names every field of the job file; each must be set by
/// a fixture, so that the walks above reach it.
#[test]
fn the_fixtures_set_every_field_of_the_job() {
    let dir = data_folder();
    let mut set = std::collections::BTreeSet::new();
    let mut schema = std::collections::BTreeSet::new();
    for job in fixtures() {
        set.extend(field_names(&job));
        schema.extend(field_names(&serde_json::to_value(&parse(dir.path(), &job).unwrap().job).unwrap()));
    }
    let missing: Vec<_> = schema.difference(&set).collect();
    assert!(missing.is_empty(), "fields no fixture sets: {missing:?}");
}

/// `name` (written with `_`, never `-`: checked where it is used) in its other spelling.
fn other(name: &str) -> String {
    name.replace('_', "-")
}

/// The names serde's unknown-variant message lists (`expected one of `a`, `b``).
fn listed_names(msg: &str) -> Option<Vec<String>> {
    let (_, list) = msg.split_once("unknown variant `no-such-name`, expected ")?;
    Some(list.split('`').skip(1).step_by(2).map(str::to_string).collect())
}

#[test]
fn every_enum_field_of_a_job_reads_both_spellings_and_writes_one() {
    let dir = data_folder();
    let normalised = |job: &Value| parse(dir.path(), job).map(|v| serde_json::to_value(&v.job).unwrap());
    let mut enums = std::collections::BTreeSet::new();
    for job in fixtures() {
        let mut all = Vec::new();
        paths(&job, &mut Vec::new(), &mut all);
        for path in all.iter().filter(|p| get(&job, p).is_string()) {
            let field = show(path);
            let Err(msg) = normalised(&with(&job, path, json!("no-such-name"))) else { continue };
            let Some(names) = listed_names(&msg) else {
                // Fields of text that are not names of an enum.
                assert!(
                    ["delimiter", "header", "path"].iter().any(|f| field.ends_with(f)),
                    "{field} refuses a name but is no enum of names!: {msg}"
                );
                continue;
            };
            enums.insert(field.clone());
            for name in names {
                assert!(!name.contains('-'), "{field}: the written spelling joins words with '_': {name}");
                let listed = normalised(&with(&job, path, json!(name)));
                let spelt = normalised(&with(&job, path, json!(other(&name))));
                assert_eq!(spelt, listed, "{field}: '{}' reads as '{name}' does", other(&name));
                // As written back (a k range is written as its list, without `spacing`; the
                // string form of `uncertainty` as the object).
                if let Some(written) = listed.as_ref().ok().and_then(|v| get(v, path).as_str()) {
                    assert_eq!(written, name, "{field}: written as listed");
                }
            }
        }
    }
    // The enums a job has today, found by the walk (a new one is found too).
    for f in ["offset", "initial_state", "spectrum", "start", "solver.huber_hessian", "solver.method", "selection.rule"]
    {
        assert!(enums.contains(f), "the walk found no enum at {f}: {enums:?}");
    }
}

#[test]
fn every_enum_argument_of_the_command_line_reads_both_spellings_and_shows_one() {
    use clap::{CommandFactory, Parser};
    let root = oesweep::cli::Cli::command();
    let mut checked = std::collections::BTreeSet::new();
    let mut stack = vec![root.clone()];
    while let Some(cmd) = stack.pop() {
        stack.extend(cmd.get_subcommands().cloned());
        // Flags (`--json`) list true and false, which are no names.
        for arg in cmd.get_arguments().filter(|a| a.get_action().takes_values()) {
            for value in arg.get_possible_values() {
                let name = value.get_name();
                assert!(!name.contains('-'), "--{}: shows {name}, not the job's spelling", arg.get_id());
                for given in [name.to_string(), other(name)] {
                    // The subcommand with this argument alone: its other required ones let go.
                    let alone = cmd.clone().mut_args(|a| a.required(false));
                    let mut argv = vec![cmd.get_name().to_string()];
                    argv.extend(arg.get_long().map(|l| format!("--{l}")));
                    argv.push(given.clone());
                    let parsed = alone.try_get_matches_from(argv);
                    assert!(parsed.is_ok(), "{} --{} {given}: {}", cmd.get_name(), arg.get_id(), parsed.unwrap_err());
                }
                checked.insert(format!("{} --{}", cmd.get_name(), arg.get_long().unwrap_or_default()));
            }
        }
    }
    // The enum arguments today, found by the walk (a new one is found too).
    for flag in [
        "fit --spectrum",
        "fit --offset",
        "fit --initial-state",
        "fit --huber-hessian",
        "fit --method",
        "spectrum --method",
        "export --to",
        "export --continuous",
    ] {
        assert!(checked.contains(flag), "the walk found no names at {flag}: {checked:?}");
    }
    // `--huber-hessian` end to end: the flag's default and both spellings are one setting.
    let parse = |extra: &[&str]| {
        let mut argv = vec!["oesweep", "fit", "--data", "d.csv", "--nb", "1", "--nf", "1", "--k", "1"];
        argv.extend(extra);
        match oesweep::cli::Cli::try_parse_from(argv).unwrap().command {
            oesweep::cli::Command::Fit(a) => a.huber_hessian,
            _ => unreachable!(),
        }
    };
    assert_eq!(parse(&[]), parse(&["--huber-hessian", "gauss-newton"]));
    assert_eq!(parse(&[]), parse(&["--huber-hessian", "gauss_newton"]));
    // `--pick` takes the rules by name (no possible values for clap to list): both spellings.
    for rule in ["paper_m1", "paper_m2", "rbic"] {
        let a: oesweep::engine::PickSpec = rule.parse().unwrap();
        assert_eq!(other(rule).parse::<oesweep::engine::PickSpec>().unwrap(), a, "--pick {}", other(rule));
    }
}

/// A one-record and a two-record job of 8 cells each on a simulated record: the summary's
/// pick lines carry the name of the column that ranked them.
#[test]
fn the_summary_names_the_fit_it_ranks_by() {
    let dir = tempfile::tempdir().unwrap();
    let noise = common::Noise { amplitude: 1.0, std: 0.02, spike_probability: 0.0, spike_range: "1,2" };
    let system = dir.path().join("system.json");
    let (b, f) = common::oe22();
    std::fs::write(&system, json!({"b": b, "f": f, "delay": 1}).to_string()).unwrap();
    common::simulate(&system, &dir.path().join("d.csv"), 2000, 3, &noise);
    let grid = json!({"nb": [1, 2], "nf": [1, 2], "k": [0.5, 1.0]});
    let cases: [(Value, &str); 2] = [
        (
            json!({"name": "v", "data": {"path": "d.csv", "ts": 1.0, "rows": [1, 1500]},
                "validation": {"rows": [1501, 2000]}, "grid": grid, "output": "out-v"}),
            "fit_val",
        ),
        (json!({"name": "e", "data": {"path": "d.csv", "ts": 1.0}, "grid": grid, "output": "out-e"}), "fit"),
    ];
    for (job, column) in cases {
        let file: PathBuf = dir.path().join(format!("{}.json", job["name"].as_str().unwrap()));
        std::fs::write(&file, job.to_string()).unwrap();
        let o = common::run_oesweep(
            dir.path(),
            &["run", file.to_str().unwrap(), "--quiet"],
            std::time::Duration::from_secs(300),
        );
        assert_eq!(o.code, Some(0), "{}", o.stderr);
        let lines: Vec<&str> = o
            .stdout
            .lines()
            .filter(|l| l.starts_with("M1 ") || l.starts_with("M2 ") || l.starts_with("pick "))
            .collect();
        assert_eq!(lines.len(), 3, "{}", o.stdout);
        for l in lines {
            for other in ["fit", "fit_val", "fit_band"] {
                assert_eq!(l.contains(&format!("  {other} = ")), other == column, "ranked by {column}: {l}");
            }
        }
    }
}

/// Through the command line: exit code 2, one line naming the file, the field and what it takes.
#[test]
fn a_wrong_type_through_plan_is_exit_2_naming_the_field() {
    let dir = data_folder();
    let job = with(&fixtures()[0], &[Seg::Key("data".into()), Seg::Key("u".into())], json!(true));
    std::fs::write(dir.path().join("job.json"), serde_json::to_string_pretty(&job).unwrap()).unwrap();
    let o = common::run_oesweep(dir.path(), &["plan", "job.json"], std::time::Duration::from_secs(60));
    assert_eq!(o.code, Some(2), "{}", o.stderr);
    assert_eq!(o.stderr.lines().count(), 1, "{}", o.stderr);
    assert!(
        o.stderr.contains("job.json: invalid job: field 'data.u': invalid type: boolean `true`, expected a column name or a 1-based column index at line"),
        "{}",
        o.stderr
    );
}
