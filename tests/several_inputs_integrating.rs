//! The integrating-plant test of several inputs (METHOD.md 7.3, 19): each input's path is tested
//! on the output less the other inputs' outputs, with their paths' errors as columns of its
//! regression, so the input whose path integrates is the one named, whichever its place; a
//! record without an integrator names none; `oesweep fit`'s warnings and a sweep's
//! `selection.json` name the input by its column.

mod common;

use common::*;
use oesweep::data::{Offset, Record};
use oesweep::engine::{FitRequest, fit_arrays};
use oesweep::estimate::InitialState;
use oesweep::estimate::integrating::pole_tests;
use oesweep::oe::{self, Orders, Structure};

/// A stable path: OE(2,2) delay 1, poles 0.6 +- 0.37i (the one of `tests/several_inputs.rs`).
const STABLE: (&[f64], &[f64]) = (&[0.5, 0.3], &[-1.2, 0.5]);
/// A slow stable path: pole 0.95, DC gain 2.
const SLOW: (&[f64], &[f64]) = (&[0.1], &[-0.95]);
/// An integrator: 0.05 / (1 - q^-1).
const INTEGRATOR: (&[f64], &[f64]) = (&[0.05], &[-1.0]);

/// The output noise's standard deviation (the stable paths' outputs have std 1-2).
const NOISE: f64 = 0.1;

/// Two inputs (random binary of levels +-1, held 10 and 7 samples) through `paths` with delay 1
/// each, plus Gaussian noise of std [`NOISE`] and 5 % spikes of 5-10 noise std: (u input after
/// input, y).
fn record(paths: [(&[f64], &[f64]); 2], n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let inputs = [binary_input(n, 10, 1.0, seed), binary_input(n, 7, 1.0, seed + 1000)];
    let mut y0 = vec![0.0; n];
    for (u, (b, f)) in inputs.iter().zip(paths) {
        oe::simulate_vec(b, f, 1, u).iter().zip(&mut y0).for_each(|(x, y)| *y += x);
    }
    let sigma = NOISE;
    let mut rng = Lcg(seed + 7);
    let y = y0
        .iter()
        .map(|v| {
            let mut e = sigma * rng.normal();
            if rng.next() < 0.05 {
                e += (5.0 + 5.0 * rng.next()) * sigma * if rng.next() < 0.5 { -1.0 } else { 1.0 };
            }
            v + e
        })
        .collect();
    (inputs.concat(), y)
}

/// Which of the two inputs' tests fired.
fn fired(paths: [(&[f64], &[f64]); 2], n: usize, seed: u64) -> [bool; 2] {
    let (u, y) = record(paths, n, seed);
    let tests = pole_tests(&u, 2, &y, &[], &[1, 1]);
    let fired = |i: usize| tests[i].expect("the test runs").integrating;
    [fired(0), fired(1)]
}

/// Twelve records of each case (seeds 1..=12): at most one of the 36 answered wrong (seed 8 of
/// input 1's integrator, where input 2's test fires too). Not a rate: over 40 records of each
/// case (seeds 1..=40, `cargo run --release --example several_inputs_integrating_mc`) the
/// input that integrates fires on 40 and 39, the other input falsely on 0 and 1, and without an
/// integrator on 0 and 0 (METHOD.md 7.3). The other inputs' paths as columns of each input's
/// regression are what keeps the other input quiet: with their outputs only subtracted it
/// fired falsely on 10 and 9 of 40, and 8 of these 36 records were answered wrong.
#[test]
fn the_input_whose_path_integrates_is_the_one_that_fires() {
    let cases = [
        ("input 2 integrates", [STABLE, INTEGRATOR], [false, true]),
        ("input 1 integrates", [INTEGRATOR, SLOW], [true, false]),
        ("no integrator", [STABLE, SLOW], [false, false]),
    ];
    let mut wrong = Vec::new();
    for seed in 1..=12 {
        for (case, paths, right) in cases {
            let answer = fired(paths, 3000, seed);
            if answer != right {
                wrong.push(format!("{case}, seed {seed}: fired {answer:?}"));
            }
        }
    }
    assert!(wrong.len() <= 1, "{wrong:?}");
}

/// One input's record is tested as before: the several-input entry point of one input is
/// `pole_test` itself.
#[test]
fn one_input_is_the_one_input_test() {
    let (u, y) = record([INTEGRATOR, STABLE], 2000, 4);
    let u = &u[..2000];
    let one = oesweep::estimate::integrating::pole_test(u, &y, &[], 1);
    assert_eq!(pole_tests(u, 1, &y, &[], &[1]), vec![one]);
}

fn fit_warnings(paths: [(&[f64], &[f64]); 2], seed: u64) -> Vec<String> {
    let n = 3000;
    let (u, y) = record(paths, n, seed);
    let o = |nb, nf| Orders { nb, nf, delay: 1 };
    let s = Structure::new(&[o(2, 2), o(1, 1)]).unwrap();
    let req = FitRequest::for_arrays(s, 1.0, 1.0, Offset::Estimate, InitialState::Estimate);
    let rec = Record {
        path: "plant.csv".into(),
        u,
        y,
        u_names: vec!["fuel".into(), "fan".into()],
        y_name: "y".into(),
        seams: Vec::new(),
        missing: Vec::new(),
    };
    fit_arrays(&req, rec, None).unwrap().warnings
}

/// `oesweep fit` of the two-input model: input 2's integrator is named by its input and
/// column (as an integrating path when the fit puts F_2 on the stability boundary, or as the
/// other cause of the stable fit's drifting residuals); input 1 is not named; a record
/// without an integrator has no such warning.
#[test]
fn the_fits_warning_names_the_integrating_input() {
    let warnings = fit_warnings([STABLE, INTEGRATOR], 1);
    let named: Vec<&String> = warnings.iter().filter(|w| w.contains("integrat")).collect();
    assert_eq!(named.len(), 1, "{warnings:?}");
    let w = named[0];
    assert!(
        w.starts_with("input 2 (fan) looks integrating: a low-order IV fit of plant.csv from that input")
            || w.contains("or input 2 (fan) integrates (a low-order IV fit of plant.csv from that input"),
        "{w}"
    );
    assert!(w.contains("has a pole at ") && !w.contains("input 1"), "{w}");

    let warnings = fit_warnings([STABLE, SLOW], 1);
    assert!(!warnings.iter().any(|w| w.contains("integrat")), "{warnings:?}");
}

/// A sweep of a two-input job: `selection.json`'s warnings name input 2 by its column.
#[test]
fn a_sweeps_warning_names_the_integrating_input() {
    let dir = tempfile::tempdir().unwrap();
    let n = 3000;
    let (u, y) = record([STABLE, INTEGRATOR], n, 3);
    let mut csv = String::from("fuel,fan,y\n");
    for t in 0..n {
        csv.push_str(&format!("{},{},{}\n", u[t], u[n + t], y[t]));
    }
    std::fs::write(dir.path().join("d.csv"), csv).unwrap();
    let job = serde_json::json!({
        "name": "integ", "data": {"path": "d.csv", "u": ["fuel", "fan"], "ts": 1},
        "grid": {"nb": [[2, 2], [1, 1]], "nf": [[2, 2], [1, 1]], "k": [1.0]}, "delay": [1, 1], "output": "out"
    });
    std::fs::write(dir.path().join("job.json"), job.to_string()).unwrap();
    let o = run_oesweep(dir.path(), &["run", "job.json", "--quiet"], std::time::Duration::from_secs(300));
    assert_eq!(o.code, Some(0), "{}", o.stderr);
    let sel: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/selection.json")).unwrap()).unwrap();
    let warnings: Vec<&str> = sel["warnings"].as_array().unwrap().iter().filter_map(|w| w.as_str()).collect();
    let named: Vec<&&str> = warnings.iter().filter(|w| w.contains("IV fit")).collect();
    assert_eq!(named.len(), 1, "{warnings:?}");
    assert!(named[0].contains("input 2 (fan)") && !named[0].contains("input 1"), "{}", named[0]);
}
