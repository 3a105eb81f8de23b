//! The uncertainty of the whole estimation, search included (METHOD.md 17.3): a parametric
//! residual bootstrap. The sandwich covariance (METHOD.md 10) is the curvature at the one
//! minimum the fit found; it cannot say that another record would have sent the search to
//! another basin, or to the stability boundary. Rerunning the search can.
//!
//! ```text
//! e      = y - yhat(theta_hat)                        residuals of the fit
//! e*_r   = circular blocks of length L from e,         r = 1..B, block starts uniform
//! y*_r   = yhat(theta_hat) + e*_r
//! theta*_r = fit_one(u, y*_r)                          least squares, Huber, every start
//!            (fit_ls alone for a least-squares model)
//! ```
//!
//! The intervals are the percentile intervals of theta*_r (and of |G_i| and the phase of G_i,
//! each input's response, at a few frequencies): `[q_{(1-level)/2}, q_{(1+level)/2}]` of the B
//! replicates, linearly interpolated. Blocks keep the residuals' colour (an output-error model
//! leaves coloured noise in them) and their spikes in place with their neighbours; L =
//! round(N^(1/3)) is the order of the optimal block length for distribution estimates (Hall,
//! Horowitz and Jing 1995). Replicate r draws from its own stream of the seed ([`Settings::seed`]) and the
//! replicates run in parallel on the current rayon pool (one [`Workspace`] each; the callers
//! install their own, [`crate::pool::local`]): the result does not depend on the thread count.

use super::fit::Judge;
use super::least_squares::{BOUNDARY, fit_ls};
use super::options::SolverOptions;
use super::problem::Problem;
use super::single::{fit_one, on_boundary};
use super::workspace::Workspace;
use crate::oe;
use crate::rng::Xoshiro256;
use rayon::prelude::*;

/// Replicates when none is asked for. The 2.5 % and 97.5 % percentiles of 200 replicates
/// are the 5th and 195th order statistics: their coverage error from the finite B is about
/// 1 % (binomial: the share of the distribution below the 5th of 200 draws has standard
/// deviation sqrt(0.025 0.975 / 200) = 1.1 %), well under the sandwich's miss on the
/// 24-parameter Monte Carlo (METHOD.md 17.3), while each replicate is a whole estimation:
/// B = 200 is the cost docs/PERFORMANCE.md measures. (Efron and Tibshirani 1993 advise
/// B >= 1000 for percentile intervals to 0.5 %.)
pub const DEFAULT_REPLICATES: usize = 200;

/// The fewest replicates allowed: with fewer than 40 the 95 % interval's ends are the sample's
/// extremes or beyond.
pub const MIN_REPLICATES: usize = 40;

/// The most replicates allowed: 100 times the 1000 that Efron and Tibshirani advise for
/// percentile intervals to 0.5 %, each a whole estimation; a typo such as `--bootstrap 1e12`
/// must be an error, not a list of replicates that aborts the process when allocated.
pub const MAX_REPLICATES: usize = 100_000;

/// The rule for B, of `fit --bootstrap` and the job's `uncertainty` alike.
pub fn check_replicates(b: usize) -> std::result::Result<(), String> {
    if (MIN_REPLICATES..=MAX_REPLICATES).contains(&b) {
        Ok(())
    } else {
        Err(format!("must be from {MIN_REPLICATES} to {MAX_REPLICATES} replicates, got {b}"))
    }
}

/// Seed when none is given.
pub const DEFAULT_SEED: u64 = 1;

/// The bootstrap's settings.
#[derive(Clone, Debug)]
pub struct Settings {
    /// B, the number of replicates.
    pub replicates: usize,
    /// Picks every replicate's resampling.
    pub seed: u64,
    /// Residual block length L (0: round(N^(1/3))).
    pub block: usize,
    /// Coverage of the intervals.
    pub level: f64,
    /// Frequencies of the intervals of G, rad/sample.
    pub frequencies: Vec<f64>,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            replicates: DEFAULT_REPLICATES,
            seed: DEFAULT_SEED,
            block: 0,
            level: 0.95,
            frequencies: default_frequencies(),
        }
    }
}

/// Ten frequencies log-spaced from 0.01 pi to pi rad/sample (1/200 of the sampling rate to
/// Nyquist).
pub fn default_frequencies() -> Vec<f64> {
    let (lo, hi, n) = (0.01 * std::f64::consts::PI, std::f64::consts::PI, 10);
    (0..n).map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64)).collect()
}

/// A percentile interval and the bootstrap standard deviation.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Interval {
    pub lower: f64,
    pub upper: f64,
    pub std: f64,
}

/// What [`run`] found.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Bootstrap {
    pub replicates: usize,
    /// Replicates whose estimation failed (no finite criterion); left out of the intervals.
    pub failed: usize,
    /// Replicates whose fit ended on the stability boundary.
    pub boundary: usize,
    pub block: usize,
    pub seed: u64,
    pub level: f64,
    /// Per parameter, in the order of theta (b, f, offset): the percentile interval.
    pub parameters: Vec<Interval>,
    /// The frequencies (rad/sample) and, one list per input, the intervals of |G_i| and of the
    /// phase of G_i = q^-d_i B_i/F_i (degrees, unwrapped to within 180 of the fit's own phase)
    /// at them. In JSON one input's lists are the list itself, several inputs' a list of lists
    /// ([`per_input`]).
    pub frequencies: Vec<f64>,
    #[serde(with = "per_input")]
    pub magnitude: Vec<Vec<Interval>>,
    #[serde(with = "per_input")]
    pub phase_deg: Vec<Vec<Interval>>,
}

/// The response intervals as JSON holds them: one input's list as it is, several inputs' as a
/// list of lists (`selection.json`'s rule of per-input fields).
mod per_input {
    use super::Interval;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(lists: &[Vec<Interval>], s: S) -> Result<S::Ok, S::Error> {
        match lists {
            [single] => s.collect_seq(single),
            several => s.collect_seq(several),
        }
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Form {
        One(Vec<Interval>),
        Several(Vec<Vec<Interval>>),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<Interval>>, D::Error> {
        Ok(match Form::deserialize(d)? {
            Form::One(v) => vec![v],
            Form::Several(v) => v,
        })
    }
}

/// The bootstrap of the model `theta` of `prob`'s structure: estimated at tuning constant `k`
/// ([`fit_one`]), or by least squares alone when `k` is None ([`fit_ls`]).
pub fn run(prob: &Problem, theta: &[f64], k: Option<f64>, settings: &Settings, opts: &SolverOptions) -> Bootstrap {
    let yhat = prob.simulate_vec(theta);
    let resid: Vec<f64> = prob.y.iter().zip(&yhat).map(|(y, v)| y - v).collect();
    let n = prob.n();
    let block = if settings.block > 0 { settings.block } else { ((n as f64).cbrt().round() as usize).max(1) };
    let judge = Judge { criterion_only: true, ..Judge::default() };
    let replicates: Vec<Option<(Vec<f64>, bool)>> = (0..settings.replicates)
        .into_par_iter()
        .map_init(Workspace::new, |ws, r| {
            let y = resampled(&yhat, &resid, block, settings.seed, r as u64);
            // A drawn block carries its missing outputs (NaN residuals) with it: a replicate
            // misses as many outputs as the record, where its blocks put them (METHOD.md 21.2).
            let missing: Vec<usize> = (0..y.len()).filter(|&t| y[t].is_nan()).collect();
            let rep = Problem { y: &y, missing: &missing, ..*prob };
            match k {
                Some(k) => {
                    let one = fit_one(&rep, k, &judge, opts, ws);
                    one.huber.criterion.is_finite().then(|| (one.huber.theta(), on_boundary(&one.huber)))
                }
                None => {
                    let ls = fit_ls(&rep, &judge, opts, ws);
                    ls.ok().then(|| (ls.theta(), rep.max_pole_radius(&ls.theta()) >= BOUNDARY))
                }
            }
        })
        .collect();
    let ok: Vec<&(Vec<f64>, bool)> = replicates.iter().flatten().collect();
    let interval = |mut v: Vec<f64>| percentile_interval(&mut v, settings.level);
    let parameters = (0..theta.len()).map(|i| interval(ok.iter().map(|t| t.0[i]).collect())).collect();
    // Each input's response at each frequency, over the replicates.
    let (mut magnitude, mut phase_deg) = (Vec::with_capacity(prob.m()), Vec::with_capacity(prob.m()));
    for i in 0..prob.m() {
        let delay = prob.structure.inputs()[i].delay;
        let (b0, f0) = prob.input_parts(theta, i);
        let (mut mag_i, mut phase_i) = (Vec::new(), Vec::new());
        for &w in &settings.frequencies {
            let phase0 = phase(b0, f0, delay, w);
            let (mut mags, mut phases) = (Vec::with_capacity(ok.len()), Vec::with_capacity(ok.len()));
            for (t, _) in &ok {
                let (b, f) = prob.input_parts(t, i);
                let (re, im) = oe::freq_response(b, f, delay, w);
                mags.push(re.hypot(im));
                let d = (im.atan2(re).to_degrees() - phase0 + 180.0).rem_euclid(360.0) - 180.0;
                phases.push(phase0 + d);
            }
            mag_i.push(interval(mags));
            phase_i.push(interval(phases));
        }
        magnitude.push(mag_i);
        phase_deg.push(phase_i);
    }
    Bootstrap {
        replicates: settings.replicates,
        failed: settings.replicates - ok.len(),
        boundary: ok.iter().filter(|t| t.1).count(),
        block,
        seed: settings.seed,
        level: settings.level,
        parameters,
        frequencies: settings.frequencies.clone(),
        magnitude,
        phase_deg,
    }
}

/// The phase of G(e^{jw}) in degrees.
fn phase(b: &[f64], f: &[f64], delay: usize, w: f64) -> f64 {
    let (re, im) = oe::freq_response(b, f, delay, w);
    im.atan2(re).to_degrees()
}

/// `yhat + e*` with `e*` circular blocks of `resid` of length `block`, from stream `r` of
/// `seed`.
pub fn resampled(yhat: &[f64], resid: &[f64], block: usize, seed: u64, r: u64) -> Vec<f64> {
    let n = resid.len();
    let mut rng = Xoshiro256::new(seed, r);
    let mut y = Vec::with_capacity(n);
    while y.len() < n {
        let start = ((rng.uniform() * n as f64) as usize).min(n - 1);
        for j in 0..block.min(n - y.len()) {
            let t = y.len();
            y.push(yhat[t] + resid[(start + j) % n]);
        }
    }
    y
}

/// The percentile interval of `v` at `level` (sorted in place; linear interpolation between
/// order statistics) and its standard deviation. NaN when `v` is empty.
pub fn percentile_interval(v: &mut [f64], level: f64) -> Interval {
    if v.is_empty() {
        return Interval { lower: f64::NAN, upper: f64::NAN, std: f64::NAN };
    }
    v.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let x = p * (v.len() - 1) as f64;
        let (i, frac) = (x.floor() as usize, x - x.floor());
        if i + 1 < v.len() { v[i] + frac * (v[i + 1] - v[i]) } else { v[i] }
    };
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len().max(2) - 1) as f64;
    Interval { lower: q((1.0 - level) / 2.0), upper: q((1.0 + level) / 2.0), std: var.sqrt() }
}
