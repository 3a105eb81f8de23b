//! This machine's multiply-add peak, for docs/PERFORMANCE.md "Where the floor is": fused
//! multiply-adds per nanosecond with one lane (scalar), four lanes (256-bit) and eight
//! (512-bit, where the CPU has AVX-512F), each over 12 independent chains (enough to cover the
//! latency on two ports, few enough to stay in 16 registers), and the latency of one dependent chain.
//!
//! Run: `cargo run --release --example fma_peak`. Each figure is the best of 2001 runs of
//! 2^14 multiply-adds per chain (tens of microseconds): on a shared machine the best run is
//! one that no other process interrupted.

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;
    use std::hint::black_box;

    const CHAINS: usize = 12;

    /// `reps` multiply-adds in each of 12 independent scalar chains.
    #[target_feature(enable = "avx2,fma")]
    pub fn scalar(reps: usize) -> f64 {
        let (a, b) = (black_box(0.999_999_9), black_box(1e-9));
        let mut acc = [1.0f64; CHAINS];
        for _ in 0..reps {
            for x in acc.iter_mut() {
                *x = x.mul_add(a, b);
            }
        }
        acc.iter().sum()
    }

    /// The same in 256-bit registers (four lanes each).
    #[target_feature(enable = "avx2,fma")]
    pub fn ymm(reps: usize) -> f64 {
        let (a, b) = (_mm256_set1_pd(black_box(0.999_999_9)), _mm256_set1_pd(black_box(1e-9)));
        let mut acc = [_mm256_set1_pd(1.0); CHAINS];
        for _ in 0..reps {
            for x in acc.iter_mut() {
                *x = _mm256_fmadd_pd(*x, a, b);
            }
        }
        let mut out = [0.0; 4];
        // SAFETY: out holds four f64.
        unsafe {
            _mm256_storeu_pd(out.as_mut_ptr(), acc.iter().fold(_mm256_setzero_pd(), |s, &x| _mm256_add_pd(s, x)))
        };
        out.iter().sum()
    }

    /// The same in 512-bit registers (eight lanes each).
    #[target_feature(enable = "avx512f")]
    pub fn zmm(reps: usize) -> f64 {
        let (a, b) = (_mm512_set1_pd(black_box(0.999_999_9)), _mm512_set1_pd(black_box(1e-9)));
        let mut acc = [_mm512_set1_pd(1.0); CHAINS];
        for _ in 0..reps {
            for x in acc.iter_mut() {
                *x = _mm512_fmadd_pd(*x, a, b);
            }
        }
        _mm512_reduce_add_pd(acc.iter().fold(_mm512_setzero_pd(), |s, &x| _mm512_add_pd(s, x)))
    }

    /// `reps` multiply-adds in one dependent chain.
    #[target_feature(enable = "avx2,fma")]
    pub fn chain(reps: usize) -> f64 {
        let (a, b) = (black_box(0.999_999_9), black_box(1e-9));
        let mut x = 1.0f64;
        for _ in 0..reps {
            x = x.mul_add(a, b);
        }
        x
    }
}

#[cfg(target_arch = "x86_64")]
fn main() {
    const REPS: usize = 1 << 14;
    let best = |f: &dyn Fn(usize) -> f64| {
        (0..2001)
            .map(|_| {
                let t = std::time::Instant::now();
                std::hint::black_box(f(REPS));
                t.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
    };
    if !(std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")) {
        println!("no AVX2 and FMA on this CPU");
        return;
    }
    let chains = 12.0 * REPS as f64;
    // SAFETY (all calls below): the CPU has AVX2 and FMA (AVX-512F where zmm runs), checked.
    let s = best(&|r| unsafe { x86::scalar(r) });
    println!("scalar: {:.2} multiply-adds per ns (12 chains)", chains / s / 1e9);
    let y = best(&|r| unsafe { x86::ymm(r) });
    println!(
        "256-bit: {:.2} lane multiply-adds per ns ({:.2} instructions per ns)",
        4.0 * chains / y / 1e9,
        chains / y / 1e9
    );
    if std::is_x86_feature_detected!("avx512f") {
        let z = best(&|r| unsafe { x86::zmm(r) });
        println!(
            "512-bit: {:.2} lane multiply-adds per ns ({:.2} instructions per ns)",
            8.0 * chains / z / 1e9,
            chains / z / 1e9
        );
    }
    let c = best(&|r| unsafe { x86::chain(r) });
    println!("one dependent chain: {:.3} ns per multiply-add", c / REPS as f64 * 1e9);
}

#[cfg(not(target_arch = "x86_64"))]
fn main() {
    println!("x86-64 only");
}
