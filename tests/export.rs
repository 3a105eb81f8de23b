//! `oesweep export`: a finished run's models as JSON (python-control, scipy), a MATLAB script
//! and a MAT-file, by rule or by cell, with the covariance the run computed.

mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn oesweep(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).args(args).output().expect("oesweep runs")
}

/// A small finished run of an OE(2,2) system with spikes: its results folder.
fn finished_run(dir: &Path) -> PathBuf {
    let (b, f) = oe22();
    let u = binary_input(1500, 3, 1.0, 21);
    let mut rng = Lcg(4);
    let y: Vec<f64> = oesweep::oe::simulate_vec(&b, &f, 1, &u)
        .iter()
        .map(|v| v + 0.05 * rng.normal() + if rng.next() < 0.05 { 2.0 } else { 0.0 } + 0.3)
        .collect();
    let mut csv = String::from("u,y\n");
    for (a, b) in u.iter().zip(&y) {
        csv.push_str(&format!("{a},{b}\n"));
    }
    std::fs::write(dir.join("data.csv"), csv).unwrap();
    let job = serde_json::json!({
        "name": "export",
        "data": { "path": "data.csv", "u": "u", "y": "y", "ts": 0.01 },
        "grid": { "nb": [1, 3], "nf": [1, 3], "k": [0.5, 1.5] },
        // One record leads with rbic by default; the job names the paper's rule, whose pick
        // selection.json keeps with its covariance.
        "selection": { "rule": "paper_m2" },
        "output": "out"
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let o = oesweep(&["run", dir.join("job.json").to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    dir.join("out")
}

fn json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn the_lead_pick_leaves_as_json_mat_and_matlab_with_the_runs_covariance() {
    let dir = tempfile::tempdir().unwrap();
    let out = finished_run(dir.path());
    let folder = out.to_str().unwrap();
    let sel: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("selection.json")).unwrap()).unwrap();
    let m2 = &sel["m2"];

    assert_eq!(sel["rule"], "paper_m2");
    assert!(sel["rule_why"].as_str().unwrap().contains("named by the job"), "{}", sel["rule_why"]);
    // JSON: the lead rule (the job's paper_m2) by default, num/den/dt as python-control takes them.
    let j = json(&oesweep(&["export", folder, "--to", "json"]));
    assert_eq!(j["b"], m2["b"]);
    assert_eq!(j["f"], m2["f"]);
    assert_eq!(j["dt"], 0.01);
    assert_eq!(j["offset"], m2["offset"]);
    let (b, f) = (j["b"].as_array().unwrap().len(), j["f"].as_array().unwrap().len());
    assert_eq!(j["den"][0], 1.0);
    assert_eq!(j["num"][0], 0.0, "delay 1: a leading zero");
    assert_eq!(j["num"][1], m2["b"][0]);
    // The covariance selection.json holds, as rows; over b, f and the estimated offset.
    let cov: Vec<f64> = j["covariance"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|r| r.as_array().unwrap().clone())
        .map(|v| v.as_f64().unwrap())
        .collect();
    let stored: Vec<f64> = m2["covariance"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(cov, stored);
    assert_eq!(j["parameters"].as_array().unwrap().len(), b + f + 1);

    // MAT: read back with another reader, the same B (with the delay's zero), F, covariance.
    let mat_path = dir.path().join("m2.mat");
    let o = oesweep(&["export", folder, "--pick", "m2", "--to", "mat", "--out", mat_path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mat = matfile::MatFile::parse(std::fs::File::open(&mat_path).unwrap()).unwrap();
    let get = |name: &str| -> Vec<f64> {
        match mat.find_by_name(name).unwrap_or_else(|| panic!("no {name}")).data() {
            matfile::NumericData::Double { real, .. } => real.clone(),
            other => panic!("{name}: {other:?}"),
        }
    };
    let mut big_b = vec![0.0];
    big_b.extend(m2["b"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()));
    assert_eq!(get("B"), big_b);
    assert_eq!(get("F")[0], 1.0);
    assert_eq!(&get("F")[1..], &j["f"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect::<Vec<_>>()[..]);
    assert_eq!(get("covariance"), stored);
    assert_eq!(get("Ts"), vec![0.01]);

    // MATLAB: the script defines what it builds the tf from.
    let o = oesweep(&["export", folder, "--to", "matlab"]);
    let script = String::from_utf8_lossy(&o.stdout);
    assert!(script.contains("G = tf(num, den, Ts);") && script.contains("idpoly(1, B, 1, 1, F,"), "{script}");
}

#[test]
fn any_rule_or_cell_leaves_with_a_covariance_computed_from_the_records() {
    let dir = tempfile::tempdir().unwrap();
    let out = finished_run(dir.path());
    let folder = out.to_str().unwrap();
    let j = json(&oesweep(&["export", folder, "--pick", "rbic", "--to", "json"]));
    let n = j["parameters"].as_array().unwrap().len();
    assert_eq!(j["covariance"].as_array().unwrap().len(), n, "{j}");
    assert!(j["model"].as_str().unwrap().contains("picked by rbic"));
    // A cell by its orders and k, and the least-squares fit of a structure.
    let j = json(&oesweep(&["export", folder, "--pick", "2,2,1.5", "--to", "json"]));
    assert_eq!((j["k"].as_f64(), j["b"].as_array().unwrap().len()), (Some(1.5), 2));
    let j = json(&oesweep(&["export", folder, "--pick", "2,2,ls,1", "--to", "json"]));
    assert!(j["k"].is_null() && j["covariance"].is_array(), "{j}");

    // Errors: one line, exit 2, nothing written.
    let target = dir.path().join("x.mat");
    for args in [
        vec!["export", folder, "--pick", "2,2,0.7", "--to", "json"],
        vec!["export", folder, "--pick", "bogus", "--to", "json"],
        vec!["export", folder, "--to", "mat"],
        vec!["export", "/nonexistent/folder", "--to", "mat", "--out", target.to_str().unwrap()],
    ] {
        let o = oesweep(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
        assert!(o.stdout.is_empty() && !target.exists(), "{args:?}");
    }
}

/// `--continuous zoh|tustin`: the continuous equivalent beside the discrete model, in every
/// format, the same numbers as the library's; a pick with no ZOH equivalent is one line, exit
/// 2 and no file.
#[test]
fn continuous_equivalents_leave_with_the_model() {
    use oesweep::export::continuous::{Method, to_continuous};
    let dir = tempfile::tempdir().unwrap();
    let out = finished_run(dir.path());
    let folder = out.to_str().unwrap();
    for method in [Method::Zoh, Method::Tustin] {
        let j = json(&oesweep(&["export", folder, "--to", "json", "--continuous", method.as_str()]));
        let floats =
            |v: &serde_json::Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect() };
        let want = to_continuous(&floats(&j["num"]), &floats(&j["den"]), 0.01, method).unwrap();
        let c = &j["continuous"];
        assert_eq!(c["method"], method.as_str());
        assert_eq!(floats(&c["num"]), want.num);
        assert_eq!(floats(&c["den"]), want.den);
        assert_eq!(c["den"][0], 1.0);
        // The zeros, poles and gain, as [re, im] pairs, and the state space.
        let pairs = |v: &serde_json::Value| -> Vec<(f64, f64)> {
            v.as_array().unwrap().iter().map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap())).collect()
        };
        assert_eq!((pairs(&c["zeros"]), pairs(&c["poles"])), (want.zeros.clone(), want.poles.clone()));
        assert_eq!(c["gain"].as_f64(), Some(want.gain));
        assert_eq!(floats(&c["state_space"]["b"]), want.state_space.b);
        // Delay 1 is the hold's own sample: no dead time.
        assert_eq!((c["delay_samples"].as_u64(), c["input_delay"].as_f64()), (Some(0), Some(0.0)), "{c}");
        // The discrete document is unchanged.
        let plain = json(&oesweep(&["export", folder, "--to", "json"]));
        let mut without = j.clone();
        without.as_object_mut().unwrap().remove("continuous");
        assert_eq!(without, plain);

        let o = oesweep(&["export", folder, "--to", "matlab", "--continuous", method.as_str()]);
        let script = String::from_utf8_lossy(&o.stdout);
        assert!(script.contains("Gc = tf(numc, denc, 'InputDelay', input_delay);"), "{script}");
        assert!(script.contains("Gz = zpk(zc, pc, kc, 'InputDelay', input_delay);"), "{script}");
        assert!(script.contains(&format!("continuous-time equivalent ({method})")), "{script}");

        let mat_path = dir.path().join(format!("{method}.mat"));
        let o = oesweep(&[
            "export",
            folder,
            "--to",
            "mat",
            "--continuous",
            method.as_str(),
            "--out",
            mat_path.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let mat = matfile::MatFile::parse(std::fs::File::open(&mat_path).unwrap()).unwrap();
        match mat.find_by_name("denc").expect("denc").data() {
            matfile::NumericData::Double { real, .. } => assert_eq!(real, &want.den),
            other => panic!("denc: {other:?}"),
        }
        // The poles one a row, real and imaginary part (column-major: the real parts first).
        let poles: Vec<f64> = want.poles.iter().map(|p| p.0).chain(want.poles.iter().map(|p| p.1)).collect();
        let pc = mat.find_by_name("pc").expect("pc");
        assert_eq!(pc.size(), &[want.poles.len(), 2]);
        match pc.data() {
            matfile::NumericData::Double { real, .. } => assert_eq!(real, &poles),
            other => panic!("pc: {other:?}"),
        }
    }

    // Every cell of the table whose model has no ZOH equivalent is refused, and every other one
    // leaves: a real pole below zero, or (delay 1) nB > nF + 1, more B than the poles hold,
    // which leaves poles at the origin beyond the delay.
    let rows = oesweep::results::read_results(&out).unwrap().rows;
    let mut refused = 0;
    for r in rows.iter().filter(|r| r.ok() && r.k.is_some()) {
        let pick = format!("{},{},{}", r.key.nb, r.key.nf, r.k.unwrap());
        let target = dir.path().join("c.json");
        let o = oesweep(&[
            "export",
            folder,
            "--pick",
            &pick,
            "--to",
            "json",
            "--continuous",
            "zoh",
            "--out",
            target.to_str().unwrap(),
        ]);
        let negative = oesweep::oe::poles(&r.fit.f).iter().any(|&(re, im)| re < 0.0 && im.abs() <= 1e-4 * re.hypot(im));
        let at_origin = r.key.nb > r.key.nf + 1;
        if negative || at_origin {
            refused += 1;
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(2), "{pick}: {err}");
            let why = if at_origin { "origin" } else { "negative real axis" };
            assert!(err.contains("--continuous zoh") && err.contains(why), "{err}");
            assert_eq!(err.lines().count(), 1, "{err}");
            assert!(!target.exists());
        } else {
            assert!(o.status.success(), "{pick}: {}", String::from_utf8_lossy(&o.stderr));
            std::fs::remove_file(&target).unwrap();
        }
    }
    assert!(refused > 0 && refused < rows.len(), "{refused} of {} refused", rows.len());
    let o = oesweep(&["export", folder, "--to", "json", "--continuous", "foh"]);
    assert_eq!(o.status.code(), Some(2));
}
