//! The separable (variable projection) solver, `solver.method = "separable"` (METHOD.md 5.6):
//! known solutions, the inner optimum, the invariants of the outer iteration, and agreement
//! with the full Levenberg-Marquardt solver on noisy data; and the exploration of a long
//! record on its head (`solver.explore_rows`, METHOD.md 5.2 step 5 and 5.5).

mod common;

use common::*;
use oesweep::estimate::chains::{CellOutcome, PairProblem, walk_pair};
use oesweep::estimate::normal::{Layout, NormalEquations};
use oesweep::estimate::{self, Judge, Loss, Problem, SolverMethod, SolverOptions, Workspace, solver};
use oesweep::oe;
use oesweep::oe::Structure;

fn separable() -> SolverOptions {
    SolverOptions { method: SolverMethod::Separable, ..SolverOptions::default() }
}

/// Noisy OE(3,3)-ish data with 5 % spikes (deterministic).
fn spiky(n: usize, offset: f64) -> (Vec<f64>, Vec<f64>) {
    let (b, f) = oe22();
    let u = binary_input(n, 4, 2.0, 11);
    let y0 = oe::simulate_vec(&b, &f, 1, &u);
    let mut rng = Lcg(5);
    let y = y0
        .iter()
        .map(|v| {
            let spike = if rng.next() < 0.05 { 3.0 * (rng.next() - 0.5) * 10.0 } else { 0.0 };
            v + offset + 0.05 * rng.normal() + spike
        })
        .collect();
    (u, y)
}

#[test]
fn noise_free_data_recovers_the_true_parameters_from_a_poor_start() {
    for (b, f, n) in [(oe22().0, oe22().1, 2000), (oe1010().0, oe1010().1, 5000)] {
        for offset in [None, Some(97.0)] {
            let u = binary_input(n, 3, 10.0, 7);
            let mut y = oe::simulate_vec(&b, &f, 1, &u);
            y.iter_mut().for_each(|v| *v += offset.unwrap_or(0.0));
            let prob = Problem {
                u: &u,
                y: &y,
                structure: Structure::siso(b.len(), f.len(), 1),
                offset: offset.is_some(),
                seams: &[],
                missing: &[],
            };
            let truth = estimate::theta_of(&b, &f, offset);
            // F's poles pulled towards the origin, B halved, no offset: the inner problem
            // must find b and c, the outer one F.
            let mut start = estimate::theta_of(&b, &f, offset.map(|_| 0.0));
            for v in &mut start[..b.len()] {
                *v *= 0.5;
            }
            for (j, v) in start[b.len()..b.len() + f.len()].iter_mut().enumerate() {
                *v *= 0.97f64.powi(j as i32 + 1);
            }
            let mut ws = Workspace::new();
            let scale = (y.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
            for loss in [Loss::LeastSquares, Loss::Huber { gamma: 0.05 * scale }] {
                let sol = solver::minimise(&prob, loss, &start, &separable(), &mut ws);
                assert!(
                    sol.termination.converged(),
                    "nb={} offset={offset:?} {loss:?} {:?} crit {:e} it {} theta {:?}",
                    b.len(),
                    sol.termination,
                    sol.criterion,
                    sol.iterations,
                    sol.theta
                );
                let worst =
                    sol.theta.iter().zip(&truth).map(|(g, t)| (g - t).abs() / t.abs().max(1.0)).fold(0.0, f64::max);
                assert!(worst < 1e-6, "nb={} offset={offset:?} {loss:?}: worst relative error {worst:e}", b.len());
            }
        }
    }
}

/// At a separable solution, b and c are the optimum for its F: the gradient of the criterion in
/// them vanishes (to rounding for least squares, to the inner tolerance for Huber).
#[test]
fn the_linear_parameters_are_at_their_inner_optimum() {
    let (u, y) = spiky(3000, 5.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(3, 2, 1), offset: true, seams: &[], missing: &[] };
    let mut ws = Workspace::new();
    let start = vec![0.1, 0.0, 0.0, -1.0, 0.5, 0.0];
    for loss in [Loss::LeastSquares, Loss::Huber { gamma: 0.1 }] {
        let sol = solver::minimise(&prob, loss, &start, &separable(), &mut ws);
        assert!(sol.usable());
        let (b, f, c) = prob.split(&sol.theta);
        let mut xu = vec![0.0; u.len()];
        let mut yhat = vec![0.0; u.len()];
        let mut xy = vec![0.0; u.len()];
        oe::simulate_filtered(b, f, 1, &u, &mut xu, &mut yhat, &mut xy);
        let r: Vec<f64> = y.iter().zip(&yhat).map(|(a, p)| loss.psi(a - p - c)).collect();
        let lay = Layout::siso(3, 2, 1);
        let (mut h, mut g) = (vec![0.0; 36], vec![0.0; 6]);
        let mut ne = NormalEquations::default();
        ne.build(&lay, &xu, &xy, None, &r, &mut h, &mut g);
        ne.add_offset(&lay, &xu, &xy, None, &r, &mut h, &mut g);
        // Relative to the size of the gradient's terms: mean |psi| times the signal level.
        let level = r.iter().map(|v| v.abs()).sum::<f64>() / r.len() as f64 * 2.0;
        for i in [0, 1, 2, 5] {
            assert!(g[i].abs() <= 1e-9 * level, "{loss:?}: d criterion / d beta_{i} = {:e}", g[i]);
        }
    }
}

#[test]
fn the_criterion_falls_on_every_accepted_step_and_f_stays_stable() {
    let (u, y) = spiky(4000, 0.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(4, 4, 1), offset: false, seams: &[], missing: &[] };
    let mut ws = Workspace::new();
    ws.record_trace = true;
    let judge = Judge::default();
    let ls = estimate::fit_ls(&prob, &judge, &separable(), &mut ws);
    assert!(ls.ok());
    for k in [0.05, 0.3, 2.0] {
        let h = estimate::fit_huber(&prob, ls.sigma, k, &ls.theta(), &judge, &separable(), &mut ws);
        assert!(ws.trace.len() >= 2, "k={k}: no step taken");
        for w in ws.trace.windows(2) {
            assert!(w[1] < w[0], "k={k}: W rose from {} to {}", w[0], w[1]);
        }
        assert!(oe::is_stable(&h.f), "k={k}");
    }
}

/// On the same data and from the same start both methods reach the same minimum.
#[test]
fn separable_and_full_levenberg_marquardt_agree() {
    let (u, y) = spiky(5000, 2.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(2, 2, 1), offset: true, seams: &[], missing: &[] };
    let judge = Judge::default();
    let mut ws = Workspace::new();
    let lm = SolverOptions::default();
    let ls_lm = estimate::fit_ls(&prob, &judge, &lm, &mut ws);
    let ls_vp = estimate::fit_ls(&prob, &judge, &separable(), &mut ws);
    assert!(
        (ls_lm.criterion - ls_vp.criterion).abs() <= 1e-9 * ls_lm.criterion,
        "{} {}",
        ls_lm.criterion,
        ls_vp.criterion
    );
    for k in [0.05, 0.2, 1.0] {
        let a = estimate::fit_huber(&prob, ls_lm.sigma, k, &ls_lm.theta(), &judge, &lm, &mut ws);
        let b = estimate::fit_huber(&prob, ls_lm.sigma, k, &ls_lm.theta(), &judge, &separable(), &mut ws);
        assert!((a.criterion - b.criterion).abs() <= 1e-7 * a.criterion, "k={k}: {} vs {}", a.criterion, b.criterion);
        for (p, q) in a.theta().iter().zip(b.theta()) {
            assert!((p - q).abs() <= 1e-4 * p.abs().max(1e-3), "k={k}: {:?} vs {:?}", a.theta(), b.theta());
        }
    }
}

/// The job field: a sweep with `solver.method = "separable"` runs and says so in job.json.
/// `oesweep run` of `job` (written to `dir/job.json`) on 2 threads; it must succeed.
fn run_job(dir: &std::path::Path, job: &serde_json::Value) {
    let path = dir.join("job.json");
    std::fs::write(&path, job.to_string()).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["run", path.to_str().unwrap(), "--threads", "2", "--quiet"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_job_selects_the_separable_solver() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = spiky(1500, 0.0);
    let mut csv = String::from("u,y\n");
    for (a, b) in u.iter().zip(&y) {
        csv.push_str(&format!("{a},{b}\n"));
    }
    std::fs::write(dir.path().join("d.csv"), csv).unwrap();
    let job = serde_json::json!({
        "name": "vp",
        "data": {"path": dir.path().join("d.csv"), "ts": 1e-3, "rows": [1, 1000]},
        "validation": {"rows": [1001, 1500]},
        "grid": {"nb": [1, 3], "nf": [1, 3], "k": {"from": 0.1, "to": 1.0, "count": 3}},
        "solver": {"method": "separable"},
        "output": dir.path().join("out"),
    });
    run_job(dir.path(), &job);
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/job.json")).unwrap()).unwrap();
    assert_eq!(written["solver"]["method"], "separable");
    let sel: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("out/selection.json")).unwrap()).unwrap();
    // The L1C pick is the true structure.
    assert_eq!((&sel["m2"]["nb"], &sel["m2"]["nf"]), (&serde_json::json!(2), &serde_json::json!(2)));
}

/// Settings that explore on the whole 40 000-sample record of the two tests below, and on
/// its first 4096 samples.
fn whole_and_head() -> [SolverOptions; 2] {
    [0, 4096].map(|explore_rows| SolverOptions { explore_rows, ..SolverOptions::default() })
}

/// A record four times `solver.explore_rows` explores its least-squares starts on its head and
/// minimises the best on the whole record: on a long record with spikes it reaches the
/// minima of the whole-record exploration (least squares and the Huber cells from its starts).
#[test]
fn exploring_the_starts_on_the_head_reaches_the_whole_record_minima() {
    let (u, y) = spiky(40_000, 1.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(3, 3, 1), offset: true, seams: &[], missing: &[] };
    let (judge, mut ws) = (Judge::default(), Workspace::new());
    let [whole, head] = whole_and_head();
    let a = estimate::fit_ls(&prob, &judge, &whole, &mut ws);
    let b = estimate::fit_ls(&prob, &judge, &head, &mut ws);
    assert!((a.criterion - b.criterion).abs() <= 1e-8 * a.criterion, "{} vs {}", a.criterion, b.criterion);
    for k in [0.05, 0.5, 2.0] {
        let (ha, _) = estimate::fit_huber_multi(&prob, &a, k, &judge, &whole, &mut ws);
        let (hb, _) = estimate::fit_huber_multi(&prob, &b, k, &judge, &head, &mut ws);
        assert!(
            (ha.criterion - hb.criterion).abs() <= 1e-7 * ha.criterion,
            "k={k}: {} vs {}",
            ha.criterion,
            hb.criterion
        );
    }
}

/// The cells `walk_pair` fits for the k not `done`, as (k index, fit); a panicked cell fails
/// the test.
fn walked_cells(
    pair: &PairProblem,
    ls: &estimate::LsFit,
    ks: &[(usize, f64)],
    done: &[bool],
    ws: &mut Workspace,
) -> Vec<(usize, estimate::HuberFit)> {
    let cells = walk_pair(pair, &ls.theta(), &ls.alternatives, ks, done, &|| false, ws).unwrap();
    cells
        .into_iter()
        .map(|(ki, c)| match c {
            CellOutcome::Fit { fit, .. } => (ki, *fit),
            CellOutcome::Panicked(r) => panic!("{r}"),
        })
        .collect()
}

/// On a record four times `solver.explore_rows` the chains walk on its head and each cell is
/// then fitted on the whole record from there: every cell reaches the whole-record walk's
/// minimum (or a lower one), and is a fit of the whole record.
#[test]
fn walking_the_chains_on_the_head_reaches_the_whole_record_cells() {
    let (u, y) = spiky(40_000, 1.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(3, 3, 1), offset: true, seams: &[], missing: &[] };
    let (judge, mut ws) = (Judge::default(), Workspace::new());
    let [whole, head] = whole_and_head();
    let ls = estimate::fit_ls(&prob, &judge, &whole, &mut ws);
    let ks: Vec<(usize, f64)> = (0..10).map(|i| (i, 0.05 * 40f64.powf(i as f64 / 9.0))).collect();
    let done = vec![false; ks.len()];
    let mut walk = |opts: &SolverOptions| {
        let pair = PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts };
        walked_cells(&pair, &ls, &ks, &done, &mut ws)
    };
    let (a, b) = (walk(&whole), walk(&head));
    for ((_, x), (_, z)) in a.iter().zip(&b) {
        assert!(
            z.criterion <= x.criterion * (1.0 + 1e-6),
            "k = {}: {} on the head, {} whole",
            x.k,
            z.criterion,
            x.criterion
        );
        // A fit of the whole record: its W is that of its parameters there.
        let yhat = prob.simulate_vec(&z.theta());
        let w = Loss::Huber { gamma: z.gamma }.criterion(&y, &yhat);
        assert!((w - z.criterion).abs() <= 1e-9 * w, "k = {}: {w} vs {}", z.k, z.criterion);
    }
}

/// A resumed long-record pair (cells an earlier run finished are not returned) gives its other
/// cells bit for bit as the uninterrupted walk: each cell's whole-record fit starts from the
/// previous cell's shift, which the walk computes again for a finished cell.
#[test]
fn a_resumed_head_walk_gives_the_same_cells() {
    let (u, y) = spiky(30_000, 1.0);
    let prob = Problem { u: &u, y: &y, structure: Structure::siso(3, 3, 1), offset: true, seams: &[], missing: &[] };
    let (judge, mut ws) = (Judge::default(), Workspace::new());
    let [_, head] = whole_and_head();
    let ls = estimate::fit_ls(&prob, &judge, &head, &mut ws);
    let ks: Vec<(usize, f64)> = (0..8).map(|i| (i, 0.05 * 40f64.powf(i as f64 / 7.0))).collect();
    let pair = PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &head };
    let mut walk = |done: &[bool]| {
        let cells = walked_cells(&pair, &ls, &ks, done, &mut ws);
        cells.into_iter().map(|(ki, fit)| (ki, fit.theta(), fit.criterion)).collect::<Vec<_>>()
    };
    let all = walk(&[false; 8]);
    let done = [true, false, true, true, false, false, true, false];
    let resumed = walk(&done);
    let expected: Vec<_> = all.into_iter().filter(|(ki, _, _)| !done[*ki]).collect();
    assert_eq!(resumed, expected);
}

/// On a record explored on its head the nested starts are minimised on the whole record, so a
/// pair's least-squares criterion is never above its sub-models' (METHOD.md 5.2 steps 2 and 5).
/// Explored on the head with the rest (before ba7b1b8), 9 of these 64 pairs were above.
#[test]
fn a_head_explored_record_keeps_larger_models_no_worse_than_their_sub_models() {
    use oesweep::table::FitKind;
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("rec.csv");
    let noise = Noise { amplitude: 10.0, std: 0.1, spike_probability: 0.05, spike_range: "20,60" };
    simulate(&piezo_system(), &data, 8000, 5, &noise);
    let job = serde_json::json!({
        "name": "nested-on-head", "data": {"path": data, "ts": 1e-4}, "offset": "none", "initial_state": "zero",
        "grid": {"nb": [1, 8], "nf": [1, 8], "k": [1.0]},
        // 8000 samples are at least four heads of 1000: the starts are explored on the head.
        "solver": {"explore_rows": 1000},
        "output": dir.path().join("out"),
    });
    run_job(dir.path(), &job);
    let rows = oesweep::export::parquet::read_cells(&dir.path().join("out/cells.parquet")).unwrap();
    let ls: std::collections::HashMap<(u32, u32), f64> = rows
        .iter()
        .filter(|r| r.key.kind == FitKind::Ls)
        .map(|r| ((r.key.nb, r.key.nf), r.fit.criterion.expect("every fit usable")))
        .collect();
    assert_eq!(ls.len(), 64);
    for (&(nb, nf), &v) in &ls {
        for sub in [(nb - 1, nf), (nb, nf - 1)] {
            if let Some(&s) = ls.get(&sub) {
                assert!(v <= s * (1.0 + 1e-9), "OE({nb},{nf}) {v} is above its sub-model OE{sub:?} {s}");
            }
        }
    }
}
