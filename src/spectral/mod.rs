//! Welch spectral estimate of the system and the frequency-domain band fit (METHOD.md 6,
//! `fit_band`).
//!
//! # Nonparametric estimate
//! The record `u_0..u_{N-1}`, `y_0..y_{N-1}` is cut into `K` segments of length `M` (a power
//! of two), each starting `S = round(M (1 - overlap))` samples after the previous one
//! (default `M = 1024`, overlap 50 %); trailing samples that do not fill a segment are unused.
//! Each segment is detrended (its mean is subtracted), multiplied by the periodic Hann window
//! `w_n = 1/2 - 1/2 cos(2 pi n / M)` and transformed, `X_k = sum_n w_n x_n e^{-j 2 pi k n / M}`.
//! The averaged one-sided spectra on bins `k = 0..=M/2`, at `f_k = k / (M Ts)` Hz, are
//!
//! ```text
//! S_uu(k) = (1/K) sum_segments |U_k|^2
//! S_yy(k) = (1/K) sum_segments |Y_k|^2
//! S_yu(k) = (1/K) sum_segments conj(U_k) Y_k
//! G_spec(k)   = S_yu(k) / S_uu(k)                      (the H1 estimator)
//! gamma^2(k)  = |S_yu(k)|^2 / (S_uu(k) S_yy(k))        (magnitude-squared coherence)
//! ```
//!
//! The window and the `1/K` scale cancel in both ratios, so no power normalisation is applied.
//! With the `e^{-j...}` transform, `Y/U = G(e^{jw})` at `w = 2 pi k / M` rad/sample for a
//! noise-free LTI system, the convention of [`crate::oe::freq_response`]: a one-sample delay
//! gives `G = e^{-jw}`. H1 is unbiased for output noise uncorrelated with `u`, which is the
//! output-error setting. Averaging `K >= 2` segments is what makes the coherence informative
//! (with one segment it is identically 1), hence `M` is clamped to at most `N/2`.
//!
//! Bins where the input has no power (`S_uu <= 1e-12 max_k S_uu`, e.g. between the lines of a
//! periodic input or for a constant one) carry no information on `G`; there `G_spec` and the
//! coherence are stored as NaN and [`SpectralEstimate::band`] never returns them.
//!
//! # Band fit
//! Over the selected bins `k in band = {k : f_lo <= f_k <= f_hi, S_uu(k) usable}`,
//!
//! ```text
//! fit_band = 100 (1 - ||G_model - G_spec|| / ||G_spec||)   %
//! ||X||^2  = sum_{k in band} |X(k)|^2
//! ```
//!
//! with `G_model(k) = freq_response(b, f, d, 2 pi f_k Ts)`. 100 is a perfect match, 0 is no
//! better than `G_model = 0`, and it is negative for worse models (like the time-domain `fit`).

pub mod clean;
mod deferred;
mod fft;
mod gaps;
mod inputs;

use fft::{Fft, detrend_window};

pub use deferred::Deferred;
pub use inputs::{combined_band_fit, estimate_inputs, welch_inputs};

use crate::error::{Error, Result};
use crate::oe::freq_response;
use std::f64::consts::PI;

/// Which nonparametric estimate judges models (`fit_band`) and is drawn in the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpectrumMethod {
    /// Welch of the record with its output's spikes cleaned out first ([`clean`]).
    #[default]
    Robust,
    /// Plain Welch of the record as it is.
    Welch,
}

crate::names::names!(SpectrumMethod { Robust = "robust", Welch = "welch" });

/// The spectral estimate of a record by `method` (default Welch settings): the one entry
/// point for the sweep, `oesweep fit`, `oesweep spectrum` and the report.
pub fn estimate(u: &[f64], y: &[f64], ts: f64, method: SpectrumMethod) -> Result<SpectralEstimate> {
    estimate_within(u, y, &[], &[], ts, method)
}

/// [`estimate`] of a record of several experiments separated by `seams`
/// ([`crate::data::Record::seams`]; empty: one) and with the outputs at `missing` missing
/// ([`crate::data::Record::missing`]; NaN in `y`): each stretch of observed outputs (an
/// experiment, or a part of one between gaps) cleaned on its own, and the Welch spectra summed
/// over the segments of every stretch, none across a seam (METHOD.md 16) or a gap (21.3).
pub fn estimate_within(
    u: &[f64],
    y: &[f64],
    seams: &[usize],
    missing: &[usize],
    ts: f64,
    method: SpectrumMethod,
) -> Result<SpectralEstimate> {
    let opts = WelchOptions::default();
    match method {
        SpectrumMethod::Welch => welch_within(u, y, seams, missing, ts, &opts),
        SpectrumMethod::Robust => {
            // Checked before cleaning so that its messages are Welch's.
            if u.len() != y.len() || u.len() < MIN_SAMPLES {
                return welch_within(u, y, seams, missing, ts, &opts);
            }
            if seams.is_empty() && missing.is_empty() {
                let cleaned = clean::clean(u, y, &clean::CleanOptions::default());
                let mut est = welch(u, &cleaned.y, ts, &opts)?;
                est.replaced = cleaned.replaced;
                return Ok(est);
            }
            let (all, replaced) = cleaned_stretches(u, y, seams, missing);
            let mut est = welch_within(u, &all, seams, missing, ts, &opts)?;
            est.replaced = replaced;
            Ok(est)
        }
    }
}

/// The output with each stretch of observed outputs cleaned on its own ([`clean::clean`] with
/// every input column of `u`, one after the other), a missing output left NaN, and the count of
/// samples replaced.
fn cleaned_stretches(u: &[f64], y: &[f64], seams: &[usize], missing: &[usize]) -> (Vec<f64>, usize) {
    let n = y.len();
    let (mut all, mut replaced) = (y.to_vec(), 0);
    for e in crate::data::observed_ranges(n, seams, missing) {
        let columns: Vec<f64> = u.chunks_exact(n).flat_map(|c| c[e.clone()].iter().copied()).collect();
        let cleaned = clean::clean(&columns, &y[e.clone()], &clean::CleanOptions::default());
        all[e].copy_from_slice(&cleaned.y);
        replaced += cleaned.replaced;
    }
    (all, replaced)
}

/// Shortest record accepted by [`welch`]: two segments of the smallest length.
const MIN_SAMPLES: usize = 2 * MIN_SEGMENT;
/// Smallest segment length: below it the Hann window leaves too few bins to be useful.
const MIN_SEGMENT: usize = 16;
/// A bin is usable when `S_uu` exceeds this fraction of its maximum over the bins.
const SUU_REL_FLOOR: f64 = 1e-12;

/// Welch-averaged nonparametric estimate of the frequency response `G = S_yu / S_uu` on the
/// one-sided bins `k = 0..=segment/2`.
#[derive(Debug, Clone, PartialEq)]
pub struct SpectralEstimate {
    /// Bin frequencies `f_k = k / (segment ts)`, Hz.
    pub freq_hz: Vec<f64>,
    /// Real part of `G_spec`; NaN where the input has no power.
    pub re: Vec<f64>,
    /// Imaginary part of `G_spec`; NaN where the input has no power.
    pub im: Vec<f64>,
    /// Magnitude-squared coherence in [0, 1]; NaN where the input has no power.
    pub coherence: Vec<f64>,
    /// Segment length actually used (after clamping).
    pub segment: usize,
    /// Sampling period, s.
    pub ts: f64,
    /// Number of segments averaged.
    pub segments: usize,
    /// Output samples replaced by the cleaning of [`SpectrumMethod::Robust`] (0 for plain Welch).
    pub replaced: usize,
    /// Samples inside at least one segment: with missing outputs, the observed samples the
    /// estimate rests on (the stretches too short for a segment, and every tail, are unused).
    pub used: usize,
    /// One input of several ([`welch_inputs`]): the normalised random error of `|G_spec|` per
    /// bin (NaN where the inputs have no power), which [`SpectralEstimate::magnitude_band`]
    /// takes instead of the one-input formula. Empty for one input.
    pub gain_error: Vec<f64>,
}

/// Settings of [`welch`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WelchOptions {
    /// Requested segment length; rounded down to a power of two and clamped to
    /// `[16, N/2]`. Default 1024.
    pub segment: usize,
    /// Fraction of a segment shared with the next one, in `[0, 1)`. Default 0.5.
    pub overlap: f64,
}

impl Default for WelchOptions {
    fn default() -> Self {
        WelchOptions { segment: 1024, overlap: 0.5 }
    }
}

/// Welch estimate of `G = S_yu / S_uu` and the coherence from one record (see the module docs).
///
/// The segment length is the largest power of two `<= min(opts.segment, N/2)`, and at least 16.
///
/// # Errors
/// [`Error::Invalid`] when `u` and `y` differ in length, `N < 32`, `ts` is not a positive finite
/// number, `overlap` is outside `[0, 1)`, or a sample is not finite.
pub fn welch(u: &[f64], y: &[f64], ts: f64, opts: &WelchOptions) -> Result<SpectralEstimate> {
    welch_within(u, y, &[], &[], ts, opts)
}

/// [`welch`] over the experiments of a record separated by `seams` (empty: one): the segment
/// length is set by the shortest experiment, and the segments of every experiment are summed
/// (none crosses a seam). With missing outputs (`missing`, sorted; NaN in `y`) the segments lie
/// in the stretches of observed outputs and their length is chosen from those ([`gaps`]).
pub fn welch_within(
    u: &[f64],
    y: &[f64],
    seams: &[usize],
    missing: &[usize],
    ts: f64,
    opts: &WelchOptions,
) -> Result<SpectralEstimate> {
    let n = u.len();
    if y.len() != n {
        return Err(Error::Invalid(format!("spectral estimate: input has {n} samples but output has {}", y.len())));
    }
    let (m, starts) = segmentation(u, y, seams, missing, ts, opts)?;
    let segments = starts.len();
    let bins = m / 2 + 1;

    let fft = Fft::new(m);
    let window: Vec<f64> = (0..m).map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / m as f64).cos()).collect();
    let (mut ur, mut ui) = (vec![0.0; m], vec![0.0; m]);
    let (mut yr, mut yi) = (vec![0.0; m], vec![0.0; m]);
    let mut suu = vec![0.0; bins];
    let mut syy = vec![0.0; bins];
    let mut syu_re = vec![0.0; bins];
    let mut syu_im = vec![0.0; bins];

    for &start in &starts {
        detrend_window(&u[start..start + m], &window, &mut ur, &mut ui);
        detrend_window(&y[start..start + m], &window, &mut yr, &mut yi);
        fft.forward(&mut ur, &mut ui);
        fft.forward(&mut yr, &mut yi);
        for k in 0..bins {
            suu[k] += ur[k] * ur[k] + ui[k] * ui[k];
            syy[k] += yr[k] * yr[k] + yi[k] * yi[k];
            // conj(U) Y = (ur - j ui)(yr + j yi)
            syu_re[k] += ur[k] * yr[k] + ui[k] * yi[k];
            syu_im[k] += ur[k] * yi[k] - ui[k] * yr[k];
        }
    }
    // The 1/K averaging cancels in G and the coherence, so the sums are used as they are.

    let suu_max = suu.iter().copied().fold(0.0, f64::max);
    let floor = SUU_REL_FLOOR * suu_max;
    let mut re = vec![f64::NAN; bins];
    let mut im = vec![f64::NAN; bins];
    let mut coherence = vec![f64::NAN; bins];
    for k in 0..bins {
        if suu[k] > floor && suu[k] > 0.0 {
            re[k] = syu_re[k] / suu[k];
            im[k] = syu_im[k] / suu[k];
            let cross = syu_re[k] * syu_re[k] + syu_im[k] * syu_im[k];
            // y without power at this bin: nothing in it is explained by u.
            coherence[k] = if syy[k] > 0.0 { (cross / (suu[k] * syy[k])).min(1.0) } else { 0.0 };
        }
    }
    let freq_hz = (0..bins).map(|k| k as f64 / (m as f64 * ts)).collect();
    let used = gaps::covered(&starts, m);
    Ok(SpectralEstimate {
        freq_hz,
        re,
        im,
        coherence,
        segment: m,
        ts,
        segments,
        replaced: 0,
        used,
        gain_error: Vec::new(),
    })
}

impl SpectralEstimate {
    /// An approximate 95 % band of `|G_spec|` at bin `k`: `|G| (1 -/+ 2 e)` with the normalised
    /// random error of a gain estimate `e = sqrt(1 - gamma^2) / (|gamma| sqrt(2 K))` (Bendat &
    /// Piersol, Random Data, 9.3), K segments, gamma^2 the coherence; one input of several
    /// takes its own `e` ([`SpectralEstimate::gain_error`]). None where `G_spec` is not finite.
    pub fn magnitude_band(&self, k: usize) -> Option<(f64, f64)> {
        let (re, im, c) = (self.re[k], self.im[k], self.coherence[k]);
        if !(re.is_finite() && im.is_finite() && c.is_finite()) {
            return None;
        }
        let mag = re.hypot(im);
        let e = if let Some(&e) = self.gain_error.get(k) {
            if e.is_finite() { e } else { f64::INFINITY }
        } else if c > 0.0 {
            (1.0 - c).max(0.0).sqrt() / (c.sqrt() * (2.0 * self.segments as f64).sqrt())
        } else {
            f64::INFINITY
        };
        Some(((mag * (1.0 - 2.0 * e)).max(0.0), mag * (1.0 + 2.0 * e)))
    }

    /// Indices of the usable bins (finite `G_spec`, i.e. the input has power there) with
    /// `lo_hz <= f_k <= hi_hz`, ascending. Empty when `lo_hz > hi_hz` or either is NaN.
    pub fn band(&self, lo_hz: f64, hi_hz: f64) -> Vec<usize> {
        // Compare in bin units with a small slack, so that a band edge given exactly at a bin
        // frequency (e.g. the Nyquist frequency 1/(2 Ts)) keeps that bin despite rounding.
        let scale = self.segment as f64 * self.ts;
        let (lo, hi) = (lo_hz * scale - 1e-9, hi_hz * scale + 1e-9);
        (0..self.freq_hz.len())
            .filter(|&k| {
                let kf = k as f64;
                lo <= kf && kf <= hi && self.re[k].is_finite() && self.im[k].is_finite()
            })
            .collect()
    }
}

/// Band fit of the OE model `(b, f, delay)` against the spectral estimate over `bins` (from
/// [`SpectralEstimate::band`]): `100 (1 - ||G_model - G_spec|| / ||G_spec||)` in percent.
///
/// Does not allocate (it runs once per fitted model). Bins with a non-finite `G_spec` are
/// skipped. Returns `None` when no usable bin remains or `G_spec` is zero on all of them (the
/// relative error is undefined), and `Some(-inf)` when the model's response is not finite on a
/// bin (a root of `F` on the unit circle there): such a model is as bad as it gets.
///
/// # Panics
/// If a bin index is out of range of `est` (a programming error).
pub fn band_fit(est: &SpectralEstimate, bins: &[usize], b: &[f64], f: &[f64], delay: usize) -> Option<f64> {
    let (mut err2, mut ref2) = (0.0, 0.0);
    let mut used = 0usize;
    let rad_per_bin = 2.0 * PI / est.segment as f64;
    for &k in bins {
        let (sr, si) = (est.re[k], est.im[k]);
        if !(sr.is_finite() && si.is_finite()) {
            continue;
        }
        // w = 2 pi f_k Ts = 2 pi k / M, computed from k to avoid the round trip through Hz.
        let (mr, mi) = freq_response(b, f, delay, rad_per_bin * k as f64);
        let (dr, di) = (mr - sr, mi - si);
        err2 += dr * dr + di * di;
        ref2 += sr * sr + si * si;
        used += 1;
    }
    if used == 0 || ref2 <= 0.0 {
        return None;
    }
    if !err2.is_finite() {
        return Some(f64::NEG_INFINITY);
    }
    Some(100.0 * (1.0 - (err2 / ref2).sqrt()))
}

/// The segment length and the segments' starts of the record `u` (any number of input
/// columns, one after the other), `y` cut at `seams` and at the missing outputs `missing` (see
/// [`welch_within`]), after checking its length, samples, `ts` and the overlap.
fn segmentation(
    u: &[f64],
    y: &[f64],
    seams: &[usize],
    missing: &[usize],
    ts: f64,
    opts: &WelchOptions,
) -> Result<(usize, Vec<usize>)> {
    let n = y.len();
    if n < MIN_SAMPLES {
        return Err(Error::Invalid(format!("spectral estimate: {n} samples, need at least {MIN_SAMPLES}")));
    }
    if !(ts.is_finite() && ts > 0.0) {
        return Err(Error::Invalid(format!("spectral estimate: sampling period must be positive, got {ts}")));
    }
    if !(0.0..1.0).contains(&opts.overlap) {
        return Err(Error::Invalid(format!("spectral estimate: overlap must be in [0, 1), got {}", opts.overlap)));
    }
    let inputs = u.len() / n;
    // A missing output is NaN by design (and no segment holds it).
    let observed = |t: usize| missing.binary_search(&t).is_err();
    if let Some(t) =
        (0..n).find(|&t| !((y[t].is_finite() || !observed(t)) && (0..inputs).all(|i| u[i * n + t].is_finite())))
    {
        return Err(Error::Invalid(format!("spectral estimate: non-finite sample at index {t}")));
    }
    if !missing.is_empty() {
        return gaps::segments(n, seams, missing, opts);
    }
    let experiments = crate::data::experiment_ranges(n, seams);
    let shortest = experiments.iter().map(|e| e.len()).min().unwrap_or(n);
    if shortest < MIN_SAMPLES {
        return Err(Error::Invalid(format!(
            "spectral estimate: an experiment of {shortest} samples, need at least {MIN_SAMPLES}"
        )));
    }
    let m = segment_length(opts.segment, shortest);
    // round() keeps 50 % overlap exact; clamp(1, ..) guards an overlap close to 1.
    let step = ((m as f64 * (1.0 - opts.overlap)).round() as usize).clamp(1, m);
    let starts =
        experiments.iter().flat_map(|e| (0..1 + (e.len() - m) / step).map(move |s| e.start + s * step)).collect();
    Ok((m, starts))
}

/// Largest power of two `<= min(requested, n/2)`, at least [`MIN_SEGMENT`]; `n >= MIN_SAMPLES`.
fn segment_length(requested: usize, n: usize) -> usize {
    let cap = requested.min(n / 2).max(MIN_SEGMENT);
    // Largest power of two <= cap (cap >= 16 > 0).
    1usize << (usize::BITS - 1 - cap.leading_zeros())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::simulate_vec;

    use super::fft::tests::pm1;

    #[test]
    fn pure_delay_gives_exp_minus_jw() {
        let ts = 1e-4;
        let u = pm1(16384, 1);
        let mut y = vec![0.0; u.len()];
        y[1..].copy_from_slice(&u[..u.len() - 1]);
        let est = welch(&u, &y, ts, &WelchOptions::default()).unwrap();
        assert_eq!(est.segment, 1024);
        assert_eq!(est.freq_hz.len(), 513);
        let mut checked = 0;
        for k in 0..est.freq_hz.len() {
            if est.freq_hz[k] >= 0.4 / ts {
                continue;
            }
            let w = 2.0 * PI * est.freq_hz[k] * ts;
            let (dr, di) = (est.re[k] - w.cos(), est.im[k] + w.sin());
            assert!(dr.hypot(di) < 1e-2, "bin {k}: |G - e^(-jw)| = {}", dr.hypot(di));
            assert!(est.coherence[k] > 0.99, "bin {k}: coherence {}", est.coherence[k]);
            checked += 1;
        }
        assert!(checked > 400);
        let bins = est.band(0.0, 0.5 / ts);
        assert_eq!(bins.len(), 513, "Nyquist bin kept at an exact band edge");
        let fit = band_fit(&est, &bins, &[1.0], &[], 1).unwrap();
        assert!(fit > 99.0, "fit {fit}");
        // The same model without the delay is far off at high frequency.
        let fit0 = band_fit(&est, &bins, &[1.0], &[], 0).unwrap();
        assert!(fit0 < 50.0, "fit {fit0}");
    }

    #[test]
    fn oe22_true_model_fits_wrong_gain_does_not() {
        let ts = 1.0;
        let (b, f, d) = ([0.5, 0.3], [-1.2, 0.5], 1);
        let u = pm1(8192, 42);
        let y = simulate_vec(&b, &f, d, &u);
        let est = welch(&u, &y, ts, &WelchOptions::default()).unwrap();
        let bins = est.band(0.0, 0.2 / ts);
        assert!(!bins.is_empty());
        let fit = band_fit(&est, &bins, &b, &f, d).unwrap();
        assert!(fit > 95.0, "true model fit {fit}");
        let wrong = band_fit(&est, &bins, &[1.0, 0.6], &f, d).unwrap();
        assert!(wrong < 50.0, "doubled gain fit {wrong}");
        let wrong_pole = band_fit(&est, &bins, &b, &[-0.9, 0.2], d).unwrap();
        assert!(wrong_pole < fit, "wrong poles {wrong_pole} vs true {fit}");
    }

    #[test]
    fn output_noise_lowers_coherence_but_not_the_fit() {
        let (b, f, d) = ([0.5, 0.3], [-1.2, 0.5], 1);
        let u = pm1(32768, 3);
        let e = pm1(32768, 99);
        let y0 = simulate_vec(&b, &f, d, &u);
        let y: Vec<f64> = y0.iter().zip(&e).map(|(a, n)| a + 0.5 * n).collect();
        let est = welch(&u, &y, 1.0, &WelchOptions::default()).unwrap();
        let bins = est.band(0.0, 0.5);
        let mean_coh = bins.iter().map(|&k| est.coherence[k]).sum::<f64>() / bins.len() as f64;
        assert!(mean_coh < 0.95 && mean_coh > 0.3, "mean coherence {mean_coh}");
        let fit = band_fit(&est, &est.band(0.0, 0.2), &b, &f, d).unwrap();
        assert!(fit > 90.0, "fit {fit}");
    }

    #[test]
    fn segment_is_clamped() {
        let opts = WelchOptions::default();
        let seg = |n: usize, o: &WelchOptions| welch(&pm1(n, 5), &pm1(n, 6), 1.0, o).unwrap();
        assert_eq!(seg(100, &opts).segment, 32);
        assert_eq!(seg(32, &opts).segment, 16);
        assert_eq!(seg(5000, &opts).segment, 1024);
        let odd = WelchOptions { segment: 1000, overlap: 0.0 };
        assert_eq!(seg(5000, &odd).segment, 512);
        let tiny = WelchOptions { segment: 4, overlap: 0.5 };
        let est = seg(5000, &tiny);
        assert_eq!(est.segment, 16);
        assert_eq!(est.freq_hz.len(), 9);
        assert!((est.freq_hz[8] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn bad_input_is_rejected() {
        let opts = WelchOptions::default();
        let u = pm1(31, 1);
        assert!(matches!(welch(&u, &u, 1.0, &opts), Err(Error::Invalid(_))));
        let u = pm1(64, 1);
        assert!(welch(&u, &u[..63], 1.0, &opts).is_err());
        assert!(welch(&u, &u, 0.0, &opts).is_err());
        assert!(welch(&u, &u, f64::NAN, &opts).is_err());
        let full = WelchOptions { segment: 1024, overlap: 1.0 };
        assert!(welch(&u, &u, 1.0, &full).is_err());
        let mut v = u.clone();
        v[10] = f64::INFINITY;
        assert!(welch(&v, &u, 1.0, &opts).is_err());
    }

    #[test]
    fn band_selects_bins_in_range() {
        let ts = 0.01;
        let u = pm1(4096, 8);
        let est = welch(&u, &u, ts, &WelchOptions { segment: 256, overlap: 0.5 }).unwrap();
        let (lo, hi) = (5.0, 20.0);
        let bins = est.band(lo, hi);
        assert!(!bins.is_empty());
        for k in 0..est.freq_hz.len() {
            let inside = est.freq_hz[k] >= lo - 1e-9 && est.freq_hz[k] <= hi + 1e-9;
            assert_eq!(bins.contains(&k), inside, "bin {k} at {} Hz", est.freq_hz[k]);
        }
        // Identity system: perfect fit with the static gain 1.
        let fit = band_fit(&est, &bins, &[1.0], &[], 0).unwrap();
        assert!((fit - 100.0).abs() < 1e-9);
    }

    #[test]
    fn empty_band_has_no_fit() {
        let u = pm1(4096, 8);
        let est = welch(&u, &u, 1.0, &WelchOptions::default()).unwrap();
        // Between two bins, reversed, and above Nyquist.
        for (lo, hi) in [(0.1001, 0.1002), (0.3, 0.2), (0.6, 0.9), (f64::NAN, 0.4)] {
            let bins = est.band(lo, hi);
            assert!(bins.is_empty(), "[{lo}, {hi}] gave {bins:?}");
            assert_eq!(band_fit(&est, &bins, &[1.0], &[], 0), None);
        }
    }

    #[test]
    fn bins_without_input_power_are_skipped() {
        // An on-bin sinusoid puts power only in bins k0-1..=k0+1 of each Hann-windowed segment.
        let (m, k0) = (64usize, 10usize);
        let u: Vec<f64> = (0..1024).map(|t| (2.0 * PI * (k0 * t) as f64 / m as f64).cos()).collect();
        let y: Vec<f64> = u.iter().map(|v| 3.0 * v).collect();
        let est = welch(&u, &y, 1.0, &WelchOptions { segment: m, overlap: 0.5 }).unwrap();
        assert_eq!(est.band(0.0, 0.5), vec![k0 - 1, k0, k0 + 1]);
        assert!(est.re[0].is_nan() && est.coherence[20].is_nan());
        let fit = band_fit(&est, &(0..=m / 2).collect::<Vec<_>>(), &[3.0], &[], 0).unwrap();
        assert!((fit - 100.0).abs() < 1e-6, "fit {fit}");
        // A constant input has no usable bin at all.
        let c = vec![2.0; 256];
        let est = welch(&c, &c, 1.0, &WelchOptions::default()).unwrap();
        assert!(est.band(0.0, 0.5).is_empty());
    }

    #[test]
    fn model_with_unit_circle_pole_is_worst() {
        let u = pm1(4096, 8);
        let est = welch(&u, &u, 1.0, &WelchOptions::default()).unwrap();
        let bins = est.band(0.0, 0.5);
        // F = 1 - q^-1 has a root at z = 1: infinite response at DC.
        let fit = band_fit(&est, &bins, &[1.0], &[-1.0], 0).unwrap();
        assert_eq!(fit, f64::NEG_INFINITY);
    }
}
