//! The bootstrap's response intervals of several inputs (METHOD.md 17.3, 19): one list per
//! input, of that input's q^-d_i B_i/F_i; over independent records of a two-input system they
//! cover each input's true response at about the rate a percentile interval of B replicates
//! has and are as wide as the fits' own errors say; `fit --json` holds them as one list per
//! input.

mod common;

use common::*;
use oesweep::data::{Offset, Record};
use oesweep::engine::{FitRequest, fit_arrays};
use oesweep::estimate::{self, InitialState, Judge, Problem, SolverOptions, Workspace, bootstrap};
use oesweep::oe::{self, Orders, Structure};

/// Input 1 OE(2,2) delay 1, input 2 OE(1,1) delay 2 (the system of `tests/several_inputs_picks.rs`).
const PATHS: [(&[f64], &[f64], usize); 2] = [(&[0.5, 0.3], &[-1.2, 0.5], 1), (&[0.4], &[-0.8], 2)];

fn structure() -> Structure {
    let o = |(b, f, delay): (&[f64], &[f64], usize)| Orders { nb: b.len(), nf: f.len(), delay };
    Structure::new(&[o(PATHS[0]), o(PATHS[1])]).unwrap()
}

/// Two random binary inputs (held 3 and 5 samples) through [`PATHS`] plus Gaussian noise of std
/// `noise`: (u input after input, y).
fn record(n: usize, noise: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let inputs = [binary_input(n, 3, 1.0, seed), binary_input(n, 5, 1.0, seed + 500)];
    let mut rng = Lcg(seed + 11);
    let mut y: Vec<f64> = (0..n).map(|_| noise * rng.normal()).collect();
    for (u, (b, f, d)) in inputs.iter().zip(PATHS) {
        oe::simulate_vec(b, f, d, u).iter().zip(&mut y).for_each(|(x, y)| *y += x);
    }
    (inputs.concat(), y)
}

/// The phase of `(re, im)` in degrees, unwrapped to within 180 of `near`.
fn phase_near(re: f64, im: f64, near: f64) -> f64 {
    near + (im.atan2(re).to_degrees() - near + 180.0).rem_euclid(360.0) - 180.0
}

/// Over 12 records of 800 samples (B = 60 each), each input's intervals of |G_i| and of its
/// phase at the ten frequencies cover that input's true response at about the rate of a correct
/// percentile interval of 60 replicates, (s - r)/(B + 1) = 56.05/61 = 0.92 (see
/// `tests/uncertainty.rs`), and their mean width is about 0.92 x 3.92 times the fits' rms error
/// around the truth (known to about 20 % from 12 records). Intervals of the wrong input's
/// response, or of a response without its delay, cover almost nothing.
#[test]
fn each_inputs_response_intervals_cover_its_truth_at_the_nominal_rate() {
    let s = structure();
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    let (records, replicates) = (12, 60);
    let freqs = bootstrap::default_frequencies();
    // Per input: covered magnitude and phase intervals, and per frequency the mean width of
    // |G_i|'s interval and the mean squared error of the fit's |G_i|.
    let mut covered = [[0usize; 2]; 2];
    let mut widths = vec![vec![0.0; freqs.len()]; 2];
    let mut square_errors = vec![vec![0.0; freqs.len()]; 2];
    for seed in 0..records {
        let (u, y) = record(800, 0.3, 40 + seed);
        let prob = Problem { u: &u, y: &y, structure: s, offset: false, seams: &[], missing: &[] };
        let one = estimate::fit_one(&prob, 1.5, &Judge::default(), &opts, &mut ws);
        let theta = one.huber.theta();
        let settings = bootstrap::Settings { replicates, seed, ..Default::default() };
        let boot = bootstrap::run(&prob, &theta, Some(one.huber.k), &settings, &opts);
        assert_eq!((boot.magnitude.len(), boot.phase_deg.len()), (2, 2));
        assert_eq!(boot.frequencies, freqs);
        for (i, (b, f, d)) in PATHS.into_iter().enumerate() {
            let (bi, fi) = prob.input_parts(&theta, i);
            for (j, &w) in freqs.iter().enumerate() {
                let (re, im) = oe::freq_response(b, f, d, w);
                let (mag, ph) = (boot.magnitude[i][j], boot.phase_deg[i][j]);
                covered[i][0] += usize::from((mag.lower..=mag.upper).contains(&re.hypot(im)));
                let truth_phase = phase_near(re, im, 0.5 * (ph.lower + ph.upper));
                covered[i][1] += usize::from((ph.lower..=ph.upper).contains(&truth_phase));
                let (fre, fim) = oe::freq_response(bi, fi, d, w);
                widths[i][j] += (mag.upper - mag.lower) / records as f64;
                square_errors[i][j] += (fre.hypot(fim) - re.hypot(im)).powi(2) / records as f64;
            }
        }
    }
    let of = (records as usize * freqs.len()) as f64;
    for i in 0..2 {
        for (what, c) in ["|G|", "phase"].iter().zip(covered[i]) {
            let rate = c as f64 / of;
            assert!((0.75..=1.0).contains(&rate), "input {}: {what} covered {c} of {of}", i + 1);
        }
        let ratio = (0..freqs.len()).map(|j| widths[i][j] / (3.92 * square_errors[i][j].sqrt())).sum::<f64>()
            / freqs.len() as f64;
        assert!((0.55..=1.6).contains(&ratio), "input {}: mean width / (3.92 rms error) = {ratio}", i + 1);
    }
}

/// `fit --json`'s bootstrap of a two-input model: the frequencies once, `magnitude` and
/// `phase_deg` one list of ten intervals per input; one input's stay flat lists.
#[test]
fn the_fits_json_holds_one_list_of_response_intervals_per_input() {
    let (u, y) = record(600, 0.2, 3);
    let mut req = FitRequest::for_arrays(structure(), 1.5, 1.0, Offset::Estimate, InitialState::Estimate);
    req.bootstrap = Some(40);
    req.threads = 1;
    let rec =
        Record::from_input_arrays("<u, y arrays>", vec![u[..600].to_vec(), u[600..].to_vec()], y.clone()).unwrap();
    let v: serde_json::Value = serde_json::from_str(&fit_arrays(&req, rec, None).unwrap().to_json()).unwrap();
    let boot = &v["bootstrap"];
    assert_eq!(boot["frequencies"].as_array().unwrap().len(), 10, "{boot}");
    for field in ["magnitude", "phase_deg"] {
        let lists = boot[field].as_array().unwrap();
        assert_eq!(lists.len(), 2, "{field}: {boot}");
        for list in lists {
            let list = list.as_array().unwrap();
            assert_eq!(list.len(), 10, "{field}");
            assert!(list.iter().all(|iv| iv["lower"].as_f64().unwrap() <= iv["upper"].as_f64().unwrap()));
        }
    }
    // The two inputs' responses differ: input 2's static gain 2, input 1's 2.67.
    let low = |i: usize| boot["magnitude"][i][0]["upper"].as_f64().unwrap();
    assert!(low(0) > 2.3 && low(1) < 2.4, "{boot}");

    let mut req = FitRequest::for_arrays(Structure::siso(2, 2, 1), 1.5, 1.0, Offset::Estimate, InitialState::Estimate);
    req.bootstrap = Some(40);
    req.threads = 1;
    let rec = Record::from_input_arrays("<u, y arrays>", vec![u[..600].to_vec()], y).unwrap();
    let v: serde_json::Value = serde_json::from_str(&fit_arrays(&req, rec, None).unwrap().to_json()).unwrap();
    let mag = v["bootstrap"]["magnitude"].as_array().unwrap();
    assert!(mag.len() == 10 && mag[0]["lower"].is_number(), "{}", v["bootstrap"]);
}
