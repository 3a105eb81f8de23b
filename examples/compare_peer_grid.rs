//! Answer quality against the scipy peer on a grid, at the same gamma (issue 4).
//!
//! Usage: `cargo run --release --example compare_peer_grid -- EST.csv PEER.jsonl`
//! where PEER.jsonl is the output of
//! `python3 ../shared/peer/peer.py --est EST.csv --val VAL.csv --grid nb=.. nf=.. k=.. --out PEER.jsonl`.
//!
//! For every order pair it runs oesweep's least-squares phase and compares its criterion with
//! the peer's (`mse / 2`); for every Huber line it runs oesweep's Huber fit from oesweep's own
//! least-squares solution with the *peer's* gamma, so both minimise the same W, and compares
//! the criteria with a relative tolerance of 1e-4 (METHOD.md 8: local minima differ in the
//! 5th digit). Prints the share of cells where oesweep is no worse, and the worst cases.

use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, solver};
use std::collections::BTreeMap;

struct Crit {
    criterion: f64,
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: compare_peer_grid EST.csv PEER.jsonl");
        std::process::exit(2);
    }
    let rec = oesweep::data::read_record(args[1].as_ref(), "u", "y").expect("estimation data");
    let text = std::fs::read_to_string(&args[2]).expect("peer output");
    let mut by_pair: BTreeMap<(usize, usize), Vec<serde_json::Value>> = BTreeMap::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let v: serde_json::Value = serde_json::from_str(line).expect("JSON line");
        let key = (v["nb"].as_u64().unwrap() as usize, v["nf"].as_u64().unwrap() as usize);
        by_pair.entry(key).or_default().push(v);
    }
    // OESWEEP_EXTRA_STARTS overrides solver.huber_extra_starts (to measure its effect).
    let mut opts = SolverOptions::default();
    if let Ok(v) = std::env::var("OESWEEP_EXTRA_STARTS") {
        opts.huber_extra_starts = v.parse().expect("a count");
    }
    let mut ws = Workspace::new();
    let tol = 1e-4;
    let (mut ls_ok, mut ls_n, mut h_ok, mut h_n) = (0, 0, 0, 0);
    let mut worst: Vec<(f64, String)> = Vec::new();
    for ((nb, nf), lines) in &by_pair {
        let prob = Problem { u: &rec.u, y: &rec.y, nb: *nb, nf: *nf, delay: 1 };
        let ls = estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws);
        for v in lines {
            if v["method"] == "ls" {
                let peer = v["mse"].as_f64().unwrap() / 2.0;
                let rel = (ls.criterion - peer) / peer;
                ls_n += 1;
                if rel <= tol {
                    ls_ok += 1;
                } else {
                    worst.push((rel, format!("ls    OE({nb},{nf}): ours {:.8e} peer {:.8e}", ls.criterion, peer)));
                }
            } else {
                let gamma = v["gamma"].as_f64().unwrap();
                let peer = v["W"].as_f64().unwrap();
                // oesweep's multi-start Huber phase (estimate::fit_huber_multi), at the peer's gamma.
                let mut crit = f64::INFINITY;
                for start in std::iter::once(ls.theta()).chain(ls.alternatives.iter().cloned()) {
                    let sol = solver::minimise(&prob, Loss::Huber { gamma }, &start, &opts, &mut ws);
                    crit = crit.min(sol.criterion);
                }
                let sol = Crit { criterion: crit };
                let rel = (sol.criterion - peer) / peer;
                h_n += 1;
                if rel <= tol {
                    h_ok += 1;
                } else {
                    worst.push((
                        rel,
                        format!(
                            "huber OE({nb},{nf}) k={}: ours {:.8e} peer {:.8e}",
                            v["k"].as_f64().unwrap(),
                            sol.criterion,
                            peer
                        ),
                    ));
                }
            }
        }
    }
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (rel, what) in worst.iter().take(15) {
        println!("worse by {:.2e}: {what}", rel);
    }
    println!(
        "least squares: no worse than the peer in {ls_ok}/{ls_n} order pairs ({:.1} %)",
        100.0 * ls_ok as f64 / ls_n.max(1) as f64
    );
    println!(
        "Huber (same gamma): no worse than the peer in {h_ok}/{h_n} cells ({:.1} %)",
        100.0 * h_ok as f64 / h_n.max(1) as f64
    );
}
