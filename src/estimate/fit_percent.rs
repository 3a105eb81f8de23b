//! The fit percentage of a model's output against a record's (METHOD.md 6), and the record's
//! side of it kept across the fits of one record.

/// Fit percentage `100 (1 - ||y - yhat|| / ||y - mean(y)||)` over the observed outputs: a
/// missing one (NaN in `y`, [`crate::data::Record::missing`]) is left out of both norms and the
/// mean (METHOD.md 21.2).
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> f64 {
    let seen = || y.iter().zip(yhat).filter(|(a, _)| !a.is_nan());
    let count = seen().count();
    let mean = seen().map(|(a, _)| a).sum::<f64>() / count as f64;
    let num: f64 = seen().map(|(a, b)| (a - b) * (a - b)).sum();
    let den: f64 = seen().map(|(a, _)| (a - mean) * (a - mean)).sum();
    100.0 * (1.0 - (num / den).sqrt())
}

/// The record's side of [`fit_percent`], the same for every model of a record and so kept
/// across fits (one per record a worker judges on, in its [`super::Workspace`]): the output it was
/// computed from, its observed count, mean and `sum (y - mean)^2`. A fit then sums only its
/// own errors; every sum is [`fit_percent`]'s, in its order, so the bits are its bits (the
/// judging of the paper grid summed each record's output three times per fit).
#[derive(Default, Debug)]
pub(crate) struct OutputSpread {
    y: Vec<f64>,
    count: usize,
    mean: f64,
    den: f64,
}

impl OutputSpread {
    /// [`fit_percent`]`(y, yhat)`, the output's sums computed again only when `y` is not the
    /// output they were computed from (compared by bits: the buffer of a record that is gone
    /// may hold another).
    pub(crate) fn fit_percent(&mut self, y: &[f64], yhat: &[f64]) -> f64 {
        let same = self.y.len() == y.len() && self.y.iter().zip(y).all(|(a, b)| a.to_bits() == b.to_bits());
        if !same {
            let observed = || y.iter().filter(|a| !a.is_nan());
            self.count = observed().count();
            self.mean = observed().sum::<f64>() / self.count as f64;
            let mean = self.mean;
            self.den = observed().map(|a| (a - mean) * (a - mean)).sum();
            self.y.clear();
            self.y.extend_from_slice(y);
        }
        let num: f64 = y.iter().zip(yhat).filter(|(a, _)| !a.is_nan()).map(|(a, b)| (a - b) * (a - b)).sum();
        100.0 * (1.0 - (num / self.den).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit % with a record's sums kept is `fit_percent`'s to the bit, whichever record
    /// comes next: the same one, another of the same length, a shorter one, one with missing
    /// outputs (NaN), and the first again.
    #[test]
    fn kept_output_sums_give_fit_percents_bits() {
        let wave = |n: usize, f: f64, phase: f64| -> Vec<f64> {
            (0..n).map(|t| (f * t as f64 + phase).sin() * 3.0 + 0.7).collect()
        };
        let est = wave(5000, 0.013, 0.0);
        let other = wave(5000, 0.021, 0.4);
        let short = wave(1200, 0.05, 1.0);
        let mut missing = wave(3000, 0.017, 0.2);
        for t in (0..3000).step_by(37) {
            missing[t] = f64::NAN;
        }
        let mut spread = OutputSpread::default();
        for (i, y) in [&est, &est, &other, &short, &missing, &missing, &est].into_iter().enumerate() {
            let yhat: Vec<f64> = y.iter().enumerate().map(|(t, v)| v * 0.97 + 0.01 * ((t + i) as f64).cos()).collect();
            let kept = spread.fit_percent(y, &yhat);
            assert_eq!(kept.to_bits(), fit_percent(y, &yhat).to_bits(), "record {i}");
            assert!(kept.is_finite() && kept < 100.0);
        }
    }
}
