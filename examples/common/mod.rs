//! What the Monte Carlo examples share (and tests/common includes by path): a small, fully
//! specified random source, so their counts are the same on every machine, and the random
//! binary input they drive their plants with.

/// A 64-bit LCG (Knuth's MMIX constants), uniform draws from its top 53 bits, Gaussian ones by
/// Box-Muller.
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn normal(&mut self) -> f64 {
        let (a, b) = (self.next().max(1e-300), self.next());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// A random binary signal of `n` samples between `lo` and `hi`, each level held `hold` samples.
#[allow(dead_code)]
pub fn binary(n: usize, hold: usize, lo: f64, hi: f64, rng: &mut Lcg) -> Vec<f64> {
    let mut v = lo;
    (0..n)
        .map(|t| {
            if t % hold == 0 {
                v = if rng.next() < 0.5 { lo } else { hi };
            }
            v
        })
        .collect()
}
