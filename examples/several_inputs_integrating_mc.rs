//! `cargo run --release --example several_inputs_integrating_mc -- [RECORDS]` (default 40):
//! how often each input's integrating-plant test fires on records of two inputs
//! (`estimate::integrating::pole_tests`, METHOD.md 7.3 "Several inputs"), on the records of
//! `tests/several_inputs_integrating.rs` (seeds 1..=RECORDS): two random binary inputs of
//! levels +-1 held 10 and 7 samples, 3000 samples, each through its path with delay 1, Gaussian
//! output noise of std 0.1 and 5 % spikes of 5-10 noise std. Three cases: input 2 through an
//! integrator, input 1 through one, neither; and a fourth of three inputs (a third held 13
//! samples), the integrator on input 2. Prints per case and input how many records fired and
//! the median and range of `A_i(1) / se` (the test fires at 1.96 and below). Seeded: the same
//! counts on every run.

use oesweep::estimate::integrating::pole_tests;
use oesweep::oe;

mod common;

use common::Lcg;

/// The test's input: +-1, each level held `hold` samples (`tests/common`'s `binary_input`).
fn binary_input(n: usize, hold: usize, seed: u64) -> Vec<f64> {
    common::binary(n, hold, -1.0, 1.0, &mut Lcg(seed))
}

type Path = (&'static [f64], &'static [f64]);
/// OE(2,2) delay 1, poles 0.6 +- 0.37i.
const STABLE: Path = (&[0.5, 0.3], &[-1.2, 0.5]);
/// Pole 0.95, DC gain 2.
const SLOW: Path = (&[0.1], &[-0.95]);
/// 0.05 / (1 - q^-1).
const INTEGRATOR: Path = (&[0.05], &[-1.0]);
const NOISE: f64 = 0.1;
const N: usize = 3000;

/// The record of `tests/several_inputs_integrating.rs::record` (two inputs; a third held 13
/// samples): (u input after input, y).
fn record(paths: &[Path], seed: u64) -> (Vec<f64>, Vec<f64>) {
    let holds = [(10, 0), (7, 1000), (13, 2000)];
    let inputs: Vec<Vec<f64>> = holds[..paths.len()].iter().map(|&(h, s)| binary_input(N, h, seed + s)).collect();
    let mut y0 = vec![0.0; N];
    for (u, &(b, f)) in inputs.iter().zip(paths) {
        oe::simulate_vec(b, f, 1, u).iter().zip(&mut y0).for_each(|(x, y)| *y += x);
    }
    let mut rng = Lcg(seed + 7);
    let y = y0
        .iter()
        .map(|v| {
            let mut e = NOISE * rng.normal();
            if rng.next() < 0.05 {
                e += (5.0 + 5.0 * rng.next()) * NOISE * if rng.next() < 0.5 { -1.0 } else { 1.0 };
            }
            v + e
        })
        .collect();
    (inputs.concat(), y)
}

fn main() {
    let records: u64 = std::env::args().nth(1).map_or(40, |s| s.parse().expect("RECORDS is a count"));
    let cases: [(&str, &[Path]); 4] = [
        ("input 2 integrates (OE(2,2), integrator)", &[STABLE, INTEGRATOR]),
        ("input 1 integrates (integrator, pole 0.95)", &[INTEGRATOR, SLOW]),
        ("no integrator (OE(2,2), pole 0.95)", &[STABLE, SLOW]),
        ("three inputs, input 2 integrates (OE(2,2), integrator, pole 0.95)", &[STABLE, INTEGRATOR, SLOW]),
    ];
    println!("| case | fired per input | of | A(1)/se per input: median (range) |");
    println!("|---|---|---|---|");
    for (name, paths) in cases {
        let m = paths.len();
        let mut fired = vec![0; m];
        let mut z = vec![Vec::new(); m];
        for seed in 1..=records {
            let (u, y) = record(paths, seed);
            let tests = pole_tests(&u, m, &y, &[], &vec![1; m]);
            for i in 0..m {
                let t = tests[i].expect("the test runs");
                fired[i] += usize::from(t.integrating);
                z[i].push(t.a_at_1 / t.a_at_1_std);
                if std::env::var("VERBOSE").is_ok() {
                    eprintln!("{name} seed {seed} input {}: {t:?}", i + 1);
                }
            }
        }
        let summary = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            format!("{:.2} ({:.2}..{:.2})", v[v.len() / 2], v[0], v[v.len() - 1])
        };
        let fired: Vec<String> = fired.iter().map(|f| f.to_string()).collect();
        let z: Vec<String> = z.iter_mut().map(summary).collect();
        println!("| {name} | {} | {records} | {} |", fired.join(", "), z.join(", "));
    }
}
