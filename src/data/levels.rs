//! Signal levels: how a record's constant offsets are handled (METHOD.md 9.1).
//!
//! Every real sensor has an offset, and the OE model `y = q^-d B/F u` has none: fitted as it
//! is, a record whose output sits at 97 C gives fits far below zero. The job's `offset`:
//!
//! | mode | input | output |
//! |---|---|---|
//! | `estimate` (default) | less the estimation record's mean `u0` | a constant `c` estimated jointly with B and F (inside the Huber criterion, so robust) |
//! | `mean` / `median` | less `u0` (mean / median of the estimation input) | less `y0` (mean / median of the estimation output) |
//! | `none` | as it is | as it is (the paper's model) |
//!
//! The validation record is shifted by the same `u0` and `y0`, so the model is
//! `y = q^-d B/F (u - u0) + offset` in the data's own units, with `offset = y0` for `mean` and
//! `median`, `c` for `estimate` (there `y0 = 0`), none for `none`.

use serde::Serialize;

use super::Record;

/// The job's `offset` setting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Offset {
    #[default]
    Estimate,
    Mean,
    Median,
    None,
}

crate::names::names!(Offset { Estimate = "estimate", Mean = "mean", Median = "median", None = "none" });

impl Offset {
    /// True when the fits estimate the output offset c.
    pub fn estimated(self) -> bool {
        self == Offset::Estimate
    }
}

/// The levels taken out of the records (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Levels {
    pub mode: Offset,
    /// Subtracted from the input of both records.
    pub u0: f64,
    /// Subtracted from the output of both records.
    pub y0: f64,
}

impl Levels {
    /// The levels `mode` takes from the estimation record.
    pub fn of(mode: Offset, est: &Record) -> Levels {
        let (u0, y0) = match mode {
            Offset::None => (0.0, 0.0),
            Offset::Estimate => (mean(&est.u), 0.0),
            Offset::Mean => (mean(&est.u), mean(&est.y)),
            Offset::Median => (median(&est.u), median(&est.y)),
        };
        Levels { mode, u0, y0 }
    }

    /// No levels: the paper's model.
    pub fn none() -> Levels {
        Levels { mode: Offset::None, u0: 0.0, y0: 0.0 }
    }

    /// `rec` with the levels taken out.
    pub fn apply(&self, rec: &mut Record) {
        if self.u0 != 0.0 {
            rec.u.iter_mut().for_each(|v| *v -= self.u0);
        }
        if self.y0 != 0.0 {
            rec.y.iter_mut().for_each(|v| *v -= self.y0);
        }
    }

    /// The model's output offset in the data's units (the table's `offset` column) from the
    /// fit's estimated c: c, y0, or none.
    pub fn offset(&self, c: Option<f64>) -> Option<f64> {
        match self.mode {
            Offset::None => None,
            Offset::Estimate => c,
            Offset::Mean | Offset::Median => Some(self.y0),
        }
    }

    /// The estimated c back from a table's `offset` (what a resumed fit restarts from).
    pub fn estimated_c(&self, offset: Option<f64>) -> Option<f64> {
        if self.mode.estimated() { Some(offset.unwrap_or(0.0)) } else { None }
    }
}

/// A warning for `none` when the output's mean is large against its spread (a sensor offset
/// that the paper's model would fit with its dynamics): None when there is nothing to say.
pub fn offset_warning(mode: Offset, est: &Record) -> Option<String> {
    if mode != Offset::None {
        return None;
    }
    let m = mean(&est.y);
    let sd = (est.y.iter().map(|v| (v - m).powi(2)).sum::<f64>() / est.y.len() as f64).sqrt();
    (m.abs() > OFFSET_WARNING_RATIO * sd).then(|| {
        format!(
            "offset \"none\": the output's mean {m:.6} is {:.1} times its standard deviation {sd:.6}; \
             the model has no offset and will spend its dynamics on this level (offset \"estimate\", the \
             default, estimates it)",
            m.abs() / sd.max(f64::MIN_POSITIVE)
        )
    })
}

/// Mean / standard deviation above which `none` gets a warning.
const OFFSET_WARNING_RATIO: f64 = 1.0;

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

fn median(x: &[f64]) -> f64 {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(u: Vec<f64>, y: Vec<f64>) -> Record {
        Record { path: "r".into(), u, y, u_names: vec!["u".into()], y_name: "y".into(), seams: Vec::new() }
    }

    #[test]
    fn levels_of_each_mode() {
        let r = rec(vec![1.0, 2.0, 6.0], vec![10.0, 11.0, 15.0]);
        assert_eq!(Levels::of(Offset::None, &r), Levels::none());
        let e = Levels::of(Offset::Estimate, &r);
        assert_eq!((e.u0, e.y0), (3.0, 0.0));
        assert_eq!(e.offset(Some(1.5)), Some(1.5));
        let m = Levels::of(Offset::Median, &r);
        assert_eq!((m.u0, m.y0), (2.0, 11.0));
        assert_eq!(m.offset(None), Some(11.0));
        let mut v = r.clone();
        Levels::of(Offset::Mean, &r).apply(&mut v);
        assert_eq!(v.u, vec![-2.0, -1.0, 3.0]);
        assert_eq!(v.y, vec![-2.0, -1.0, 3.0]);
        assert!(offset_warning(Offset::None, &r).is_some());
        assert!(offset_warning(Offset::Estimate, &r).is_none());
        assert!(offset_warning(Offset::None, &rec(vec![1.0, 2.0], vec![-1.0, 1.2])).is_none());
    }
}
