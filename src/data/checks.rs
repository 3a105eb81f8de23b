//! What a record must be to identify a model, checked once where the records are read (a job's,
//! `oesweep fit`'s, the Python package's arrays): long enough for the largest model, no
//! constant input or output, and, with several inputs, inputs the model can tell apart (no two
//! perfectly collinear once their means are out). Each problem is one [`Error::Data`] naming
//! the file and the column.

use super::{Record, input_error};
use crate::error::Result;
use crate::oe::Structure;

/// Smallest record length accepted for OE(nb, nf) with delay `delay`:
/// `max(20, delay + max(nb, nf) + 4 (nb + nf))`.
///
/// The first `delay + max(nb, nf)` samples are dominated by the zero initial conditions (the
/// ARX initialisation cannot even form its regressors there); after them we ask for at least
/// four samples per parameter so that the least-squares problems of the initialisation and the
/// L2 phase are clearly overdetermined. This is a floor against nonsense, not a guarantee of a
/// good fit: the paper uses N = 5000 for 24 parameters.
pub fn min_samples(nb: usize, nf: usize, delay: usize) -> usize {
    min_samples_of(&Structure::siso(nb, nf, delay))
}

/// [`min_samples`] of a structure of any number of inputs: the longest start-up over the
/// inputs, `max_i(d_i + max(nB_i, nF_i))`, plus four samples per parameter of every input.
pub fn min_samples_of(s: &Structure) -> usize {
    // Saturating: a job may ask for any delay up to usize::MAX, and a wrapped sum would
    // let it through.
    let start = s.inputs().iter().map(|o| o.delay.saturating_add(o.nb.max(o.nf))).max().unwrap_or(0);
    let params = s.inputs().iter().fold(0usize, |a, o| a.saturating_add(o.nb.saturating_add(o.nf)));
    start.saturating_add(4usize.saturating_mul(params)).max(20)
}

/// Checks that `rec` can identify OE(nb, nf) with delay `delay` ([`check_for_structure`] of
/// one input).
pub fn check_for_model(rec: &Record, nb: usize, nf: usize, delay: usize) -> Result<()> {
    check_for_structure(rec, &Structure::siso(nb, nf, delay))
}

/// Checks that `rec` can identify the model `s` (its largest of a grid): at least
/// [`min_samples_of`] samples, no input and not the output constant (a constant input does not
/// excite the system; a constant output leaves nothing to fit), and no two inputs perfectly
/// collinear ([`check_inputs_distinct`]).
pub fn check_for_structure(rec: &Record, s: &Structure) -> Result<()> {
    debug_assert_eq!(rec.u.len(), rec.inputs() * rec.len());
    // Only the observed outputs identify anything (METHOD.md 21.1).
    let n = rec.len() - rec.missing.len();
    let need = min_samples_of(s);
    if n < need {
        let model = match s.single() {
            Some(o) => format!("OE(nb={}, nf={}) with delay {}", o.nb, o.nf, o.delay),
            None => s.label(),
        };
        let what = match rec.missing.len() {
            0 => format!("{n} samples"),
            k => format!("{n} observed outputs ({k} of {} missing)", rec.len()),
        };
        return Err(input_error(&rec.path, format!("{what} are too few for {model}: need at least {need}")));
    }
    for (i, name) in rec.u_names.iter().enumerate() {
        if let Some(v) = constant_value(rec.input(i)) {
            return Err(input_error(
                &rec.path,
                format!("input column '{name}' is constant (value {v}): it does not excite the system"),
            ));
        }
    }
    let observed: Vec<f64> = rec.y.iter().copied().filter(|v| !v.is_nan()).collect();
    if let Some(v) = constant_value(&observed) {
        return Err(input_error(
            &rec.path,
            format!("output column '{}' is constant (value {v}): there is nothing to fit", rec.y_name),
        ));
    }
    check_inputs_distinct(rec)
}

/// `Some(mean)` when the spread of `x` is negligible relative to its level
/// (max - min <= 1e-12 max(1, |mean|)): such a column carries no information, only round-off.
fn constant_value(x: &[f64]) -> Option<f64> {
    if x.is_empty() {
        return None;
    }
    let (mut lo, mut hi, mut sum) = (f64::INFINITY, f64::NEG_INFINITY, 0.0);
    for &v in x {
        lo = lo.min(v);
        hi = hi.max(v);
        sum += v;
    }
    let mean = sum / x.len() as f64;
    (hi - lo <= 1e-12 * mean.abs().max(1.0)).then_some(mean)
}

/// Below this, a centred input's share that the inputs before it do not explain (the pivot of
/// the Cholesky factor of their correlation matrix, 1 for an input uncorrelated with them) is
/// round-off: the input is a combination of those before it.
const COLLINEAR: f64 = 1e-12;

/// No two inputs perfectly collinear after their means are taken out, nor one a combination of
/// the others: the model could not tell their contributions apart. The rank of the centred
/// inputs' Gram matrix, tested relative to each input's own spread: the Cholesky factor of
/// their correlation matrix, in the inputs' order, whose pivot `1 - R^2` (R^2 of the input on
/// those before it) falls to round-off. Names both columns of a pair (|correlation| above
/// `1 - 1e-12`), else the input and the ones it is a combination of. Constant inputs are
/// refused before ([`check_for_structure`]).
pub fn check_inputs_distinct(rec: &Record) -> Result<()> {
    let m = rec.inputs();
    if m < 2 {
        return Ok(());
    }
    let n = rec.len() as f64;
    let centred: Vec<Vec<f64>> = (0..m)
        .map(|i| {
            let x = rec.input(i);
            let mean = x.iter().sum::<f64>() / n;
            x.iter().map(|v| v - mean).collect()
        })
        .collect();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let norms: Vec<f64> = centred.iter().map(|c| dot(c, c).sqrt()).collect();
    let mut corr = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..=i {
            let r = if i == j { 1.0 } else { dot(&centred[i], &centred[j]) / (norms[i] * norms[j]) };
            corr[i * m + j] = r;
            corr[j * m + i] = r;
        }
    }
    let name = |i: usize| format!("'{}'", rec.u_names[i]);
    for i in 0..m {
        for j in 0..i {
            let r = corr[i * m + j];
            if r.abs() > 1.0 - COLLINEAR {
                return Err(input_error(
                    &rec.path,
                    format!(
                        "input columns {} and {} are perfectly collinear (correlation {r:.12} after their \
                         means are taken out): the model cannot tell them apart",
                        name(j),
                        name(i)
                    ),
                ));
            }
        }
    }
    // Cholesky of the correlation matrix in the inputs' order (lower factor, row by row).
    let mut l = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..=i {
            let s = corr[i * m + j] - (0..j).map(|k| l[i * m + k] * l[j * m + k]).sum::<f64>();
            if i == j {
                if s <= COLLINEAR {
                    let before: Vec<String> = (0..i).map(name).collect();
                    return Err(input_error(
                        &rec.path,
                        format!(
                            "input column {} is a combination of the input columns {} after the means are taken \
                             out (unexplained share {s:.3e}): the model cannot tell their contributions apart",
                            name(i),
                            before.join(", ")
                        ),
                    ));
                }
                l[i * m + i] = s.sqrt();
            } else {
                l[i * m + j] = s / l[j * m + j];
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rec(inputs: &[Vec<f64>]) -> Record {
        let n = inputs[0].len();
        Record {
            path: "r.csv".into(),
            u: inputs.concat(),
            y: (0..n).map(|t| (t as f64 * 0.37).sin()).collect(),
            u_names: (0..inputs.len()).map(|i| format!("u{}", i + 1)).collect(),
            y_name: "y".into(),
            seams: Vec::new(),
            missing: Vec::new(),
        }
    }

    fn wave(n: usize, f: f64) -> Vec<f64> {
        (0..n).map(|t| (t as f64 * f).sin() + 0.3 * (t as f64 * 2.1 * f).cos()).collect()
    }

    #[test]
    fn min_samples_rule() {
        assert_eq!(min_samples(1, 1, 1), 20);
        assert_eq!(min_samples(12, 12, 1), 1 + 12 + 96);
        assert_eq!(min_samples(9, 12, 2), 2 + 12 + 84);
        let o = |nb, nf, delay| crate::oe::Orders { nb, nf, delay };
        let two = Structure::new(&[o(2, 2, 5), o(9, 3, 0)]).unwrap();
        assert_eq!(min_samples_of(&two), 9 + 4 * 16);
    }

    #[test]
    fn constant_detection_is_relative() {
        assert_eq!(constant_value(&[3.0, 3.0, 3.0]), Some(3.0));
        assert!(constant_value(&[1e6, 1e6 + 1e-7]).is_some());
        assert!(constant_value(&[0.0, 1e-9]).is_none());
        assert!(constant_value(&[1e6, 1e6 + 1e-3]).is_none());
    }

    #[test]
    fn collinear_inputs_are_named_and_independent_ones_pass() {
        let (a, b, c) = (wave(200, 0.1), wave(200, 0.23), wave(200, 0.71));
        check_inputs_distinct(&rec(&[a.clone(), b.clone(), c.clone()])).unwrap();
        // A scaled copy with an offset: collinear once the means are out.
        let copy: Vec<f64> = a.iter().map(|v| 5.0 - 2.0 * v).collect();
        let m = check_inputs_distinct(&rec(&[a.clone(), b.clone(), copy])).unwrap_err().to_string();
        assert!(m.contains("input columns 'u1' and 'u3' are perfectly collinear"), "{m}");
        // A combination of two others: no pair is collinear, the three are.
        let sum: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + 0.5 * y + 1.0).collect();
        let m = check_inputs_distinct(&rec(&[a.clone(), b.clone(), sum])).unwrap_err().to_string();
        assert!(m.contains("input column 'u3' is a combination of the input columns 'u1', 'u2'"), "{m}");
        // Strongly but not perfectly correlated inputs are the fit's business, not an error.
        let near: Vec<f64> = a.iter().zip(&c).map(|(x, y)| x + 1e-3 * y).collect();
        check_inputs_distinct(&rec(&[a, near])).unwrap();
    }
}
