//! `cargo run --release --example integrating_mc -- [REALISATIONS]` (default 10):
//! Monte Carlo of the integrating-plant test (`estimate::integrating`, METHOD.md 7.3) on
//! stable plants with time constants from a few samples to longer than the record, on stable
//! plants whose output drifts slowly (a random walk, a slow sine or a ramp added), on
//! integrators and on unstable plants. Each realisation draws a random binary input (each level
//! held 10 samples; 50 for the tanks), simulates the plant, adds Gaussian noise of 10-25 % of
//! the noise-free output's standard deviation and, in two of the three rows, spikes of 5-10
//! noise standard deviations on 5 % or 15 % of the samples. Where the IV test fires, the record
//! is swept (`engine::run_text`: nB 1..2, nF 1..3, k 0.5 and 1.5, delay 1) and the test judged
//! against the picks as a run judges it. Prints a Markdown table: how often the IV test fired,
//! how often the run then warned of an integrating plant and of drifting residuals, and the
//! median tested pole and half-width of its 95 % interval. Seeded: the same numbers on every
//! run. `ONLY=text` runs the plants whose name contains it.

use oesweep::engine::{self, RunEnd, RunOptions};
use oesweep::estimate::integrating::pole_test;
use oesweep::oe;

mod common;

use common::{Lcg, binary};

/// A plant of the study: a linear OE model `q^-1 B/F`, or the nonlinear tanks.
enum Plant {
    Linear { b: Vec<f64>, f: Vec<f64> },
    Tanks,
}

/// A slow disturbance added to the output, in noise-free output standard deviations `sd`.
#[derive(Clone, Copy)]
enum Drift {
    None,
    /// A random walk with steps of this times sd.
    Walk(f64),
    /// A sine of this amplitude times sd, one period over the record, at a random phase.
    Sine(f64),
    /// A ramp from 0 to this times sd over the record.
    Ramp(f64),
}

impl Drift {
    fn add(self, y: &mut [f64], sd: f64, rng: &mut Lcg) {
        let n = y.len() as f64;
        match self {
            Drift::None => {}
            Drift::Walk(q) => {
                let mut d = 0.0;
                for v in y.iter_mut() {
                    d += q * sd * rng.normal();
                    *v += d;
                }
            }
            Drift::Sine(a) => {
                let phase = std::f64::consts::TAU * rng.next();
                for (t, v) in y.iter_mut().enumerate() {
                    *v += a * sd * (std::f64::consts::TAU * t as f64 / n + phase).sin();
                }
            }
            Drift::Ramp(a) => {
                for (t, v) in y.iter_mut().enumerate() {
                    *v += a * sd * t as f64 / n;
                }
            }
        }
    }
}

/// What a run said of the record (u, y): (warned of an integrating plant, warned of drifting
/// residuals), from a sweep of nB 1..2, nF 1..3, k 0.5 and 1.5 in a temporary folder.
fn run_warnings(u: &[f64], y: &[f64]) -> (bool, bool) {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let mut csv = String::from("u,y\n");
    for (a, b) in u.iter().zip(y) {
        csv.push_str(&format!("{a},{b}\n"));
    }
    std::fs::write(dir.path().join("data.csv"), csv).expect("the record written");
    let job = r#"{"name": "mc", "data": {"path": "data.csv", "u": "u", "y": "y", "ts": 1.0}, "delay": 1,
        "grid": {"nb": [1, 2], "nf": [1, 3], "k": [0.5, 1.5]}, "output": "out"}"#;
    let opts = RunOptions {
        threads: 0,
        quiet: true,
        force: false,
        checkpoint_every: 60.0,
        shard: None,
        report: false,
        watch: None,
        profile: false,
    };
    let outcome = engine::run_text(&dir.path().join("job.json"), job, &opts, &|_| {}).expect("the sweep runs");
    let RunEnd::Merged { selection, .. } = outcome.end else { panic!("the sweep ends merged") };
    let has = |what: &str| selection.warnings.iter().any(|w| w.contains(what));
    (has("the plant looks integrating"), has(" drift (above "))
}

/// F with the given (radius, angle) pairs (each a conjugate pair) and real poles.
fn f_from_poles(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    oesweep::oe::poly_from_poles(pairs, real)
}

/// `q^-1 B/F` with F from the poles and a one-coefficient B giving a static gain of 1 (of 1
/// per sample for a plant with poles at 1: B = F with the poles at 1 left out, at z = 1).
fn linear(pairs: &[(f64, f64)], real: &[f64]) -> Plant {
    let f = f_from_poles(pairs, real);
    let rest: Vec<f64> = real.iter().copied().filter(|&p| p != 1.0).collect();
    let g = f_from_poles(pairs, &rest);
    Plant::Linear { b: vec![1.0 + g.iter().sum::<f64>()], f }
}

/// Two tanks in series fed by a pump (`u` in [0.3, 1]), outflows through orifices (square
/// roots), the upper tank overflowing at level 10 (a third of the overflow into the lower
/// one), the lower one at 10: a slow stable plant with saturation, like the cascaded-tanks
/// benchmark. Euler steps of one sample; linearised time constants of about 40-80 samples.
fn tanks(u: &[f64]) -> Vec<f64> {
    let (k1, k2, k3, k4) = (0.1, 0.1, 0.1, 0.35);
    let (mut x1, mut x2) = (3.0_f64, 3.0_f64);
    u.iter()
        .map(|&ut| {
            let out1 = k1 * x1.max(0.0).sqrt();
            x1 += k4 * ut - out1;
            let over = (x1 - 10.0).max(0.0);
            x1 -= over;
            x2 += k2 / k1 * out1 + over / 3.0 - k3 * x2.max(0.0).sqrt();
            x2 = x2.min(10.0);
            x2
        })
        .collect()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let reps: usize = std::env::args().nth(1).map_or(10, |s| s.parse().expect("REALISATIONS is a count"));
    let plants: Vec<(&str, &str, Plant, Drift)> = vec![
        ("pole 0.5", "1.4", linear(&[], &[0.5]), Drift::None),
        ("pole 0.9", "9.5", linear(&[], &[0.9]), Drift::None),
        ("poles 0.9, 0.95", "19.5", linear(&[], &[0.9, 0.95]), Drift::None),
        ("pole 0.99", "99.5", linear(&[], &[0.99]), Drift::None),
        ("resonant 0.98 e^(+-0.1i)", "49.5", linear(&[(0.98, 0.1)], &[]), Drift::None),
        ("flexible arm, 6th order", "99.5", linear(&[(0.99, 0.1), (0.97, 0.5), (0.95, 1.2)], &[]), Drift::None),
        ("tanks with overflow", "~60", Plant::Tanks, Drift::None),
        ("pole 0.999", "999.5", linear(&[], &[0.999]), Drift::None),
        ("pole 0.9999", "9999.5", linear(&[], &[0.9999]), Drift::None),
        ("integrator", "inf", linear(&[], &[1.0]), Drift::None),
        ("integrator x lag 0.9", "inf", linear(&[], &[1.0, 0.9]), Drift::None),
        ("double integrator", "inf", linear(&[], &[1.0, 1.0]), Drift::None),
        ("unstable 1.001", "-", linear(&[], &[1.001]), Drift::None),
        ("unstable 1.01", "-", linear(&[], &[1.01]), Drift::None),
        ("pole 0.978 + random walk 0.005", "45", linear(&[], &[0.978]), Drift::Walk(0.005)),
        ("pole 0.978 + random walk 0.02", "45", linear(&[], &[0.978]), Drift::Walk(0.02)),
        ("poles 0.978, 0.85 + random walk 0.005", "45", linear(&[], &[0.978, 0.85]), Drift::Walk(0.005)),
        ("pole 0.9 + random walk 0.005", "9.5", linear(&[], &[0.9]), Drift::Walk(0.005)),
        ("pole 0.978 + sine 0.5", "45", linear(&[], &[0.978]), Drift::Sine(0.5)),
        ("pole 0.978 + ramp 1", "45", linear(&[], &[0.978]), Drift::Ramp(1.0)),
    ];
    println!(
        "| plant | tau (samples) | spikes | N | IV fired | integrating warnings | drift warnings | realisations | \
         median slowest pole | median 95 % half-width |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let only = std::env::var("ONLY").ok();
    for (p, (name, tau, plant, drift)) in plants.iter().enumerate() {
        if only.as_deref().is_some_and(|o| !name.contains(o)) {
            continue;
        }
        for (s, spikes) in [0.0, 0.05, 0.15].into_iter().enumerate() {
            for n in [2000, 5000] {
                let mut rng = Lcg(1000 * p as u64 + 100 * s as u64 + n as u64);
                let (mut fired, mut poles, mut widths) = (0, Vec::new(), Vec::new());
                let (mut integrating, mut drifting) = (0, 0);
                for _ in 0..reps {
                    let (u, y0) = match plant {
                        Plant::Linear { b, f } => {
                            let u = binary(n, 10, -1.0, 1.0, &mut rng);
                            let y0 = oe::simulate_vec(b, f, 1, &u);
                            (u, y0)
                        }
                        Plant::Tanks => {
                            let u = binary(n, 50, 0.3, 1.0, &mut rng);
                            let y0 = tanks(&u);
                            (u, y0)
                        }
                    };
                    let mean = y0.iter().sum::<f64>() / n as f64;
                    let sd = (y0.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
                    let sigma = (0.1 + 0.15 * rng.next()) * sd;
                    let mut y: Vec<f64> = y0
                        .iter()
                        .map(|v| {
                            let mut e = sigma * rng.normal();
                            if rng.next() < spikes {
                                e += (5.0 + 5.0 * rng.next()) * sigma * if rng.next() < 0.5 { -1.0 } else { 1.0 };
                            }
                            v + e
                        })
                        .collect();
                    drift.add(&mut y, sd, &mut rng);
                    if let Some(t) = pole_test(&u, &y, &[], 1) {
                        fired += usize::from(t.integrating);
                        if t.integrating {
                            let (i, d) = run_warnings(&u, &y);
                            integrating += usize::from(i);
                            drifting += usize::from(d);
                        }
                        poles.push(t.pole.0);
                        widths.push(t.interval.map_or(f64::NAN, |(lo, hi)| 0.5 * (hi - lo)));
                    }
                }
                let (mp, mw) =
                    if poles.is_empty() { (f64::NAN, f64::NAN) } else { (median(&mut poles), median(&mut widths)) };
                println!(
                    "| {name} | {tau} | {:.0} % | {n} | {fired} | {integrating} | {drifting} | {reps} | {mp:.5} | {mw:.2e} |",
                    100.0 * spikes
                );
            }
        }
    }
}
