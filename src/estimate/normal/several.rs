//! The normal equations of several inputs (METHOD.md 19), in two forms that give the same sums.
//!
//! **Correlations** (the one input's form of the parent module, over 2m sequences). The
//! Jacobian's columns are runs of consecutive shifts of one of `xu_1, xy_1, .., xu_m, xy_m`
//! ([`Layout::runs`]), so the Gram block of two runs p, q is made of lagged dot products
//! `R_pq(L) = sum_s p[s] q[s+L]` of their sequences at the lag differences between them, less
//! the end terms whose shift runs past the record; `g` is the lagged products of each sequence
//! with `r`, and the offset's column the sums of each sequence less its last terms. Per
//! experiment (the signals restart at a seam) that is O(N_k (lags of every pair of runs)),
//! O(N m d) in all for d = sum(nB_i + nF_i): linear in the orders where the rows' product is
//! quadratic. Weights other than 1 enter as a correction over the reweighted rows (with the
//! offset's 1 in them), or, when most rows are reweighted, the rows with a weight are summed
//! directly, exactly as for one input.
//!
//! **Rows**: every row with a weight packed, 512 at a time, into one register-tiled product,
//! O(N d^2). Kept for the measurement that chose between the two (`benches/kernels.rs`,
//! `normal_equations_several`; docs/PERFORMANCE.md).

use super::super::layout::{Run, Seq};
use super::{Layout, NormalEquations, PACK_BLOCK, PACK_MIN_ROWS, compact_rows, sum};
use crate::kernels::{lagged_dots, rank1_upper, syrk_upper};
use crate::structure::MAX_INPUTS;

/// How [`NormalEquations::build_several`] forms `J^T W J` for several inputs.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum SeveralForm {
    /// Lagged correlations of the 2m sequences, end corrections, reweighted rows: O(N m d).
    Correlations,
    /// Packed Jacobian rows, one matrix product per block: O(N d^2).
    Rows,
}

/// The slice of experiment `e` of input i's run sequence within the m x N buffers.
fn seq<'a>(run: &Run, xu: &'a [f64], xy: &'a [f64], n: usize, e: &std::ops::Range<usize>) -> &'a [f64] {
    let x = if run.seq == Seq::U { xu } else { xy };
    &x[run.input * n + e.start..run.input * n + e.end]
}

/// `out[j] = sum_s a[s] b[s + lo + j]` over the common length (zeros where the lag reaches
/// past the record).
fn lagged_from(a: &[f64], b: &[f64], lo: usize, out: &mut [f64]) {
    if lo < b.len() {
        lagged_dots(a, &b[lo..], out);
    } else {
        out.fill(0.0);
    }
}

impl NormalEquations {
    /// The normal equations of several inputs (offset and seams included) in the given form:
    /// `h = (1/N) J^T W J` (d x d, full), `g = (1/N) J^T r`, as [`NormalEquations::build_all`].
    #[allow(clippy::too_many_arguments)]
    pub fn build_several(
        &mut self,
        form: SeveralForm,
        lay: &Layout,
        offset: bool,
        seams: &[usize],
        xu: &[f64],
        xy: &[f64],
        w: Option<&[f64]>,
        r: &[f64],
        h: &mut [f64],
        g: &mut [f64],
    ) {
        let n = r.len();
        let m = lay.structure.m();
        let d = lay.dim() + usize::from(offset);
        assert!(xu.len() == m * n && xy.len() == m * n && h.len() >= d * d && g.len() >= d);
        assert!(w.is_none_or(|w| w.len() == n));
        match form {
            SeveralForm::Correlations => self.build_correlations(lay, offset, seams, xu, xy, w, r, h, g),
            SeveralForm::Rows => self.build_rows(lay, offset, seams, xu, xy, w, r, h, g),
        }
        let inv_n = 1.0 / n as f64;
        for gc in &mut g[..d] {
            *gc *= inv_n;
        }
        for i in 0..d {
            for j in i..d {
                let v = h[i * d + j] * inv_n;
                h[i * d + j] = v;
                h[j * d + i] = v;
            }
        }
    }

    /// Unscaled upper triangle of `J^T W J` and `J^T r` from lagged correlations (module doc).
    #[allow(clippy::too_many_arguments)]
    fn build_correlations(
        &mut self,
        lay: &Layout,
        offset: bool,
        seams: &[usize],
        xu: &[f64],
        xy: &[f64],
        w: Option<&[f64]>,
        r: &[f64],
        h: &mut [f64],
        g: &mut [f64],
    ) {
        let n = r.len();
        let d0 = lay.dim();
        let d = d0 + usize::from(offset);
        h[..d * d].fill(0.0);
        g[..d].fill(0.0);
        let mut all = [Run::default(); 2 * MAX_INPUTS];
        let count = lay.runs(&mut all);
        let runs = &all[..count];

        // Rows whose weight differs from 1; when they are most rows, the rows with a weight
        // are summed directly and the Gram matrix is not needed.
        self.m = match w {
            Some(w) => compact_rows(&mut self.rows, None, w, 1.0),
            None => 0,
        };
        let direct = w.is_some() && 2 * self.m > n;
        self.direct = direct;

        let longest = runs.iter().map(|p| p.lag + p.len).max().unwrap_or(0);
        if self.lagged.len() < 2 * longest {
            self.lagged.resize(2 * longest, 0.0);
        }
        for k in 0..=seams.len() {
            let start = if k == 0 { 0 } else { seams[k - 1] };
            let e = start..seams.get(k).copied().unwrap_or(n);
            let nk = e.len();
            let rk = &r[e.clone()];
            // g_c = sign_c R_{s_c, r}(lag_c).
            for p in runs {
                let out = &mut self.lagged[..p.len];
                lagged_from(seq(p, xu, xy, n, &e), rk, p.lag, out);
                for (gc, v) in g[p.col..p.col + p.len].iter_mut().zip(out.iter()) {
                    *gc += p.sign * v;
                }
            }
            if offset {
                g[d0] += sum(rk);
            }
            if direct {
                continue;
            }
            for (i, p) in runs.iter().enumerate() {
                for q in &runs[i..] {
                    self.gram_block(p, q, seq(p, xu, xy, n, &e), seq(q, xu, xy, n, &e), h, d);
                }
                if offset {
                    // h[c, c_off] = sign_c sum_{s < nk - lag_c} s_c[s], lag after lag.
                    let a = seq(p, xu, xy, n, &e);
                    let mut total = if p.lag < nk { sum(&a[..nk - p.lag]) } else { 0.0 };
                    for j in 0..p.len {
                        let lag = p.lag + j;
                        if lag >= nk {
                            break;
                        }
                        if j > 0 {
                            total -= a[nk - lag];
                        }
                        h[(p.col + j) * d + d0] += p.sign * total;
                    }
                }
            }
            if offset {
                h[d0 * d + d0] += nk as f64;
            }
        }
        if let Some(w) = w {
            if direct {
                self.m = compact_rows(&mut self.rows, Some(&mut self.alpha), w, 0.0);
            } else {
                self.alpha.clear();
                self.alpha.extend(self.rows[..self.m].iter().map(|&t| w[t as usize] - 1.0));
            }
            self.add_rows_of(lay, offset, seams, xu, xy, h);
        }
    }

    /// `h[c, e] += sum_t psi_tc psi_te` for c in run p, e in run q (p no later than q; c <= e
    /// when they are one run), over one experiment whose sequences are `a` (p's) and `b` (q's).
    ///
    /// With `la >= lb` the lags of c and e, the sum is `R_ab(la - lb)` less its terms with
    /// `s >= nk - la` (their row `s + la` lies past the record); otherwise `R_ba(lb - la)` less
    /// the terms with `s >= nk - lb`.
    fn gram_block(&mut self, p: &Run, q: &Run, a: &[f64], b: &[f64], h: &mut [f64], d: usize) {
        let nk = a.len();
        let same = p.col == q.col;
        let (p_last, q_last) = (p.lag + p.len - 1, q.lag + q.len - 1);
        // R_ab at L = la - lb in [ab_lo, ab_lo + ab.len()), and R_ba at L = lb - la >= 1.
        let ab_lo = p.lag.saturating_sub(q_last);
        let ab_len = (p_last + 1).saturating_sub(q.lag + ab_lo);
        let ba_lo = q.lag.saturating_sub(p_last).max(1);
        let ba_len = if same { 0 } else { (q_last + 1).saturating_sub(p.lag + ba_lo) };
        let (ab, rest) = self.lagged.split_at_mut(ab_len);
        let ba = &mut rest[..ba_len];
        lagged_from(a, b, ab_lo, ab);
        lagged_from(b, a, ba_lo, ba);
        let sign = p.sign * q.sign;
        for i in 0..p.len {
            let (c, la) = (p.col + i, p.lag + i);
            for j in if same { i } else { 0 }..q.len {
                let (e, lb) = (q.col + j, q.lag + j);
                let (full, x, y, last, lag) = if same {
                    (ab[j - i], a, a, lb, j - i)
                } else if la >= lb {
                    (ab[la - lb - ab_lo], a, b, la, la - lb)
                } else {
                    (ba[lb - la - ba_lo], b, a, lb, lb - la)
                };
                if last >= nk {
                    // One of the columns lies entirely past this experiment.
                    continue;
                }
                let mut tail = 0.0;
                for s in nk - last..nk - lag {
                    tail += x[s] * y[s + lag];
                }
                h[c * d + e] += sign * (full - tail);
            }
        }
    }

    /// `h += sum_k alpha_k psi_k psi_k^T` (upper triangle, the offset's 1 in each row when
    /// `offset`) over the rows `rows[..m]`, each restarted at its experiment's start; the same
    /// packing and products as one input's `add_rows`.
    fn add_rows_of(&mut self, lay: &Layout, offset: bool, seams: &[usize], xu: &[f64], xy: &[f64], h: &mut [f64]) {
        let d0 = lay.dim();
        let d = d0 + usize::from(offset);
        let dp = d.div_ceil(4) * 4;
        let m = self.m;
        if m == 0 {
            return;
        }
        let (rows, alpha) = (&self.rows[..m], &self.alpha[..m]);
        let mut seam = 0;
        let mut t0 = 0;
        let mut start_of = |t: usize| {
            while seam < seams.len() && seams[seam] <= t {
                t0 = seams[seam];
                seam += 1;
            }
            t0
        };
        if m < PACK_MIN_ROWS {
            self.psi.resize(dp, 0.0);
            for (&t, &a) in rows.iter().zip(alpha) {
                let t = t as usize;
                lay.row_from(xu, xy, t, start_of(t), &mut self.psi[..d0]);
                if offset {
                    self.psi[d0] = 1.0;
                }
                rank1_upper(h, d, &self.psi[..d], a);
            }
            return;
        }
        let uniform = alpha.iter().all(|&a| a == alpha[0]);
        let scale = if uniform { alpha[0] } else { 1.0 };
        self.packed.resize(PACK_BLOCK.min(m) * dp, 0.0);
        if !uniform {
            self.scaled.resize(PACK_BLOCK.min(m) * dp, 0.0);
        }
        for (rows, alpha) in rows.chunks(PACK_BLOCK).zip(alpha.chunks(PACK_BLOCK)) {
            let mb = rows.len();
            for (row, &t) in self.packed.chunks_exact_mut(dp).zip(rows) {
                let t = t as usize;
                lay.row_from(xu, xy, t, start_of(t), &mut row[..d0]);
                if offset {
                    row[d0] = 1.0;
                }
                row[d..].fill(0.0);
            }
            if !uniform {
                for ((dst, src), &a) in self.scaled.chunks_exact_mut(dp).zip(self.packed.chunks_exact(dp)).zip(alpha) {
                    for (q, &p) in dst.iter_mut().zip(src) {
                        *q = a * p;
                    }
                }
            }
            let q = if uniform { &self.packed[..mb * dp] } else { &self.scaled[..mb * dp] };
            syrk_upper(h, d, &self.packed[..mb * dp], q, dp, mb, scale);
        }
    }

    /// Unscaled upper triangle of `J^T W J` and `J^T r` from the Jacobian's rows: `g` over
    /// every row, `h` over the rows with a weight, packed in blocks for one matrix product
    /// each. O(N d^2).
    #[allow(clippy::too_many_arguments)]
    fn build_rows(
        &mut self,
        lay: &Layout,
        offset: bool,
        seams: &[usize],
        xu: &[f64],
        xy: &[f64],
        w: Option<&[f64]>,
        r: &[f64],
        h: &mut [f64],
        g: &mut [f64],
    ) {
        let n = r.len();
        let d0 = lay.dim();
        let d = d0 + usize::from(offset);
        let dp = d.div_ceil(4) * 4;
        h[..d * d].fill(0.0);
        g[..d].fill(0.0);
        self.packed.resize(PACK_BLOCK * dp, 0.0);
        self.scaled.resize(PACK_BLOCK * dp, 0.0);
        let mut mb = 0;
        let mut seam = 0;
        let mut t0 = 0;
        for t in 0..n {
            while seam < seams.len() && seams[seam] <= t {
                t0 = seams[seam];
                seam += 1;
            }
            let row = &mut self.packed[mb * dp..(mb + 1) * dp];
            lay.row_from(xu, xy, t, t0, &mut row[..d0]);
            if offset {
                row[d0] = 1.0;
            }
            row[d..].fill(0.0);
            for (gc, &p) in g[..d].iter_mut().zip(&row[..d]) {
                *gc += p * r[t];
            }
            let a = w.map_or(1.0, |w| w[t]);
            if a == 0.0 {
                continue;
            }
            for (q, &p) in self.scaled[mb * dp..(mb + 1) * dp].iter_mut().zip(&self.packed[mb * dp..(mb + 1) * dp]) {
                *q = a * p;
            }
            mb += 1;
            if mb == PACK_BLOCK || t + 1 == n {
                syrk_upper(h, d, &self.packed[..mb * dp], &self.scaled[..mb * dp], dp, mb, 1.0);
                mb = 0;
            }
        }
        if mb > 0 {
            syrk_upper(h, d, &self.packed[..mb * dp], &self.scaled[..mb * dp], dp, mb, 1.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::structure::{Orders, Structure};

    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        }
    }

    /// `(1/N) J^T W J` and `(1/N) J^T r` from the explicit Jacobian, rows restarted at seams.
    fn explicit(
        lay: &Layout,
        offset: bool,
        seams: &[usize],
        xu: &[f64],
        xy: &[f64],
        w: &[f64],
        r: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let n = r.len();
        let d0 = lay.dim();
        let d = d0 + usize::from(offset);
        let (mut h, mut g, mut row) = (vec![0.0; d * d], vec![0.0; d], vec![0.0; d]);
        for t in 0..n {
            let t0 = seams.iter().copied().filter(|&s| s <= t).max().unwrap_or(0);
            lay.row_from(xu, xy, t, t0, &mut row[..d0]);
            if offset {
                row[d0] = 1.0;
            }
            for i in 0..d {
                g[i] += row[i] * r[t] / n as f64;
                for j in 0..d {
                    h[i * d + j] += w[t] * row[i] * row[j] / n as f64;
                }
            }
        }
        (h, g)
    }

    #[test]
    fn correlations_of_several_inputs_match_the_explicit_jacobian() {
        let o = |nb, nf, delay| Orders { nb, nf, delay };
        let cases: &[(&[Orders], usize, &[usize])] = &[
            (&[o(2, 2, 1), o(1, 1, 2)], 300, &[]),
            (&[o(3, 1, 0), o(2, 4, 3)], 700, &[200, 450]),
            (&[o(2, 2, 1), o(1, 1, 2), o(2, 1, 0)], 900, &[]),
            (&[o(4, 3, 5), o(1, 0, 1), o(3, 6, 2)], 1200, &[100, 111, 800]),
            // Experiments shorter than some lags: columns shifted entirely out of them.
            (&[o(6, 6, 4), o(5, 7, 0)], 400, &[5, 12, 390]),
        ];
        let mut rng = Lcg(7);
        for &(inputs, n, seams) in cases {
            let lay = Layout::new(Structure::new(inputs).unwrap());
            let m = inputs.len();
            let xu: Vec<f64> = (0..m * n).map(|_| rng.next()).collect();
            let xy: Vec<f64> = (0..m * n).map(|_| rng.next()).collect();
            let r: Vec<f64> = (0..n).map(|_| rng.next()).collect();
            // None; IRLS weights on few rows (corrections, one at a time and packed) and on
            // most (direct sum); Gauss-Newton weights 0/1 on few and on most rows.
            for (frac, gauss_newton) in
                [(0.0, false), (0.02, false), (0.2, false), (0.8, false), (0.2, true), (0.8, true)]
            {
                let w: Vec<f64> = (0..n)
                    .map(|t| {
                        if ((t * 7919) % 100) as f64 / 100.0 >= frac {
                            1.0
                        } else if gauss_newton {
                            0.0
                        } else {
                            (t % 3) as f64 * 0.25
                        }
                    })
                    .collect();
                let weights = (frac > 0.0).then_some(&w[..]);
                for offset in [false, true] {
                    let d = lay.dim() + usize::from(offset);
                    let (he, ge) = explicit(&lay, offset, seams, &xu, &xy, &w, &r);
                    let scale = he.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    for form in [SeveralForm::Correlations, SeveralForm::Rows] {
                        let (mut h, mut g) = (vec![0.0; d * d], vec![0.0; d]);
                        let mut ne = NormalEquations::default();
                        // Twice through one workspace: the second build reuses its buffers.
                        for _ in 0..2 {
                            ne.build_several(form, &lay, offset, seams, &xu, &xy, weights, &r, &mut h, &mut g);
                        }
                        for k in 0..d * d {
                            assert!(
                                (h[k] - he[k]).abs() <= 1e-10 * scale,
                                "{form:?} h[{},{}] {} vs {} ({inputs:?}, {seams:?}, {frac}, {gauss_newton}, {offset})",
                                k / d,
                                k % d,
                                h[k],
                                he[k]
                            );
                        }
                        let gs = ge.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                        for k in 0..d {
                            assert!((g[k] - ge[k]).abs() <= 1e-10 * gs, "{form:?} g[{k}] {} vs {}", g[k], ge[k]);
                        }
                    }
                }
            }
        }
    }
}
