//! The integrating-plant test of a record (METHOD.md 7.3): does the plant have a pole at 1, or
//! a real one above it? An output-error model is stable by construction, so on such a plant
//! every fit of the sweep is a stable stand-in for it.
//!
//! A low-order model with a constant, `A(q) y_t = B(q) u_{t-d} + c + v_t` with nA = nB = n,
//! n = 1 and 2, at the job's smallest delay d, is fitted by refined instrumental variables
//! (Young's SRIV): the rows `phi_t = [u_{t-d}, .., -y_{t-1}, .., 1]` and `y_t`, and the
//! instruments `z_t`, the same with the noise-free output x simulated from the previous
//! estimate, are filtered by `1/A_prev` (its poles scaled into radius [`CAP`]), and
//! `sum_t w_t z_t (y_t - phi_t^T theta) = 0` is solved, filtered quantities throughout. The
//! instruments are uncorrelated with output-error noise e (least squares would bias the poles
//! towards 0), and the prefilter turns the equation error `A e` back into nearly white e: the
//! plain IV of ARX is too inefficient to tell a pole at 0.99 from 1 in a few thousand samples.
//! Every pass starts from the last (the first from ARX least squares, [`arx`], and again from a
//! slow start, B a delay and all poles at 0.999: ARX of a double integrator lands far off; the
//! start whose estimate has the smaller equation errors under both fits' filters is kept).
//! Spikes: Huber weights `w_t = min(1, k s / |eps_t|)` on the filtered equation error (`k =
//! 2`, `s = 1.4826 median |eps|`; a spike in y stays one sample wide there). Rows whose lags
//! reach before the start of their experiment are left out and the filters start at rest at
//! each experiment's first complete row, so nothing crosses a seam; the filters' start leaves
//! a transient of the equation errors before it, spanned by nA filtered pulses per experiment,
//! which are estimated with the model and dropped, as are the constants of experiments 2..
//! (experiments may sit at different levels). The sums stream: memory is three
//! record-length vectors.
//!
//! The order: the smaller BIC `N ln s^2 + dim ln N` of the filtered equation errors (an
//! over-parameterised fit is near singular along the common factor of A and B).
//!
//! The decision is on `A(1) = 1 + a_1 + .. + a_n = g^T theta`, which is 0 exactly when A has a
//! root at 1 and negative when it has one real root above 1; it is linear in theta, so the
//! M-estimator's sandwich `C = G^-1 S G^-T` (`G = sum psi'(eps) z phi^T`, `S` the Newey-West
//! long-run covariance of `h_t = z_t psi(eps_t)`, Bartlett weights up to lag
//! `floor(4 (N/100)^(2/9))`, so coloured noise is allowed for) gives its variance `g^T C g =
//! v^T S v`, `G^T v = g`, without linearisation: the long-run variance of the one series `v^T
//! h_t`. A(1) stays well determined where single roots do not (two close poles, a double
//! integrator: a root moves with the square root of a coefficient there). The test fires
//! when the 95 % interval `A(1) +- 1.96 se` reaches 0 or lies below it. It is reported as the
//! slowest pole p (largest real part) with the interval `1 - [A(1) +- 1.96 se] / R(1)`, `R(1)
//! = prod (1 - p_i)` over the other poles: the delta method of `p = 1 - A(1)/R(1)` with those
//! held.
//!
//! The judgement ([`doubt`]): a slow drift in the output (a disturbance, not the plant) also
//! puts the low-order fit's pole at 1, so the test is judged against the models fitted to the
//! record (a run's watched picks, `oesweep fit`'s model). A model on the stability boundary
//! agrees with it: the integrating plant is named. Stable models are judged by their
//! residuals (the initial state of each experiment fitted): the KPSS statistic
//! ([`drift_statistic`]) of their Huber-clipped residuals against a level. None above its 5 %
//! point: the stable models explain the record, and nothing is said. Otherwise the warning
//! names what was seen, the drift of those residuals, whose cause may be a slow disturbance or
//! an integrating plant (a stable model of an integrator leaves a drift too).
//!
//! Missing outputs (METHOD.md 21.3; NaN in `y`): the rows and the filters need an unbroken
//! output history, so the test runs on the stretches of observed outputs as experiments of
//! their own (the record compacted, [`Stretches`]), each with its pulses and its constant; a
//! stretch shorter than [`MIN_STRETCH`] is left out (its rows would hardly outnumber its
//! nuisance columns). The judgement's drift statistic is over the observed residuals.
//!
//! Several inputs ([`pole_tests`], `several.rs`): each input is tested on its own one-input
//! model, fitted by backfitting to the output less the other inputs' outputs, with the other
//! inputs' paths as further columns of its regression ([`Others`]: their sensitivity signals,
//! each its own instrument), so that the errors of their fits are estimated, not subtracted.
//!
//! What no test can do: a stable pole whose time constant is as long as the record or longer
//! gives data that an integrator explains as well; there the test may fire and the fits lie on
//! the boundary (METHOD.md 7.3 measures where).

use super::initial_guess::{arx, regressor};
use super::least_squares::BOUNDARY;
use super::problem::Problem;
use crate::oe;
use crate::oe::Structure;
use faer::Mat;

/// The samples a record is tested on at most (its head): time constants up to about a tenth of
/// this are told from an integrator (METHOD.md 7.3).
pub const MAX_ROWS: usize = 50_000;
/// The largest nA = nB tried.
const ORDER: usize = 2;
/// Huber's constant of the weighted IV passes, in robust scales of the equation error.
const HUBER_K: f64 = 2.0;
/// IV passes: the first unweighted, then reweighted.
const PASSES: usize = 4;
/// The largest pole radius of the prefilter: an integrating 1/A over the whole record would
/// integrate the data once or twice more (a double integrator's columns become collinear to
/// working precision), and a radius of 0.995 still whitens all but the lowest frequencies.
const CAP: f64 = 0.995;
/// The poles of the slow start.
const SLOW: f64 = 0.999;
/// The 0.975 quantile of the standard normal.
const Z95: f64 = 1.959_963_984_540_054;
/// A(1) within this of 0 is 0 (a noise-free record gives a standard error of 0).
const ROUNDING: f64 = 1e-10;
/// Below this |imaginary part| relative to the modulus a pole is real.
const REAL: f64 = 1e-9;

/// The shortest stretch of observed outputs the test of a record with missing outputs uses.
pub const MIN_STRETCH: usize = 32;

/// The stretches of observed outputs of a record's head the test runs on, as experiments of a
/// compacted record: `ranges` in the record, `seams` where stretches 2.. begin in the compacted
/// one. A complete record is its experiments as they are.
struct Stretches {
    ranges: Vec<std::ops::Range<usize>>,
    seams: Vec<usize>,
}

impl Stretches {
    /// The stretches of `y` (a missing output is NaN) with experiments beginning at `seams`.
    fn of(y: &[f64], seams: &[usize]) -> Stretches {
        let missing: Vec<usize> = (0..y.len()).filter(|&t| y[t].is_nan()).collect();
        let ranges: Vec<_> = if missing.is_empty() {
            crate::data::experiment_ranges(y.len(), seams)
        } else {
            crate::data::observed_ranges(y.len(), seams, &missing)
                .into_iter()
                .filter(|r| r.len() >= MIN_STRETCH)
                .collect()
        };
        let seams = ranges.iter().scan(0, |at, r| Some(std::mem::replace(at, *at + r.len()))).skip(1).collect();
        Stretches { ranges, seams }
    }

    /// The samples of `x` (one column of the record) in the stretches, one after the other.
    fn take(&self, x: &[f64]) -> Vec<f64> {
        self.ranges.iter().flat_map(|r| x[r.clone()].iter().copied()).collect()
    }
}

/// The outcome of the test on one record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoleTest {
    /// nA = nB of the model tested.
    pub order: usize,
    /// Its slowest pole (largest real part), (re, im) (the one with im >= 0 of a pair).
    pub pole: (f64, f64),
    /// The pole's 95 % interval from that of A(1), when the pole is real and the other poles'
    /// `R(1)` is positive.
    pub interval: Option<(f64, f64)>,
    /// `A(1) = 1 + a_1 + .. + a_n` and its standard error.
    pub a_at_1: f64,
    pub a_at_1_std: f64,
    /// The 95 % interval of A(1) reaches 0 or lies below it: a pole that may be 1, or a real
    /// pole above 1.
    pub integrating: bool,
}

impl PoleTest {
    pub fn is_real(&self) -> bool {
        self.pole.1.abs() <= REAL * self.pole.0.hypot(self.pole.1)
    }
}

/// The integrating-plant test of the record `u`, `y` (experiments starting at `seams`) with
/// input delay `delay`. None when the regressions are degenerate (e.g. a constant input).
pub fn pole_test(u: &[f64], y: &[f64], seams: &[usize], delay: usize) -> Option<PoleTest> {
    // A long record is tested on its head: the test's ~40 streamed passes would otherwise cost
    // more than a whole sweep of a 1e6-sample record.
    let head = u.len().min(MAX_ROWS);
    let (u, y) = (&u[..head], &y[..head]);
    let stretches = Stretches::of(y, &head_seams(seams, head));
    let (u, y) = (stretches.take(u), stretches.take(y));
    let (prob, fit) = fitted(&u, &y, &stretches.seams, delay, &Others::none())?;
    test_poles(&prob, &fit, &Others::none())
}

/// The seams of a record's first `head` samples.
fn head_seams(seams: &[usize], head: usize) -> Vec<usize> {
    seams.iter().copied().filter(|&s| s < head).collect()
}

/// The test's model of one input's record (its head): the order (nA = nB = 1 or 2) whose IV
/// fit has the smaller BIC, each order from the better of its two starts.
fn fitted<'a>(
    u: &'a [f64],
    y: &'a [f64],
    seams: &'a [usize],
    delay: usize,
    others: &Others,
) -> Option<(Problem<'a>, IvFit)> {
    let fits: Vec<(Problem, IvFit)> = (1..=ORDER)
        .filter_map(|n| {
            let prob = Problem { u, y, structure: Structure::siso(n, n, delay), offset: true, seams, missing: &[] };
            let from_arx = arx(&prob).and_then(|a| iv_fit(&prob, a[..2 * n].to_vec(), others));
            let mut slow = vec![0.0; 2 * n];
            slow[0] = 1.0;
            slow[n..].copy_from_slice(&oe::poly_from_roots(&vec![(SLOW, 0.0); n]));
            let best = match (from_arx, iv_fit(&prob, slow, others)) {
                (Some(a), Some(b)) => {
                    let lags = lags(&prob);
                    let under = |fit: &IvFit, on: &IvFit| scale_under(&prob, &fit.theta, &on.filter, lags, others);
                    if under(&b, &a) < under(&a, &a) && under(&b, &b) < under(&a, &b) { b } else { a }
                }
                (a, b) => a.or(b)?,
            };
            Some((prob, best))
        })
        .collect();
    let bic =
        |(p, f): &(Problem, IvFit)| f.rows as f64 * (f.scale * f.scale).ln() + p.dim() as f64 * (f.rows as f64).ln();
    let best = (0..fits.len()).min_by(|&a, &b| bic(&fits[a]).total_cmp(&bic(&fits[b])))?;
    fits.into_iter().nth(best)
}

/// The IV estimate `[b, a, F(1) c, nuisance, others]` (the regression's own coefficients, A not
/// stabilised), the model that simulated its instruments and the prefilter of its last pass,
/// and the robust scale of its filtered equation errors over the rows used; `model` is its
/// `[b, a]` with A stabilised (the noise-free output of several inputs' backfitting).
struct IvFit {
    theta: Vec<f64>,
    instruments: Vec<f64>,
    model: Vec<f64>,
    filter: Vec<f64>,
    scale: f64,
    rows: usize,
}

fn iv_fit(prob: &Problem, start: Vec<f64>, others: &Others) -> Option<IvFit> {
    let (n, d, nbf) = (prob.n(), prob.dim(), prob.one().nb + prob.one().nf);
    let lags = lags(prob);
    let rows = (0..n).filter(|&t| complete(prob, lags, t)).count();
    if rows <= 4 * d {
        return None;
    }
    // The instruments' model and the prefilter 1/A: stable; no offset (the constant column
    // carries it, and F(1) c of an integrator divided by F(1) ~ 0 would swamp the instruments).
    let mut model = start;
    let plain = Problem { offset: false, ..*prob };
    let mut x = vec![0.0; n];
    let mut eps = vec![0.0; n];
    let mut scale = f64::INFINITY;
    let dd = extended_dim(prob, others);
    let mut theta = vec![0.0; dd];
    let mut filter = model[prob.one().nb..].to_vec();
    capped(&mut filter);
    let (mut instruments, mut used) = (model.clone(), filter.clone());
    for _ in 0..PASSES {
        instruments.copy_from_slice(&model);
        used.copy_from_slice(&filter);
        plain.simulate(&model, &mut x);
        if !x.iter().all(|s| s.is_finite()) {
            return None;
        }
        // sum_t w_t z_t [phi_t | y_t]^T of the filtered rows, row-major (row i at i * (dd + 1)):
        // a plain slice per row, which the compiler vectorises across the columns (each
        // entry's sum over t in the same order as before).
        let mut m = vec![0.0; dd * (dd + 1)];
        filtered_rows(prob, &x, &filter, lags, others, |t, phi, z| {
            let w = huber_weight(eps[t], scale);
            for (i, row) in m.chunks_exact_mut(dd + 1).enumerate() {
                let zi = w * if i < d { z[i] } else { phi[i] };
                for (mc, pc) in row.iter_mut().zip(&phi[..=dd]) {
                    *mc += zi * pc;
                }
            }
        });
        let at = |i: usize, c: usize| m[i * (dd + 1) + c];
        let lhs = Mat::from_fn(dd, dd, at);
        let sol = crate::dense::Lu::new(lhs.as_ref()).solve(Mat::from_fn(dd, 1, |i, _| at(i, dd)).as_ref());
        theta = (0..dd).map(|i| sol[(i, 0)]).collect();
        if !theta.iter().all(|s| s.is_finite()) {
            return None;
        }
        filtered_rows(prob, &x, &filter, lags, others, |t, phi, _| {
            eps[t] = phi[dd] - (0..dd).map(|c| phi[c] * theta[c]).sum::<f64>();
        });
        scale = robust_scale(&eps, |t| complete(prob, lags, t));
        model.copy_from_slice(&theta[..nbf]);
        prob.reflect_unstable(&mut model);
        filter.copy_from_slice(&model[prob.one().nb..]);
        capped(&mut filter);
    }
    Some(IvFit { theta, instruments, model, filter: used, scale, rows })
}

/// The sandwich variance of A(1) = `g^T theta` (g: ones at a): `g^T G^-1 S G^-T g = v^T S v`
/// with `G^T v = g`, `G = sum psi'(eps) z phi^T` at the fit's instruments and filter, and
/// `v^T S v` the Newey-West long-run variance of the scalar `v^T z_t psi(eps_t)` (Bartlett
/// weights up to lag `floor(4 (N/100)^(2/9))`): two passes, no d x d sum per lag.
fn a_at_1_variance(prob: &Problem, fit: &IvFit, others: &Others) -> Option<f64> {
    let (d, dd, lags) = (prob.dim(), extended_dim(prob, others), lags(prob));
    let x = Problem { offset: false, ..*prob }.simulate_vec(&fit.instruments);
    let cut = HUBER_K * fit.scale;
    let theta = &fit.theta;
    let eps = |phi: &[f64]| phi[dd] - (0..dd).map(|c| phi[c] * theta[c]).sum::<f64>();
    let mut g = Mat::<f64>::zeros(dd, dd);
    filtered_rows(prob, &x, &fit.filter, lags, others, |_, phi, z| {
        if eps(phi).abs() <= cut {
            for i in 0..dd {
                let zi = if i < d { z[i] } else { phi[i] };
                for c in 0..dd {
                    g[(i, c)] += zi * phi[c];
                }
            }
        }
    });
    let ones =
        Mat::from_fn(dd, 1, |i, _| f64::from(u8::from((prob.one().nb..prob.one().nb + prob.one().nf).contains(&i))));
    let v = crate::dense::Lu::new(g.transpose()).solve(ones.as_ref());
    let lag = (4.0 * (fit.rows as f64 / 100.0).powf(2.0 / 9.0)).floor().max(1.0) as usize;
    // The complete rows of an experiment are consecutive: one run of h per experiment.
    let (mut h, mut runs, mut start) = (Vec::with_capacity(fit.rows), Vec::new(), usize::MAX);
    filtered_rows(prob, &x, &fit.filter, lags, others, |t, phi, z| {
        if prob.experiment_start(t) != start {
            start = prob.experiment_start(t);
            runs.push(h.len());
        }
        h.push(eps(phi).clamp(-cut, cut) * (0..dd).map(|i| v[(i, 0)] * if i < d { z[i] } else { phi[i] }).sum::<f64>());
    });
    runs.push(h.len());
    let var = long_run_sum(runs.windows(2).map(|w| &h[w[0]..w[1]]), lag);
    var.is_finite().then_some(var.max(0.0))
}

/// `sum_t h_t^2 + 2 sum_{l=1}^{L} (1 - l/(L+1)) sum_t h_t h_{t-l}` over each run of `h`, no
/// product pairing two runs: N times the Newey-West long-run variance (Bartlett weights) of
/// the series, the one of the test's A(1) and of the residuals' drift statistic.
fn long_run_sum<'h>(runs: impl Iterator<Item = &'h [f64]>, lag: usize) -> f64 {
    runs.map(|h| {
        let mut s = h.iter().map(|v| v * v).sum::<f64>();
        for l in 1..=lag.min(h.len().saturating_sub(1)) {
            let w = 1.0 - l as f64 / (lag + 1) as f64;
            s += 2.0 * w * h[l..].iter().zip(h).map(|(a, b)| a * b).sum::<f64>();
        }
        s
    })
    .sum()
}

/// The robust scale of the equation errors of `theta` filtered by `1/F`, the pulses left out
/// (the other inputs' columns kept: they are part of the model): two fits compared on the same
/// filter.
fn scale_under(prob: &Problem, theta: &[f64], f: &[f64], lags: usize, others: &Others) -> f64 {
    let d = prob.dim();
    let dd = extended_dim(prob, others);
    let mut abs = Vec::new();
    let model = (0..d).chain(dd - others.len(prob.one().nf)..dd);
    filtered_rows(prob, prob.y, f, lags, others, |_, phi, _| {
        abs.push((phi[dd] - model.clone().map(|c| phi[c] * theta[c]).sum::<f64>()).abs());
    });
    if abs.is_empty() {
        return f64::INFINITY;
    }
    let mid = abs.len() / 2;
    *abs.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// `F(q/k)`, its poles scaled by k, when its largest pole radius r is above [`CAP`] (k = CAP/r).
fn capped(f: &mut [f64]) {
    let r = oe::max_pole_radius(f);
    if r > CAP {
        let mut kj = 1.0;
        for v in f.iter_mut() {
            kj *= CAP / r;
            *v *= kj;
        }
    }
}

/// The largest lag of the model's rows.
fn lags(prob: &Problem) -> usize {
    (prob.one().delay + prob.one().nb - 1).max(prob.one().nf)
}

/// Whether row t has all its lags inside its own experiment.
fn complete(prob: &Problem, lags: usize, t: usize) -> bool {
    t >= prob.experiment_start(t) + lags
}

/// The rows `[phi_t, p_t | y_t]` and the instruments `z_t` (those of [`regressor`], from `y`
/// and from `x`), each column filtered by `1/F`, for every complete row t in order: the
/// filters start from rest at the first complete row of each experiment, so that no lag and no
/// filter reaches across a seam. `p_t` are the pulses at the first nF complete rows of every
/// experiment, filtered (columns `d + nF k + j`): the filter's start from rest leaves in the
/// filtered equation error a transient of the equation errors before it, which these columns
/// span (for an integrator it never decays); then the steps of experiments 2.. (their own
/// constants); then the other inputs' columns of several inputs ([`Others`]), each its own
/// instrument like the pulses and steps. Streams: no buffer grows with N.
fn filtered_rows(
    prob: &Problem,
    x: &[f64],
    f: &[f64],
    lags: usize,
    others: &Others,
    mut each: impl FnMut(usize, &[f64], &[f64]),
) {
    let (d, nf) = (prob.dim(), f.len());
    let dd = extended_dim(prob, others);
    let pulses = nf * (prob.seams.len() + 1);
    // The other inputs' columns come last: (signal, lag) of each.
    let columns = others.columns(prob.one().nf);
    let own = dd - columns.len();
    let m = dd + 1 + d;
    // The last nf filtered rows, newest first.
    let mut past = vec![0.0; nf.max(1) * m];
    let mut row = vec![0.0; m];
    let mut started = usize::MAX;
    for t in 0..prob.n() {
        let start = prob.experiment_start(t);
        if t < start + lags {
            continue;
        }
        if started != start {
            started = start;
            past.iter_mut().for_each(|v| *v = 0.0);
        }
        let k = prob.seams.partition_point(|&s| s <= t);
        for c in 0..m {
            let raw = if c < d {
                regressor(prob, prob.y, t, c)
            } else if c < d + pulses {
                f64::from(u8::from(c == d + nf * k + (t - start - lags)))
            } else if c < own {
                f64::from(u8::from(c == d + pulses + k - 1))
            } else if c < dd {
                others.value(columns[c - own], t)
            } else if c == dd {
                prob.y[t]
            } else {
                regressor(prob, x, t, c - dd - 1)
            };
            row[c] = raw - (0..nf).map(|j| f[j] * past[j * m + c]).sum::<f64>();
        }
        if nf > 0 {
            past.copy_within(0..(nf - 1) * m, m);
            past[..m].copy_from_slice(&row);
        }
        each(t, &row[..=dd], &row[dd + 1..]);
    }
}

/// Columns of the filtered regression: the model's d, nF pulses per experiment, a constant
/// for each experiment after the first (experiments may sit at different levels) and the other
/// inputs' columns (none for one input).
fn extended_dim(prob: &Problem, others: &Others) -> usize {
    prob.dim() + (prob.one().nf + 1) * (prob.seams.len() + 1) - 1 + others.len(prob.one().nf)
}

/// `min(1, k s / |v|)`: the IRLS weight of Huber's psi (1 while there is no scale yet).
fn huber_weight(v: f64, scale: f64) -> f64 {
    let cut = HUBER_K * scale;
    if v.abs() > cut { cut / v.abs() } else { 1.0 }
}

/// `1.4826 median |v_t|` over the complete rows (the constant column centres v), or infinity
/// (no weighting) when that is 0.
fn robust_scale(v: &[f64], complete: impl Fn(usize) -> bool) -> f64 {
    let mut abs: Vec<f64> = v.iter().enumerate().filter(|&(t, _)| complete(t)).map(|(_, x)| x.abs()).collect();
    if abs.is_empty() {
        return f64::INFINITY;
    }
    let mid = abs.len() / 2;
    let (_, m, _) = abs.select_nth_unstable_by(mid, f64::total_cmp);
    let s = 1.4826 * *m;
    if s > 0.0 { s } else { f64::INFINITY }
}

/// The test of `fit`: A(1) against 0, reported at the slowest pole.
fn test_poles(prob: &Problem, fit: &IvFit, others: &Others) -> Option<PoleTest> {
    let (nb, nf) = (prob.one().nb, prob.one().nf);
    let a = &fit.theta[nb..nb + nf];
    let poles = oe::poles(a);
    let slowest = (0..poles.len())
        .filter(|&i| poles[i].1 >= -REAL * poles[i].0.hypot(poles[i].1))
        .max_by(|&i, &j| poles[i].0.total_cmp(&poles[j].0))?;
    let pole = poles[slowest];
    let a_at_1 = 1.0 + a.iter().sum::<f64>();
    let std = a_at_1_variance(prob, fit, others)?.sqrt();
    let (lo, hi) = (a_at_1 - Z95 * std, a_at_1 + Z95 * std);
    // R(1) = prod (1 - p_i) over the other poles (real for a conjugate pair).
    let rest = poles.iter().enumerate().filter(|&(i, _)| i != slowest).fold((1.0, 0.0), |acc: (f64, f64), (_, p)| {
        let f = (1.0 - p.0, -p.1);
        (acc.0 * f.0 - acc.1 * f.1, acc.0 * f.1 + acc.1 * f.0)
    });
    let mut test = PoleTest { order: nb, pole, interval: None, a_at_1, a_at_1_std: std, integrating: lo <= ROUNDING };
    if test.is_real() && rest.0 > 0.0 {
        test.interval = Some((1.0 - hi / rest.0, 1.0 - lo / rest.0));
    }
    Some(test)
}

mod judged;
mod several;
pub use judged::{
    DRIFT_LEVEL, Judged, doubt, doubts, drift_statistic, input_doubt, input_name, input_radius, judged_by_residuals,
    residual_drift,
};
use several::Others;
pub use several::pole_tests;
