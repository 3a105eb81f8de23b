//! The spectral estimate of a record of several inputs (METHOD.md 11, 19), and the band fit
//! of a several-input model.
//!
//! The segments, window and averaging are those of one input ([`super::welch_within`]). With
//! m inputs the sums over the K segments become, at each bin k,
//!
//! ```text
//! P(k)_ji  = sum_segments conj(U_j) U_i        (m x m, Hermitian: the inputs' cross-spectra)
//! s(k)_j   = sum_segments conj(U_j) Y
//! S_yy(k)  = sum_segments |Y|^2
//! ```
//!
//! and for `Y = sum_i G_i U_i` each `conj(U_j) Y = sum_i G_i conj(U_j) U_i`, so `P G = s`: the
//! estimate is `H(k) = P(k)^-1 s(k)` (the H1 estimator of several inputs; one input:
//! `S_yu / S_uu`). It is unbiased for output noise uncorrelated with the inputs, and needs the
//! inputs not to be collinear at that frequency (P of full rank, hence K >= m segments).
//! Alongside: the multiple coherence `gamma^2 = Re(s^H H) / S_yy` (the share of the output's
//! power the inputs explain together; one input: the coherence) and, per input, the normalised
//! random error of `|H_i|`, `e_i = sqrt(S_nn (P^-1)_ii / (2 (K - m + 1))) / |H_i|` with the
//! residual spectrum `S_nn = S_yy - Re(s^H H)`, which for one input is Bendat & Piersol's
//! `sqrt(1 - gamma^2) / (|gamma| sqrt(2 K))` ([`SpectralEstimate::magnitude_band`]).
//!
//! A bin is usable when every input has power there (`P_ii > 1e-12 max_k P_ii`) and P is not
//! nearly singular: every Cholesky pivot of the normalised matrix `D^-1/2 P D^-1/2` (unit
//! diagonal, D = diag P) exceeds 1e-10. Elsewhere every input's estimate is NaN, so the bins
//! of [`SpectralEstimate::band`] are the same for every input.
//!
//! The band fit of a several-input model is one fit % per input (input i's `B_i/F_i` with
//! delay d_i against `H_i`, [`super::band_fit`]) and their mean ([`combined_band_fit`]).

use super::{Fft, cleaned_stretches, detrend_window, estimate_within, gaps, segmentation, welch_within};
use super::{MIN_SAMPLES, SUU_REL_FLOOR, SpectralEstimate, SpectrumMethod, WelchOptions};
use crate::error::{Error, Result};
use std::f64::consts::PI;
use std::ops::{Add, AddAssign, Mul, Sub};

/// [`super::estimate_within`] of a record of `m` inputs (`u`: the m columns one after the
/// other, as [`crate::data::Record::u`]): one estimate per input, `H_i`, the bins, coherence
/// and segments common to all. One input: exactly [`super::estimate_within`]'s estimate. The
/// robust method cleans the output with a predictor of every input ([`super::clean::clean`]). With
/// missing outputs (`missing`, [`crate::data::Record::missing`]) the segments lie in the
/// stretches of observed outputs (METHOD.md 21.3).
pub fn estimate_inputs(
    u: &[f64],
    m: usize,
    y: &[f64],
    seams: &[usize],
    missing: &[usize],
    ts: f64,
    method: SpectrumMethod,
) -> Result<Vec<SpectralEstimate>> {
    if m == 1 {
        return Ok(vec![estimate_within(u, y, seams, missing, ts, method)?]);
    }
    let opts = WelchOptions::default();
    let n = y.len();
    // Checked before cleaning so that its messages are Welch's.
    if method == SpectrumMethod::Welch || u.len() != m * n || n < MIN_SAMPLES {
        return welch_inputs(u, m, y, seams, missing, ts, &opts);
    }
    let (all, replaced) = cleaned_stretches(u, y, seams, missing);
    let mut ests = welch_inputs(u, m, &all, seams, missing, ts, &opts)?;
    for est in &mut ests {
        est.replaced = replaced;
    }
    Ok(ests)
}

/// The Welch estimate of every input's response `H_i = (P^-1 s)_i` from a record of `m`
/// inputs (see the module docs); one input: [`welch_within`]'s.
///
/// # Errors
/// Those of [`welch_within`], and [`Error::Invalid`] when `u` does not hold m columns of
/// `y`'s length.
pub fn welch_inputs(
    u: &[f64],
    m: usize,
    y: &[f64],
    seams: &[usize],
    missing: &[usize],
    ts: f64,
    opts: &WelchOptions,
) -> Result<Vec<SpectralEstimate>> {
    let n = y.len();
    if m == 0 || u.len() != m * n {
        return Err(Error::Invalid(format!(
            "spectral estimate: {} input samples for {m} inputs of an output of {n}",
            u.len()
        )));
    }
    if m == 1 {
        return Ok(vec![welch_within(u, y, seams, missing, ts, opts)?]);
    }
    let (seg, starts) = segmentation(u, y, seams, missing, ts, opts)?;
    let segments = starts.len();
    let bins = seg / 2 + 1;
    let fft = Fft::new(seg);
    let window: Vec<f64> = (0..seg).map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / seg as f64).cos()).collect();
    let (mut ur, mut ui) = (vec![0.0; m * seg], vec![0.0; m * seg]);
    let (mut yr, mut yi) = (vec![0.0; seg], vec![0.0; seg]);
    let mut p = vec![C::ZERO; bins * m * m];
    let mut s = vec![C::ZERO; bins * m];
    let mut syy = vec![0.0; bins];
    for &start in &starts {
        for (i, (re, im)) in ur.chunks_exact_mut(seg).zip(ui.chunks_exact_mut(seg)).enumerate() {
            detrend_window(&u[i * n + start..i * n + start + seg], &window, re, im);
            fft.forward(re, im);
        }
        detrend_window(&y[start..start + seg], &window, &mut yr, &mut yi);
        fft.forward(&mut yr, &mut yi);
        for k in 0..bins {
            let yk = C { re: yr[k], im: yi[k] };
            syy[k] += yk.norm2();
            for j in 0..m {
                let uj = C { re: ur[j * seg + k], im: ui[j * seg + k] }.conj();
                s[k * m + j] += uj * yk;
                for i in 0..m {
                    p[(k * m + j) * m + i] += uj * C { re: ur[i * seg + k], im: ui[i * seg + k] };
                }
            }
        }
    }
    // The 1/K averaging cancels in H and the coherence, so the sums are used as they are.

    let diag_max: Vec<f64> = (0..m).map(|i| (0..bins).map(|k| p[(k * m + i) * m + i].re).fold(0.0, f64::max)).collect();
    let nan = || vec![f64::NAN; bins];
    let (mut re, mut im, mut err) = (vec![nan(); m], vec![nan(); m], vec![nan(); m]);
    let mut coherence = nan();
    // Degrees of freedom of the residual spectrum: K segments less the m - 1 further unknowns.
    let dof = (segments + 1).saturating_sub(m).max(1) as f64;
    for k in 0..bins {
        let pk = &p[k * m * m..(k + 1) * m * m];
        if !(0..m).all(|i| pk[i * m + i].re > SUU_REL_FLOOR * diag_max[i] && pk[i * m + i].re > 0.0) {
            continue;
        }
        let sk = &s[k * m..(k + 1) * m];
        let Some((h, inv_diag)) = solve_bin(pk, sk, m) else { continue };
        let explained: f64 = sk.iter().zip(&h).map(|(&sj, &hj)| (sj.conj() * hj).re).sum();
        // y without power at this bin: nothing in it is explained by the inputs.
        coherence[k] = if syy[k] > 0.0 { (explained / syy[k]).clamp(0.0, 1.0) } else { 0.0 };
        let noise = (syy[k] - explained).max(0.0);
        for i in 0..m {
            re[i][k] = h[i].re;
            im[i][k] = h[i].im;
            err[i][k] = (noise * inv_diag[i] / (2.0 * dof)).sqrt() / h[i].norm2().sqrt();
        }
    }
    let freq_hz: Vec<f64> = (0..bins).map(|k| k as f64 / (seg as f64 * ts)).collect();
    let used = gaps::covered(&starts, seg);
    Ok(re
        .into_iter()
        .zip(im)
        .zip(err)
        .map(|((re, im), gain_error)| SpectralEstimate {
            freq_hz: freq_hz.clone(),
            re,
            im,
            coherence: coherence.clone(),
            segment: seg,
            ts,
            segments,
            replaced: 0,
            used,
            gain_error,
        })
        .collect())
}

/// The band fit of a model of several inputs from each input's ([`super::band_fit`] of
/// `B_i/F_i` against `H_i`): their mean, so that no input's units weigh in it (each input's fit
/// is unchanged by a scale of that input). None when an input has none; one input: its fit.
pub fn combined_band_fit(per_input: &[Option<f64>]) -> Option<f64> {
    let fits: Option<Vec<f64>> = per_input.iter().copied().collect();
    fits.filter(|f| !f.is_empty()).map(|f| f.iter().sum::<f64>() / f.len() as f64)
}

/// `H = P^-1 s` at one bin and the diagonal of `P^-1`, through the Cholesky factor of the
/// normalised `A = D^-1/2 P D^-1/2`; None when a pivot of A is below 1e-10 (inputs collinear
/// at this frequency).
fn solve_bin(p: &[C], s: &[C], m: usize) -> Option<(Vec<C>, Vec<f64>)> {
    const PIVOT: f64 = 1e-10;
    let r: Vec<f64> = (0..m).map(|i| 1.0 / p[i * m + i].re.sqrt()).collect();
    // L lower triangular, row-major, with a real positive diagonal: A = L L^H.
    let mut l = vec![C::ZERO; m * m];
    for j in 0..m {
        let mut d = 1.0;
        for q in 0..j {
            d -= l[j * m + q].norm2();
        }
        if d.is_nan() || d <= PIVOT {
            return None;
        }
        let ljj = d.sqrt();
        l[j * m + j] = C { re: ljj, im: 0.0 };
        for i in j + 1..m {
            let mut a = p[i * m + j].scale(r[i] * r[j]);
            for q in 0..j {
                a = a - l[i * m + q] * l[j * m + q].conj();
            }
            l[i * m + j] = a.scale(1.0 / ljj);
        }
    }
    // A x = D^-1/2 s, then H = D^-1/2 x.
    let b: Vec<C> = s.iter().zip(&r).map(|(&sj, &rj)| sj.scale(rj)).collect();
    let z = forward(&l, &b, m);
    let x = backward(&l, &z, m);
    let h = x.iter().zip(&r).map(|(&xj, &rj)| xj.scale(rj)).collect();
    // (A^-1)_ii = ||L^-1 e_i||^2 and (P^-1)_ii = (A^-1)_ii / P_ii.
    let inv_diag = (0..m)
        .map(|i| {
            let e: Vec<C> = (0..m).map(|q| C { re: f64::from(u8::from(q == i)), im: 0.0 }).collect();
            forward(&l, &e, m).iter().map(|c| c.norm2()).sum::<f64>() * r[i] * r[i]
        })
        .collect();
    Some((h, inv_diag))
}

/// Solves `L z = b` (L lower triangular, row-major).
fn forward(l: &[C], b: &[C], m: usize) -> Vec<C> {
    let mut z = b.to_vec();
    for i in 0..m {
        for q in 0..i {
            z[i] = z[i] - l[i * m + q] * z[q];
        }
        z[i] = z[i].scale(1.0 / l[i * m + i].re);
    }
    z
}

/// Solves `L^H x = z` (L lower triangular, row-major).
fn backward(l: &[C], z: &[C], m: usize) -> Vec<C> {
    let mut x = z.to_vec();
    for i in (0..m).rev() {
        for q in i + 1..m {
            x[i] = x[i] - l[q * m + i].conj() * x[q];
        }
        x[i] = x[i].scale(1.0 / l[i * m + i].re);
    }
    x
}

/// A complex number, as much of one as the estimate needs.
#[derive(Clone, Copy, Debug, PartialEq)]
struct C {
    re: f64,
    im: f64,
}

impl C {
    const ZERO: C = C { re: 0.0, im: 0.0 };
    fn conj(self) -> C {
        C { re: self.re, im: -self.im }
    }
    fn norm2(self) -> f64 {
        self.re * self.re + self.im * self.im
    }
    fn scale(self, a: f64) -> C {
        C { re: a * self.re, im: a * self.im }
    }
}

impl Add for C {
    type Output = C;
    fn add(self, o: C) -> C {
        C { re: self.re + o.re, im: self.im + o.im }
    }
}

impl AddAssign for C {
    fn add_assign(&mut self, o: C) {
        *self = *self + o;
    }
}

impl Sub for C {
    type Output = C;
    fn sub(self, o: C) -> C {
        C { re: self.re - o.re, im: self.im - o.im }
    }
}

impl Mul for C {
    type Output = C;
    fn mul(self, o: C) -> C {
        C { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::{freq_response, simulate_vec};

    /// Gaussian-ish white noise: the sum of 12 uniforms less 6, from a 64-bit LCG.
    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        (0..n).map(|_| (0..12).map(|_| next()).sum::<f64>() - 6.0).collect()
    }

    /// Two inputs through OE(2,2) d = 1 and OE(1,1) d = 2, noise-free: each `H_i` is input
    /// i's response in the band, and the true model fits each input near 100 %.
    #[test]
    fn two_white_inputs_give_each_response() {
        let n = 16384;
        let (u1, u2) = (white(n, 1), white(n, 2));
        let (b1, f1, d1) = ([0.5, 0.3], [-1.2, 0.5], 1);
        let (b2, f2, d2) = ([0.4], [-0.8], 2);
        let y: Vec<f64> =
            simulate_vec(&b1, &f1, d1, &u1).iter().zip(simulate_vec(&b2, &f2, d2, &u2)).map(|(a, b)| a + b).collect();
        let u: Vec<f64> = u1.iter().chain(&u2).copied().collect();
        for method in [SpectrumMethod::Welch, SpectrumMethod::Robust] {
            let ests = estimate_inputs(&u, 2, &y, &[], &[], 1.0, method).unwrap();
            assert_eq!(ests.len(), 2);
            let bins = ests[0].band(0.0, 0.25);
            assert_eq!(bins, ests[1].band(0.0, 0.25), "the same bins for every input");
            assert!(bins.len() > 200, "{} bins", bins.len());
            for (est, (b, f, d)) in ests.iter().zip([(&b1[..], &f1[..], d1), (&b2[..], &f2[..], d2)]) {
                let mut worst: f64 = 0.0;
                // The DC bin of mean-removed segments holds only their leakage: left out.
                for &k in bins.iter().filter(|&&k| k > 0) {
                    let (gr, gi) = freq_response(b, f, d, 2.0 * PI * k as f64 / est.segment as f64);
                    worst = worst.max((est.re[k] - gr).hypot(est.im[k] - gi) / gr.hypot(gi));
                    assert!(est.coherence[k] > 0.99, "bin {k}: coherence {}", est.coherence[k]);
                }
                assert!(worst < 0.05, "{method:?}: largest relative error {worst}");
                let fit = super::super::band_fit(est, &bins, b, f, d).unwrap();
                assert!(fit > 97.0, "{method:?}: true model's band fit {fit}");
                // The other input's model is far off.
                let (ob, of, od) = if d == 1 { (&b2[..], &f2[..], d2) } else { (&b1[..], &f1[..], d1) };
                assert!(super::super::band_fit(est, &bins, ob, of, od).unwrap() < 50.0);
            }
        }
    }

    /// With output noise the estimate stays unbiased and the gain error of each input is of the
    /// size of the estimate's scatter around the truth.
    #[test]
    fn output_noise_lowers_the_coherence_and_the_gain_error_measures_the_scatter() {
        let n = 32768;
        let (u1, u2, e) = (white(n, 3), white(n, 4), white(n, 5));
        let (b1, f1) = ([1.0], [-0.5]);
        let (b2, f2) = ([0.5, 0.2], [0.3]);
        let y: Vec<f64> = simulate_vec(&b1, &f1, 0, &u1)
            .iter()
            .zip(simulate_vec(&b2, &f2, 1, &u2))
            .zip(&e)
            .map(|((a, b), e)| a + b + 0.7 * e)
            .collect();
        let u: Vec<f64> = u1.iter().chain(&u2).copied().collect();
        let ests = welch_inputs(&u, 2, &y, &[], &[], 1.0, &WelchOptions::default()).unwrap();
        let bins = ests[0].band(0.0, 0.5);
        for (est, (b, f, d)) in ests.iter().zip([(&b1[..], &f1[..], 0), (&b2[..], &f2[..], 1)]) {
            // |H| - |G| over its predicted std e |G| (e the normalised gain error).
            let z2: f64 = bins
                .iter()
                .map(|&k| {
                    let g = freq_response(b, f, d, 2.0 * PI * k as f64 / est.segment as f64);
                    let mag = g.0.hypot(g.1);
                    let sd = est.gain_error[k] * mag;
                    ((est.re[k].hypot(est.im[k]) - mag) / sd).powi(2)
                })
                .sum::<f64>()
                / bins.len() as f64;
            // Neighbouring bins of overlapped Hann segments are correlated: a loose check.
            assert!((0.4..2.5).contains(&z2), "mean squared standardised gain error {z2}");
            let mean_coh = bins.iter().map(|&k| est.coherence[k]).sum::<f64>() / bins.len() as f64;
            assert!(mean_coh < 0.95 && mean_coh > 0.5, "multiple coherence {mean_coh}");
            let band = est.magnitude_band(bins[10]).unwrap();
            assert!(band.0 < band.1);
        }
    }

    #[test]
    fn collinear_inputs_leave_no_usable_bin() {
        let n = 4096;
        let u1 = white(n, 6);
        let u: Vec<f64> = u1.iter().chain(u1.iter().map(|v| 2.0 * v).collect::<Vec<_>>().iter()).copied().collect();
        let ests = welch_inputs(&u, 2, &u1, &[], &[], 1.0, &WelchOptions::default()).unwrap();
        assert!(ests.iter().all(|e| e.band(0.0, 0.5).is_empty()));
        let err = welch_inputs(&u[1..], 2, &u1, &[], &[], 1.0, &WelchOptions::default()).unwrap_err();
        assert!(err.to_string().contains("for 2 inputs"), "{err}");
    }

    #[test]
    fn one_input_is_the_one_input_estimate() {
        let u = white(4096, 7);
        let y: Vec<f64> = simulate_vec(&[0.5], &[-0.7], 1, &u);
        let one = estimate_within(&u, &y, &[], &[], 1.0, SpectrumMethod::Robust).unwrap();
        let ests = estimate_inputs(&u, 1, &y, &[], &[], 1.0, SpectrumMethod::Robust).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(ests.len(), 1);
        assert_eq!((bits(&ests[0].re), bits(&ests[0].im)), (bits(&one.re), bits(&one.im)));
        assert_eq!((ests[0].replaced, ests[0].segments, ests[0].gain_error.len()), (one.replaced, one.segments, 0));
        assert_eq!(combined_band_fit(&[Some(90.0), Some(80.0)]), Some(85.0));
        assert_eq!(combined_band_fit(&[Some(90.0), None]), None);
    }
}
