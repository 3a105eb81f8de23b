//! Monte Carlo benchmark of the pick rules (METHOD.md 7.1): how often each rule of
//! `selection.json`'s `picks` finds the true orders of a 3rd-order OE system.
//!
//! ```text
//! cargo run --release --example order_selection_mc -- [REALISATIONS] [THREADS] [NOISE]
//! ```
//!
//! (defaults 50, 2, 0.05; `MC_KEEP=DIR` keeps each realisation's job and results in DIR).
//!
//! Per realisation (seeded, so the table is reproducible): a PRBS (10-bit register, levels +/-1)
//! through `B = 1 + 0.5 q^-1 + 0.3 q^-2`, `F` with poles 0.85 and 0.6 +/- 0.5j, delay 1,
//! N = 2000, Gaussian noise of NOISE times the output's RMS (5 % by default), and on 0 %, 5 % or 15 % of the
//! samples a spike of 5 to 15 noise standard deviations of random sign; a validation record of
//! the same kind (another seed). The job: grid nB, nF 1..5, delay 1, six k from 0.1 to 2 (log),
//! the default offset and initial state, run through `engine::run` like `oesweep run`. Prints a
//! Markdown table: per rule, the realisations whose pick has the true orders (3, 3), and after
//! the slash those whose pick is larger in nB + nF (over-fitted).

use oesweep::engine::{self, RunEnd, RunOptions};
use oesweep::reduce::Rule;
use oesweep::simulate::{self, NoiseKind, Outliers, SimOptions, SystemSpec};
use std::collections::BTreeMap;
use std::path::Path;

const N: usize = 2000;
const TRUE_ORDERS: (u32, u32) = (3, 3);
const SPIKE_SHARES: [f64; 3] = [0.0, 0.05, 0.15];

fn system() -> SystemSpec {
    // (1 - 0.85 q^-1)(1 - 1.2 q^-1 + 0.61 q^-2)
    SystemSpec { b: vec![1.0, 0.5, 0.3], f: vec![-2.05, 1.63, -0.5185], delay: 1 }
}

/// The record of one seed: noise `noise` times the noise-free output's RMS, spikes on `share`.
fn record(seed: u64, share: f64, noise: f64, path: &Path) {
    let sys = system();
    let clean =
        SimOptions { n: N, bits: 10, amplitude: 1.0, seed, noise_std: 0.0, noise: NoiseKind::Gaussian, outliers: None };
    let y0 = simulate::generate(&sys, &clean).expect("the benchmark system").y0;
    let rms = (y0.iter().map(|v| v * v).sum::<f64>() / N as f64).sqrt();
    let sd = noise * rms;
    let opts = SimOptions {
        noise_std: sd,
        outliers: (share > 0.0).then_some(Outliers { probability: share, min: 5.0 * sd, max: 15.0 * sd }),
        ..clean
    };
    let rec = simulate::generate(&sys, &opts).expect("the benchmark system");
    simulate::write_csv(path, &rec).expect("a writable temporary folder");
}

/// The picks of one realisation: rule -> (nB, nF).
fn picks(dir: &Path, seed: u64, share: f64, noise: f64, threads: usize) -> BTreeMap<Rule, Option<(u32, u32)>> {
    record(seed, share, noise, &dir.join("est.csv"));
    record(seed + 1_000_000, share, noise, &dir.join("val.csv"));
    let job = serde_json::json!({
        "name": "order-selection-mc",
        "data": { "path": "est.csv", "u": "u", "y": "y", "ts": 1.0 },
        "validation": { "path": "val.csv", "u": "u", "y": "y" },
        "delay": 1,
        "grid": { "nb": [1, 5], "nf": [1, 5], "k": { "from": 0.1, "to": 2.0, "count": 6, "spacing": "log" } },
        "output": "out"
    });
    std::fs::write(dir.join("job.json"), job.to_string()).unwrap();
    let opts = RunOptions { threads, quiet: true, force: true, ..RunOptions::default() };
    let outcome = engine::run(&dir.join("job.json"), &opts, &|_| {}).expect("the benchmark job runs");
    let RunEnd::Merged { selection, .. } = outcome.end else { panic!("the run did not finish") };
    selection.picks.iter().map(|(rule, p)| (*rule, p.model.as_ref().map(|m| (m.key.nb, m.key.nf)))).collect()
}

fn main() {
    let args: Vec<f64> = std::env::args().skip(1).map(|a| a.parse().expect("a number")).collect();
    let realisations = args.first().map_or(50, |&v| v as usize);
    let threads = args.get(1).map_or(2, |&v| v as usize);
    let noise = args.get(2).copied().unwrap_or(0.05);
    let dir = tempfile::tempdir().unwrap();
    let keep = std::env::var("MC_KEEP").ok();
    // rule -> per spike share: (true orders, over-fitted)
    let mut hits: BTreeMap<Rule, Vec<(usize, usize)>> = BTreeMap::new();
    for (s, &share) in SPIKE_SHARES.iter().enumerate() {
        for r in 0..realisations {
            let seed = 1 + r as u64 + 10_000 * s as u64;
            let here =
                keep.as_ref().map_or(dir.path().to_path_buf(), |k| std::path::PathBuf::from(format!("{k}/{s}-{r}")));
            std::fs::create_dir_all(&here).unwrap();
            for (rule, orders) in picks(&here, seed, share, noise, threads) {
                let e = &mut hits.entry(rule).or_insert_with(|| vec![(0, 0); SPIKE_SHARES.len()])[s];
                if orders == Some(TRUE_ORDERS) {
                    e.0 += 1;
                } else if orders.is_some_and(|(b, f)| b + f > TRUE_ORDERS.0 + TRUE_ORDERS.1) {
                    e.1 += 1;
                }
            }
            eprint!("\rspikes {:>4.0} %: {}/{realisations}", share * 100.0, r + 1);
        }
        eprintln!();
    }
    println!(
        "Noise {} % of the output RMS; picks with the true orders (3, 3) / with more parameters, of \
         {realisations} realisations:\n",
        noise * 100.0
    );
    println!("| rule | Gaussian | 5 % spikes | 15 % spikes |");
    println!("|---|---|---|---|");
    for (rule, counts) in &hits {
        let cells: Vec<String> = counts.iter().map(|(t, o)| format!("{t} / {o}")).collect();
        println!("| `{}` | {} |", rule.as_str(), cells.join(" | "));
    }
}
