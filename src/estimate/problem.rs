//! One estimation problem (a record and a model structure) and the result of minimising a
//! criterion on it.

use super::normal::Layout;
use super::options::Termination;
use crate::oe;

/// One SISO estimation problem: data and model structure.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    pub u: &'a [f64],
    pub y: &'a [f64],
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    /// Estimate a constant output offset c jointly with B and F (METHOD.md 9.1): theta is
    /// `[b, f, c]` and `yhat = q^-d B/F u + c`.
    pub offset: bool,
    /// Where the experiments after the first begin when the record is several experiments
    /// one after the other ([`crate::data::Record::seams`]; empty: one experiment). The
    /// criterion sums over all samples; the simulation and the Jacobian signals restart from
    /// zero at every seam and no lag reaches across one (METHOD.md 16).
    pub seams: &'a [usize],
}

impl<'a> Problem<'a> {
    /// Number of parameters: nB + nF (+ 1 with an offset).
    pub fn dim(&self) -> usize {
        self.nb + self.nf + usize::from(self.offset)
    }

    /// `theta` as (b, f, c); c = 0 without an offset.
    pub fn split<'t>(&self, theta: &'t [f64]) -> (&'t [f64], &'t [f64], f64) {
        let (b, rest) = theta.split_at(self.nb);
        let (f, c) = rest.split_at(self.nf);
        (b, f, c.first().copied().unwrap_or(0.0))
    }

    /// The F part of `theta`, mutable (for pole reflection).
    pub fn f_mut<'t>(&self, theta: &'t mut [f64]) -> &'t mut [f64] {
        &mut theta[self.nb..self.nb + self.nf]
    }

    /// [`Self::simulate`] into a new vector.
    pub fn simulate_vec(&self, theta: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.u.len()];
        self.simulate(theta, &mut y);
        y
    }

    /// The model's output at `theta` from zero initial conditions (in every experiment),
    /// offset included.
    pub fn simulate(&self, theta: &[f64], yhat: &mut [f64]) {
        let (b, f, c) = self.split(theta);
        if self.seams.is_empty() {
            oe::simulate(b, f, self.delay, self.u, yhat);
        } else {
            for e in self.experiments() {
                oe::simulate(b, f, self.delay, &self.u[e.clone()], &mut yhat[e]);
            }
        }
        add_offset(yhat, c);
    }

    /// The first sample of the experiment sample `t` belongs to (0 for one experiment).
    #[inline]
    pub fn experiment_start(&self, t: usize) -> usize {
        match self.seams.partition_point(|&s| s <= t) {
            0 => 0,
            k => self.seams[k - 1],
        }
    }

    /// The sample ranges of the experiments (`0..n` for one), without allocating.
    pub fn experiments(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let n = self.u.len();
        (0..=self.seams.len()).map(move |i| {
            let start = if i == 0 { 0 } else { self.seams[i - 1] };
            let end = self.seams.get(i).copied().unwrap_or(n);
            start..end
        })
    }

    /// [`oe::simulate_filtered`] of the problem's input, restarted at every seam.
    pub fn simulate_filtered(&self, b: &[f64], f: &[f64], xu: &mut [f64], yhat: &mut [f64], xy: &mut [f64]) {
        if self.seams.is_empty() {
            oe::simulate_filtered(b, f, self.delay, self.u, xu, yhat, xy);
        } else {
            for e in self.experiments() {
                let u = &self.u[e.clone()];
                oe::simulate_filtered(b, f, self.delay, u, &mut xu[e.clone()], &mut yhat[e.clone()], &mut xy[e]);
            }
        }
    }

    /// `x <- (1/F) x`, restarted at every seam.
    pub fn inv_f(&self, f: &[f64], x: &mut [f64]) {
        if self.seams.is_empty() {
            oe::inv_f_in_place(f, x);
        } else {
            for e in self.experiments() {
                oe::inv_f_in_place(f, &mut x[e]);
            }
        }
    }

    /// `out <- q^-d B x`, restarted at every seam.
    pub fn delayed_fir(&self, b: &[f64], x: &[f64], out: &mut [f64]) {
        if self.seams.is_empty() {
            oe::delayed_fir(b, self.delay, x, out);
        } else {
            for e in self.experiments() {
                oe::delayed_fir(b, self.delay, &x[e.clone()], &mut out[e]);
            }
        }
    }

    /// The problem restricted to the samples `..rows` (the seams before it kept).
    pub fn head(&self, rows: usize) -> Problem<'a> {
        let seams = &self.seams[..self.seams.partition_point(|&s| s < rows)];
        Problem { u: &self.u[..rows], y: &self.y[..rows], seams, ..*self }
    }
    pub fn layout(&self) -> Layout {
        Layout { nb: self.nb, nf: self.nf, delay: self.delay }
    }
    pub fn n(&self) -> usize {
        self.u.len()
    }
}

/// Result of one minimisation.
#[derive(Clone, Debug)]
pub struct Solution {
    pub theta: Vec<f64>,
    pub criterion: f64,
    /// Outer iterations (each builds the normal equations once).
    pub iterations: usize,
    pub termination: Termination,
    /// Accepted steps that needed a pole reflection.
    pub reflections: usize,
    /// Damping at the end.
    pub lambda: f64,
}

impl Solution {
    /// See [`Termination::usable`].
    pub fn usable(&self) -> bool {
        self.termination.usable(self.criterion)
    }
}

/// `yhat += c`: the offset sits outside the dynamics, so the Jacobian signals `xu` and
/// `xy = (1/F) (yhat - c)` of [`oe::simulate_filtered`] stay as they are.
pub(super) fn add_offset(yhat: &mut [f64], c: f64) {
    if c != 0.0 {
        yhat.iter_mut().for_each(|v| *v += c);
    }
}

/// `xy = (1/F) (yhat - c)`: the F columns' signal of the Jacobian from a given output (a
/// separable evaluation's, or a re-simulated one), when no fused pass computed it.
pub(super) fn output_filtered(prob: &Problem, theta: &[f64], yhat: &[f64], xy: &mut [f64]) {
    let (_, f, c) = prob.split(theta);
    for (x, &v) in xy.iter_mut().zip(yhat) {
        *x = v - c;
    }
    prob.inv_f(f, xy);
}
