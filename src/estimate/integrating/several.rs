//! The integrating-plant test of each input of several (METHOD.md 7.3 "Several inputs", 19):
//! Young's refined IV of a model with a denominator per input, by backfitting, with the other
//! inputs' paths as columns of each input's regression.
//!
//! Input i's one-input test model `A_i y_i = B_i u_i + c + v` is fitted to `y_i = y - sum_{j
//! != i} x_j`, the output less the other inputs' noise-free outputs `x_j = (B_j/A_j) u_j` of
//! their latest fits (A_j stabilised), input after input, [`ROUNDS`] rounds; each input is
//! tested on its last fit as one input is. Another input's integrator must come out of the
//! output first: in `y` itself it is a drift that input i's low-order fit puts a pole at 1 for.
//!
//! Subtracted alone, `x_j` carries the error of j's fit into input i's equation as `A_i (x_j -
//! x̂_j)`, and beside an integrating input that error (a gain or pole error times the
//! integrated input) is a drift over the record, which input i's fit follows with a pole near
//! 1 (its test then fires on a quarter of the records). So the error is estimated instead: to
//! first order in j's parameters `x_j - x̂_j = (dB_j q^-d_j u_j - dA_j x̂_j) / Â_j`, and `A_i`
//! times it lies in the span of the signals `u_j / Â_j` at lags `d_j .. d_j + nb_j + n_i - 1`
//! and `x̂_j / Â_j` at lags `1 ..= nf_j + n_i` ([`Others`]), which are further columns of input
//! i's regression with free coefficients. They are noise-free (functions of u_j and j's fit),
//! so each is its own instrument, and input i's instruments, functions of u_i, stay
//! uncorrelated with the equation error; the sandwich standard error of A_i(1) then counts the
//! estimation of their coefficients, and what remains of j's error is of second order.

use super::{IvFit, MAX_ROWS, PoleTest, Stretches, fitted, head_seams, pole_test, test_poles};
use crate::estimate::problem::Problem;
use crate::oe::Structure;

/// Rounds of backfitting: each input's fit to the output less the other inputs' outputs,
/// input after input.
const ROUNDS: usize = 3;

/// The integrating-plant test of each input of a record of `m` inputs (`u` input after input,
/// N samples each; `delays` one per input): one entry per input, None where its regressions
/// are degenerate. One input is [`pole_test`]; several are fitted by backfitting with the
/// other inputs' paths as columns (the module's doc), and an input whose path integrates
/// leaves A_i(1) = 0 however the others behave.
pub fn pole_tests(u: &[f64], m: usize, y: &[f64], seams: &[usize], delays: &[usize]) -> Vec<Option<PoleTest>> {
    assert_eq!((u.len(), delays.len()), (m * y.len(), m), "the inputs' columns and delays");
    if m == 1 {
        return vec![pole_test(u, y, seams, delays[0])];
    }
    let n = y.len();
    let head = n.min(MAX_ROWS);
    let seams = head_seams(seams, head);
    let input = |i: usize| &u[i * n..i * n + head];
    let y = &y[..head];
    // Each input's fit on the stretches of observed outputs; the other inputs' outputs x_j
    // simulated over the whole head (the inputs are complete), then taken to the stretches.
    let stretches = Stretches::of(y, &seams);
    let at: Vec<usize> = stretches.ranges.iter().flat_map(|r| r.clone()).collect();
    let inputs: Vec<Vec<f64>> = (0..m).map(|i| stretches.take(input(i))).collect();
    // Each input's noise-free output x_i over the head, and its latest fit.
    let mut parts = vec![vec![0.0; head]; m];
    let mut fits: Vec<Option<(Structure, IvFit)>> = (0..m).map(|_| None).collect();
    let mut tests = vec![None; m];
    for round in 0..ROUNDS {
        for i in 0..m {
            let seen: Vec<f64> =
                (0..head).map(|t| y[t] - (0..m).filter(|&j| j != i).map(|j| parts[j][t]).sum::<f64>()).collect();
            let taken = stretches.take(&seen);
            let paths = (0..m).filter(|&j| j != i).filter_map(|j| {
                let (structure, fit) = fits[j].as_ref()?;
                let whole =
                    Problem { u: input(j), y, structure: *structure, offset: false, seams: &seams, missing: &[] };
                Some((whole, &fit.model[..], &parts[j][..]))
            });
            let others = Others::of(paths, &at, &seams);
            fits[i] = fitted(&inputs[i], &taken, &stretches.seams, delays[i], &others).map(|(prob, fit)| {
                if round + 1 == ROUNDS {
                    tests[i] = test_poles(&prob, &fit, &others);
                }
                let whole = Problem { u: input(i), y, offset: false, seams: &seams, ..prob };
                whole.simulate(&fit.model, &mut parts[i]);
                (prob.structure, fit)
            });
            if fits[i].is_none() {
                parts[i].iter_mut().for_each(|v| *v = 0.0);
            }
        }
    }
    tests
}

/// The other inputs' paths as further columns of one input's regression (the module's doc):
/// for each other input j, `u_j / Â_j` at lags `d_j .. d_j + nb_j + n - 1` and `x̂_j / Â_j`
/// at lags `1 ..= nf_j + n`, n the order of the regression. None for one input.
pub(super) struct Others {
    signals: Vec<Signal>,
    /// The head sample of each row of the regression's record (the stretches of observed
    /// outputs one after the other).
    at: Vec<usize>,
    /// Where the head's experiments 2.. begin: no lag reaches across one (the signals start
    /// from rest in each experiment, as the fits' simulations do).
    seams: Vec<usize>,
}

/// A signal over the head and its lags `first .. first + lags + n`.
struct Signal {
    samples: Vec<f64>,
    first: usize,
    lags: usize,
}

impl Others {
    pub(super) fn none() -> Others {
        Others { signals: Vec::new(), at: Vec::new(), seams: Vec::new() }
    }

    /// The columns of `paths`, each another input's record over the head (its structure, the
    /// problem's seams), its fit's `[b, a]` (A stable) and its noise-free output `x̂_j`.
    fn of<'a>(
        paths: impl Iterator<Item = (Problem<'a>, &'a [f64], &'a [f64])>,
        at: &[usize],
        seams: &[usize],
    ) -> Others {
        let mut signals = Vec::new();
        for (prob, model, x) in paths {
            let o = prob.one();
            let a = &model[o.nb..];
            let mut u = prob.u.to_vec();
            prob.inv_f(a, &mut u);
            signals.push(Signal { samples: u, first: o.delay, lags: o.nb });
            let mut x = x.to_vec();
            prob.inv_f(a, &mut x);
            signals.push(Signal { samples: x, first: 1, lags: o.nf });
        }
        Others { signals, at: at.to_vec(), seams: seams.to_vec() }
    }

    /// The number of columns of a regression of order n.
    pub(super) fn len(&self, n: usize) -> usize {
        self.signals.iter().map(|s| s.lags + n).sum()
    }

    /// (signal, lag) of each column of a regression of order n.
    pub(super) fn columns(&self, n: usize) -> Vec<(usize, usize)> {
        let lags = |(k, s): (usize, &Signal)| (s.first..s.first + s.lags + n).map(move |l| (k, l));
        self.signals.iter().enumerate().flat_map(lags).collect()
    }

    /// Column `(signal, lag)` at row t of the regression's record: 0 where the lag reaches
    /// before the start of the experiment.
    pub(super) fn value(&self, (k, lag): (usize, usize), t: usize) -> f64 {
        let h = self.at[t];
        let start = match self.seams.partition_point(|&s| s <= h) {
            0 => 0,
            e => self.seams[e - 1],
        };
        if h >= start + lag { self.signals[k].samples[h - lag] } else { 0.0 }
    }
}
