//! What the `1/F` recursion's state costs (docs/PERFORMANCE.md "Where the floor is"): one
//! 256-bit chain of `x_t - sum_j f_j x_{t-j}` over 5 000 samples, nF = 10 and 15, in the
//! kernels' operation order, its state kept two ways:
//! - `shifted`: as the kernels keep it, `s[j] = x_{t-1-j}` shifted by one each sample
//!   (nF - 1 register moves per sample);
//! - `rotated`: the same registers used as a ring whose start moves back one each sample, the
//!   loop unrolled by nF so that every index is a constant (no moves).
//!
//! Both give the same bits (checked); the times are the best of 2001 calls each, interleaved.
//! Run: `cargo run --release --example recursion_state`.

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    /// The kernels' layout: state shifted each sample.
    #[target_feature(enable = "avx2,fma")]
    pub fn shifted<const M: usize>(neg: &[__m256d; M], x: &[f64], out: &mut [f64]) {
        let mut s = [_mm256_setzero_pd(); M];
        for (t, o) in out.iter_mut().enumerate() {
            let mut acc = _mm256_set1_pd(x[t]);
            for j in (0..M).rev() {
                acc = _mm256_fmadd_pd(neg[j], s[j], acc);
            }
            for j in (1..M).rev() {
                s[j] = s[j - 1];
            }
            s[0] = acc;
            *o = _mm256_cvtsd_f64(acc);
        }
    }

    /// One sample with the ring's start at `H`: `ring[(H + j) % M]` holds `x_{t-1-j}`; the new
    /// output replaces the oldest, and the next sample's start is `H - 1 (mod M)`.
    #[inline(always)]
    fn ring_step<const M: usize, const H: usize>(neg: &[__m256d; M], ring: &mut [__m256d; M], x: f64) -> f64 {
        // SAFETY: inlined into `rotated`, compiled with AVX2 and FMA.
        unsafe {
            let mut acc = _mm256_set1_pd(x);
            for j in (0..M).rev() {
                acc = _mm256_fmadd_pd(neg[j], ring[(H + j) % M], acc);
            }
            ring[(H + M - 1) % M] = acc;
            _mm256_cvtsd_f64(acc)
        }
    }

    macro_rules! rotated {
        ($name:ident, $m:literal, $($h:literal)*) => {
            /// The ring layout for nF = M, unrolled by M (the tail sample by sample, shifted).
            #[target_feature(enable = "avx2,fma")]
            pub fn $name(neg: &[__m256d; $m], x: &[f64], out: &mut [f64]) {
                let mut ring = [_mm256_setzero_pd(); $m];
                let mut t = 0;
                while t + $m <= x.len() {
                    let mut k = 0;
                    $(
                        out[t + k] = ring_step::<$m, $h>(neg, &mut ring, x[t + k]);
                        k += 1;
                    )*
                    let _ = k;
                    t += $m;
                }
                // The tail: back to the shifted order (start 0).
                while t < x.len() {
                    // The new output took the oldest's place, ring[M - 1]: rotate it to the front.
                    out[t] = ring_step::<$m, 0>(neg, &mut ring, x[t]);
                    ring.rotate_right(1);
                    t += 1;
                }
            }
        };
    }
    rotated!(rotated10, 10, 0 9 8 7 6 5 4 3 2 1);
    rotated!(rotated15, 15, 0 14 13 12 11 10 9 8 7 6 5 4 3 2 1);
}

#[cfg(target_arch = "x86_64")]
fn main() {
    use std::arch::x86_64::*;
    if !(std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")) {
        println!("no AVX2 and FMA on this CPU");
        return;
    }
    let n = 5000;
    let x: Vec<f64> = (0..n).map(|i| ((i * 37 % 11) as f64 - 5.0) * 0.3).collect();
    // Small coefficients, so the recursion stays bounded (its values do not move the time).
    let f = |m: usize| -> Vec<f64> { (1..=m).map(|j| (-0.5f64).powi(j as i32) / j as f64).collect() };
    let time = |run: &mut dyn FnMut()| {
        let t = std::time::Instant::now();
        run();
        t.elapsed().as_secs_f64()
    };
    macro_rules! compare {
        ($m:literal, $rot:ident) => {{
            let fm = f($m);
            // SAFETY: the CPU has AVX2 (checked above).
            let neg: [__m256d; $m] = std::array::from_fn(|j| unsafe { _mm256_set1_pd(-fm[j]) });
            let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
            let (mut best_a, mut best_b) = (f64::INFINITY, f64::INFINITY);
            for _ in 0..2001 {
                // SAFETY: the CPU has AVX2 and FMA (checked above).
                best_a = best_a.min(time(&mut || unsafe { x86::shifted::<$m>(&neg, &x, &mut a) }));
                best_b = best_b.min(time(&mut || unsafe { x86::$rot(&neg, &x, &mut b) }));
            }
            assert!(a.iter().zip(&b).all(|(p, q)| p.to_bits() == q.to_bits()), "the same bits");
            println!(
                "nF = {}: shifted {:.2} us ({:.2} ns per sample), rotated {:.2} us ({:.2} ns per sample)",
                $m,
                best_a * 1e6,
                best_a * 1e9 / n as f64,
                best_b * 1e6,
                best_b * 1e9 / n as f64
            );
        }};
    }
    compare!(10, rotated10);
    compare!(15, rotated15);
}

#[cfg(not(target_arch = "x86_64"))]
fn main() {
    println!("x86-64 only");
}
