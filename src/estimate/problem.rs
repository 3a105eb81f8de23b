//! One estimation problem (a record and a model structure) and the result of minimising a
//! criterion on it.

use super::huber::Loss;
use super::layout::Layout;
use super::options::Termination;
use crate::oe::{self, Orders, Structure};

/// One estimation problem: data and model structure, with m >= 1 inputs.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    /// The inputs, input after input: `u[i N .. (i+1) N]` is input i (one input: all of it).
    pub u: &'a [f64],
    pub y: &'a [f64],
    /// Every input's orders; theta is `[b_1, f_1, ..., b_m, f_m]` (+ c).
    pub structure: Structure,
    /// Estimate a constant output offset c jointly with B and F (METHOD.md 9.1): theta is
    /// `[b, f, c]` and `yhat = q^-d B/F u + c`.
    pub offset: bool,
    /// Where the experiments after the first begin when the record is several experiments
    /// one after the other ([`crate::data::Record::seams`]; empty: one experiment). The
    /// criterion sums over all samples; the simulation and the Jacobian signals restart from
    /// zero at every seam and no lag reaches across one (METHOD.md 16).
    pub seams: &'a [usize],
    /// The samples whose output is missing ([`crate::data::Record::missing`]; `y` is NaN
    /// there): simulated through, their residuals left out of the criterion, the normal
    /// equations and every count N (METHOD.md 21). Empty: a complete record.
    pub missing: &'a [usize],
}

impl<'a> Problem<'a> {
    /// Number of parameters: sum_i (nB_i + nF_i) (+ 1 with an offset).
    pub fn dim(&self) -> usize {
        self.structure.dim() + usize::from(self.offset)
    }

    /// Number of inputs m.
    pub fn m(&self) -> usize {
        self.structure.m()
    }

    /// Input i's samples.
    pub fn input(&self, i: usize) -> &'a [f64] {
        let n = self.n();
        &self.u[i * n..(i + 1) * n]
    }

    /// The orders of a single-input problem (code that is not yet written for several
    /// inputs: the callers' boundary keeps several inputs away from it).
    pub fn one(&self) -> Orders {
        self.structure.one()
    }

    /// Input i's (b_i, f_i) in `theta`.
    pub fn input_parts<'t>(&self, theta: &'t [f64], i: usize) -> (&'t [f64], &'t [f64]) {
        (&theta[self.structure.b_range(i)], &theta[self.structure.f_range(i)])
    }

    /// The offset c in `theta` (0 without one).
    pub fn offset_of(&self, theta: &[f64]) -> f64 {
        if self.offset { theta[self.structure.dim()] } else { 0.0 }
    }

    /// `theta` of a single-input problem as (b, f, c); c = 0 without an offset.
    pub fn split<'t>(&self, theta: &'t [f64]) -> (&'t [f64], &'t [f64], f64) {
        let (b, f) = self.input_parts(theta, 0);
        debug_assert_eq!(self.m(), 1, "split of a several-input theta");
        (b, f, self.offset_of(theta))
    }

    /// Makes every F_i stable by reflecting its unstable roots; true when one was.
    pub fn reflect_unstable(&self, theta: &mut [f64]) -> bool {
        let mut any = false;
        for i in 0..self.m() {
            any |= oe::reflect_unstable(&mut theta[self.structure.f_range(i)]);
        }
        any
    }

    /// True when every F_i is stable.
    pub fn is_stable(&self, theta: &[f64]) -> bool {
        (0..self.m()).all(|i| oe::is_stable(&theta[self.structure.f_range(i)]))
    }

    /// The largest pole radius over the inputs' F_i.
    pub fn max_pole_radius(&self, theta: &[f64]) -> f64 {
        (0..self.m()).map(|i| oe::max_pole_radius(&theta[self.structure.f_range(i)])).fold(0.0, f64::max)
    }

    /// [`Self::simulate`] into a new vector.
    pub fn simulate_vec(&self, theta: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n()];
        self.simulate(theta, &mut y);
        y
    }

    /// The model's output at `theta` from zero initial conditions (in every experiment),
    /// offset included. Several inputs need one record-length scratch vector (allocated here:
    /// no iteration loop calls this).
    pub fn simulate(&self, theta: &[f64], yhat: &mut [f64]) {
        let mut part = Vec::new();
        for i in 0..self.m() {
            let (b, f) = self.input_parts(theta, i);
            let d = self.structure.inputs()[i].delay;
            let u = self.input(i);
            let out: &mut [f64] = if i == 0 {
                &mut *yhat
            } else {
                part.resize(yhat.len(), 0.0);
                &mut part
            };
            for e in self.experiments() {
                oe::simulate(b, f, d, &u[e.clone()], &mut out[e]);
            }
            if i > 0 {
                yhat.iter_mut().zip(&part).for_each(|(a, p)| *a += p);
            }
        }
        add_offset(yhat, self.offset_of(theta));
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
        let n = self.n();
        (0..=self.seams.len()).map(move |i| {
            let start = if i == 0 { 0 } else { self.seams[i - 1] };
            let end = self.seams.get(i).copied().unwrap_or(n);
            start..end
        })
    }

    /// The simulation and the Jacobian signals at `theta` (no offset added), restarted at
    /// every seam: per input `xu_i = (1/F_i) u_i` and `xy_i = (1/F_i) yhat_i` (input after
    /// input in `xu` and `xy`, m x N each), `yhat = sum_i yhat_i`. One input is one fused
    /// pass ([`oe::simulate_filtered`]); with several, input i's contribution passes through
    /// its `xy_i` slot before `1/F_i` filters it in place, so no further buffer is needed.
    pub fn simulate_filtered(&self, theta: &[f64], xu: &mut [f64], yhat: &mut [f64], xy: &mut [f64]) {
        let n = self.n();
        if self.m() == 1 {
            let (b, f) = self.input_parts(theta, 0);
            let d = self.structure.inputs()[0].delay;
            for e in self.experiments() {
                let u = &self.u[e.clone()];
                oe::simulate_filtered(b, f, d, u, &mut xu[e.clone()], &mut yhat[e.clone()], &mut xy[e]);
            }
            return;
        }
        yhat[..n].fill(0.0);
        for i in 0..self.m() {
            let (b, f) = self.input_parts(theta, i);
            let d = self.structure.inputs()[i].delay;
            let (xu, xy) = (&mut xu[i * n..(i + 1) * n], &mut xy[i * n..(i + 1) * n]);
            xu.copy_from_slice(self.input(i));
            for e in self.experiments() {
                oe::inv_f_in_place(f, &mut xu[e.clone()]);
                oe::delayed_fir(b, d, &xu[e.clone()], &mut xy[e.clone()]);
            }
            yhat[..n].iter_mut().zip(&xy[..]).for_each(|(a, p)| *a += p);
            for e in self.experiments() {
                oe::inv_f_in_place(f, &mut xy[e]);
            }
        }
    }

    /// `xu_i <- (1/F_i) u_i` for every input (m x N), restarted at every seam.
    pub fn filtered_inputs(&self, theta: &[f64], xu: &mut [f64]) {
        let n = self.n();
        for i in 0..self.m() {
            let f = self.input_parts(theta, i).1;
            let x = &mut xu[i * n..(i + 1) * n];
            x.copy_from_slice(self.input(i));
            for e in self.experiments() {
                oe::inv_f_in_place(f, &mut x[e]);
            }
        }
    }

    /// `x <- (1/F) x`, restarted at every seam.
    pub fn inv_f(&self, f: &[f64], x: &mut [f64]) {
        for e in self.experiments() {
            oe::inv_f_in_place(f, &mut x[e]);
        }
    }

    /// `out <- sum_i q^-d_i B_i xu_i` over the filtered inputs `xu` (m x N) with the b's of
    /// `b_all` (`[b_1, ..., b_m]`, the B parts of theta one after the other), restarted at
    /// every seam.
    pub fn delayed_fir(&self, b_all: &[f64], xu: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) {
        let n = self.n();
        let mut at = 0;
        for (i, o) in self.structure.inputs().iter().enumerate() {
            let b = &b_all[at..at + o.nb];
            at += o.nb;
            let x = &xu[i * n..(i + 1) * n];
            let dst: &mut [f64] = if i == 0 {
                &mut *out
            } else {
                scratch.resize(n, 0.0);
                &mut scratch[..]
            };
            for e in self.experiments() {
                oe::delayed_fir(b, o.delay, &x[e.clone()], &mut dst[e]);
            }
            if i > 0 {
                out.iter_mut().zip(&scratch[..]).for_each(|(a, p)| *a += p);
            }
        }
    }

    /// The problem restricted to the samples `..rows` (the seams and missing outputs before it
    /// kept).
    pub fn head(&self, rows: usize) -> Problem<'a> {
        let seams = &self.seams[..self.seams.partition_point(|&s| s < rows)];
        let n = self.n();
        let u = if self.m() == 1 {
            &self.u[..rows]
        } else {
            // Inputs are not contiguous in a head: only one input's problem is cut this way.
            assert!(rows == n, "the head of a several-input problem");
            self.u
        };
        let missing = &self.missing[..self.missing.partition_point(|&t| t < rows)];
        Problem { u, y: &self.y[..rows], seams, missing, ..*self }
    }
    /// Number of observed outputs: N less the missing ones (METHOD.md 21.2). Every mean over
    /// residuals (W, L1C, sigma, fit %, the criteria's N) divides by this.
    pub fn n_obs(&self) -> usize {
        self.n() - self.missing.len()
    }

    /// The runs of consecutive observed outputs (the complement of `missing`; seams do not
    /// cut them: the criterion is a plain sum over samples).
    pub fn observed(&self) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        observed_runs(self.n(), self.missing)
    }

    /// The criterion `loss` at the simulated output `yhat`: the mean of rho over the observed
    /// residuals ([`Loss::criterion`] of a complete record).
    pub fn criterion(&self, loss: Loss, yhat: &[f64]) -> f64 {
        if self.missing.is_empty() {
            return loss.criterion(self.y, yhat);
        }
        let total: f64 = self.observed().map(|r| loss.total(&self.y[r.clone()], &yhat[r])).sum();
        total / self.n_obs() as f64
    }

    /// The mean square of the observed outputs.
    pub fn mean_square_output(&self) -> f64 {
        let total: f64 = self.observed().map(|r| self.y[r].iter().map(|v| v * v).sum::<f64>()).sum();
        total / self.n_obs().max(1) as f64
    }

    pub fn layout(&self) -> Layout {
        Layout::new(self.structure)
    }
    pub fn n(&self) -> usize {
        self.y.len()
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

/// The runs of `0..n` between the sorted indices `missing`, empty runs left out.
pub fn observed_runs(n: usize, missing: &[usize]) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
    let ends = missing.iter().copied().chain(std::iter::once(n));
    let starts = std::iter::once(0).chain(missing.iter().map(|t| t + 1));
    starts.zip(ends).filter(|(a, b)| a < b).map(|(a, b)| a..b)
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
///
/// One input only: with several, the F_i columns need each input's own contribution, which
/// only [`Problem::simulate_filtered`] has.
pub(super) fn output_filtered(prob: &Problem, theta: &[f64], yhat: &[f64], xy: &mut [f64]) {
    let (_, f, c) = prob.split(theta);
    for (x, &v) in xy.iter_mut().zip(yhat) {
        *x = v - c;
    }
    prob.inv_f(f, xy);
}

/// The flat B and F coefficients of `theta` (`[b_1.., b_m..]`, `[f_1.., f_m..]`: every input's
/// one after the other; one input: its b and f) and the offset.
pub fn flat_parts(s: &Structure, theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let b = (0..s.m()).flat_map(|i| theta[s.b_range(i)].iter().copied()).collect();
    let f = (0..s.m()).flat_map(|i| theta[s.f_range(i)].iter().copied()).collect();
    (b, f)
}

/// The solver's theta from flat B and F coefficients ([`flat_parts`]) and the offset.
pub fn theta_in(s: &Structure, b: &[f64], f: &[f64], offset: Option<f64>) -> Vec<f64> {
    let (mut ib, mut jf) = (0, 0);
    let mut out = Vec::with_capacity(b.len() + f.len() + 1);
    for o in s.inputs() {
        out.extend_from_slice(&b[ib..ib + o.nb]);
        out.extend_from_slice(&f[jf..jf + o.nf]);
        ib += o.nb;
        jf += o.nf;
    }
    out.extend(offset);
    out
}
