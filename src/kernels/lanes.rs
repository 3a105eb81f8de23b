//! Several fits side by side: the simulation and both Jacobian signals (METHOD.md 2) of L
//! independent fits of the same orders on the same record, each with its own B and F,
//! advanced together in the lanes of one vector register.
//!
//! Why: the `1/F` recursion is one serial chain of fused multiply-adds per sample, nF of them,
//! and [`super::simulate_filtered`] runs a fit's two recursions (`(1/F) u` and `(1/F) yhat`,
//! the second one block behind) in the two lanes of a 128-bit register. The chain cannot be
//! reordered without changing the bits; what a wider register buys is more fits per
//! instruction: two fits fill a 256-bit register (nF multiply-adds per sample for two fits
//! where the one-fit kernel spends nF on one), four a 512-bit one. (Four in two 256-bit
//! registers need twice the state, which AVX2's 16 registers do not hold at nF >= 5: measured
//! slower per fit than two; without AVX-512 four lanes run as two pairs, `avx2_lanes.rs`.)
//! docs/PERFORMANCE.md "Where the floor is" has the measurements.
//!
//! Same answers: slot `k < L` of the register runs lane k's `(1/F) u`, slot `L + k` its
//! `(1/F) yhat`, and every slot does exactly the operations of the one-fit recursion
//! ([`super::generic::inv_f_impl`]) in the same order (`acc = x_t`, then
//! `acc = madd(-f_j, x_{t-j}, acc)` from the oldest output to the newest), a fused
//! multiply-add where the one-fit build fuses (the AVX2+FMA build) and a multiply and an add
//! where it does not (the baseline build). The FIR of each lane is the one-fit FIR
//! ([`super::generic::fir_range_impl`]) block by block, whose sums do not depend on the
//! blocking. So each lane's `xu`, `yhat` and `xy` are the one-fit kernel's bit for bit, in
//! either flavour, and a table does not depend on how its fits were batched. Orders the one-fit
//! kernel does not specialise (nF = 0 or nF > 24) take the one-fit kernel lane by lane.
//!
//! The rest of an iteration needs no lane kernel: the lagged correlations of the normal
//! equations, the weighted rows' product and the criterion already run four samples to a
//! 256-bit register within one fit (their sums are over the record), so batching fits does
//! not shorten them; each lane takes the one-fit kernels on its own signals, which is why the
//! lanes' signals stay one contiguous record per fit (not interleaved).

use super::generic::{fir_range_impl, madd};

/// Samples per block: lane k's `(1/F) yhat` runs one block behind its `(1/F) u`, so that
/// the FIR has turned the block into `yhat` by then; 256 samples of the L lanes' three signals
/// stay in L1.
const BLOCK: usize = 256;

/// One fit of a batch: its polynomials (B, and F without its leading 1) and the signals
/// [`super::simulate_filtered`] writes, `xu = (1/F) u`, `yhat = q^-d B xu`,
/// `xy = (1/F) yhat`, each as long as the record.
pub struct Lane<'a> {
    pub b: &'a [f64],
    pub f: &'a [f64],
    pub xu: &'a mut [f64],
    pub yhat: &'a mut [f64],
    pub xy: &'a mut [f64],
}

/// The `2 L` recursions of a batch, one sample at a time: slots `0..L` are fed `u_t` and
/// return the lanes' `(1/F) u`, slots `L..2L` are fed the lanes' `yhat` one block behind and
/// return their `(1/F) yhat`. Each slot is [`super::generic::inv_f_impl`]'s recursion with its
/// lane's F, operation for operation; the builds differ only in how the slots share registers.
pub(super) trait Slots<const L: usize> {
    fn step(&mut self, u: f64, yhat: [f64; L]) -> ([f64; L], [f64; L]);
}

/// The portable slots: arrays of `S = 2 L` values, the baseline build's.
struct Portable<const M: usize, const S: usize, const FMA: bool> {
    neg: [[f64; S]; M],
    /// `s[j]` holds `x_{t-1-j}` of every slot.
    s: [[f64; S]; M],
}

impl<const M: usize, const S: usize, const FMA: bool> Portable<M, S, FMA> {
    fn new(lanes: &[Lane]) -> Self {
        let mut neg = [[0.0; S]; M];
        for (j, row) in neg.iter_mut().enumerate() {
            for (k, c) in row.iter_mut().enumerate() {
                *c = -lanes[k % lanes.len()].f[j];
            }
        }
        Portable { neg, s: [[0.0; S]; M] }
    }
}

impl<const M: usize, const L: usize, const S: usize, const FMA: bool> Slots<L> for Portable<M, S, FMA> {
    #[inline(always)]
    fn step(&mut self, u: f64, yhat: [f64; L]) -> ([f64; L], [f64; L]) {
        let mut acc = [u; S];
        acc[L..].copy_from_slice(&yhat);
        for j in (0..M).rev() {
            for (a, (&c, &v)) in acc.iter_mut().zip(self.neg[j].iter().zip(&self.s[j])) {
                *a = madd::<FMA>(c, v, *a);
            }
        }
        for j in (1..M).rev() {
            self.s[j] = self.s[j - 1];
        }
        self.s[0] = acc;
        let mut out = ([0.0; L], [0.0; L]);
        out.0.copy_from_slice(&acc[..L]);
        out.1.copy_from_slice(&acc[L..]);
        out
    }
}

/// [`super::simulate_filtered`] of the `L` lanes through `slots` (which hold their F):
/// slots `0..L` run the lanes' `(1/F) u` block by block, each lane's FIR turns a finished block
/// into its `yhat`, and slots `L..2L` run the lanes' `(1/F) yhat` one block behind.
///
/// # Safety
/// `lanes.len() == L` and every lane's `xu`, `yhat` and `xy` have the length of `u` (checked by
/// [`super::simulate_filtered_lanes`]; the unchecked accesses rely on it). Built with FMA only
/// for a CPU that has it.
#[inline(always)]
pub(super) unsafe fn run<const L: usize, const FMA: bool>(
    slots: &mut impl Slots<L>,
    delay: usize,
    u: &[f64],
    lanes: &mut [Lane],
) {
    let n = u.len();
    // Raw pointers, taken once: the loop writes three signals of every lane per sample, and
    // through the lane structs each access would reload its slice. Every access below goes
    // through them (no reference to the signals is used meanwhile).
    let mut xu = [std::ptr::null_mut::<f64>(); L];
    let mut yhat = [std::ptr::null_mut::<f64>(); L];
    let mut xy = [std::ptr::null_mut::<f64>(); L];
    for (k, lane) in lanes.iter_mut().enumerate() {
        xu[k] = lane.xu.as_mut_ptr();
        yhat[k] = lane.yhat.as_mut_ptr();
        xy[k] = lane.xy.as_mut_ptr();
    }
    // The `(1/F) yhat` slots are fed zeros during the first block: with zero state they stay
    // exactly zero, i.e. start on yhat_0 from zero initial conditions. The `(1/F) u` slots
    // are fed zeros past the end; their outputs there are dropped.
    let mut t0 = 0;
    // SAFETY: t0 + i < n and p0 + i < n wherever a signal is read or written (i < len0 or
    // i < len1), every signal has length n (this function's contract), and the signals of
    // one lane and of different lanes are distinct slices.
    unsafe {
        while t0 < n + BLOCK {
            let len0 = n.saturating_sub(t0).min(BLOCK);
            let p0 = t0.wrapping_sub(BLOCK);
            let len1 = if t0 >= BLOCK { (n - p0).min(BLOCK) } else { 0 };
            let both = len0.min(len1);
            for i in 0..both {
                let (a, b) = slots.step(*u.get_unchecked(t0 + i), std::array::from_fn(|k| *yhat[k].add(p0 + i)));
                for k in 0..L {
                    *xu[k].add(t0 + i) = a[k];
                    *xy[k].add(p0 + i) = b[k];
                }
            }
            for i in both..len0 {
                let (a, _) = slots.step(*u.get_unchecked(t0 + i), [0.0; L]);
                for k in 0..L {
                    *xu[k].add(t0 + i) = a[k];
                }
            }
            for i in both..len1 {
                let (_, b) = slots.step(0.0, std::array::from_fn(|k| *yhat[k].add(p0 + i)));
                for k in 0..L {
                    *xy[k].add(p0 + i) = b[k];
                }
            }
            if len0 > 0 {
                for k in 0..L {
                    let xu = std::slice::from_raw_parts(xu[k], n);
                    let yhat = std::slice::from_raw_parts_mut(yhat[k], n);
                    fir_range_impl::<FMA>(lanes[k].b, delay, xu, yhat, t0, t0 + len0);
                }
            }
            t0 += BLOCK;
        }
    }
}

/// The baseline build of the lane kernel for `nF = M`, `L` lanes (`S = 2 L` slots).
///
/// # Safety
/// As [`run`]'s, and every lane's `f` has M coefficients.
#[inline(always)]
unsafe fn portable<const M: usize, const L: usize, const S: usize>(delay: usize, u: &[f64], lanes: &mut [Lane]) {
    let mut slots = Portable::<M, S, false>::new(lanes);
    // SAFETY: this function's own contract.
    unsafe { run::<L, false>(&mut slots, delay, u, lanes) }
}

/// The baseline build of the lane kernel: 2 or 4 lanes of `nF` in 1..=24; false (nothing
/// done) otherwise.
///
/// # Safety
/// As [`run`]'s (the caller checked the lanes).
pub(super) unsafe fn simulate_filtered(delay: usize, u: &[f64], lanes: &mut [Lane]) -> bool {
    macro_rules! orders {
        ($($m:literal)*) => {
            // SAFETY: this function's own contract; the match gives M.
            match (lanes[0].f.len(), lanes.len()) {
                $(
                    ($m, 2) => unsafe { portable::<$m, 2, 4>(delay, u, lanes) },
                    ($m, 4) => unsafe { portable::<$m, 4, 8>(delay, u, lanes) },
                )*
                _ => return false,
            }
        };
    }
    orders!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stable F of order nf with poles at radius `r`, spread over angles shifted by `phase`,
    /// and a B of nb taps: a different model per lane.
    fn model(nb: usize, nf: usize, r: f64, phase: f64) -> (Vec<f64>, Vec<f64>) {
        let mut roots = Vec::new();
        for j in 0..nf / 2 {
            let a = phase + 2.5 * j as f64 / nf as f64;
            roots.push((r * a.cos(), r * a.sin()));
            roots.push((r * a.cos(), -r * a.sin()));
        }
        if nf % 2 == 1 {
            roots.push((-0.5 * r, 0.0));
        }
        let f = crate::oe::poly_from_roots(&roots);
        let b = (0..nb).map(|i| (1.0 + phase) / (i as f64 + 1.5)).collect();
        (b, f)
    }

    type Signals = (Vec<f64>, Vec<f64>, Vec<f64>);

    /// Each lane's signals from `run` given the lanes (all of the record's length).
    fn lanes_of(models: &[(Vec<f64>, Vec<f64>)], n: usize, run: impl FnOnce(&mut [Lane])) -> Vec<Signals> {
        let mut out: Vec<Signals> =
            models.iter().map(|_| (vec![f64::NAN; n], vec![f64::NAN; n], vec![f64::NAN; n])).collect();
        let mut lanes: Vec<Lane> =
            models.iter().zip(out.iter_mut()).map(|((b, f), (xu, yhat, xy))| Lane { b, f, xu, yhat, xy }).collect();
        run(&mut lanes);
        out
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    const ORDERS: [(usize, usize, usize); 9] =
        [(4, 4, 1), (10, 10, 1), (14, 15, 1), (1, 1, 0), (7, 2, 4), (3, 24, 2), (12, 12, 1), (2, 25, 1), (5, 0, 1)];

    fn record(n: usize) -> Vec<f64> {
        (0..n).map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3 + (i as f64 * 0.1).sin()).collect()
    }

    /// The dispatched lane kernel (AVX2+FMA here when the CPU has it) against the one-fit
    /// kernel of the same flavour, lane by lane, bit for bit: 1 to 5 lanes (5 = 4 + 1, 3 =
    /// 2 + 1), every lane its own B and F, records across block boundaries, and the orders
    /// the lane kernel leaves to the one-fit kernel (nF = 0, nF = 25).
    #[test]
    fn every_lane_is_the_one_fit_kernel_bit_for_bit() {
        for n in [0, 1, 7, 255, 256, 257, 600, 5000] {
            let u = record(n);
            for (nb, nf, delay) in ORDERS {
                for count in 1..=5 {
                    let models: Vec<_> =
                        (0..count).map(|l| model(nb, nf, 0.95 - 0.04 * l as f64, 0.3 + 0.2 * l as f64)).collect();
                    let got = lanes_of(&models, n, |lanes| super::super::simulate_filtered_lanes(delay, &u, lanes));
                    // Four lanes as two pairs of 256-bit registers, what a CPU without
                    // AVX-512 runs (this one may run them in one 512-bit register above).
                    #[cfg(target_arch = "x86_64")]
                    if count == 4 && super::super::has_fma() {
                        let pairs = lanes_of(&models, n, |lanes| {
                            // SAFETY: the CPU has AVX2 and FMA; the lanes have one nF and
                            // signals of the record's length.
                            let done =
                                unsafe { super::super::avx2_lanes::simulate_filtered_lanes(delay, &u, lanes, false) };
                            if !done {
                                super::super::simulate_filtered_lanes(delay, &u, lanes);
                            }
                        });
                        let all =
                            |v: &[Signals]| v.iter().map(|(a, b, c)| (bits(a), bits(b), bits(c))).collect::<Vec<_>>();
                        assert_eq!(all(&pairs), all(&got), "n {n} OE({nb},{nf}): four lanes as two pairs");
                    }
                    for (l, ((b, f), (xu, yhat, xy))) in models.iter().zip(&got).enumerate() {
                        let (mut wxu, mut wyhat, mut wxy) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
                        super::super::simulate_filtered(b, f, delay, &u, &mut wxu, &mut wyhat, &mut wxy);
                        let what = format!("n {n} OE({nb},{nf}) delay {delay}, lane {l} of {count}");
                        assert_eq!(bits(xu), bits(&wxu), "xu, {what}");
                        assert_eq!(bits(yhat), bits(&wyhat), "yhat, {what}");
                        assert_eq!(bits(xy), bits(&wxy), "xy, {what}");
                    }
                    if count > 1 && n > 10 && nf > 0 {
                        assert_ne!(got[0].2, got[1].2, "the lanes ran different models");
                    }
                }
            }
        }
    }

    /// The baseline lane kernel against the baseline one-fit passes (`1/F`, FIR, `1/F`), the
    /// flavour a CPU without AVX2 and FMA runs, bit for bit.
    #[test]
    fn the_baseline_lanes_are_the_baseline_passes_bit_for_bit() {
        use super::super::generic;
        for n in [1, 255, 257, 5000] {
            let u = record(n);
            for (nb, nf, delay) in ORDERS {
                for count in [2, 4] {
                    let models: Vec<_> =
                        (0..count).map(|l| model(nb, nf, 0.9 + 0.02 * l as f64, 0.1 + 0.3 * l as f64)).collect();
                    // SAFETY: the lanes have one nF and signals of the record's length.
                    let got = lanes_of(&models, n, |lanes| {
                        let done = unsafe { simulate_filtered(delay, &u, lanes) };
                        assert_eq!(done, (1..=24).contains(&nf), "which orders the lane kernel takes");
                        if !done {
                            for l in lanes {
                                l.xu.copy_from_slice(&u);
                                generic::inv_f(l.f, l.xu);
                                generic::fir(l.b, delay, l.xu, l.yhat);
                                l.xy.copy_from_slice(l.yhat);
                                generic::inv_f(l.f, l.xy);
                            }
                        }
                    });
                    for (l, ((b, f), (xu, yhat, xy))) in models.iter().zip(&got).enumerate() {
                        let mut wxu = u.clone();
                        generic::inv_f(f, &mut wxu);
                        let mut wyhat = vec![0.0; n];
                        generic::fir(b, delay, &wxu, &mut wyhat);
                        let mut wxy = wyhat.clone();
                        generic::inv_f(f, &mut wxy);
                        let what = format!("n {n} OE({nb},{nf}) delay {delay}, lane {l} of {count}");
                        assert_eq!(bits(xu), bits(&wxu), "xu, {what}");
                        assert_eq!(bits(yhat), bits(&wyhat), "yhat, {what}");
                        assert_eq!(bits(xy), bits(&wxy), "xy, {what}");
                    }
                }
            }
        }
    }
}
