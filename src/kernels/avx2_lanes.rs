//! The AVX2+FMA build of the lane kernel ([`super::lanes`]): the slots of a batch in 256-bit
//! registers with explicit vectors (left to the compiler, the portable slots came out slower
//! per fit than the one-fit kernel).
//!
//! Two lanes fill one 256-bit register, `[xu_0, xu_1, xy_0, xy_1]`: per sample nF fused
//! multiply-adds for two fits, where the one-fit kernel spends nF on one, with the state in
//! registers and the coefficients read from memory as the one-fit kernel does. Four lanes
//! fill one 512-bit register on a CPU with AVX-512F (nF for four fits); without it they run
//! as two pairs. Each slot runs [`super::generic::inv_f_impl`]'s fused multiply-adds in its
//! order, and a fused multiply-add rounds a lane alike in any register width, so each lane is
//! the one-fit kernel bit for bit.
//!
//! # Safety
//! Every function here may only run on a CPU with AVX2 and FMA (and [`Four`] with AVX-512F);
//! the slot types are built only inside the functions that require it.

use super::lanes::{Lane, Slots, run};
use std::arch::x86_64::*;

/// Two lanes in one register: slots `[xu_0, xu_1, xy_0, xy_1]`.
struct Two<const M: usize> {
    neg: [__m256d; M],
    /// `s[j]` holds `x_{t-1-j}` of every slot.
    s: [__m256d; M],
}

impl<const M: usize> Slots<2> for Two<M> {
    #[inline(always)]
    fn step(&mut self, u: f64, yhat: [f64; 2]) -> ([f64; 2], [f64; 2]) {
        // SAFETY: a `Two` exists only inside `simulate_filtered_lanes`, on a CPU with AVX2 and
        // FMA, which this inlines into.
        unsafe {
            let mut acc = _mm256_set_pd(yhat[1], yhat[0], u, u);
            for j in (0..M).rev() {
                acc = _mm256_fmadd_pd(self.neg[j], self.s[j], acc);
            }
            for j in (1..M).rev() {
                self.s[j] = self.s[j - 1];
            }
            self.s[0] = acc;
            let (lo, hi) = (_mm256_castpd256_pd128(acc), _mm256_extractf128_pd::<1>(acc));
            (
                [_mm_cvtsd_f64(lo), _mm_cvtsd_f64(_mm_unpackhi_pd(lo, lo))],
                [_mm_cvtsd_f64(hi), _mm_cvtsd_f64(_mm_unpackhi_pd(hi, hi))],
            )
        }
    }
}

/// Four lanes in one 512-bit register: slots `[xu_0 .. xu_3, xy_0 .. xy_3]`. AVX-512's 32
/// registers hold the state of nF <= 24 (AVX2's 16 do not hold two 256-bit chains: four lanes
/// in two 256-bit registers spilled, slower per fit than two lanes).
struct Four<const M: usize> {
    neg: [__m512d; M],
    s: [__m512d; M],
}

impl<const M: usize> Slots<4> for Four<M> {
    #[inline(always)]
    fn step(&mut self, u: f64, yhat: [f64; 4]) -> ([f64; 4], [f64; 4]) {
        // SAFETY: a `Four` exists only inside `simulate_filtered_lanes`, on a CPU with AVX-512F
        // (and FMA), which this inlines into; `out` holds eight f64.
        unsafe {
            let mut acc = _mm512_set_pd(yhat[3], yhat[2], yhat[1], yhat[0], u, u, u, u);
            for j in (0..M).rev() {
                acc = _mm512_fmadd_pd(self.neg[j], self.s[j], acc);
            }
            for j in (1..M).rev() {
                self.s[j] = self.s[j - 1];
            }
            self.s[0] = acc;
            let mut out = [0.0; 8];
            _mm512_storeu_pd(out.as_mut_ptr(), acc);
            ([out[0], out[1], out[2], out[3]], [out[4], out[5], out[6], out[7]])
        }
    }
}

/// True when four lanes can run in one 512-bit register. A 512-bit fused multiply-add rounds
/// each lane as a 256-bit one does, so the answer does not depend on it (the kernel flavour
/// stays `avx2-fma`).
fn has_avx512() -> bool {
    static AVX512: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX512.get_or_init(|| std::is_x86_feature_detected!("avx512f"))
}

/// Two lanes of `nF = M` in one 256-bit register.
///
/// # Safety
/// As [`simulate_filtered_lanes`]'s, with two lanes of M coefficients.
#[inline(always)]
unsafe fn two<const M: usize>(delay: usize, u: &[f64], lanes: &mut [Lane]) {
    // SAFETY: the caller's contract.
    unsafe {
        let neg =
            std::array::from_fn(|j| _mm256_set_pd(-lanes[1].f[j], -lanes[0].f[j], -lanes[1].f[j], -lanes[0].f[j]));
        let mut slots = Two::<M> { neg, s: [_mm256_setzero_pd(); M] };
        run::<2, true>(&mut slots, delay, u, lanes)
    }
}

/// Four lanes of `nF = M` in one 512-bit register.
///
/// # Safety
/// As [`simulate_filtered_lanes`]'s, with four lanes of M coefficients, on a CPU with AVX-512F.
#[target_feature(enable = "avx2,fma,avx512f")]
unsafe fn four<const M: usize>(delay: usize, u: &[f64], lanes: &mut [Lane]) {
    let f = |k: usize, j: usize| -lanes[k].f[j];
    let neg =
        std::array::from_fn(|j| _mm512_set_pd(f(3, j), f(2, j), f(1, j), f(0, j), f(3, j), f(2, j), f(1, j), f(0, j)));
    let mut slots = Four::<M> { neg, s: [_mm512_setzero_pd(); M] };
    // SAFETY: the caller's contract.
    unsafe { run::<4, true>(&mut slots, delay, u, lanes) }
}

/// [`super::simulate_filtered_lanes`] for 2 or 4 lanes of `nF <= 24`; returns false (and does
/// nothing) otherwise. Four lanes run in one 512-bit register where the CPU has AVX-512F and
/// `wide` allows it, else as two pairs.
///
/// # Safety
/// The CPU supports AVX2 and FMA; the lanes were checked as [`super::lanes::run`] asks.
#[target_feature(enable = "avx2,fma")]
pub unsafe fn simulate_filtered_lanes(delay: usize, u: &[f64], lanes: &mut [Lane], wide: bool) -> bool {
    macro_rules! orders {
        ($($m:literal)*) => {
            // SAFETY: this function's own contract; the match gives M, `four` runs only on a
            // CPU with AVX-512F.
            match (lanes[0].f.len(), lanes.len()) {
                $(
                    ($m, 2) => unsafe { two::<$m>(delay, u, lanes) },
                    ($m, 4) if wide && has_avx512() => unsafe { four::<$m>(delay, u, lanes) },
                    ($m, 4) => unsafe {
                        let (a, b) = lanes.split_at_mut(2);
                        two::<$m>(delay, u, a);
                        two::<$m>(delay, u, b);
                    },
                )*
                _ => return false,
            }
        };
    }
    orders!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
    true
}
