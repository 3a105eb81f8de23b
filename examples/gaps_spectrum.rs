//! The spectral estimate of a record with missing outputs (METHOD.md 21.3): the segment length
//! the stretches between gaps allow, the samples used and the band fit of the true model
//! against the estimate, for 0, 5 and 20 % of the outputs missing at random, in bursts of 20 or
//! half and half (an OE(2,2) with poles at radius 0.9, white binary input, noise 0.1).
//! `cargo run --release --example gaps_spectrum` (seconds).

use oesweep::oe;
use oesweep::spectral::{SpectrumMethod, band_fit, estimate_inputs};
struct R(u64);
impl R {
    fn u(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn g(&mut self) -> f64 {
        let (a, b) = (self.u(), self.u());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}
fn main() {
    let (b, f) = (vec![0.5, 0.3], vec![-0.9 * 2.0 * 0.5f64.cos(), 0.81]);
    for n in [3000usize, 8192] {
        for (share, burst) in [(0.0, 0.5), (0.05, 0.0), (0.05, 0.5), (0.05, 1.0), (0.2, 0.5), (0.2, 1.0)] {
            let mut r = R(7);
            let u: Vec<f64> = (0..n).map(|_| if r.u() < 0.5 { 1.0 } else { -1.0 }).collect();
            let mut y = oe::simulate_vec(&b, &f, 1, &u);
            y.iter_mut().for_each(|v| *v += 0.1 * r.g());
            let mut gone = vec![false; n];
            let target = (share * n as f64) as usize;
            let mut c = 0;
            while c < (burst * target as f64) as usize {
                let s = (r.u() * (n - 20) as f64) as usize;
                for g in &mut gone[s..s + 20] {
                    c += usize::from(!*g);
                    *g = true;
                }
            }
            while c < target {
                let t = (r.u() * n as f64) as usize;
                c += usize::from(!gone[t]);
                gone[t] = true;
            }
            let missing: Vec<usize> = (0..n).filter(|&t| gone[t]).collect();
            for &t in &missing {
                y[t] = f64::NAN;
            }
            match estimate_inputs(&u, 1, &y, &[], &missing, 1.0, SpectrumMethod::Welch) {
                Ok(e) => {
                    let e = &e[0];
                    let bins = e.band(0.0, 0.5);
                    println!(
                        "N {n} missing {:.0} % (bursts {:.0} %): segment {} x {} segments, used {} of {} observed, band fit of the true model {:.1} %",
                        share * 100.0,
                        burst * 100.0,
                        e.segment,
                        e.segments,
                        e.used,
                        n - missing.len(),
                        band_fit(e, &bins, &b, &f, 1).unwrap()
                    );
                }
                Err(err) => println!("N {n} missing {:.0} % (bursts {:.0} %): {err}", share * 100.0, burst * 100.0),
            }
        }
    }
}
