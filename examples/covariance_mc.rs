//! `cargo run --release --example covariance_mc -- [N] [M] [SIGMA] [prbs|multisine] [WARMUP]
//! [SYSTEM]`:
//! Monte Carlo check of the reported parameter standard deviations (METHOD.md 10) on a
//! lightly damped OE(12,12) system (three resonances, as a piezo actuator). Each of M noise
//! realisations of N samples is fitted by least squares and by Huber (k = 1.5) at the true
//! orders, started from the true parameters so that every fit reaches the minimum near them.
//! Prints, per parameter, the mean reported std against the spread of the estimates (plain
//! and MAD-based), and the same for |G| at a few frequencies. WARMUP > 0 makes the records
//! start from the true system's state after that many samples of input (a transient that
//! the zero-initial-state model cannot follow). SYSTEM picks the true OE(12,12) (`c`, the
//! default: scaled Gram condition 5e8; `d` 8e11; `g` 2e13; `a` 6e15, the one of
//! `tests/covariance_large.rs`). Environment: `HOLD=k` holds each binary level k samples,
//! `PER_INPUT=1` draws a new input per realisation, `TIGHT=1` fits with tolerances 1e-15.
//! The fits report the library's std; the line "std of 672e0f6" recomputes the old one (the
//! Cholesky inverse of the formed Gram matrix) at the same estimates.

use faer::linalg::solvers::DenseSolveCore;
use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, evidence};
use oesweep::oe;

mod common;

use common::Lcg;

fn poly(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    oesweep::oe::poly_from_poles(pairs, real)
}

/// The true OE(12,12) systems: three lightly damped modes (as the piezo system of
/// `jobs/data/piezo_system.json`) and further poles; zeros away from the poles except in
/// `piezo12`, `oe1010` and `b` (near cancellations: numerically singular Gram matrices).
fn system(which: &str) -> (Vec<f64>, Vec<f64>) {
    let (f, bz) = match which {
        "piezo12" => (
            poly(&[(0.9891, 0.4398), (0.9612, 1.3195), (0.9015, 2.0735)], &[0.85, 0.5, 0.3, 0.1, -0.5, -0.2]),
            poly(&[(0.85, 0.817), (0.9, 1.696), (0.7, 2.8)], &[-1.8, -0.8, -0.6, 0.65, 0.7]),
        ),
        "oe1010" => (
            poly(&[(0.985, 0.45), (0.97, 1.3), (0.9, 2.2)], &[0.8, 0.5, -0.3, 0.6]),
            poly(&[(0.8, 0.9), (0.85, 2.0)], &[-0.7, 0.4, -0.2, 0.3, 0.55]),
        ),
        "a" => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.8, 0.5), (0.7, 1.5), (0.6, 2.5)], &[]),
            poly(&[(0.9, 1.25), (0.85, 2.6)], &[-0.9, -0.6, -0.3, 0.2, 0.45, -1.5, 1.3]),
        ),
        "d" => (
            poly(&[(0.985, 0.45), (0.97, 1.3), (0.95, 2.2), (0.8, 0.9), (0.7, 2.7)], &[0.6, -0.5]),
            poly(&[(0.8, 0.8), (0.85, 1.8), (0.7, 2.5)], &[-0.7, 0.4, -0.3, 0.5, 0.2]),
        ),
        "e" => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.6, 0.5), (0.6, 1.5), (0.5, 2.5)], &[]),
            poly(&[(0.9, 0.6), (0.9, 1.25), (0.9, 2.2)], &[-1.5, 1.5, -2.0, 2.0, -3.0]),
        ),
        "f" => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.7, 0.5), (0.7, 1.5), (0.6, 2.5)], &[]),
            poly(&[(0.9, 0.6), (0.9, 1.25), (0.9, 2.2)], &[-1.5, 1.5, -2.0, 2.0, -3.0]),
        ),
        "g" => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.8, 0.5), (0.7, 1.5), (0.6, 2.5)], &[]),
            poly(&[(0.9, 0.6), (0.9, 1.25), (0.9, 2.2)], &[-1.5, 1.5, -2.0, 2.0, -3.0]),
        ),
        "b" => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6)], &[0.9, 0.7, 0.5, 0.3, 0.1, -0.1]),
            poly(&[(0.9, 1.25), (0.85, 2.6)], &[-0.9, -0.6, -0.3, 0.2, 0.45, -1.5, 1.3]),
        ),
        _ => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.5, 1.0), (0.5, 2.0), (0.5, 3.0)], &[]),
            poly(&[(0.9, 0.6), (0.9, 1.25), (0.9, 2.2)], &[-1.5, 1.5, -2.0, 2.0, -3.0]),
        ),
    };
    // poly_from_roots gives the monic [1, c1, ...]; B = g (1 + c1 q^-1 + ...).
    let (fs, bs): (f64, f64) = (1.0 + f.iter().sum::<f64>(), bz.iter().sum::<f64>() + 1.0);
    let b: Vec<f64> = std::iter::once(1.0).chain(bz.iter().copied()).map(|v| v * fs / bs).collect();
    (b, f)
}

fn input(kind: &str, n: usize, seed: u64) -> Vec<f64> {
    let mut r = Lcg(seed);
    match kind {
        "multisine" => {
            let k = 200;
            let ph: Vec<f64> = (0..k).map(|_| std::f64::consts::TAU * r.next()).collect();
            (0..n)
                .map(|t| {
                    (0..k)
                        .map(|i| (std::f64::consts::PI * (i as f64 + 0.5) / k as f64 * t as f64 + ph[i]).cos())
                        .sum::<f64>()
                        / (k as f64 / 2.0).sqrt()
                })
                .collect()
        }
        _ => {
            let hold: usize = std::env::var("HOLD").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
            common::binary(n, hold, -1.0, 1.0, &mut r)
        }
    }
}

/// The std of commit 672e0f6: the Cholesky inverse of the formed, diagonally scaled Gram
/// matrix (lagged correlations, `NormalEquations::build`), kappa = mean(e^2). None: the
/// Cholesky factorisation failed.
fn gram_cholesky_std(prob: &Problem, theta: &[f64]) -> Option<Vec<f64>> {
    let (n, d) = (prob.n(), prob.dim());
    let (b, f, _) = prob.split(theta);
    let (mut xu, mut yh, mut xy) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    oe::simulate_filtered(b, f, prob.one().delay, prob.u, &mut xu, &mut yh, &mut xy);
    let r: Vec<f64> = prob.y.iter().zip(&yh).map(|(y, v)| y - v).collect();
    let kappa = r.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let (mut h, mut g) = (vec![0.0; d * d], vec![0.0; d]);
    estimate::normal::NormalEquations::default().build(&prob.layout(), &xu, &xy, None, &r, &mut h, &mut g);
    let sc: Vec<f64> = (0..d).map(|i| h[i * d + i].sqrt()).collect();
    let a = faer::Mat::<f64>::from_fn(d, d, |i, j| h[i * d + j] / (sc[i] * sc[j]));
    let inv = a.llt(faer::Side::Lower).ok()?.inverse();
    Some((0..d).map(|i| (inv[(i, i)] * kappa / n as f64).sqrt() / sc[i]).collect())
}

fn mad_std(v: &[f64]) -> f64 {
    let med = |x: &mut Vec<f64>| {
        x.sort_by(|a, b| a.total_cmp(b));
        x[x.len() / 2]
    };
    let mut x = v.to_vec();
    let m = med(&mut x);
    let mut dev: Vec<f64> = v.iter().map(|a| (a - m).abs()).collect();
    1.4826 * med(&mut dev)
}

fn std_of(v: &[f64]) -> f64 {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|a| (a - m).powi(2)).sum::<f64>() / (v.len() as f64 - 1.0)).sqrt()
}

fn summary(what: &str, est: &[Vec<f64>], rep: &[Vec<f64>]) {
    let d = est[0].len();
    let mut ratios = Vec::new();
    let mut ratios_mad = Vec::new();
    for i in 0..d {
        let col: Vec<f64> = est.iter().map(|t| t[i]).collect();
        let r = rep.iter().map(|s| s[i]).sum::<f64>() / rep.len() as f64;
        ratios.push(r / std_of(&col));
        ratios_mad.push(r / mad_std(&col));
    }
    let fmt = |v: &[f64]| v.iter().map(|x| format!("{x:.2}")).collect::<Vec<_>>().join(" ");
    let med = |v: &[f64]| {
        let mut x = v.to_vec();
        x.sort_by(|a, b| a.total_cmp(b));
        x[x.len() / 2]
    };
    let within = |v: &[f64]| v.iter().filter(|r| (0.5..=2.0).contains(*r)).count();
    println!("{what}: reported/spread  median {:.2}, within x2 {}/{d}", med(&ratios), within(&ratios));
    println!("  per parameter: {}", fmt(&ratios));
    println!("  reported/MAD-spread median {:.2}: {}", med(&ratios_mad), fmt(&ratios_mad));
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.to_string());
    let n: usize = arg(0, "5000").parse().unwrap();
    let m: u64 = arg(1, "200").parse().unwrap();
    let sigma: f64 = arg(2, "0.1").parse().unwrap();
    let kind = arg(3, "prbs");
    let warmup: usize = arg(4, "0").parse().unwrap();
    let (b, f) = system(&arg(5, "oe1212"));
    let delay = 1;
    let (nb, nf) = (b.len(), f.len());
    let truth: Vec<f64> = b.iter().chain(&f).copied().collect();
    let per_input = std::env::var("PER_INPUT").is_ok();
    let make = |seed: u64| {
        let u_all = input(&kind, n + warmup, seed);
        let y0_all = oe::simulate_vec(&b, &f, delay, &u_all);
        (u_all[warmup..].to_vec(), y0_all[warmup..].to_vec())
    };
    let (u0, y00) = make(7);
    let (u, y0) = (&u0[..], &y00[..]);
    println!(
        "OE({nb},{nf}), N {n}, {m} realisations, sigma {sigma}, input {kind}, warmup {warmup}, std(y0) {:.3}",
        std_of(y0)
    );
    {
        // Conditioning of the diagonally scaled Gram matrix at the truth (noise-free signals).
        let d = nb + nf;
        let (mut xu, mut yh, mut xy) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        oe::simulate_filtered(&b, &f, delay, u, &mut xu, &mut yh, &mut xy);
        let lay = estimate::normal::Layout::siso(nb, nf, delay);
        let mut h = vec![0.0; d * d];
        let mut row = vec![0.0; d];
        for t in 0..n {
            lay.row(&xu, &xy, t, &mut row);
            for i in 0..d {
                for j in 0..d {
                    h[i * d + j] += row[i] * row[j] / n as f64;
                }
            }
        }
        let a = faer::Mat::<f64>::from_fn(d, d, |i, j| h[i * d + j] / (h[i * d + i] * h[j * d + j]).sqrt());
        let ev = a.self_adjoint_eigenvalues(faer::Side::Lower).unwrap();
        println!(
            "scaled Gram at the truth: eigenvalues {:.3e} .. {:.3e}, condition {:.3e}",
            ev[0],
            ev[d - 1],
            ev[d - 1] / ev[0]
        );
        let inv = a.llt(faer::Side::Lower).map(|c| c.inverse());
        if let Ok(inv) = inv {
            let s: Vec<f64> = (0..d).map(|i| (sigma * sigma * inv[(i, i)] / h[i * d + i] / n as f64).sqrt()).collect();
            println!(
                "asymptotic std / |theta|: {}",
                s.iter().zip(&truth).map(|(a, b)| format!("{:.3}", a / b.abs())).collect::<Vec<_>>().join(" ")
            );
        }
    }
    let ws_freqs = [0.1, 0.44, 0.8, 1.32, 2.07, 2.8];
    let mut opts = SolverOptions::default();
    if std::env::var("TIGHT").is_ok() {
        (opts.ftol, opts.xtol, opts.gtol, opts.huber_tol, opts.max_iterations) = (1e-15, 1e-15, 1e-13, 1e-15, 2000);
    }
    let judge = Judge::default();
    let mut ws = Workspace::new();
    let (mut ls_est, mut ls_rep, mut h_est, mut h_rep) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut g_est, mut g_rep, mut at_true) = (Vec::new(), Vec::new(), Vec::new());
    let mut worse = 0;
    let (mut old_est, mut old_rep, mut old_failed) = (Vec::new(), Vec::new(), 0);
    for seed in 0..m {
        let mut rng = Lcg(1000 + seed);
        let (uo, y0o) = if per_input { make(5000 + seed) } else { (u0.clone(), y00.clone()) };
        let (u, y0) = (&uo[..], &y0o[..]);
        let y: Vec<f64> = y0.iter().map(|v| v + sigma * rng.normal()).collect();
        let prob = Problem {
            u,
            y: &y,
            structure: oesweep::oe::Structure::siso(nb, nf, delay),
            offset: false,
            seams: &[],
            missing: &[],
        };
        let ls = estimate::fit_ls_from(&prob, &truth, &judge, &opts, &mut ws);
        let th = ls.theta();
        if seed < 5 {
            let other = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
            if other.criterion < ls.criterion * (1.0 - 1e-9) {
                worse += 1;
            }
        }
        let e = &ls.assessment.evidence;
        match gram_cholesky_std(&prob, &th) {
            Some(s) => {
                old_est.push(th.clone());
                old_rep.push(s);
            }
            None => old_failed += 1,
        }
        ls_est.push(th.clone());
        ls_rep.push([&e.b_std[..], &e.f_std[..]].concat());
        // The reported std had the fit stopped at the true parameters.
        let dd = nb + nf;
        let cov_true =
            evidence::covariance(&prob, &truth, Loss::LeastSquares, y0).unwrap_or(vec![f64::INFINITY; dd * dd]);
        at_true.push((0..dd).map(|i| cov_true[i * dd + i].sqrt()).collect::<Vec<_>>());
        let cov = evidence::covariance(&prob, &th, Loss::LeastSquares, &prob.simulate_vec(&th))
            .unwrap_or(vec![f64::INFINITY; dd * dd]);
        let (mut gm, mut gs) = (Vec::new(), Vec::new());
        for &w in &ws_freqs {
            let (mag, s) = evidence::gain_std(&th[..nb], &th[nb..], delay, &cov, w);
            gm.push(mag);
            gs.push(s);
        }
        g_est.push(gm);
        g_rep.push(gs);
        let h = estimate::fit_huber(&prob, ls.sigma, 1.5, &th, &judge, &opts, &mut ws);
        let e = &h.assessment.evidence;
        h_est.push(h.theta());
        h_rep.push([&e.b_std[..], &e.f_std[..]].concat());
    }
    println!("truth {:?}", truth.iter().map(|v| format!("{v:.3}")).collect::<Vec<_>>().join(" "));
    println!("least-squares fits from the truth beaten by fit_ls's own starts: {worse}/5");
    summary("least squares", &ls_est, &ls_rep);
    if !old_est.is_empty() {
        summary(
            &format!("least squares, std of 672e0f6 (Cholesky of J^T J; failed in {old_failed})"),
            &old_est,
            &old_rep,
        );
    }
    summary("Huber k=1.5", &h_est, &h_rep);
    summary("|G| at w = 0.1 0.44 0.8 1.32 2.07 2.8", &g_est, &g_rep);
}
