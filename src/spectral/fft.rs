//! The FFT and the segment preparation of the Welch estimate (METHOD.md 11).

use std::f64::consts::PI;

/// `out = w (x - mean(x))`, imaginary part zeroed: the FFT input of one segment.
pub(super) fn detrend_window(x: &[f64], w: &[f64], out_re: &mut [f64], out_im: &mut [f64]) {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    for ((o, &xi), &wi) in out_re.iter_mut().zip(x).zip(w) {
        *o = wi * (xi - mean);
    }
    out_im.fill(0.0);
}

/// In-place iterative radix-2 complex FFT, `X_k = sum_n x_n e^{-j 2 pi k n / M}`, with the
/// twiddle factors and bit-reversal table precomputed once per segment length.
pub(super) struct Fft {
    n: usize,
    /// `e^{-j 2 pi k / n}` for `k < n/2`.
    tw_re: Vec<f64>,
    tw_im: Vec<f64>,
    /// Bit-reversed index of each position.
    rev: Vec<usize>,
}

impl Fft {
    pub(super) fn new(n: usize) -> Self {
        assert!(n.is_power_of_two() && n >= 2, "FFT length {n} is not a power of two >= 2");
        let bits = n.trailing_zeros();
        let (tw_re, tw_im) = (0..n / 2)
            .map(|k| {
                let a = -2.0 * PI * k as f64 / n as f64;
                (a.cos(), a.sin())
            })
            .unzip();
        let rev = (0..n).map(|i| i.reverse_bits() >> (usize::BITS - bits)).collect();
        Fft { n, tw_re, tw_im, rev }
    }

    pub(super) fn forward(&self, re: &mut [f64], im: &mut [f64]) {
        assert!(re.len() == self.n && im.len() == self.n);
        for i in 0..self.n {
            let j = self.rev[i];
            if i < j {
                re.swap(i, j);
                im.swap(i, j);
            }
        }
        let mut len = 2;
        while len <= self.n {
            let half = len / 2;
            let stride = self.n / len;
            for start in (0..self.n).step_by(len) {
                for k in 0..half {
                    let (wr, wi) = (self.tw_re[k * stride], self.tw_im[k * stride]);
                    let (a, b) = (start + k, start + k + half);
                    let tr = re[b] * wr - im[b] * wi;
                    let ti = re[b] * wi + im[b] * wr;
                    re[b] = re[a] - tr;
                    im[b] = im[a] - ti;
                    re[a] += tr;
                    im[a] += ti;
                }
            }
            len *= 2;
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Deterministic +/-1 sequence from a 64-bit LCG (Knuth's MMIX constants), top bit.
    pub(in crate::spectral) fn pm1(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                if s >> 63 == 1 { 1.0 } else { -1.0 }
            })
            .collect()
    }

    #[test]
    fn fft_matches_naive_dft() {
        let n = 64;
        let x = pm1(n, 7);
        let xi: Vec<f64> = pm1(n, 11).iter().map(|v| 0.5 * v).collect();
        let (mut re, mut im) = (x.clone(), xi.clone());
        Fft::new(n).forward(&mut re, &mut im);
        for k in 0..n {
            let (mut sr, mut si) = (0.0, 0.0);
            for t in 0..n {
                let a = -2.0 * PI * (k * t) as f64 / n as f64;
                sr += x[t] * a.cos() - xi[t] * a.sin();
                si += x[t] * a.sin() + xi[t] * a.cos();
            }
            assert!((re[k] - sr).abs() < 1e-10 && (im[k] - si).abs() < 1e-10, "bin {k}");
        }
    }
}
