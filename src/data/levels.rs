//! Signal levels: how a record's constant offsets are handled (METHOD.md 9.1).
//!
//! Every real sensor has an offset, and the OE model `y = q^-d B/F u` has none: fitted as it
//! is, a record whose output sits at 97 C gives fits far below zero. The job's `offset`:
//!
//! | mode | input | output |
//! |---|---|---|
//! | `estimate` (default) | less the estimation record's mean `u0` (one per input) | a constant `c` estimated jointly with B and F (inside the Huber criterion, so robust) |
//! | `mean` / `median` | less `u0` (mean / median of each estimation input) | less `y0` (mean / median of the estimation output) |
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
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Levels {
    pub mode: Offset,
    /// Subtracted from each input of both records: one level per input (empty for `none`:
    /// nothing is taken out; [`Levels::u0`] reads it as zeros).
    #[serde(serialize_with = "one_or_list")]
    pub u0: Vec<f64>,
    /// Subtracted from the output of both records.
    pub y0: f64,
}

impl Levels {
    /// The levels `mode` takes from the estimation record.
    pub fn of(mode: Offset, est: &Record) -> Levels {
        let inputs = (0..est.inputs()).map(|i| est.input(i));
        let (u0, y0) = match mode {
            Offset::None => (Vec::new(), 0.0),
            Offset::Estimate => (inputs.map(mean).collect(), 0.0),
            Offset::Mean => (inputs.map(mean).collect(), mean(&observed(est))),
            Offset::Median => (inputs.map(median).collect(), median(&observed(est))),
        };
        Levels { mode, u0, y0 }
    }

    /// No levels: the paper's model.
    pub fn none() -> Levels {
        Levels { mode: Offset::None, u0: Vec::new(), y0: 0.0 }
    }

    /// Input i's level (0 where none was taken out).
    pub fn u0(&self, i: usize) -> f64 {
        self.u0.get(i).copied().unwrap_or(0.0)
    }

    /// `rec` with the levels taken out.
    pub fn apply(&self, rec: &mut Record) {
        let n = rec.len();
        for (i, &u0) in self.u0.iter().enumerate() {
            if u0 != 0.0 {
                rec.u[i * n..(i + 1) * n].iter_mut().for_each(|v| *v -= u0);
            }
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
    let y = observed(est);
    let m = mean(&y);
    let sd = (y.iter().map(|v| (v - m).powi(2)).sum::<f64>() / y.len() as f64).sqrt();
    (m.abs() > OFFSET_WARNING_RATIO * sd).then(|| {
        format!(
            "offset \"none\": the output's mean {m:.6} is {:.1} times its standard deviation {sd:.6}; \
             the model has no offset and will spend its dynamics on this level (offset \"estimate\", the \
             default, estimates it)",
            m.abs() / sd.max(f64::MIN_POSITIVE)
        )
    })
}

/// One input's level as a number (as before several inputs), several as a list.
pub(crate) fn one_or_list<S: serde::Serializer>(u0: &[f64], s: S) -> Result<S::Ok, S::Error> {
    match u0 {
        [] => s.serialize_f64(0.0),
        [one] => s.serialize_f64(*one),
        all => all.serialize(s),
    }
}

/// Mean / standard deviation above which `none` gets a warning.
const OFFSET_WARNING_RATIO: f64 = 1.0;

/// The record's observed outputs (a missing one is NaN, METHOD.md 21.1): the output levels
/// are theirs.
fn observed(rec: &Record) -> Vec<f64> {
    rec.y.iter().copied().filter(|v| !v.is_nan()).collect()
}

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
        Record {
            path: "r".into(),
            u,
            y,
            u_names: vec!["u".into()],
            y_name: "y".into(),
            seams: Vec::new(),
            missing: Vec::new(),
        }
    }

    #[test]
    fn levels_of_each_mode() {
        let r = rec(vec![1.0, 2.0, 6.0], vec![10.0, 11.0, 15.0]);
        assert_eq!(Levels::of(Offset::None, &r), Levels::none());
        assert_eq!(Levels::none().u0(0), 0.0);
        let e = Levels::of(Offset::Estimate, &r);
        assert_eq!((e.u0(0), e.y0), (3.0, 0.0));
        assert_eq!(e.offset(Some(1.5)), Some(1.5));
        let m = Levels::of(Offset::Median, &r);
        assert_eq!((m.u0.clone(), m.y0), (vec![2.0], 11.0));
        assert_eq!(m.offset(None), Some(11.0));
        let mut v = r.clone();
        Levels::of(Offset::Mean, &r).apply(&mut v);
        assert_eq!(v.u, vec![-2.0, -1.0, 3.0]);
        assert_eq!(v.y, vec![-2.0, -1.0, 3.0]);
        assert!(offset_warning(Offset::None, &r).is_some());
        assert!(offset_warning(Offset::Estimate, &r).is_none());
        assert!(offset_warning(Offset::None, &rec(vec![1.0, 2.0], vec![-1.0, 1.2])).is_none());
    }

    #[test]
    fn one_level_per_input() {
        let mut r = rec(vec![1.0, 2.0, 6.0, 10.0, 20.0, 30.0], vec![10.0, 11.0, 15.0]);
        r.u_names = vec!["a".into(), "b".into()];
        let e = Levels::of(Offset::Mean, &r);
        assert_eq!(e.u0, vec![3.0, 20.0]);
        assert_eq!(Levels::of(Offset::Median, &r).u0, vec![2.0, 20.0]);
        e.apply(&mut r);
        assert_eq!(r.u, vec![-2.0, -1.0, 3.0, -10.0, 0.0, 10.0]);
        assert_eq!(serde_json::to_value(&e).unwrap()["u0"], serde_json::json!([3.0, 20.0]));
        let one = Levels::of(Offset::Mean, &rec(vec![1.0, 3.0], vec![0.0, 1.0]));
        assert_eq!(serde_json::to_value(&one).unwrap()["u0"], serde_json::json!(2.0));
    }
}
