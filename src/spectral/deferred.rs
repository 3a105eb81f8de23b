//! The spectral estimate a run's band fits compare with (`fit_band`, METHOD.md 11), checked
//! before the run and computed during it.
//!
//! Which bins of the estimate are usable depends on the inputs alone (a bin is usable where
//! every input has power, [`super::welch_within`], [`super::welch_inputs`]); the output only
//! enters `G_spec`'s values. So a job's `band_hz` is checked against the bins of the plain
//! Welch estimate of the record as measured (FFTs: milliseconds), and the robust estimate,
//! whose cleaning of the output's spikes is the cost ([`super::clean`]: 0.14 s of the paper
//! grid's 1.04 s on 16 workers, where it was a serial part), runs once, on first use: the
//! sweep makes it a task of its graph that the judging tasks come after, so it runs beside the
//! pairs' own least-squares minima instead of before them.
//!
//! The robust estimate uses the same segments as the plain one (its cleaned output is finite
//! wherever the measured one is), so it has the same bins and fails where that one fails. Were
//! it to fail anyway (a prediction of the cleaning not finite), the plain Welch estimate of the
//! record as measured is the estimate, as it is for a record too short to clean.

use super::{SpectralEstimate, SpectrumMethod, WelchOptions, estimate_inputs, welch_inputs};
use crate::data::Record;
use crate::error::Result;
use std::sync::OnceLock;

/// A record's spectral estimate by `method` and the bins of a band, the estimate computed on
/// first use ([`Deferred::estimate`]).
#[derive(Debug)]
pub struct Deferred {
    /// The usable bins in the band, ascending ([`SpectralEstimate::band`]; not empty).
    pub bins: Vec<usize>,
    method: SpectrumMethod,
    ts: f64,
    /// The plain Welch estimate of the record as measured, one per input (the estimate itself
    /// for [`SpectrumMethod::Welch`]).
    welch: Vec<SpectralEstimate>,
    robust: OnceLock<Vec<SpectralEstimate>>,
}

impl Deferred {
    /// The bins of `[lo_hz, hi_hz]` in the estimate of `rec` (sampling period `ts`), and the
    /// estimate to come. Errors: those of the spectral estimate (too short a record, a
    /// non-finite sample); `Ok(None)`: the band holds no usable bin.
    pub fn new(rec: &Record, ts: f64, method: SpectrumMethod, lo_hz: f64, hi_hz: f64) -> Result<Option<Deferred>> {
        let welch = welch_inputs(&rec.u, rec.inputs(), &rec.y, &rec.seams, &rec.missing, ts, &WelchOptions::default())?;
        let bins = welch[0].band(lo_hz, hi_hz);
        if bins.is_empty() {
            return Ok(None);
        }
        Ok(Some(Deferred { bins, method, ts, welch, robust: OnceLock::new() }))
    }

    /// The estimate of `rec` (the record [`Deferred::new`] was given), one per input: computed
    /// by the first caller, which the others wait for.
    pub fn estimate(&self, rec: &Record) -> &[SpectralEstimate] {
        if self.method == SpectrumMethod::Welch {
            return &self.welch;
        }
        self.robust.get_or_init(|| {
            estimate_inputs(&rec.u, rec.inputs(), &rec.y, &rec.seams, &rec.missing, self.ts, self.method)
                .unwrap_or_else(|_| self.welch.clone())
        })
    }

    /// True once [`Deferred::estimate`] has nothing left to compute.
    pub fn is_ready(&self) -> bool {
        self.method == SpectrumMethod::Welch || self.robust.get().is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A record of `n` samples through a second-order system, with 5 % spikes on the output
    /// (the robust estimate then differs from the plain one) and `inputs` input columns.
    fn record(n: usize, inputs: usize, seams: Vec<usize>, missing: Vec<usize>) -> Record {
        let mut s = 11u64;
        let mut rand = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let u: Vec<f64> = (0..n * inputs).map(|_| rand()).collect();
        let mut y = vec![0.0; n];
        for t in 2..n {
            let drive: f64 = (0..inputs).map(|i| u[i * n + t - 1] * (1.0 + i as f64)).sum();
            y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + drive;
        }
        for v in y.iter_mut() {
            if rand() > 0.45 {
                *v += 40.0 * rand().signum();
            }
        }
        for &t in &missing {
            y[t] = f64::NAN;
        }
        Record {
            path: "test.csv".into(),
            u,
            y,
            u_names: (0..inputs).map(|i| format!("u{i}")).collect(),
            y_name: "y".into(),
            seams,
            missing,
        }
    }

    /// The robust estimate has the bins the check found in the plain one, on one input and
    /// two, with seams and missing outputs, and differs from it in its values; the Welch
    /// method's estimate is the plain one.
    #[test]
    fn the_checked_bins_are_the_robust_estimates() {
        let missing: Vec<usize> = (900..960).collect();
        for (inputs, seams, missing) in
            [(1, vec![], vec![]), (2, vec![], vec![]), (1, vec![2500], missing.clone()), (2, vec![3000], missing)]
        {
            let rec = record(6000, inputs, seams, missing);
            let ts = 1e-3;
            let d = Deferred::new(&rec, ts, SpectrumMethod::Robust, 0.0, 200.0).unwrap().expect("bins in the band");
            assert!(!d.is_ready());
            let robust = d.estimate(&rec).to_vec();
            assert!(d.is_ready());
            assert_eq!(robust.len(), inputs);
            assert_eq!(robust[0].band(0.0, 200.0), d.bins);
            let direct =
                estimate_inputs(&rec.u, inputs, &rec.y, &rec.seams, &rec.missing, ts, SpectrumMethod::Robust).unwrap();
            assert_eq!(format!("{robust:?}"), format!("{direct:?}"), "the estimate is estimate_inputs'");
            assert!(robust[0].replaced > 0 && robust[0].re != d.welch[0].re);
            let w = Deferred::new(&rec, ts, SpectrumMethod::Welch, 0.0, 200.0).unwrap().unwrap();
            assert!(w.is_ready());
            assert_eq!(w.bins, d.bins);
            assert_eq!(format!("{:?}", w.estimate(&rec)), format!("{:?}", d.welch));
        }
        // A band above the Nyquist frequency holds no bin.
        let rec = record(6000, 1, vec![], vec![]);
        assert!(Deferred::new(&rec, 1e-3, SpectrumMethod::Robust, 600.0, 700.0).unwrap().is_none());
    }
}
