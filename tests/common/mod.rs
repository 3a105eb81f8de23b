//! Shared helpers of the integration tests: deterministic signals and test systems.
#![allow(dead_code)]

pub mod mat;

use oesweep::oe;

/// Deterministic uniform numbers in [0, 1) (64-bit LCG; only for test signals).
pub struct Lcg(pub u64);
impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn normal(&mut self) -> f64 {
        let (a, b) = (self.next().max(1e-300), self.next());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// Random binary (+/-amp) input that holds each level for `hold` samples.
pub fn binary_input(n: usize, hold: usize, amp: f64, seed: u64) -> Vec<f64> {
    let mut r = Lcg(seed);
    let mut v = 0.0;
    (0..n)
        .map(|t| {
            if t % hold == 0 {
                v = if r.next() < 0.5 { -amp } else { amp };
            }
            v
        })
        .collect()
}

/// F with the given poles, as (radius, angle) pairs (each a conjugate pair) plus real poles.
pub fn f_from_poles(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    oe::poly_from_poles(pairs, real)
}

/// A known OE(2,2) system.
pub fn oe22() -> (Vec<f64>, Vec<f64>) {
    (vec![0.5, 0.3], f_from_poles(&[(0.9, 0.5)], &[]))
}

/// A known OE(10,10) system: two lightly damped resonances and real poles.
pub fn oe1010() -> (Vec<f64>, Vec<f64>) {
    let f = f_from_poles(&[(0.985, 0.45), (0.97, 1.3), (0.9, 2.2)], &[0.8, 0.5, -0.3, 0.6]);
    let b = vec![0.02, 0.05, -0.03, 0.04, 0.01, -0.02, 0.03, 0.015, -0.01, 0.005];
    (b, f)
}

/// Spikes and noise of [`simulate`].
pub struct Noise<'a> {
    pub amplitude: f64,
    pub std: f64,
    pub spike_probability: f64,
    pub spike_range: &'a str,
}

/// Run `oesweep simulate` of the system file `system` into `out` (CSV with u, y, y0).
pub fn simulate(system: &std::path::Path, out: &std::path::Path, n: usize, seed: u64, noise: &Noise) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["simulate", "--system", system.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(["--n", &n.to_string(), "--seed", &seed.to_string(), "--amplitude", &noise.amplitude.to_string()])
        .args(["--noise-std", &noise.std.to_string(), "--outlier-prob", &noise.spike_probability.to_string()])
        .args(["--outlier-range", noise.spike_range])
        .output()
        .expect("oesweep runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The bundled piezo-like system file.
pub fn piezo_system() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data/piezo_system.json")
}
