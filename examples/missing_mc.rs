//! `cargo run --release --example missing_mc -- [M] [N]`: Monte Carlo of records with missing
//! outputs (METHOD.md 21.4). A lightly damped OE(4,4) system (two resonances) driven by a
//! binary input, N samples (default 3000), Gaussian noise of std 0.05 and 5 % spikes of +-1 (20
//! std). In each of M realisations (default 100) the same record is fitted with 0, 5 and 20 % of
//! its outputs missing (half at random, half in bursts of 20), by least squares and by Huber at
//! k = 1, with the engine's own starts (`estimate::fit_one`, as `oesweep fit` runs it). Prints per
//! share and loss: the largest |bias| / spread over the parameters, the median and range of the
//! reported std over the spread, and the share of estimates within two reported std of the
//! truth (0.95 when the std is right and the estimate unbiased), and how much the spread grew
//! against the complete record's (sqrt(1 / (1 - share)) if a missing output cost only itself).

use oesweep::estimate::{self, Judge, Problem, SolverOptions, Workspace};
use oesweep::oe::{self, Structure};

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (a, b) = (self.next(), self.next());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// Indices of `share` of `n` outputs: half in bursts of 20, half at random.
fn gaps(n: usize, share: f64, r: &mut Lcg) -> Vec<usize> {
    let mut gone = vec![false; n];
    let target = (share * n as f64).round() as usize;
    let mut count = 0;
    while count < target / 2 {
        let start = (r.next() * (n - 20) as f64) as usize;
        for g in &mut gone[start..start + 20] {
            count += usize::from(!*g);
            *g = true;
        }
    }
    while count < target {
        let t = (r.next() * n as f64) as usize;
        count += usize::from(!gone[t]);
        gone[t] = true;
    }
    (0..n).filter(|&t| gone[t]).collect()
}

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).filter_map(|a| a.parse().ok()).collect();
    let m = args.first().copied().unwrap_or(100);
    let n = args.get(1).copied().unwrap_or(3000);
    let f = oe::poly_from_poles(&[(0.95, 0.5), (0.9, 1.4)], &[]);
    let b = vec![0.1, 0.15, -0.05, 0.08];
    let truth: Vec<f64> = [&b[..], &f[..]].concat();
    let structure = Structure::siso(4, 4, 1);
    let shares = [0.0, 0.05, 0.20];
    // est[share][loss] = (theta, std) per realisation.
    let mut est = vec![vec![Vec::new(), Vec::new()]; shares.len()];
    let opts = SolverOptions::default();
    let judge = Judge::default();
    let mut ws = Workspace::new();
    for rep in 0..m {
        let mut r = Lcg(0x5eed ^ (rep as u64).wrapping_mul(0x9e37_79b9));
        let mut v = 0.0;
        let u: Vec<f64> = (0..n)
            .map(|t| {
                if t % 3 == 0 {
                    v = if r.next() < 0.5 { -1.0 } else { 1.0 };
                }
                v
            })
            .collect();
        let clean = oe::simulate_vec(&b, &f, 1, &u);
        let y: Vec<f64> = clean
            .iter()
            .map(|c| {
                let spike = if r.next() < 0.05 { if r.next() < 0.5 { 1.0 } else { -1.0 } } else { 0.0 };
                c + 0.05 * r.normal() + spike
            })
            .collect();
        for (si, &share) in shares.iter().enumerate() {
            let missing = gaps(n, share, &mut Lcg(rep as u64 * 7 + 1));
            let mut y = y.clone();
            for &t in &missing {
                y[t] = f64::NAN;
            }
            let prob = Problem { u: &u, y: &y, structure, offset: false, seams: &[], missing: &missing };
            let one = estimate::fit_one(&prob, 1.0, &judge, &opts, &mut ws);
            for (li, (theta, ev)) in
                [(one.ls.theta(), &one.ls.assessment.evidence), (one.huber.theta(), &one.huber.assessment.evidence)]
                    .into_iter()
                    .enumerate()
            {
                let std: Vec<f64> = ev.b_std.iter().chain(&ev.f_std).copied().collect();
                est[si][li].push((theta, std));
            }
        }
    }
    println!("OE(4,4), N = {n}, {m} realisations, noise std 0.05 + 5 % spikes of +-1; k = 1");
    println!(
        "| missing | fit | max abs bias / spread | reported std / spread: median (range) | within 2 std | spread / spread at 0 %: median |"
    );
    println!("|---|---|---|---|---|---|");
    let spreads = |si: usize, li: usize| -> Vec<f64> {
        (0..truth.len())
            .map(|p| {
                let vals: Vec<f64> = est[si][li].iter().map(|(t, _)| t[p]).collect();
                let mean = vals.iter().sum::<f64>() / vals.len() as f64;
                (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vals.len() - 1) as f64).sqrt()
            })
            .collect()
    };
    for (si, &share) in shares.iter().enumerate() {
        for (li, name) in ["least squares", "Huber k = 1"].iter().enumerate() {
            let runs = &est[si][li];
            let ok: Vec<&(Vec<f64>, Vec<f64>)> =
                runs.iter().filter(|(t, s)| t.len() == truth.len() && s.len() == truth.len()).collect();
            let (mut worst_bias, mut ratios, mut inside, mut total) = (0.0f64, Vec::new(), 0, 0);
            for p in 0..truth.len() {
                let vals: Vec<f64> = ok.iter().map(|(t, _)| t[p]).collect();
                let mean = vals.iter().sum::<f64>() / vals.len() as f64;
                let spread = (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vals.len() - 1) as f64).sqrt();
                let reported = ok.iter().map(|(_, s)| s[p]).sum::<f64>() / ok.len() as f64;
                worst_bias = worst_bias.max((mean - truth[p]).abs() / spread);
                ratios.push(reported / spread);
                for (t, s) in &ok {
                    total += 1;
                    inside += usize::from((t[p] - truth[p]).abs() <= 2.0 * s[p]);
                }
            }
            ratios.sort_by(f64::total_cmp);
            let mut growth: Vec<f64> = spreads(si, li).iter().zip(spreads(0, li)).map(|(a, b)| a / b).collect();
            growth.sort_by(f64::total_cmp);
            println!(
                "| {:.0} % | {name} | {worst_bias:.2} | {:.2} ({:.2}-{:.2}) | {:.3} | {:.3} |",
                share * 100.0,
                ratios[ratios.len() / 2],
                ratios[0],
                ratios[ratios.len() - 1],
                inside as f64 / total as f64,
                growth[growth.len() / 2]
            );
        }
    }
}
