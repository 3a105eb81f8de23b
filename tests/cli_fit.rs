//! `oesweep fit` and `oesweep simulate` driven as a user would: the binary, files, exit codes.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("binary runs")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// System file for the simulator: our OE(2,2) test system.
fn system_file(dir: &Path) -> PathBuf {
    let (b, f) = common::oe22();
    write(dir, "sys.json", &serde_json::json!({"b": b, "f": f, "delay": 1}).to_string())
}

#[test]
fn simulate_then_fit_json_reports_every_field() {
    let dir = tempfile::tempdir().unwrap();
    let sys = system_file(dir.path());
    let est = dir.path().join("est.csv");
    let val = dir.path().join("val.csv");
    for (out, seed) in [(&est, "1"), (&val, "2")] {
        let o = oesweep(&[
            "simulate",
            "--system",
            sys.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--n",
            "3000",
            "--seed",
            seed,
            "--noise-std",
            "0.05",
            "--outlier-prob",
            "0.05",
            "--outlier-range",
            "2,5",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = oesweep(&[
        "fit",
        "--data",
        est.to_str().unwrap(),
        "--validation",
        val.to_str().unwrap(),
        "--nb",
        "2",
        "--nf",
        "2",
        "--k",
        "0.1",
        "--ts",
        "1e-4",
        "--band",
        "0,2000",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("one JSON object");
    for key in [
        "nb",
        "nf",
        "delay",
        "k",
        "sigma",
        "gamma",
        "criterion",
        "l1c",
        "fit",
        "fit_val",
        "fit_band",
        "iterations",
        "termination",
        "max_pole_radius",
        "b",
        "f",
        "ls",
    ] {
        assert!(v.get(key).is_some(), "missing field {key} in {v}");
    }
    for key in ["criterion", "fit", "fit_val", "b", "f"] {
        assert!(v["ls"].get(key).is_some(), "missing ls.{key}");
    }
    assert_eq!(v["validation_column"], "y0");
    assert!(v["fit_val"].as_f64().unwrap() > 99.0, "{v}");
    assert!(v["fit_band"].as_f64().is_some());
    assert!((v["gamma"].as_f64().unwrap() - 0.1 * v["sigma"].as_f64().unwrap()).abs() < 1e-12);
    // Without validation or band the fields are null, not missing.
    let o = oesweep(&["fit", "--data", est.to_str().unwrap(), "--nb", "2", "--nf", "2", "--k", "1", "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(v["fit_val"].is_null() && v["fit_band"].is_null() && v["ls"]["fit_val"].is_null());
    // Human-readable summary by default.
    let o = oesweep(&["fit", "--data", est.to_str().unwrap(), "--nb", "2", "--nf", "2", "--k", "1"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("least squares") && text.contains("termination"), "{text}");
}

/// Every bad input gives exit 2 and one message naming the file and the problem.
#[test]
fn bad_inputs_give_exit_2_and_a_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let good: String = std::iter::once("u,y".to_string())
        .chain((0..200).map(|t| format!("{},{}", if (t / 3) % 2 == 0 { 1.0 } else { -1.0 }, (t as f64 * 0.1).sin())))
        .collect::<Vec<_>>()
        .join("\n");
    let good_p = write(d, "good.csv", &good);
    let cases: Vec<(PathBuf, Vec<&str>, &str)> = vec![
        (d.join("missing.csv"), vec![], "cannot open file"),
        (write(d, "nocol.csv", "t,y\n1,2\n"), vec![], "no column 'u'"),
        (write(d, "text.csv", &good.replacen("\n1,", "\nabc,", 1)), vec![], "'abc' is not a number"),
        (
            write(
                d,
                "allnan.csv",
                &good
                    .lines()
                    .enumerate()
                    .map(|(i, l)| if i == 0 { l.to_string() } else { format!("{},NaN", l.split(',').next().unwrap()) })
                    .collect::<Vec<_>>()
                    .join("\n"),
            ),
            vec![],
            "every output of column 'y' is missing",
        ),
        (good_p.clone(), vec!["--interpolate-inputs", "5000"], "--interpolate-inputs"),
        (write(d, "inf.csv", &good.replacen("\n1,", "\ninf,", 1)), vec![], "infinite"),
        (write(d, "short.csv", "u,y\n1,0\n-1,1\n1,0\n"), vec![], "too few"),
        (
            write(
                d,
                "const.csv",
                &good
                    .lines()
                    .enumerate()
                    .map(|(i, l)| if i == 0 { l.to_string() } else { format!("2,{}", l.split(',').nth(1).unwrap()) })
                    .collect::<Vec<_>>()
                    .join("\n"),
            ),
            vec![],
            "constant",
        ),
        (good_p.clone(), vec!["--band", "0,100"], "--band needs --ts"),
        (good_p.clone(), vec!["--k=-1"], "--k must be positive"),
    ];
    for (path, extra, needle) in cases {
        let mut args = vec!["fit", "--data", path.to_str().unwrap(), "--nb", "2", "--nf", "2"];
        if !extra.iter().any(|e| e.starts_with("--k")) {
            args.extend(["--k", "0.5"]);
        }
        args.extend(extra.iter().copied());
        let o = oesweep(&args);
        let msg = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{path:?}: {msg}");
        assert!(msg.contains(needle), "{path:?}: expected '{needle}' in: {msg}");
        if !needle.starts_with("--") {
            assert!(msg.contains(path.file_name().unwrap().to_str().unwrap()), "file not named: {msg}");
        }
        assert_eq!(msg.trim().lines().count(), 1, "one line expected: {msg}");
    }
}

/// The command line run in-process (the Python package's `oesweep` command) gives the binary's
/// exit codes, `--help` and usage errors included, and returns rather than exits.
#[test]
fn the_command_line_in_process_returns_the_binarys_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let sys = system_file(dir.path());
    let data = dir.path().join("d.csv");
    let (sys, data) = (sys.to_str().unwrap(), data.to_str().unwrap());
    let cases: [(&[&str], u8); 5] = [
        (&["--help"], 0),
        (&["fit", "--nb", "2"], 2),
        (&["fit", "--data", "missing.csv", "--nb", "2", "--nf", "2", "--k", "1"], 2),
        (&["simulate", "--system", sys, "--out", data, "--n", "300"], 0),
        (&["fit", "--data", data, "--nb", "2", "--nf", "2", "--k", "1", "--json"], 0),
    ];
    for (args, code) in cases {
        let argv = std::iter::once("oesweep").chain(args.iter().copied());
        assert_eq!(oesweep::cli::main_with_args(argv), code, "{args:?}");
        assert_eq!(oesweep(args).status.code(), Some(i32::from(code)), "{args:?}");
    }
}

/// `fit` reads a record with gaps as a run does (METHOD.md 21): a job's marker given as
/// `--missing`, the input gap cut, the counts in `--json` and the summary.
#[test]
fn fit_reads_missing_samples_and_reports_their_counts() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 600;
    let u: Vec<f64> = (0..n).map(|t| if (t / 3 + t / 7) % 2 == 0 { 1.0 } else { -1.0 }).collect();
    let y = oesweep::oe::simulate_vec(&[0.5, 0.3], &[-1.2, 0.5], 1, &u);
    let lines: Vec<String> = (0..n)
        .map(|t| {
            let u = if t == 300 { String::new() } else { u[t].to_string() };
            let y = if (100..110).contains(&t) {
                "-999".to_string()
            } else {
                (y[t] + 0.01 * ((t * 7919) % 13) as f64).to_string()
            };
            format!("{u},{y}")
        })
        .collect();
    let path = write(d, "gappy.csv", &format!("u,y\n{}\n", lines.join("\n")));
    let args = ["fit", "--data", path.to_str().unwrap(), "--nb", "2", "--nf", "2", "--k", "1", "--missing", "-999"];
    let o = oesweep(&[&args[..], &["--json"]].concat());
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let g = &v["gaps"]["data"];
    assert_eq!((g["rows"].as_u64(), g["samples"].as_u64()), (Some(600), Some(599)), "{g}");
    assert_eq!(
        (g["outputs_missing"].as_u64(), g["rows_cut"].as_u64(), g["segments"].as_u64()),
        (Some(10), Some(1), Some(2))
    );
    assert_eq!(v["n"].as_u64(), Some(599));
    let b = v["b"].as_array().unwrap();
    assert!((b[0].as_f64().unwrap() - 0.5).abs() < 0.05, "{b:?}");
    // Without the marker, -999 is a number: the record is read whole and fitted badly.
    let o = oesweep(&args[..args.len() - 2]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = oesweep(&args);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("gaps       data: 599 of 600 rows fitted: 10 outputs missing"), "{out}");
}
