//! The integrating-plant test (METHOD.md 7.3) on cases made for it: integrators fire with and
//! without spikes, slow and lightly damped stable plants do not, the warning names the pole and
//! its interval, and no lag reaches across a seam.

mod common;

use common::*;
use oesweep::data::{Offset, Record};
use oesweep::estimate::integrating::pole_test;
use oesweep::oe;

/// `q^-1 b/F u` plus Gaussian noise of `noise` times the output's standard deviation and, on
/// a fraction `spikes` of the samples, spikes of 5-10 noise standard deviations.
fn record(b: &[f64], f: &[f64], n: usize, noise: f64, spikes: f64, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let u = binary_input(n, 10, 1.0, seed);
    let y0 = oe::simulate_vec(b, f, 1, &u);
    let mean = y0.iter().sum::<f64>() / n as f64;
    let sigma = noise * (y0.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    let mut rng = Lcg(seed + 1);
    let y = y0
        .iter()
        .map(|v| {
            let mut e = sigma * rng.normal();
            if rng.next() < spikes {
                e += (5.0 + 5.0 * rng.next()) * sigma * if rng.next() < 0.5 { -1.0 } else { 1.0 };
            }
            v + e
        })
        .collect();
    (u, y)
}

fn integrating(u: &[f64], y: &[f64]) -> bool {
    pole_test(u, y, &[], 1).expect("the test runs").integrating
}

#[test]
fn an_integrator_fires() {
    for seed in [1, 2, 3] {
        let (u, y) = record(&[0.1], &[-1.0], 3000, 0.2, 0.0, seed);
        let t = pole_test(&u, &y, &[], 1).unwrap();
        assert!(t.integrating, "{t:?}");
        assert!((t.pole.0 - 1.0).abs() < 0.01, "{t:?}");
    }
}

#[test]
fn an_integrator_with_ten_percent_spikes_fires() {
    for seed in [4, 5, 6] {
        let (u, y) = record(&[0.1], &[-1.0], 3000, 0.2, 0.10, seed);
        assert!(integrating(&u, &y), "{:?}", pole_test(&u, &y, &[], 1));
    }
}

#[test]
fn a_double_integrator_and_an_unstable_plant_fire() {
    let (u, y) = record(&[0.01], &f_from_poles(&[], &[1.0, 1.0]), 2000, 0.2, 0.05, 7);
    assert!(integrating(&u, &y), "{:?}", pole_test(&u, &y, &[], 1));
    let (u, y) = record(&[0.01], &[-1.01], 2000, 0.2, 0.05, 8);
    let t = pole_test(&u, &y, &[], 1).unwrap();
    assert!(t.integrating && t.a_at_1 < 0.0 && t.interval.is_some_and(|(lo, _)| lo > 1.0), "{t:?}");
}

#[test]
fn a_slow_stable_plant_with_spikes_does_not_fire() {
    for (seed, spikes) in [(9, 0.05), (10, 0.10), (11, 0.15)] {
        let (u, y) = record(&[0.01], &[-0.99], 3000, 0.2, spikes, seed);
        let t = pole_test(&u, &y, &[], 1).unwrap();
        assert!(!t.integrating, "{t:?}");
        assert!((t.pole.0 - 0.99).abs() < 0.01, "{t:?}");
    }
}

#[test]
fn a_lightly_damped_resonant_plant_does_not_fire() {
    for seed in [12, 13] {
        let f = f_from_poles(&[(0.98, 0.1)], &[]);
        let (u, y) = record(&[1.0 + f.iter().sum::<f64>()], &f, 3000, 0.2, 0.05, seed);
        assert!(!integrating(&u, &y), "{:?}", pole_test(&u, &y, &[], 1));
    }
}

/// Two experiments of a fast stable plant whose levels differ by far more than the signal:
/// a lag across the seam would see a step no input explains.
#[test]
fn no_lag_reaches_across_a_seam() {
    let (u1, y1) = record(&[0.5], &[-0.5], 1500, 0.2, 0.0, 14);
    let (u2, y2) = record(&[0.5], &[-0.5], 1500, 0.2, 0.0, 15);
    let u: Vec<f64> = u1.iter().chain(&u2).copied().collect();
    let y: Vec<f64> = y1.iter().map(|v| v + 100.0).chain(y2.iter().map(|v| v - 100.0)).collect();
    assert!(!pole_test(&u, &y, &[1500], 1).unwrap().integrating);
}

/// The warning as the records are read: it names the pole and its 95 % interval, and the
/// record of a stable plant far from zero (the test fits its own constant) has none.
#[test]
fn the_warning_names_the_pole_and_its_interval() {
    let rec = |u: Vec<f64>, y: Vec<f64>| Record {
        path: "plant.csv".into(),
        u,
        y,
        u_name: "u".into(),
        y_name: "y".into(),
        seams: Vec::new(),
    };
    let (u, y) = record(&[0.1], &[-1.0], 3000, 0.2, 0.05, 16);
    let inputs = oesweep::job::inputs_of_records(rec(u, y), None, Offset::Estimate, (2, 2, 1), 1).unwrap();
    let w = inputs.warnings.iter().find(|w| w.contains("integrating")).expect("the integrating warning");
    assert!(w.contains("plant.csv") && w.contains("has a pole at ") && w.contains("95 % interval "), "{w}");
    let (lo, hi) = w.split("95 % interval ").nth(1).unwrap().split_once("..").unwrap();
    let hi: String = hi.chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    let (lo, hi): (f64, f64) = (lo.parse().unwrap(), hi.parse().unwrap());
    assert!(lo < 1.0 && 1.0 <= hi, "{w}");

    let (u, y) = record(&[0.3], &[-0.7], 3000, 0.2, 0.05, 17);
    let y = y.iter().map(|v| v + 97.0).collect();
    let inputs = oesweep::job::inputs_of_records(rec(u, y), None, Offset::Estimate, (2, 2, 1), 1).unwrap();
    assert!(inputs.warnings.is_empty(), "{:?}", inputs.warnings);
}
