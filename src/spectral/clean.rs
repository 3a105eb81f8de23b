//! Cleaning spikes out of the output before a spectral estimate (METHOD.md 11), after Kleiner,
//! Martin & Thomson, "Robust estimation of power spectra", JRSS-B 41 (1979): a robust
//! high-order prediction filter is fitted, and every sample its prediction misses by more than
//! a few robust standard deviations is replaced by the prediction, recursively (the
//! predictions use the cleaned past). The Welch estimate of the cleaned record is then no
//! longer spread by the spikes' energy over every bin.
//!
//! The predictor is an ARX model `y_t = sum_{j=1}^{p} a_j y_{t-j} + sum_{i=0}^{p} b_i u_{t-i} + c`
//! (a high-order ARX model approximates the one-step predictor of an OE system with white
//! output noise; several inputs: one sum of p + 1 lags per input), fitted by Huber IRLS (tuning 1.345 robust standard deviations, scale 1.4826
//! times the median absolute residual). Regressors of past outputs are spikes themselves until
//! cleaned, so fit and cleaning alternate for a few passes, each fit on the previous pass's
//! cleaned output.

use faer::Mat;

/// Settings of [`clean`].
#[derive(Clone, Debug, PartialEq)]
pub struct CleanOptions {
    /// Order p of the prediction filter (clamped to N/20).
    pub order: usize,
    /// A sample is replaced when its prediction error exceeds this many robust standard
    /// deviations.
    pub threshold: f64,
    /// Fit-and-clean passes.
    pub passes: usize,
}

impl Default for CleanOptions {
    fn default() -> Self {
        CleanOptions { order: 30, threshold: 3.0, passes: 3 }
    }
}

/// The cleaned output and how many samples were replaced.
#[derive(Clone, Debug)]
pub struct Cleaned {
    pub y: Vec<f64>,
    pub replaced: usize,
}

/// `y` with its spikes replaced by robust predictions from the cleaned past and `u`: one input
/// column or several, one after the other (`u.len()` a multiple of `y.len()`; each input gets
/// its own p + 1 lags in the predictor).
pub fn clean(u: &[f64], y: &[f64], opts: &CleanOptions) -> Cleaned {
    let n = y.len();
    assert!(n > 0 && u.len().is_multiple_of(n) && !u.is_empty(), "{} input values for {n} output samples", u.len());
    let p = opts.order.min(n / 20).max(1);
    let d = columns(p, u.len() / n);
    let mut replaced = 0;
    if n <= 4 * d {
        return Cleaned { y: y.to_vec(), replaced };
    }
    // The first fit's regressors are the output's own past, spikes included: start from the
    // output with its isolated spikes replaced by a running median, so that the first fit is
    // not already spoiled by them (each spike sits in p regressors of as many rows).
    let start = median_cleaned(y, opts.threshold);
    let mut yc = start.clone();
    let mut ws = Workspace::new(n - p, d);
    for _ in 0..opts.passes {
        let Some((theta, scale)) = robust_arx(u, &yc, p, &mut ws) else { break };
        if scale.is_nan() || scale <= 0.0 {
            break;
        }
        // Recursive cleaning from the measured output: each prediction uses the cleaned past.
        // A run of more than p replacements means the filter has lost track of the output (not
        // a spike): it takes the measured samples again.
        let mut run = 0;
        // The first p samples have no full past: they keep the running-median cleaning.
        let mut next = y.to_vec();
        next[..p].copy_from_slice(&start[..p]);
        replaced = (0..p).filter(|&t| start[t] != y[t]).count();
        for t in p..n {
            let pred = predict(&theta, u, &next, p, t);
            if (y[t] - pred).abs() > opts.threshold * scale && run < p {
                next[t] = pred;
                replaced += 1;
                run += 1;
            } else {
                run = 0;
            }
        }
        // A pass is a function of the output it starts from: one that changed nothing would
        // be repeated, to the bit, by every pass left.
        let settled = same_bits(&next, &yc);
        yc = next;
        if settled {
            break;
        }
    }
    Cleaned { y: yc, replaced }
}

/// `y` with the samples that stand out of their 5-sample running median by more than
/// `threshold` robust standard deviations (of those differences) replaced by the median.
fn median_cleaned(y: &[f64], threshold: f64) -> Vec<f64> {
    const HALF: usize = 2;
    let n = y.len();
    let med: Vec<f64> = (0..n)
        .map(|t| {
            let (a, b) = (t.saturating_sub(HALF), (t + HALF + 1).min(n));
            let mut w = [0.0; 2 * HALF + 1];
            let w = &mut w[..b - a];
            w.copy_from_slice(&y[a..b]);
            w.sort_by(f64::total_cmp);
            w[w.len() / 2]
        })
        .collect();
    let mut dev: Vec<f64> = y.iter().zip(&med).map(|(a, m)| (a - m).abs()).collect();
    dev.sort_by(f64::total_cmp);
    let scale = 1.4826 * dev[n / 2];
    y.iter().zip(&med).map(|(&v, &m)| if (v - m).abs() > threshold * scale { m } else { v }).collect()
}

/// The predictor's number of parameters: p output lags, p + 1 lags of each of `m` inputs, and
/// the constant.
fn columns(p: usize, m: usize) -> usize {
    p + m * (p + 1) + 1
}

/// The ARX prediction of sample t from `y`'s past and `u` (every input) up to t.
fn predict(theta: &[f64], u: &[f64], y: &[f64], p: usize, t: usize) -> f64 {
    let n = y.len();
    let m = u.len() / n;
    let mut s = theta[columns(p, m) - 1];
    for j in 1..=p {
        s += theta[j - 1] * y[t - j];
    }
    for (input, th) in u.chunks_exact(n).zip(theta[p..].chunks_exact(p + 1)) {
        for i in 0..=p {
            s += th[i] * input[t - i];
        }
    }
    s
}

/// Bitwise equality (a NaN equals itself, 0 and -0 differ): equal inputs give equal results.
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The regression matrices of [`robust_arx`], allocated once for all passes: a fresh matrix of
/// this size per iteration costs more in page faults than its filling.
struct Workspace {
    /// The regressors of row r, `x[r * d..(r + 1) * d]` (row-major: each residual reads a row).
    x: Vec<f64>,
    /// The weighted regressors above the ridge rows, factored in place by each iteration.
    xw: Mat<f64>,
}

impl Workspace {
    fn new(rows: usize, d: usize) -> Workspace {
        Workspace { x: vec![0.0; rows * d], xw: Mat::zeros(rows + d, d) }
    }
}

/// Huber IRLS fit of the ARX predictor of order p on rows t = p..N: (theta, robust scale).
fn robust_arx(u: &[f64], y: &[f64], p: usize, ws: &mut Workspace) -> Option<(Vec<f64>, f64)> {
    const TUNING: f64 = 1.345;
    const ITERATIONS: usize = 5;
    let n = y.len();
    let rows = n - p;
    let d = columns(p, u.len() / n);
    let x = &mut ws.x;
    for (r, row) in x.chunks_exact_mut(d).enumerate() {
        let t = r + p;
        for (j, v) in row[..p].iter_mut().enumerate() {
            *v = y[t - 1 - j];
        }
        for (input, lags) in u.chunks_exact(n).zip(row[p..d - 1].chunks_exact_mut(p + 1)) {
            for (i, v) in lags.iter_mut().enumerate() {
                *v = input[t - i];
            }
        }
        row[d - 1] = 1.0;
    }
    let x = &ws.x;
    let mut w = vec![1.0; rows];
    let mut theta = vec![0.0; d];
    let mut scale = 0.0;
    // A ridge of 1e-6 of each column's norm (d extra rows): an input that does not excite
    // every lag (periodic, or of low order) leaves the regression rank-deficient, and the
    // recursion of an unbounded predictor would then clean everything.
    let ridge: Vec<f64> =
        (0..d).map(|c| 1e-6 * (0..rows).map(|r| x[r * d + c] * x[r * d + c]).sum::<f64>().sqrt()).collect();
    for _ in 0..ITERATIONS {
        let sw: Vec<f64> = w.iter().map(|v: &f64| v.sqrt()).collect();
        let xw = &mut ws.xw;
        for c in 0..d {
            let col = xw.col_mut(c).try_as_col_major_mut().expect("a column of a Mat is contiguous").as_slice_mut();
            for (r, v) in col[..rows].iter_mut().enumerate() {
                *v = sw[r] * x[r * d + c];
            }
            for (i, v) in col[rows..].iter_mut().enumerate() {
                *v = if i == c { ridge[c].max(f64::MIN_POSITIVE) } else { 0.0 };
            }
        }
        let yw = Mat::<f64>::from_fn(rows + d, 1, |r, _| if r < rows { sw[r] * y[r + p] } else { 0.0 });
        let sol = crate::dense::lstsq_in_place(xw.as_mut(), yw.as_ref());
        theta = (0..d).map(|i| sol[(i, 0)]).collect();
        if theta.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let resid: Vec<f64> = x
            .chunks_exact(d)
            .enumerate()
            .map(|(r, row)| y[r + p] - row.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>())
            .collect();
        let mut abs: Vec<f64> = resid.iter().map(|e| e.abs()).collect();
        abs.sort_by(f64::total_cmp);
        scale = 1.4826 * abs[rows / 2];
        if scale.is_nan() || scale <= 0.0 {
            break;
        }
        let before = std::mem::take(&mut w);
        w = resid.iter().map(|e| (TUNING * scale / e.abs().max(f64::MIN_POSITIVE)).min(1.0)).collect();
        // The same weights again: every iteration left would give this theta and scale.
        if same_bits(&w, &before) {
            break;
        }
    }
    Some((theta, scale))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cleaning as first written (a fresh regression matrix per iteration, every pass and
    /// iteration run): the reference the leaner [`clean`] must match to the bit.
    mod reference {
        use super::super::{CleanOptions, Cleaned, median_cleaned, predict};
        use faer::Mat;

        pub(super) fn clean(u: &[f64], y: &[f64], opts: &CleanOptions) -> Cleaned {
            let n = y.len();
            let p = opts.order.min(n / 20).max(1);
            let mut replaced = 0;
            if n <= 4 * (2 * p + 2) {
                return Cleaned { y: y.to_vec(), replaced };
            }
            // The first fit's regressors are the output's own past, spikes included: start from the
            // output with its isolated spikes replaced by a running median, so that the first fit is
            // not already spoiled by them (each spike sits in p regressors of as many rows).
            let start = median_cleaned(y, opts.threshold);
            let mut yc = start.clone();
            for _ in 0..opts.passes {
                let Some((theta, scale)) = robust_arx(u, &yc, p) else { break };
                if scale.is_nan() || scale <= 0.0 {
                    break;
                }
                // Recursive cleaning from the measured output: each prediction uses the cleaned past.
                // A run of more than p replacements means the filter has lost track of the output (not
                // a spike): it takes the measured samples again.
                let mut run = 0;
                // The first p samples have no full past: they keep the running-median cleaning.
                let mut next = y.to_vec();
                next[..p].copy_from_slice(&start[..p]);
                replaced = (0..p).filter(|&t| start[t] != y[t]).count();
                for t in p..n {
                    let pred = predict(&theta, u, &next, p, t);
                    if (y[t] - pred).abs() > opts.threshold * scale && run < p {
                        next[t] = pred;
                        replaced += 1;
                        run += 1;
                    } else {
                        run = 0;
                    }
                }
                yc = next;
            }
            Cleaned { y: yc, replaced }
        }
        fn robust_arx(u: &[f64], y: &[f64], p: usize) -> Option<(Vec<f64>, f64)> {
            const TUNING: f64 = 1.345;
            const ITERATIONS: usize = 5;
            let n = y.len();
            let rows = n - p;
            let d = 2 * p + 2;
            let x = Mat::<f64>::from_fn(rows, d, |r, c| {
                let t = r + p;
                if c < p {
                    y[t - 1 - c]
                } else if c < 2 * p + 1 {
                    u[t - (c - p)]
                } else {
                    1.0
                }
            });
            let mut w = vec![1.0; rows];
            let mut theta = vec![0.0; d];
            let mut scale = 0.0;
            // A ridge of 1e-6 of each column's norm (d extra rows): an input that does not excite
            // every lag (periodic, or of low order) leaves the regression rank-deficient, and the
            // recursion of an unbounded predictor would then clean everything.
            let ridge: Vec<f64> =
                (0..d).map(|c| 1e-6 * (0..rows).map(|r| x[(r, c)] * x[(r, c)]).sum::<f64>().sqrt()).collect();
            for _ in 0..ITERATIONS {
                let sw: Vec<f64> = w.iter().map(|v: &f64| v.sqrt()).collect();
                let xw = Mat::<f64>::from_fn(rows + d, d, |r, c| {
                    if r < rows {
                        sw[r] * x[(r, c)]
                    } else if r - rows == c {
                        ridge[c].max(f64::MIN_POSITIVE)
                    } else {
                        0.0
                    }
                });
                let yw = Mat::<f64>::from_fn(rows + d, 1, |r, _| if r < rows { sw[r] * y[r + p] } else { 0.0 });
                let sol = crate::dense::lstsq(xw.as_ref(), yw.as_ref());
                theta = (0..d).map(|i| sol[(i, 0)]).collect();
                if theta.iter().any(|v| !v.is_finite()) {
                    return None;
                }
                let resid: Vec<f64> =
                    (0..rows).map(|r| y[r + p] - (0..d).map(|c| x[(r, c)] * theta[c]).sum::<f64>()).collect();
                let mut abs: Vec<f64> = resid.iter().map(|e| e.abs()).collect();
                abs.sort_by(f64::total_cmp);
                scale = 1.4826 * abs[rows / 2];
                if scale.is_nan() || scale <= 0.0 {
                    break;
                }
                for (wt, e) in w.iter_mut().zip(&resid) {
                    *wt = (TUNING * scale / e.abs().max(f64::MIN_POSITIVE)).min(1.0);
                }
            }
            Some((theta, scale))
        }
    }

    fn assert_same_bits(u: &[f64], y: &[f64], opts: &CleanOptions, what: &str) {
        let (new, old) = (clean(u, y, opts), reference::clean(u, y, opts));
        assert_eq!(new.replaced, old.replaced, "{what}: samples replaced");
        assert!(same_bits(&new.y, &old.y), "{what}: the cleaned output differs from the reference's");
    }

    #[test]
    fn cleaning_matches_the_reference_to_the_bit() {
        let est = concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/data/piezo_est.csv");
        let rec = crate::data::read_record(std::path::Path::new(est), "u", "y").unwrap();
        for passes in [1, 3, 6] {
            let opts = CleanOptions { passes, ..CleanOptions::default() };
            assert_same_bits(&rec.u, &rec.y, &opts, &format!("piezo record, {passes} passes"));
            // No spike at all: the weights and the passes settle early.
            let smooth: Vec<f64> = (0..rec.y.len()).map(|t| (t as f64 * 0.01).sin()).collect();
            assert_same_bits(&rec.u, &smooth, &opts, &format!("a sine, {passes} passes"));
        }
        let spiky: Vec<f64> = rec.y.iter().enumerate().map(|(t, v)| if t % 41 == 3 { v + 5.0 } else { *v }).collect();
        assert_same_bits(&rec.u, &spiky, &CleanOptions::default(), "piezo record with spikes");
    }

    #[test]
    fn spikes_are_replaced_and_clean_samples_kept() {
        // An AR(2) driven by a binary input, noise of std ~0.05, every 37th sample a spike of
        // +/-10.
        let n = 3000;
        let mut s = 5u64;
        let mut rnd = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let u: Vec<f64> = (0..n).map(|t| if t % 3 == 0 && rnd() < 0.5 { 1.0 } else { -1.0 }).collect();
        let mut clean_y = vec![0.0; n];
        for t in 2..n {
            clean_y[t] = 1.5 * clean_y[t - 1] - 0.7 * clean_y[t - 2] + 0.3 * u[t - 1];
        }
        let noisy: Vec<f64> = clean_y.iter().map(|v| v + 0.1 * (rnd() + rnd() + rnd() - 1.5)).collect();
        let spike = |t: usize| if t % 74 == 5 { 10.0 } else { -10.0 };
        let spiky: Vec<f64> =
            noisy.iter().enumerate().map(|(t, v)| if t % 37 == 5 { v + spike(t) } else { *v }).collect();
        let c = clean(&u, &spiky, &CleanOptions::default());
        let spikes = (0..n).filter(|t| t % 37 == 5).count();
        assert!(c.replaced >= spikes && c.replaced <= spikes + n / 50, "{} replaced, {spikes} spikes", c.replaced);
        // What remains is (about) the spike-free record: a replaced sample is a prediction,
        // off by the noise (or, in the first p samples, by a running median).
        let diff: Vec<f64> = c.y.iter().zip(&noisy).map(|(a, b)| (a - b).abs()).collect();
        let worst = diff.iter().copied().fold(0.0, f64::max);
        let mean = diff.iter().sum::<f64>() / n as f64;
        assert!(worst < 1.0 && mean < 0.01, "difference from the spike-free record: largest {worst}, mean {mean}");
    }
}
