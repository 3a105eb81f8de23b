//! Which sequence, sign and lag each column of the OE Jacobian is (METHOD.md 2): the map the
//! normal equations ([`super::normal`]) and the covariance's QR are built from.

use crate::oe::Structure;

/// Which sequence a Jacobian column is a shift of.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub(super) enum Seq {
    U,
    Y,
}

/// Columns `col .. col + len` of the Jacobian: `sign * s[t - lag - j]` for column `col + j`,
/// with `s` input `input`'s `xu` or `xy` ([`Layout::runs`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Run {
    pub input: usize,
    pub seq: Seq,
    pub sign: f64,
    pub col: usize,
    pub lag: usize,
    pub len: usize,
}

impl Default for Run {
    fn default() -> Self {
        Run { input: 0, seq: Seq::U, sign: 1.0, col: 0, lag: 0, len: 0 }
    }
}

/// Column structure of the OE Jacobian for given orders: per input i, its b_i columns
/// (`xu_i`, +1, d_i + j) and then its f_i columns (`xy_i`, -1, j), inputs one after the other
/// (theta's order). The sequences `xu` and `xy` hold every input's signal, input after input
/// (m x N); one input is today's two sequences.
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    pub structure: Structure,
    /// Input 0's orders: the lagged-correlation path of one input reads them directly.
    pub(super) nb: usize,
    pub(super) nf: usize,
    pub(super) delay: usize,
}

impl Layout {
    pub fn new(structure: Structure) -> Self {
        let o = structure.inputs()[0];
        Layout { structure, nb: o.nb, nf: o.nf, delay: o.delay }
    }

    /// One input's layout: OE(nB, nF) with delay d.
    pub fn siso(nb: usize, nf: usize, delay: usize) -> Self {
        Self::new(Structure::siso(nb, nf, delay))
    }

    pub fn dim(&self) -> usize {
        self.structure.dim()
    }

    /// The lag of column `c` (`d_i + j` for b_i,j, `j` for f_i,j).
    pub fn lag(&self, c: usize) -> usize {
        self.col_of(c).3
    }

    #[inline(always)]
    pub(super) fn col(&self, c: usize) -> (Seq, f64, usize) {
        if c < self.nb { (Seq::U, 1.0, self.delay + c) } else { (Seq::Y, -1.0, c - self.nb + 1) }
    }

    /// The columns as runs of one sequence at consecutive lags, in column order: per input,
    /// its b_i run (`xu_i`, +1, lags `d_i ..`) and then its f_i run (`xy_i`, -1, lags `1 ..`);
    /// empty runs (nB_i or nF_i = 0) are left out. Returns how many of `out` it filled
    /// (at most 2 [`crate::structure::MAX_INPUTS`]).
    pub(super) fn runs(&self, out: &mut [Run; 2 * crate::structure::MAX_INPUTS]) -> usize {
        let (mut k, mut col) = (0, 0);
        for (i, o) in self.structure.inputs().iter().enumerate() {
            for (seq, sign, lag, len) in [(Seq::U, 1.0, o.delay, o.nb), (Seq::Y, -1.0, 1, o.nf)] {
                if len > 0 {
                    out[k] = Run { input: i, seq, sign, col, lag, len };
                    k += 1;
                }
                col += len;
            }
        }
        k
    }

    /// Column `c` of any layout: (input, sequence, sign, lag).
    fn col_of(&self, c: usize) -> (usize, Seq, f64, usize) {
        let mut at = c;
        for (i, o) in self.structure.inputs().iter().enumerate() {
            if at < o.nb {
                return (i, Seq::U, 1.0, o.delay + at);
            }
            at -= o.nb;
            if at < o.nf {
                return (i, Seq::Y, -1.0, at + 1);
            }
            at -= o.nf;
        }
        panic!("column {c} of a layout with {} columns", self.dim())
    }

    /// Write column `c` of the Jacobian (c < [`Layout::dim`]) at times `start..start + out.len()`,
    /// times `factor`, into `out`.
    pub fn column_into(&self, xu: &[f64], xy: &[f64], c: usize, start: usize, factor: f64, out: &mut [f64]) {
        let (i, seq, sign, lag) = self.col_of(c);
        let n = xu.len() / self.structure.m();
        let x = if seq == Seq::U { &xu[i * n..(i + 1) * n] } else { &xy[i * n..(i + 1) * n] };
        let f = sign * factor;
        // Times before `lag` are zero; the rest is one contiguous, scaled run of x (a branch
        // per entry kept this loop from vectorising: 5 % of the paper grid's run).
        let zeros = lag.saturating_sub(start).min(out.len());
        let (head, rest) = out.split_at_mut(zeros);
        head.fill(0.0);
        if !rest.is_empty() {
            let from = start + zeros - lag;
            let len = rest.len();
            for (o, &v) in rest.iter_mut().zip(&x[from..from + len]) {
                *o = f * v;
            }
        }
    }

    /// Write `psi_t` (the Jacobian row of the predictor at time t) into `row`.
    #[inline(always)]
    pub fn row(&self, xu: &[f64], xy: &[f64], t: usize, row: &mut [f64]) {
        if self.structure.m() > 1 {
            return self.row_from(xu, xy, t, 0, row);
        }
        for (i, r) in row[..self.nb].iter_mut().enumerate() {
            let lag = self.delay + i;
            *r = if t >= lag { xu[t - lag] } else { 0.0 };
        }
        for (j, r) in row[self.nb..self.nb + self.nf].iter_mut().enumerate() {
            let lag = j + 1;
            *r = if t >= lag { -xy[t - lag] } else { 0.0 };
        }
    }

    /// `psi_t` of any layout in an experiment that starts at `t0` (no lag reaches before it).
    pub(super) fn row_from(&self, xu: &[f64], xy: &[f64], t: usize, t0: usize, row: &mut [f64]) {
        let n = xu.len() / self.structure.m();
        let mut c = 0;
        for (i, o) in self.structure.inputs().iter().enumerate() {
            let (u, y) = (&xu[i * n..(i + 1) * n], &xy[i * n..(i + 1) * n]);
            for j in 0..o.nb {
                let lag = o.delay + j;
                row[c] = if t >= t0 + lag { u[t - lag] } else { 0.0 };
                c += 1;
            }
            for j in 0..o.nf {
                let lag = j + 1;
                row[c] = if t >= t0 + lag { -y[t - lag] } else { 0.0 };
                c += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::structure::{Orders, Structure};

    /// Every column of one and of two inputs, from starts before, at and after its lag, over
    /// runs that end before the lag too, is the row-by-row definition times the factor.
    #[test]
    fn a_column_is_the_rows_entries() {
        let n = 40;
        for structure in [
            Structure::siso(3, 2, 1),
            Structure::siso(4, 5, 6),
            Structure::new(&[Orders { nb: 2, nf: 3, delay: 0 }, Orders { nb: 3, nf: 1, delay: 7 }])
                .expect("two inputs"),
        ] {
            let lay = Layout::new(structure);
            let m = lay.structure.m();
            let xu: Vec<f64> = (0..m * n).map(|t| (t as f64 * 0.37).sin() + 1.5).collect();
            let xy: Vec<f64> = (0..m * n).map(|t| (t as f64 * 0.11).cos() - 0.5).collect();
            let mut row = vec![0.0; lay.dim()];
            for c in 0..lay.dim() {
                for start in [0, 1, 3, 6, 9, 25] {
                    for len in [0, 1, 2, 5, n - start] {
                        let mut out = vec![f64::NAN; len];
                        lay.column_into(&xu, &xy, c, start, 0.5, &mut out);
                        for (k, &o) in out.iter().enumerate() {
                            lay.row(&xu, &xy, start + k, &mut row);
                            assert_eq!(o, 0.5 * row[c], "column {c}, start {start}, entry {k}");
                        }
                    }
                }
            }
        }
    }
}
