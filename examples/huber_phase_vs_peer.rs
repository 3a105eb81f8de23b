//! Speed of one Huber fit from the shared L2 start against the scipy peer's, cell by cell
//! (issue 4: "one Huber cell, OE(12,12), from the shared L2 start, >= 50x the peer").
//!
//! Usage: `cargo run --release --example huber_phase_vs_peer -- EST.csv PEER.jsonl [NB,NF ...]`
//! where PEER.jsonl is the output of
//! `python3 ../shared/peer/peer.py --est EST.csv --val VAL.csv --grid nb=.. nf=.. k=.. --jobs 1 --out PEER.jsonl`
//! run on an otherwise idle machine with `OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1`: its
//! `seconds` field times the peer's Huber fit alone (from its own L2 fit), and with `--jobs 2`
//! or a multi-threaded BLAS the two processes contend and the field comes out about 2x larger.
//!
//! For every Huber line of the file this runs oesweep's L2 phase for the order pair (once)
//! and then one Huber minimisation of W with gamma = k sigma from theta_LS, exactly as the
//! peer does (no extra starts, no continuation along k), timed as the median of 3 runs on
//! this thread. Each tool starts from its own theta_LS; both minimise W with ftol 1e-8.
//! Prints the cells of the listed order pairs one per line and each listed pair's total over
//! its k values, then the distribution of
//! peer/ours time ratios over all cells and the iterations of both sides (ours: outer
//! Levenberg-Marquardt iterations; peer: Jacobian evaluations of scipy's trf).
//! Environment: OESWEEP_METHOD and OESWEEP_EXPLORE_ROWS override `solver.method` and
//! `solver.explore_rows`.

use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, solver};
use oesweep::oe::Structure;
use std::time::Instant;

const REPEAT: usize = 3;

struct Cell {
    nb: usize,
    nf: usize,
    k: f64,
    peer_seconds: f64,
    peer_jacobians: u64,
}

fn parse_pair(s: &str) -> Option<(usize, usize)> {
    let (a, b) = s.split_once(',')?;
    Some((a.trim().parse().ok()?, b.trim().parse().ok()?))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = || -> ! {
        eprintln!("usage: huber_phase_vs_peer EST.csv PEER.jsonl [NB,NF ...]");
        std::process::exit(2);
    };
    if args.len() < 3 {
        usage();
    }
    let show: Vec<(usize, usize)> = args[3..].iter().map(|s| parse_pair(s).unwrap_or_else(|| usage())).collect();
    let rec = oesweep::data::read_record(args[1].as_ref(), "u", "y").expect("estimation data");
    let text = std::fs::read_to_string(&args[2]).expect("peer output");
    let mut cells = Vec::new();
    for line in text.lines().filter(|l| !l.trim().is_empty()) {
        let v: serde_json::Value = serde_json::from_str(line).expect("JSON line");
        if v["method"] != "huber" {
            continue;
        }
        let num = |key: &str| v[key].as_f64().unwrap_or_else(|| panic!("peer line without {key}"));
        cells.push(Cell {
            nb: num("nb") as usize,
            nf: num("nf") as usize,
            k: num("k"),
            peer_seconds: num("seconds"),
            peer_jacobians: num("njev") as u64,
        });
    }
    if cells.is_empty() {
        eprintln!("{}: no Huber lines", args[2]);
        std::process::exit(2);
    }

    let mut opts = SolverOptions::default();
    if let Ok(v) = std::env::var("OESWEEP_METHOD") {
        opts.method = serde_json::from_value(serde_json::Value::String(v)).expect("lm or separable");
    }
    if let Ok(v) = std::env::var("OESWEEP_EXPLORE_ROWS") {
        opts.explore_rows = v.parse().expect("a count");
    }
    let hopts = opts.huber();
    let mut ws = Workspace::new();
    let mut ls: Option<((usize, usize), estimate::LsFit)> = None;
    let (mut ours_total, mut peer_total) = (0.0, 0.0);
    let (mut ours_it, mut peer_it) = (0usize, 0u64);
    let mut ratios = Vec::with_capacity(cells.len());
    // Per listed order pair: (ours, peer) seconds summed over its k values, and their count.
    let mut pair_totals: Vec<((usize, usize), f64, f64, usize)> = Vec::new();
    for c in &cells {
        let prob = Problem {
            u: &rec.u,
            y: &rec.y,
            structure: Structure::siso(c.nb, c.nf, 1),
            offset: false,
            seams: &[],
            missing: &[],
        };
        if ls.as_ref().is_none_or(|(key, _)| *key != (c.nb, c.nf)) {
            ls = Some(((c.nb, c.nf), estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws)));
        }
        let fit = &ls.as_ref().expect("set above").1;
        let theta = fit.theta();
        let loss = Loss::Huber { gamma: c.k * fit.sigma };
        let mut times = [0.0; REPEAT];
        let mut sol = None;
        for t in times.iter_mut() {
            let start = Instant::now();
            sol = Some(solver::minimise(&prob, loss, &theta, &hopts, &mut ws));
            *t = start.elapsed().as_secs_f64();
        }
        times.sort_by(f64::total_cmp);
        let ours = times[REPEAT / 2];
        let sol = sol.expect("REPEAT > 0");
        ours_total += ours;
        peer_total += c.peer_seconds;
        ours_it += sol.iterations;
        peer_it += c.peer_jacobians;
        ratios.push(c.peer_seconds / ours);
        if show.contains(&(c.nb, c.nf)) {
            match pair_totals.iter_mut().find(|p| p.0 == (c.nb, c.nf)) {
                Some(p) => {
                    p.1 += ours;
                    p.2 += c.peer_seconds;
                    p.3 += 1;
                }
                None => pair_totals.push(((c.nb, c.nf), ours, c.peer_seconds, 1)),
            }
            println!(
                "OE({},{}) k = {:<7.4}: ours {:6.3} ms ({:3} it), peer {:6.1} ms ({:3} jac): {:5.1}x",
                c.nb,
                c.nf,
                c.k,
                ours * 1e3,
                sol.iterations,
                c.peer_seconds * 1e3,
                c.peer_jacobians,
                c.peer_seconds / ours
            );
        }
    }
    for ((nb, nf), ours, peer, count) in &pair_totals {
        println!(
            "OE({nb},{nf}) over its {count} k: ours {:.2} ms, peer {:.1} ms in total ({:.1}x)",
            ours * 1e3,
            peer * 1e3,
            peer / ours
        );
    }
    ratios.sort_by(f64::total_cmp);
    let q = |p: f64| ratios[((ratios.len() - 1) as f64 * p).round() as usize];
    println!(
        "{} Huber cells: ours {:.3} s, peer {:.2} s in total ({:.1}x); per cell peer/ours: median {:.1}x, \
         10 % {:.1}x, 90 % {:.1}x, min {:.1}x, max {:.1}x",
        cells.len(),
        ours_total,
        peer_total,
        peer_total / ours_total,
        q(0.5),
        q(0.1),
        q(0.9),
        ratios[0],
        ratios[ratios.len() - 1]
    );
    println!(
        "iterations: ours {ours_it} ({:.1} us each), peer {peer_it} Jacobians ({:.0} us each)",
        ours_total / ours_it.max(1) as f64 * 1e6,
        peer_total / peer_it.max(1) as f64 * 1e6
    );
}
