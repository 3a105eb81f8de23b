//! Monte Carlo benchmark of the pick rules and the lead rule (METHOD.md 7.1): how often each
//! rule of `selection.json`'s `picks` finds the true orders, from one record and with a
//! validation record, and how often a "widen the grid" warning appears on a grid that contains
//! the truth.
//!
//! ```text
//! cargo run --release --example order_selection_mc -- [REALISATIONS] [THREADS] [NOISE] [SYSTEM]
//! ```
//!
//! (defaults 50, 2, 0.05, `low`; SYSTEM is `low`, `slow`, `resonant` or `all`; `MC_KEEP=DIR`
//! keeps each realisation's job and results in DIR; `MC_SPIKES=lo,hi` sets the spikes' size in
//! noise standard deviations, default 5,15; `MC_GRID=M` searches nB, nF 1..M instead of 1..5;
//! `MC_VERBOSE=1` prints every warning about the grid).
//!
//! The systems (delay 1):
//! - `low`: `B = 1 + 0.5 q^-1 + 0.3 q^-2`, `F` with poles 0.85 and 0.6 +/- 0.5j: OE(3,3);
//! - `slow`: `B = 1 + 0.5 q^-1`, `F` with poles 0.98 and 0.7 (a pole near the unit circle): OE(2,2);
//! - `resonant`: `B = 1 + 0.4 q^-1 + 0.2 q^-2 + 0.1 q^-3`, `F` with two lightly damped pairs
//!   0.97 at +/- 0.5 rad and 0.93 at +/- 1.4 rad: OE(4,4).
//!
//! Per realisation (seeded, so the table is reproducible): a PRBS (10-bit register, levels +/-1)
//! through the system, N = 2000, Gaussian noise of NOISE times the noise-free output's RMS, and
//! on 0 %, 5 % or 15 % of the samples a spike of 5 to 15 noise standard deviations of random
//! sign; a validation record of the same kind (another seed). The job: grid nB, nF 1..5, delay
//! 1, six k from 0.1 to 2 (log), the default offset, initial state and lead rule, run through
//! `engine::run` like `oesweep run`, once without and once with the validation record.
//!
//! Prints Markdown tables: per rule (and `lead`, the rule the summary leads with by default),
//! the realisations whose pick has the true orders and, after the slash, those whose pick is
//! larger in nB + nF (over-fitted); then the runs with a "widen the grid" warning.

use oesweep::engine::{self, RunEnd, RunOptions};
use oesweep::reduce::{Rule, Selection};
use oesweep::simulate::{self, NoiseKind, Outliers, SimOptions, SystemSpec};
use std::collections::BTreeMap;
use std::path::Path;

const N: usize = 2000;
const SPIKE_SHARES: [f64; 3] = [0.0, 0.05, 0.15];

struct System {
    name: &'static str,
    spec: SystemSpec,
    orders: (u32, u32),
}

fn f_from_poles(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    oesweep::oe::poly_from_poles(pairs, real)
}

fn systems(which: &str) -> Vec<System> {
    let all = vec![
        System {
            name: "low",
            // (1 - 0.85 q^-1)(1 - 1.2 q^-1 + 0.61 q^-2)
            spec: SystemSpec { b: vec![1.0, 0.5, 0.3], f: vec![-2.05, 1.63, -0.5185], delay: 1 },
            orders: (3, 3),
        },
        System {
            name: "slow",
            spec: SystemSpec { b: vec![1.0, 0.5], f: f_from_poles(&[], &[0.98, 0.7]), delay: 1 },
            orders: (2, 2),
        },
        System {
            name: "resonant",
            spec: SystemSpec {
                b: vec![1.0, 0.4, 0.2, 0.1],
                f: f_from_poles(&[(0.97, 0.5), (0.93, 1.4)], &[]),
                delay: 1,
            },
            orders: (4, 4),
        },
    ];
    all.into_iter().filter(|s| which == "all" || s.name == which).collect()
}

/// The record of one seed: noise `noise` times the noise-free output's RMS, spikes on `share`.
fn record(sys: &SystemSpec, seed: u64, share: f64, noise: f64, spikes: (f64, f64), path: &Path) {
    let clean =
        SimOptions { n: N, bits: 10, amplitude: 1.0, seed, noise_std: 0.0, noise: NoiseKind::Gaussian, outliers: None };
    let y0 = simulate::generate(sys, &clean).expect("the benchmark system").y0;
    let rms = (y0.iter().map(|v| v * v).sum::<f64>() / N as f64).sqrt();
    let sd = noise * rms;
    let opts = SimOptions {
        noise_std: sd,
        outliers: (share > 0.0).then_some(Outliers { probability: share, min: spikes.0 * sd, max: spikes.1 * sd }),
        ..clean
    };
    let rec = simulate::generate(sys, &opts).expect("the benchmark system");
    simulate::write_csv(path, &rec).expect("a writable temporary folder");
}

/// What one run says: rule -> orders (with `None` as the lead's key), and whether a warning
/// tells the user to widen the grid.
struct Outcome {
    picks: BTreeMap<Option<Rule>, Option<(u32, u32)>>,
    widen: bool,
}

fn outcome(sel: &Selection) -> Outcome {
    let orders = |r: Rule| sel.picks.get(&r).and_then(|p| p.model.as_ref()).map(|m| (m.key.nb, m.key.nf));
    let mut picks: BTreeMap<Option<Rule>, Option<(u32, u32)>> =
        Rule::ALL.iter().map(|&r| (Some(r), orders(r))).collect();
    picks.insert(None, orders(sel.rule));
    let widen = sel.warnings.iter().any(|w| w.contains("widen the grid"));
    if std::env::var_os("MC_VERBOSE").is_some() {
        sel.warnings.iter().filter(|w| w.contains("grid")).for_each(|w| eprintln!("\n{w}"));
    }
    Outcome { picks, widen }
}

/// The outcomes of one realisation: (one record, with a validation record).
/// The grid nB, nF 1..GRID_MAX (5, or `MC_GRID`: below the true orders it checks the edge warning's hits).
fn grid_max() -> u32 {
    std::env::var("MC_GRID").ok().map_or(5, |g| g.parse().expect("MC_GRID=max"))
}

fn realisation(
    dir: &Path,
    sys: &System,
    seed: u64,
    share: f64,
    noise: f64,
    spikes: (f64, f64),
    threads: usize,
) -> [Outcome; 2] {
    record(&sys.spec, seed, share, noise, spikes, &dir.join("est.csv"));
    record(&sys.spec, seed + 1_000_000, share, noise, spikes, &dir.join("val.csv"));
    [false, true].map(|validation| {
        let mut job = serde_json::json!({
            "name": "order-selection-mc",
            "data": { "path": "est.csv", "u": "u", "y": "y", "ts": 1.0 },
            "delay": 1,
            "grid": { "nb": [1, grid_max()], "nf": [1, grid_max()], "k": { "from": 0.1, "to": 2.0, "count": 6, "spacing": "log" } },
            "output": if validation { "out-val" } else { "out-one" }
        });
        if validation {
            job["validation"] = serde_json::json!({ "path": "val.csv", "u": "u", "y": "y" });
        }
        let path = dir.join(if validation { "job-val.json" } else { "job-one.json" });
        std::fs::write(&path, job.to_string()).unwrap();
        let opts = RunOptions { threads, quiet: true, force: true, ..RunOptions::default() };
        let run = engine::run(&path, &opts, &|_| {}).expect("the benchmark job runs");
        let RunEnd::Merged { selection, .. } = run.end else { panic!("the run did not finish") };
        outcome(&selection)
    })
}

/// Rule (None: the lead) -> per spike share: (picks with the true orders, over-fitted picks).
type Hits = BTreeMap<Option<Rule>, Vec<(usize, usize)>>;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, d: f64| args.get(i).map_or(d, |a| a.parse().expect("a number"));
    let realisations = num(0, 50.0) as usize;
    let threads = num(1, 2.0) as usize;
    let noise = num(2, 0.05);
    let which = args.get(3).map_or("low", |s| s.as_str());
    let spikes = std::env::var("MC_SPIKES").ok().map_or((5.0, 15.0), |s| {
        let v: Vec<f64> = s.split(',').map(|x| x.parse().expect("MC_SPIKES=lo,hi")).collect();
        (v[0], v[1])
    });
    let dir = tempfile::tempdir().unwrap();
    let keep = std::env::var("MC_KEEP").ok();
    for sys in systems(which) {
        // [one record, validation] -> rule -> per spike share: (true orders, over-fitted); widen counts
        let mut hits: [Hits; 2] = Default::default();
        let mut widen = [[0usize; SPIKE_SHARES.len()]; 2];
        for (s, &share) in SPIKE_SHARES.iter().enumerate() {
            for r in 0..realisations {
                let seed = 1 + r as u64 + 10_000 * s as u64;
                let here = keep.as_ref().map_or(dir.path().to_path_buf(), |k| {
                    std::path::PathBuf::from(format!("{k}/{}-{s}-{r}", sys.name))
                });
                std::fs::create_dir_all(&here).unwrap();
                let outcomes = realisation(&here, &sys, seed, share, noise, spikes, threads);
                for (v, o) in outcomes.iter().enumerate() {
                    widen[v][s] += usize::from(o.widen);
                    for (rule, orders) in &o.picks {
                        let e = &mut hits[v].entry(*rule).or_insert_with(|| vec![(0, 0); SPIKE_SHARES.len()])[s];
                        if *orders == Some(sys.orders) {
                            e.0 += 1;
                        } else if orders.is_some_and(|(b, f)| b + f > sys.orders.0 + sys.orders.1) {
                            e.1 += 1;
                        }
                    }
                }
                eprint!("\r{} spikes {:>4.0} %: {}/{realisations}", sys.name, share * 100.0, r + 1);
            }
            eprintln!();
        }
        println!(
            "\nSystem `{}` (true orders {:?}), noise {} % of the output RMS, spikes of {} to {} noise standard \
             deviations; picks with the true orders / with more parameters, of {realisations} realisations \
             (one record | with a validation record):\n",
            sys.name,
            sys.orders,
            noise * 100.0,
            spikes.0,
            spikes.1
        );
        println!("| rule | Gaussian | 5 % spikes | 15 % spikes | Gaussian, val. | 5 %, val. | 15 %, val. |");
        println!("|---|---|---|---|---|---|---|");
        for rule in hits[0].keys() {
            let cells: Vec<String> =
                hits.iter().flat_map(|h| h[rule].iter().map(|(t, o)| format!("{t} / {o}"))).collect();
            let name = rule.map_or("**lead**".to_string(), |r| format!("`{}`", r.as_str()));
            println!("| {name} | {} |", cells.join(" | "));
        }
        let w: Vec<String> = widen.iter().flat_map(|v| v.iter().map(|c| c.to_string())).collect();
        println!("| runs warned \"widen the grid\" | {} |", w.join(" | "));
    }
}
