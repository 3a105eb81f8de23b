//! Records with gaps for tests and Monte Carlo (`oesweep simulate --missing P`, METHOD.md
//! 21.1): outputs and inputs taken out of a simulated record in bursts, deterministically from
//! the seed, on random streams of their own (the record's noise, spikes and inputs do not
//! move when gaps are added). The noise-free `y0` is never taken out: it is what a validation
//! judges against.

use super::{SimOptions, SimRecord};
use crate::error::{Error, Result};
use crate::rng::Xoshiro256;
use std::path::Path;

/// Streams of the gaps, far from the inputs' (`INPUT_STREAM + i`, i < 8).
const OUTPUT_GAP_STREAM: u64 = 1 << 20;
const INPUT_GAP_STREAM: u64 = (1 << 20) + 1;

/// The gaps to make ([`punch`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GapOptions {
    /// Share of the outputs to take out (0 to 1).
    pub outputs: f64,
    /// Share of the rows whose input (one input, chosen at random per burst) is taken out.
    pub inputs: f64,
    /// Length of each gap in samples (1: single samples at random).
    pub burst: usize,
}

impl GapOptions {
    fn check(&self) -> Result<()> {
        for (flag, p) in [("--missing", self.outputs), ("--missing-inputs", self.inputs)] {
            if !(0.0..=1.0).contains(&p) {
                return Err(Error::Invalid(format!("{flag} must be a share between 0 and 1, got {p}")));
            }
        }
        if self.burst == 0 {
            return Err(Error::Invalid("--missing-burst must be at least 1 sample".into()));
        }
        Ok(())
    }
}

/// Takes samples out of `rec` (NaN, written as empty fields): bursts of `burst` samples at
/// uniformly random starts until at least `round(share N)` outputs (and, apart, rows of an
/// input, one input per burst) are missing, fewer than one burst more. `seed` is the record's.
pub fn punch(rec: &mut SimRecord, gaps: &GapOptions, seed: u64) -> Result<()> {
    gaps.check()?;
    let n = rec.y.len();
    if gaps.outputs > 0.0 {
        let y = &mut rec.y;
        bursts(n, gaps, gaps.outputs, Xoshiro256::new(seed, OUTPUT_GAP_STREAM), |at, _| {
            at.filter(|&t| !std::mem::replace(&mut y[t], f64::NAN).is_nan()).count()
        });
    }
    if gaps.inputs > 0.0 {
        let (m, u) = (rec.m, &mut rec.u);
        bursts(n, gaps, gaps.inputs, Xoshiro256::new(seed, INPUT_GAP_STREAM), |at, rng| {
            let input = ((rng.uniform() * m as f64) as usize).min(m - 1);
            // Rows newly missing an input (of any input).
            at.filter(|&t| {
                let fresh = (0..m).all(|i| !u[i * n + t].is_nan());
                u[input * n + t] = f64::NAN;
                fresh
            })
            .count()
        });
    }
    Ok(())
}

/// Bursts of `gaps.burst` samples of a record of `n` at random starts drawn from `rng`, each
/// handed to `take` (which returns how many samples it newly took out), until `share` of the
/// record is out.
fn bursts(
    n: usize,
    gaps: &GapOptions,
    share: f64,
    mut rng: Xoshiro256,
    mut take: impl FnMut(std::ops::Range<usize>, &mut Xoshiro256) -> usize,
) {
    let burst = gaps.burst.min(n);
    let target = (share * n as f64).round() as usize;
    let mut count = 0;
    while count < target {
        let start = ((rng.uniform() * (n - burst + 1) as f64) as usize).min(n - burst);
        count += take(start..start + burst, &mut rng);
    }
}

/// `oesweep simulate` with gaps: the system file's record ([`super::generate_inputs`]) with the
/// samples of `gaps` taken out, written as CSV ([`super::write_csv`]). Returns the samples.
pub fn simulate_csv(system: &Path, out: &Path, opts: &SimOptions, gaps: &GapOptions) -> Result<usize> {
    gaps.check()?;
    let mut rec = super::generate_inputs(&super::read_systems(system)?, opts)?;
    punch(&mut rec, gaps, opts.seed)?;
    super::write_csv(out, &rec)?;
    Ok(opts.n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(n: usize, m: usize) -> SimRecord {
        SimRecord { u: vec![1.0; n * m], m, y: vec![2.0; n], y0: vec![3.0; n] }
    }

    #[test]
    fn shares_and_bursts_are_as_asked_and_reproducible() {
        let gaps = GapOptions { outputs: 0.05, inputs: 0.02, burst: 20 };
        let mut a = record(3000, 2);
        punch(&mut a, &gaps, 7).unwrap();
        let out = a.y.iter().filter(|v| v.is_nan()).count();
        assert!((150..170).contains(&out), "{out}");
        let rows = (0..3000).filter(|&t| a.u[t].is_nan() || a.u[3000 + t].is_nan()).count();
        assert!((60..80).contains(&rows), "{rows}");
        assert!(a.y0.iter().all(|v| *v == 3.0));
        // Bursts: every missing output has a missing neighbour.
        let lonely = (0..3000)
            .filter(|&t| a.y[t].is_nan() && !(t > 0 && a.y[t - 1].is_nan()) && !(t + 1 < 3000 && a.y[t + 1].is_nan()));
        assert_eq!(lonely.count(), 0);
        let mut b = record(3000, 2);
        punch(&mut b, &gaps, 7).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!((bits(&a.u), bits(&a.y)), (bits(&b.u), bits(&b.y)));
        let mut c = record(3000, 2);
        punch(&mut c, &gaps, 8).unwrap();
        assert_ne!(bits(&a.y), bits(&c.y));
        let single = GapOptions { outputs: 0.2, inputs: 0.0, burst: 1 };
        let mut d = record(1000, 1);
        punch(&mut d, &single, 1).unwrap();
        assert_eq!(d.y.iter().filter(|v| v.is_nan()).count(), 200);
        assert!(d.u.iter().all(|v| *v == 1.0));
    }

    #[test]
    fn options_are_checked() {
        let mut r = record(10, 1);
        let e = punch(&mut r, &GapOptions { outputs: 1.5, inputs: 0.0, burst: 1 }, 1).unwrap_err();
        assert!(e.to_string().contains("--missing must be a share between 0 and 1, got 1.5"), "{e}");
        let e = punch(&mut r, &GapOptions { outputs: 0.1, inputs: 0.0, burst: 0 }, 1).unwrap_err();
        assert!(e.to_string().contains("--missing-burst"), "{e}");
    }
}
