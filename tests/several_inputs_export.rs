//! The export and the report of a several-input run (issue 46, landing 5): `oesweep export`
//! writes MATLAB's MISO `idpoly` (B, F cell arrays with each input's numbers of selection.json),
//! per-input `num`/`den` for python-control and scipy that simulate the model, each input's
//! continuous equivalent (its frequency response that of the input's discrete filter), a cell
//! named per input; `oesweep report` draws one Bode plot per pick and input and a heat map per
//! input. Octave builds the 1 x 2 `tf` and reads the MAT-file's cell arrays where it is installed.

mod common;

use common::*;
use oesweep::export::continuous::Method;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Per input (b, f, delay): a second-order input with delay 1 and a first-order one with
/// delay 0, poles on the positive real axis (so both have a ZOH equivalent).
fn system() -> Vec<(Vec<f64>, Vec<f64>, usize)> {
    vec![(vec![0.5, 0.3], vec![-1.2, 0.35], 1), (vec![0.8], vec![-0.6], 0)]
}

fn oesweep(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).current_dir(dir).args(args).output().expect("oesweep runs")
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A finished run of two inputs with low noise and a few spikes, on a small product grid.
fn finished_run(dir: &Path) -> PathBuf {
    let n = 1200;
    let us: Vec<Vec<f64>> = (0..2).map(|i| binary_input(n, 3 + 2 * i, 1.0, 31 + i as u64)).collect();
    let mut y = vec![0.0; n];
    for (u, (b, f, d)) in us.iter().zip(system()) {
        for (t, v) in oesweep::oe::simulate_vec(&b, &f, d, u).into_iter().enumerate() {
            y[t] += v;
        }
    }
    let mut rng = Lcg(9);
    let mut csv = String::from("u,v,y\n");
    for t in 0..n {
        let e = 0.02 * rng.normal() + if t % 89 == 7 { 1.0 } else { 0.0 };
        csv.push_str(&format!("{},{},{}\n", us[0][t], us[1][t], y[t] + e));
    }
    std::fs::write(dir.join("d.csv"), csv).unwrap();
    let job = serde_json::json!({
        "name": "two inputs", "data": {"path": "d.csv", "u": ["u", "v"], "y": "y", "ts": 0.1, "rows": [1, 900]},
        "validation": {"rows": [901, 1200]},
        "grid": {"nb": [[1, 2], [1, 1]], "nf": [[1, 2], [1, 2]], "k": [1.0, 2.0]}, "delay": [1, 0], "output": "out"
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    ok(&oesweep(dir, &["run", "job.json", "--quiet"]));
    dir.join("out")
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().unwrap_or_else(|| panic!("not a list: {v}")).iter().map(|x| x.as_f64().unwrap()).collect()
}

/// `den(q) y = num(q) u` as a difference equation (scipy's `lfilter`).
fn lfilter(num: &[f64], den: &[f64], u: &[f64]) -> Vec<f64> {
    let mut y = vec![0.0; u.len()];
    for t in 0..u.len() {
        let mut v: f64 = num.iter().enumerate().filter(|(i, _)| t >= *i).map(|(i, c)| c * u[t - i]).sum();
        v -= den.iter().enumerate().skip(1).filter(|(i, _)| t >= *i).map(|(i, c)| c * y[t - i]).sum::<f64>();
        y[t] = v;
    }
    y
}

/// The discrete `num(z)/den(z)` at z = e^{j w} (polynomials in descending powers of z, of one
/// length, so in powers of z^-1 as well): (re, im).
fn discrete_response(num: &[f64], den: &[f64], w: f64) -> (f64, f64) {
    let at = |p: &[f64]| {
        p.iter()
            .enumerate()
            .fold((0.0, 0.0), |(re, im), (i, c)| (re + c * (-w * i as f64).cos(), im + c * (-w * i as f64).sin()))
    };
    let ((a, b), (c, d)) = (at(num), at(den));
    let m = c * c + d * d;
    ((a * c + b * d) / m, (b * c - a * d) / m)
}

/// |num(j w)/den(j w)| of a continuous model (descending powers of s; its dead time has
/// magnitude 1).
fn continuous_gain((num, den): (&[f64], &[f64]), w: f64) -> f64 {
    let at = |p: &[f64]| {
        let n = p.len() - 1;
        p.iter().enumerate().fold((0.0f64, 0.0f64), |(re, im), (i, v)| {
            // (j w)^(n - i)
            let k = (n - i) % 4;
            let m = v * w.powi((n - i) as i32);
            match k {
                0 => (re + m, im),
                1 => (re, im + m),
                2 => (re - m, im),
                _ => (re, im - m),
            }
        })
    };
    let ((a, b), (c, d)) = (at(num), at(den));
    a.hypot(b) / c.hypot(d)
}

#[test]
fn a_two_input_pick_leaves_per_input_in_every_form_and_the_report_draws_each_input() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().canonicalize().unwrap();
    let out = finished_run(&root);
    let sel: Value = serde_json::from_str(&std::fs::read_to_string(out.join("selection.json")).unwrap()).unwrap();
    let rule = sel["rule"].as_str().unwrap().to_string();
    let pick = &sel["picks"][&rule]["model"];
    let (b_sel, f_sel) = (&pick["b"], &pick["f"]);
    assert_eq!(b_sel.as_array().map(Vec::len), Some(2), "one b per input in selection.json: {pick}");

    // JSON: one entry per input, the numbers of selection.json's pick.
    let j: Value = serde_json::from_str(&ok(&oesweep(&root, &["export", "out", "--to", "json"]))).unwrap();
    assert_eq!((&j["b"], &j["f"]), (b_sel, f_sel), "{j}");
    assert_eq!(j["delay"], serde_json::json!([1, 0]));
    assert_eq!(j["input_level"].as_array().map(Vec::len), Some(2));
    assert_eq!(j["parameters"][0], "u1.b1");
    let np = j["parameters"].as_array().unwrap().len();
    assert_eq!(j["covariance"].as_array().map(Vec::len), Some(np), "the run's covariance, one row per parameter");
    // Each input's num/den simulate its filter; their sum is the model's output.
    let u: Vec<f64> = binary_input(300, 3, 1.0, 5);
    let v: Vec<f64> = binary_input(300, 4, 1.0, 6);
    let (b, f, delay) = (&j["b"], &j["f"], &j["delay"]);
    for (i, x) in [&u, &v].into_iter().enumerate() {
        let (num, den) = (floats(&j["num"][i]), floats(&j["den"][i]));
        assert_eq!(num.len(), den.len());
        let want = oesweep::oe::simulate_vec(&floats(&b[i]), &floats(&f[i]), delay[i].as_u64().unwrap() as usize, x);
        for (a, w) in lfilter(&num, &den, x).iter().zip(&want) {
            assert!((a - w).abs() < 1e-12, "input {i}: {a} against {w}");
        }
    }

    // MATLAB: the MISO idpoly of the same numbers, one cell per input.
    let script = ok(&oesweep(&root, &["export", "out", "--to", "matlab"]));
    let cell_of = |name: &str| -> Vec<Vec<f64>> {
        let line =
            script.lines().find(|l| l.starts_with(&format!("{name} = {{"))).unwrap_or_else(|| panic!("{script}"));
        let inner = line.trim_start_matches(&format!("{name} = {{")).trim_end_matches("};");
        inner
            .split("], [")
            .map(|p| p.trim_matches(|c| c == '[' || c == ']').split(", ").map(|x| x.parse::<f64>().unwrap()).collect())
            .collect()
    };
    let per_input = |v: &Value| -> Vec<Vec<f64>> { v.as_array().unwrap().iter().map(floats).collect() };
    assert_eq!(cell_of("b"), per_input(b_sel), "{script}");
    let with_one: Vec<Vec<f64>> = per_input(f_sel).into_iter().map(|f| [vec![1.0], f].concat()).collect();
    assert_eq!(cell_of("F"), with_one, "{script}");
    for want in ["nk = [1, 0];", "G = tf(num, den, Ts); % 1 x 2", "sys = idpoly(1, B, 1, 1, F, ", "order = ["] {
        assert!(script.contains(want), "{want} in:\n{script}");
    }

    // --continuous: each input converted on its own (the true orders' cell, whose poles lie on
    // the positive real axis); Tustin's response at the warped frequency is the discrete one's,
    // ZOH keeps the gain at 0 Hz and follows it at low frequencies.
    let true_orders = ["--pick", "2/1,2/1,1"];
    let plain = ok(&oesweep(&root, &[&["export", "out", "--to", "json"][..], &true_orders].concat()));
    let plain: Value = serde_json::from_str(&plain).unwrap();
    for method in [Method::Tustin, Method::Zoh] {
        let args = [&["export", "out", "--to", "json", "--continuous", method.as_str()][..], &true_orders].concat();
        let cj: Value = serde_json::from_str(&ok(&oesweep(&root, &args))).unwrap();
        let list = cj["continuous"].as_array().unwrap_or_else(|| panic!("one per input: {cj}"));
        assert_eq!(list.len(), 2);
        for (i, c) in list.iter().enumerate() {
            let (numc, denc) = (floats(&c["num"]), floats(&c["den"]));
            let (num, den) = (floats(&plain["num"][i]), floats(&plain["den"][i]));
            let ts = 0.1;
            for hz in [0.01, 0.1, 0.5, 1.0, 3.0] {
                let w = 2.0 * std::f64::consts::PI * hz * ts;
                let (re, im) = discrete_response(&num, &den, w);
                let g = re.hypot(im);
                let (gc, tol) = match method {
                    Method::Tustin => (continuous_gain((&numc, &denc), 2.0 / ts * (w / 2.0).tan()), 1e-9),
                    _ => (continuous_gain((&numc, &denc), w / ts), if hz <= 0.1 { 0.01 } else { f64::INFINITY }),
                };
                assert!((gc / g - 1.0).abs() < tol, "{method} input {i} at {hz} Hz: {gc} against {g}");
            }
            let dc = discrete_response(&num, &den, 0.0).0;
            let gain0 = continuous_gain((&numc, &denc), 0.0);
            assert!((gain0 / dc.abs() - 1.0).abs() < 1e-9, "{method} input {i}: gain at 0 Hz {gain0} against {dc}");
        }
        // The discrete document is the same without --continuous.
        let mut without = cj.clone();
        without.as_object_mut().unwrap().remove("continuous");
        assert_eq!(without, plain);
        let args = [&["export", "out", "--to", "matlab", "--continuous", method.as_str()][..], &true_orders].concat();
        let script = ok(&oesweep(&root, &args));
        assert!(script.contains("Gc = tf(numc, denc, 'InputDelay', input_delay);"), "{script}");
        assert!(script.contains("numc = {["), "{script}");
    }

    // A cell by its orders: one value per input, or one for every input.
    assert_eq!(
        plain["b"].as_array().map(|b| b.iter().map(|x| x.as_array().unwrap().len()).collect()),
        Some(vec![2, 1])
    );
    assert!(plain["model"].as_str().unwrap().starts_with("OE(2,2 d1; 1,1 d0) at k = 1, chosen by cell"), "{plain}");
    let cell = ok(&oesweep(&root, &["export", "out", "--to", "json", "--pick", "2/1,2,1"]));
    let cell: Value = serde_json::from_str(&cell).unwrap();
    assert_eq!(cell["f"][1].as_array().map(Vec::len), Some(2), "NF 2 for every input");
    let o = oesweep(&root, &["export", "out", "--to", "json", "--pick", "2/1/1,2,1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("3 values of NB for a model of 2 inputs"));
    let o = oesweep(&root, &["export", "out", "--to", "json", "--pick", "3/1,2,1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no row nB 3/1, nF 2/2, delay 1/0 k 1"));

    // The MAT-file of several inputs (cell arrays) is written.
    ok(&oesweep(&root, &["export", "out", "--to", "mat", "--continuous", "tustin", "--out", "m.mat"]));
    assert!(std::fs::metadata(root.join("m.mat")).unwrap().len() > 0);

    // The report: one Bode figure per pick and input against the input's measured response, a
    // heat map and curves per input.
    ok(&oesweep(&root, &["report", "out"]));
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    for file in [
        "report-bode-m1-u1.svg",
        "report-bode-m1-u2.svg",
        "report-bode-m2-u1.svg",
        "report-bode-m2-u2.svg",
        "report-heat-u1.svg",
        "report-heat-u2.svg",
        "report-w-nf-u1.svg",
        "report-l1c-nf-u2.svg",
        "report-resid-corr-u1.svg",
        "report-resid-corr-u2.svg",
        "report-residuals.svg",
        "report-output-validation.svg",
    ] {
        assert!(page.contains(&format!("src=\"{file}\"")), "{file} on the page");
        assert!(out.join(file).is_file(), "{file}");
    }
    assert_eq!(page.matches("src=\"report-bode-").count(), 4, "2 picks x 2 inputs");
    assert_eq!(page.matches("src=\"report-heat-").count(), 2, "one heat map per input");
    let bode = std::fs::read_to_string(out.join("report-bode-m1-u2.svg")).unwrap();
    assert!(bode.contains("from input v"), "the figure names its input");
    assert!(
        bode.contains("Welch estimate H = P⁻¹ s, input v"),
        "the input's measured response (tests/report_inputs.rs)"
    );
    let heat = std::fs::read_to_string(out.join("report-heat-u2.svg")).unwrap();
    assert!(heat.contains("input v (the other inputs at"), "the heat map names its input");

    octave_reads(&root);
}

/// Octave (with its control package) runs the script: `G` is 1 x 2 with input 2's numerator,
/// and the MAT-file's `b` is a cell of two. Skipped without Octave.
fn octave_reads(root: &Path) {
    let octave = Command::new("octave-cli").arg("--version").output();
    if !octave.is_ok_and(|o| o.status.success()) {
        return cannot_run("no octave-cli to run the MATLAB script of several inputs");
    }
    let pick = ["--pick", "2/1,2/1,1"];
    let script = ok(&oesweep(root, &[&["export", "out", "--to", "matlab", "--continuous", "zoh"][..], &pick].concat()));
    std::fs::write(root.join("model.m"), script).unwrap();
    let check = "model; [ny, nu] = size(G); printf('size %d %d\\n', ny, nu); \
                 [n2, d2] = tfdata(G(1, 2), 'vector'); printf('num2 %.15g\\n', n2(1)); \
                 printf('gc %d %d\\n', size(Gc)); printf('gz %d %d\\n', size(Gz)); \
                 s = load('m.mat'); printf('cells %d %d\\n', iscell(s.b), numel(s.b)); \
                 printf('pc %d\\n', size(s.pc{1}, 2));";
    let o =
        Command::new("octave-cli").current_dir(root).args(["--no-gui", "--quiet", "--eval", check]).output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{text}{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("size 1 2"), "{text}");
    assert!(text.contains("gc 1 2") && text.contains("gz 1 2"), "{text}");
    assert!(text.contains("cells 1 2") && text.contains("pc 2"), "{text}");
    let j: Value =
        serde_json::from_str(&ok(&oesweep(root, &[&["export", "out", "--to", "json"][..], &pick].concat()))).unwrap();
    let b2 = j["b"][1][0].as_f64().unwrap();
    let got: f64 = text.lines().find_map(|l| l.strip_prefix("num2 ")).unwrap().trim().parse().unwrap();
    assert!((got - b2).abs() <= 1e-12 * b2.abs().max(1.0), "input 2's numerator in Octave {got}, exported {b2}");
}
