//! Monte Carlo of the uncertainty of a large fit (issue 37, METHOD.md 10 and 17): a lightly
//! damped OE(12,12) (24 parameters), fitted as `oesweep fit` fits it, on M noise realisations
//! with spikes.
//!
//! ```text
//! cargo run --release --example uncertainty_mc -- [M] [N] [K] [NOISE] [SPIKES] [B]
//! ```
//!
//! (defaults 30, 5000, 0.0875, 0.1, 0.05, 0). The system is `covariance_mc`'s default: three
//! resonances at pole radius 0.97-0.99 and three damped pairs at 0.5, DC gain 1. Each record:
//! a 10-bit PRBS of levels +/-1 (`simulate::generate`, seed 1000 + realisation), Gaussian noise
//! of standard deviation NOISE (about 10 % of the output's), and on a share SPIKES of the
//! samples a spike of 5 to 15 noise standard deviations of random sign. Per realisation it
//! prints the fit's criterion W against W at the true parameters (same gamma), its largest
//! pole radius, the largest |theta_i - truth_i| / std_i over the parameters, and the doubt of
//! `estimate::quadratic` (METHOD.md 17). With B > 0 it also runs the bootstrap of B
//! replicates and prints, over the realisations, how often each parameter's 95 % interval
//! (sandwich: theta +/- 1.96 std; bootstrap: percentile) covers the truth, and the same for |G|
//! at a few frequencies.

use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, bootstrap, quadratic};
use oesweep::oe;
use oesweep::oe::Structure;
use oesweep::simulate::{self, NoiseKind, Outliers, SimOptions, SystemSpec};
use std::time::Instant;

/// Pole (radius, angle) pairs and real roots as the monic polynomial's coefficients after 1.
fn poly(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    oesweep::oe::poly_from_poles(pairs, real)
}

/// The true system: `c` (default) or, with `SYSTEM=piezo12`, the piezo system of
/// `jobs/data/piezo_system.json` with two more real poles and zeros (`covariance_mc`'s
/// `piezo12`: resonances at radius 0.99, 0.96, 0.90).
fn system() -> SystemSpec {
    let (f, bz) = match std::env::var("SYSTEM").as_deref() {
        Ok("piezo12") => (
            poly(&[(0.9891, 0.4398), (0.9612, 1.3195), (0.9015, 2.0735)], &[0.85, 0.5, 0.3, 0.1, -0.5, -0.2]),
            poly(&[(0.85, 0.817), (0.9, 1.696), (0.7, 2.8)], &[-1.8, -0.8, -0.6, 0.65, 0.7]),
        ),
        _ => (
            poly(&[(0.99, 0.3), (0.98, 0.9), (0.97, 1.6), (0.5, 1.0), (0.5, 2.0), (0.5, 3.0)], &[]),
            poly(&[(0.9, 0.6), (0.9, 1.25), (0.9, 2.2)], &[-1.5, 1.5, -2.0, 2.0, -3.0]),
        ),
    };
    let (fs, bs) = (1.0 + f.iter().sum::<f64>(), 1.0 + bz.iter().sum::<f64>());
    let b = std::iter::once(1.0).chain(bz).map(|v| v * fs / bs).collect();
    SystemSpec { b, f, delay: 1 }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or_else(|| default.to_string());
    let m: u64 = arg(0, "30").parse().unwrap();
    let n: usize = arg(1, "5000").parse().unwrap();
    let k: f64 = arg(2, "0.0875").parse().unwrap();
    let noise: f64 = arg(3, "0.1").parse().unwrap();
    let spikes: f64 = arg(4, "0.05").parse().unwrap();
    let replicates: usize = arg(5, "0").parse().unwrap();
    let sys = system();
    let (nb, nf) = (sys.b.len(), sys.f.len());
    let truth: Vec<f64> = sys.b.iter().chain(&sys.f).copied().collect();
    let dim = truth.len();
    let freqs = bootstrap::default_frequencies();
    let true_gain: Vec<f64> = freqs.iter().map(|&w| gain(&sys.b, &sys.f, w)).collect();
    println!("OE({nb},{nf}), N {n}, {m} realisations, k {k}, noise {noise}, spikes {spikes}, B {replicates}");
    let opts = SolverOptions::default();
    let judge = Judge::default();
    let mut ws = Workspace::new();
    let (mut cover_s, mut cover_b) = (vec![0usize; dim + freqs.len()], vec![0usize; dim + freqs.len()]);
    let (mut boot_runs, mut boot_seconds) = (0usize, 0.0);
    let mut ratios: Vec<Vec<f64>> = Vec::new();
    let mut estimates: Vec<Vec<f64>> = Vec::new();
    let mut stds: Vec<Vec<f64>> = Vec::new();
    for r in 0..m {
        let opts_sim = SimOptions {
            n,
            bits: 10,
            amplitude: 1.0,
            seed: 1000 + r,
            noise_std: noise,
            noise: NoiseKind::Gaussian,
            outliers: (spikes > 0.0).then_some(Outliers { probability: spikes, min: 5.0 * noise, max: 15.0 * noise }),
        };
        let rec = simulate::generate(&sys, &opts_sim).expect("the system");
        let prob = Problem {
            u: &rec.u,
            y: &rec.y,
            structure: Structure::siso(nb, nf, 1),
            offset: false,
            seams: &[],
            missing: &[],
        };
        // The fit as `oesweep fit` made it before the boundary's further starts, then with them.
        let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
        let (plain, start) = estimate::fit_huber_multi(&prob, &ls, k, &judge, &opts, &mut ws);
        let start = if start == 0 { "ls" } else { "ls_alt" };
        let (w_plain, r_plain) = (plain.criterion, plain.assessment.max_pole_radius);
        let one = estimate::single::off_the_boundary(
            &prob,
            estimate::OneFit { ls, huber: plain, start, fits: 0 },
            &judge,
            &opts,
            &mut ws,
        );
        let h = &one.huber;
        let theta = h.theta();
        let loss = Loss::Huber { gamma: h.gamma };
        let w_true = loss.criterion(prob.y, &prob.simulate_vec(&truth));
        let cov = estimate::evidence::covariance(&prob, &theta, loss, &prob.simulate_vec(&theta));
        let std: Vec<f64> = match &cov {
            Some(c) => (0..dim).map(|i| c[i * dim + i].sqrt()).collect(),
            None => vec![f64::INFINITY; dim],
        };
        let z: Vec<f64> = (0..dim).map(|i| (theta[i] - truth[i]).abs() / std[i]).collect();
        let zmax = z.iter().copied().fold(0.0, f64::max);
        let doubt = cov.as_ref().map(|c| quadratic::check(&prob, &theta, loss, c));
        println!(
            "{r:3}  before: dW/W {:+.2e} radius {r_plain:.5}  W {:.6e}  W(truth) {:.6e}  dW/W {:+.2e}  radius {:.5}  max|z| {zmax:6.2}  start {}  {}",
            (w_plain - w_true) / w_true,
            h.criterion,
            w_true,
            (h.criterion - w_true) / w_true,
            h.assessment.max_pole_radius,
            one.start,
            doubt.map_or("no covariance".into(), |d| d.summary()),
        );
        ratios.push(z);
        estimates.push(theta.clone());
        stds.push(std.clone());
        // The sandwich's intervals of the parameters and of |G| (delta method).
        let mut sandwich_covers = |i: usize, est: f64, sd: f64, truth: f64| {
            if (est - truth).abs() <= 1.96 * sd {
                cover_s[i] += 1;
            }
        };
        for i in 0..dim {
            sandwich_covers(i, theta[i], std[i], truth[i]);
        }
        if let Some(c) = &cov {
            for (j, &w) in freqs.iter().enumerate() {
                let (mag, sd) = estimate::evidence::gain_std(&h.b, &h.f, 1, c, w);
                sandwich_covers(dim + j, mag, sd, true_gain[j]);
            }
        }
        if replicates > 0 {
            let t0 = Instant::now();
            let settings = bootstrap::Settings { replicates, ..Default::default() };
            let b = bootstrap::run(&prob, &one.huber.theta(), Some(one.huber.k), &settings, &opts);
            boot_seconds += t0.elapsed().as_secs_f64();
            boot_runs += 1;
            for i in 0..dim {
                if (b.parameters[i].lower..=b.parameters[i].upper).contains(&truth[i]) {
                    cover_b[i] += 1;
                }
            }
            for j in 0..freqs.len() {
                if (b.magnitude[0][j].lower..=b.magnitude[0][j].upper).contains(&true_gain[j]) {
                    cover_b[dim + j] += 1;
                }
            }
        }
    }
    // Mean reported std against the spread of the estimates (the issue's "median 0.53").
    let spread_ratio: Vec<f64> = (0..dim)
        .map(|i| {
            let col: Vec<f64> = estimates.iter().map(|t| t[i]).collect();
            let mean = col.iter().sum::<f64>() / col.len() as f64;
            let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (col.len() as f64 - 1.0)).sqrt();
            stds.iter().map(|s| s[i]).sum::<f64>() / stds.len() as f64 / sd
        })
        .collect();
    println!("reported std / spread of the estimates: median {:.2}", median(spread_ratio));
    let within1 = ratios.iter().filter(|z| median(z.to_vec()) <= 1.5).count();
    println!("realisations with median |theta - truth| / std <= 1.5: {within1}/{m}");
    let pct = |c: usize| 100.0 * c as f64 / m as f64;
    let row = |name: String, i: usize| {
        if replicates > 0 {
            println!("{name:>10}  sandwich {:5.1} %  bootstrap {:5.1} %", pct(cover_s[i]), pct(cover_b[i]));
        } else {
            println!("{name:>10}  sandwich {:5.1} %", pct(cover_s[i]));
        }
    };
    println!("coverage of the truth by the 95 % intervals over {m} realisations:");
    for i in 0..dim {
        row(if i < nb { format!("b{}", i + 1) } else { format!("f{}", i - nb + 1) }, i);
    }
    for (j, w) in freqs.iter().enumerate() {
        row(format!("|G({w})|"), dim + j);
    }
    let mean_of = |c: &[usize]| 100.0 * c.iter().sum::<usize>() as f64 / (m as f64 * c.len() as f64);
    println!(
        "mean coverage: parameters sandwich {:.1} %{}; |G| sandwich {:.1} %{}",
        mean_of(&cover_s[..dim]),
        if replicates > 0 { format!(" bootstrap {:.1} %", mean_of(&cover_b[..dim])) } else { String::new() },
        mean_of(&cover_s[dim..]),
        if replicates > 0 { format!(" bootstrap {:.1} %", mean_of(&cover_b[dim..])) } else { String::new() },
    );
    if boot_runs > 0 {
        println!("bootstrap: {:.1} s per pick (B = {replicates}, N = {n})", boot_seconds / boot_runs as f64);
    }
}

fn gain(b: &[f64], f: &[f64], w: f64) -> f64 {
    let (re, im) = oe::freq_response(b, f, 1, w);
    re.hypot(im)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
