//! Normal equations of the Gauss-Newton / Levenberg-Marquardt step, without ever forming J.
//!
//! The predictor Jacobian (METHOD.md 2) has columns that are shifted copies of two sequences,
//! `xu = (1/F) u` and `xy = (1/F) yhat`:
//!
//! ```text
//! column c = sign_c * s_c[t - lag_c],   b_i: (xu, +1, d+i-1),   f_j: (xy, -1, j)
//! ```
//!
//! so the Gram matrix `J^T J` is made of lagged dot products of those two sequences,
//! `R_ab(L) = sum_s a[s] b[s+L]`, minus a few end terms where a shift runs past the record:
//! O(N (nB+nF)) work instead of O(N (nB+nF)^2) for an explicit J^T J.
//!
//! Row weights `w_t` (Huber: 1 on the L2 set; 0 on the L1 set for the exact Gauss-Newton
//! Hessian, or g/|e_t| for IRLS) enter as a correction: `J^T W J = J^T J - sum_t (1-w_t)
//! psi_t psi_t^T` over the rows with `w_t != 1`, which at a Huber solution are few. When most
//! rows are reweighted the sum is instead taken directly over the rows with `w_t > 0`, which
//! keeps the cost at O(N d + min(#reweighted, N) d^2) and avoids cancellation.
//!
//! Several inputs ([`SeveralForm`], `normal/several.rs`) have 2m sequences, `xu_i` and `xy_i`
//! input after input, and the same sums over every pair of them (METHOD.md 19). One input's
//! code below is theirs for m = 1, unchanged bit for bit.

mod several;

pub use super::layout::Layout;
use super::layout::Seq;
pub use several::SeveralForm;

/// `rows[..m]` <- the t with `w[t] != skip`, and `alpha[..m]` (if given) <- those `w[t]`;
/// returns m. Both keep their length (`w.len() + 3`, the kernel's scratch) from call to call:
/// truncating and re-growing them refilled N entries with zeros on every build.
fn compact_rows(rows: &mut Vec<u32>, alpha: Option<&mut Vec<f64>>, w: &[f64], skip: f64) -> usize {
    let n = w.len();
    if rows.len() < n + 3 {
        rows.resize(n + 3, 0);
    }
    match alpha {
        None => crate::kernels::compact(w, skip, rows, None),
        Some(alpha) => {
            if alpha.len() < n + 3 {
                alpha.resize(n + 3, 0.0);
            }
            crate::kernels::compact(w, skip, rows, Some(alpha))
        }
    }
}

/// Below this many weighted rows the rank-1 updates beat packing them for a matrix product.
const PACK_MIN_ROWS: usize = 64;
/// Rows packed per product in [`NormalEquations::add_rows`] (128 KB at d = 29: stays in L2).
const PACK_BLOCK: usize = 512;

pub use crate::kernels::dot;
use crate::kernels::{lagged_dots, rank1_upper};

/// Reusable buffers for [`NormalEquations::build`].
#[derive(Default, Debug)]
pub struct NormalEquations {
    /// Per lag L: `R_uu, R_yy, R_uy, R_yu, R_ur, R_yr` with `R_ab(L) = sum_s a[s] b[s+L]`.
    corr: Vec<[f64; 6]>,
    /// Rows whose weight differs from 1 (or, `direct`, rows with a weight): `rows[..m]`.
    rows: Vec<u32>,
    m: usize,
    psi: Vec<f64>,
    /// Packed Jacobian rows of a weighted sum (row-major, m x d padded to a multiple of 4),
    /// their weights, and the weighted copy when the weights differ.
    packed: Vec<f64>,
    alpha: Vec<f64>,
    scaled: Vec<f64>,
    /// Column sums `sum_t w_t psi_t` of the offset's row ([`NormalEquations::add_offset`]).
    sums: Vec<f64>,
    /// `sum_k alpha_k psi_{t_k}` over the rows of the last weighted sum
    /// ([`NormalEquations::add_offset`]'s scratch).
    row_sums: Vec<f64>,
    /// The last `build` summed the weighted rows directly (`rows`, `alpha` = the rows with
    /// w_t > 0 and their weights) rather than as a correction (`alpha = w_t - 1`).
    direct: bool,
    /// Lagged correlations of two sequences of several inputs ([`SeveralForm::Correlations`]).
    lagged: Vec<f64>,
    /// One experiment's `h` and `g` in [`NormalEquations::build_all`].
    part_h: Vec<f64>,
    part_g: Vec<f64>,
}

/// `sum x` in eight interleaved partial sums, which vectorise (one running sum is a chain of
/// dependent adds: it made the offset's row a fifth of the whole solver's time).
fn sum(x: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let chunks = x.chunks_exact(8);
    let rest = chunks.remainder().iter().sum::<f64>();
    for c in chunks {
        for (a, v) in acc.iter_mut().zip(c) {
            *a += v;
        }
    }
    acc.iter().sum::<f64>() + rest
}

impl NormalEquations {
    /// [`Self::build`], then [`Self::add_offset`] when `offset`, over a record of several
    /// experiments separated by `seams` (empty: one experiment, exactly `build` and
    /// `add_offset`). The Jacobian rows of an experiment lag only into that experiment (the
    /// signals restart at its start), so the sums are the experiments' own normal equations
    /// weighted by their lengths: `h = sum_k (N_k/N) h_k`, the same for g (METHOD.md 16).
    #[allow(clippy::too_many_arguments)]
    pub fn build_all(
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
        if lay.structure.m() > 1 {
            return self.build_several(SeveralForm::Correlations, lay, offset, seams, xu, xy, w, r, h, g);
        }
        if seams.is_empty() {
            self.build(lay, xu, xy, w, r, h, g);
            if offset {
                self.add_offset(lay, xu, xy, w, r, h, g);
            }
            return;
        }
        let n = xu.len();
        let d = lay.dim() + usize::from(offset);
        let mut part_h = std::mem::take(&mut self.part_h);
        let mut part_g = std::mem::take(&mut self.part_g);
        part_h.resize(d * d, 0.0);
        part_g.resize(d, 0.0);
        h[..d * d].fill(0.0);
        g[..d].fill(0.0);
        for k in 0..=seams.len() {
            let start = if k == 0 { 0 } else { seams[k - 1] };
            let end = seams.get(k).copied().unwrap_or(n);
            let e = start..end;
            let wk = w.map(|w| &w[e.clone()]);
            let (xu, xy, r) = (&xu[e.clone()], &xy[e.clone()], &r[e.clone()]);
            self.build(lay, xu, xy, wk, r, &mut part_h, &mut part_g);
            if offset {
                self.add_offset(lay, xu, xy, wk, r, &mut part_h, &mut part_g);
            }
            let share = (end - start) as f64 / n as f64;
            for (a, p) in h[..d * d].iter_mut().zip(&part_h) {
                *a += share * p;
            }
            for (a, p) in g[..d].iter_mut().zip(&part_g) {
                *a += share * p;
            }
        }
        self.part_h = part_h;
        self.part_g = part_g;
    }

    /// Build `h = (1/N) J^T W J` (d x d, row-major, full) and `g = (1/N) J^T r`.
    ///
    /// `w` gives the row weights (None = all ones); `r` is the weighted residual psi_g(e).
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        &mut self,
        lay: &Layout,
        xu: &[f64],
        xy: &[f64],
        w: Option<&[f64]>,
        r: &[f64],
        h: &mut [f64],
        g: &mut [f64],
    ) {
        let n = xu.len();
        let d = lay.dim();
        assert!(xy.len() == n && r.len() == n && h.len() >= d * d && g.len() >= d);
        self.psi.resize(d, 0.0);
        let inv_n = 1.0 / n as f64;

        self.m = match w {
            Some(w) => compact_rows(&mut self.rows, None, w, 1.0),
            None => 0,
        };
        // Most rows reweighted: the sum is taken over them directly and needs no Gram matrix.
        let direct = w.is_some() && 2 * self.m > n;
        self.direct = direct;

        // g_c = sign_c sum_s s_c[s] r[s + lag_c]: consecutive lags of (xu, r) from d and of
        // (xy, r) from 1, i.e. lagged dot products of a shifted r.
        let (nb, nf, dl) = (lay.nb, lay.nf, lay.delay);
        if direct {
            if dl < n {
                lagged_dots(&xu[..n - dl], &r[dl..], &mut g[..nb]);
            } else {
                g[..nb].fill(0.0);
            }
            if n > 1 {
                lagged_dots(&xy[..n - 1], &r[1..], &mut g[nb..d]);
            } else {
                g[nb..d].fill(0.0);
            }
        } else {
            // All correlations the Gram matrix and g need, in one pass.
            self.corr.resize((dl + nb).max(nf + 1), [0.0; 6]);
            crate::kernels::correlations(xu, xy, r, &mut self.corr);
            for (gi, c) in g[..nb].iter_mut().zip(&self.corr[dl..]) {
                *gi = c[4];
            }
            for (gj, c) in g[nb..d].iter_mut().zip(&self.corr[1..]) {
                *gj = c[5];
            }
        }
        for (c, gc) in g[..d].iter_mut().enumerate() {
            let sign = if c < nb { 1.0 } else { -1.0 };
            *gc *= sign * inv_n;
        }

        let h = &mut h[..d * d];
        match w {
            Some(w) if direct => {
                h.fill(0.0);
                self.m = compact_rows(&mut self.rows, Some(&mut self.alpha), w, 0.0);
                self.add_rows(lay, xu, xy, h);
            }
            _ => {
                self.gram(lay, xu, xy, h);
                if let Some(w) = w {
                    self.alpha.clear();
                    self.alpha.extend(self.rows[..self.m].iter().map(|&t| w[t as usize] - 1.0));
                    self.add_rows(lay, xu, xy, h);
                }
            }
        }
        for i in 0..d {
            for j in i..d {
                let v = h[i * d + j] * inv_n;
                h[i * d + j] = v;
                h[j * d + i] = v;
            }
        }
    }

    /// Extends the normal equations of [`Self::build`] (nB + nF parameters, `h` with that
    /// stride) by an output offset c, whose Jacobian column is all ones (METHOD.md 9.1): `h`
    /// becomes (d0 + 1) x (d0 + 1) with the new row `(1/N) sum_t w_t [psi_t, 1]`, and
    /// `g_c = (1/N) sum_t r_t`. The column sums of the unweighted Jacobian are sums of `xu` and
    /// `xy` less a few end terms; the rows with `w_t != 1` that `build` left (with alpha =
    /// w_t - 1) are then corrected by their weighted sums (or, when `build` summed the weighted
    /// rows directly, the sums are those rows'). O(N + m d) for m reweighted rows; must follow
    /// `build` with the same arguments; no allocation after the first call.
    #[allow(clippy::too_many_arguments)]
    pub fn add_offset(
        &mut self,
        lay: &Layout,
        xu: &[f64],
        xy: &[f64],
        w: Option<&[f64]>,
        r: &[f64],
        h: &mut [f64],
        g: &mut [f64],
    ) {
        let n = xu.len();
        let d0 = lay.dim();
        let d = d0 + 1;
        assert!(h.len() >= d * d && g.len() >= d && r.len() == n);
        let inv_n = 1.0 / n as f64;
        // Re-stride from d0 to d in place, last entry first (targets never precede sources).
        for i in (0..d0).rev() {
            for j in (0..d0).rev() {
                h[i * d + j] = h[i * d0 + j];
            }
        }
        self.sums.resize(d0, 0.0);
        let mut weight;
        if w.is_some() && self.direct {
            // `build` summed over the rows with w_t > 0 directly: (rows, alpha) = (t, w_t).
            self.sums.fill(0.0);
            weight = 0.0;
        } else {
            // The unweighted column sums; `build` left the rows with w_t != 1 and
            // alpha = w_t - 1 (none without weights) for the correction below.
            let (total_u, total_y) = (sum(xu), sum(xy));
            for (c, s) in self.sums.iter_mut().enumerate() {
                let (seq, sign, lag) = lay.col(c);
                let (a, total) = if seq == Seq::U { (xu, total_u) } else { (xy, total_y) };
                // psi_tc = sign a[t - lag] for t >= lag: the sum runs over a[0 ..= n - 1 - lag].
                *s = if lag >= n { 0.0 } else { sign * (total - sum(&a[n - lag..])) };
            }
            weight = n as f64;
        }
        if w.is_some() {
            // The weighted rows' sums over `build`'s rows and weights (alpha = w_t - 1 for the
            // correction, w_t where it summed the rows directly), row after row. Taken here,
            // not beside `build`'s product: only a model with an offset reads them (d
            // multiply-adds per weighted row that the paper's model, `offset: none`, paid for
            // nothing, a fifth of the packed product's time).
            let m = self.m;
            self.row_sums.clear();
            self.row_sums.resize(d0, 0.0);
            for (&t, &a) in self.rows[..m].iter().zip(&self.alpha[..m]) {
                lay.row(xu, xy, t as usize, &mut self.psi);
                for (s, &p) in self.row_sums.iter_mut().zip(&self.psi) {
                    *s += a * p;
                }
            }
            for (s, p) in self.sums.iter_mut().zip(&self.row_sums) {
                *s += p;
            }
            weight += self.alpha[..m].iter().sum::<f64>();
        }
        for (c, s) in self.sums.iter().enumerate() {
            h[d0 * d + c] = s * inv_n;
            h[c * d + d0] = s * inv_n;
        }
        h[d0 * d + d0] = weight * inv_n;
        g[d0] = sum(r) * inv_n;
    }

    /// `h += sum_k alpha_k psi_{t_k} psi_{t_k}^T` (upper triangle) over `t_k = rows[k]`.
    ///
    /// Few rows go one rank-1 update at a time; more are packed into an m x d matrix P and
    /// the sum taken as one product P^T diag(alpha) P (`kernels::syrk_upper`, register-tiled),
    /// which does the same multiply-adds without a load and a store of `h` for each of them.
    fn add_rows(&mut self, lay: &Layout, xu: &[f64], xy: &[f64], h: &mut [f64]) {
        let d = lay.dim();
        let m = self.m;
        let (rows, alpha) = (&self.rows[..m], &self.alpha[..m]);
        if m < PACK_MIN_ROWS {
            for (&t, &a) in rows.iter().zip(alpha) {
                lay.row(xu, xy, t as usize, &mut self.psi);
                rank1_upper(h, d, &self.psi, a);
            }
            return;
        }
        // Rows of P, padded to a multiple of 4 columns for the kernel's vector loads, packed
        // PACK_BLOCK rows at a time so the buffers stay small whatever N (a whole m x d
        // matrix was 30 N-length vectors at OE(14,15)). Row t is xu[t-delay-nb+1 ..= t-delay]
        // and -xy[t-nf ..= t-1], both reversed.
        let dp = d.div_ceil(4) * 4;
        let (nb, dl) = (lay.nb, lay.delay);
        let first_full = (dl + nb).max(lay.nf + 1).max(dl + 1) - 1;
        // One weight for all rows (the Gauss-Newton Huber Hessian: -1 or 1) needs no copy.
        let uniform = alpha.iter().all(|&a| a == alpha[0]);
        let scale = if uniform { alpha[0] } else { 1.0 };
        self.packed.resize(PACK_BLOCK.min(m) * dp, 0.0);
        if !uniform {
            self.scaled.resize(PACK_BLOCK.min(m) * dp, 0.0);
        }
        for (rows, alpha) in rows.chunks(PACK_BLOCK).zip(alpha.chunks(PACK_BLOCK)) {
            let mb = rows.len();
            // The rows come in time order: those whose lags reach before the record first.
            let k0 = rows.partition_point(|&t| (t as usize) < first_full);
            for (row, &t) in self.packed.chunks_exact_mut(dp).zip(&rows[..k0]) {
                lay.row(xu, xy, t as usize, &mut row[..d]);
                row[d..].fill(0.0);
            }
            crate::kernels::pack_rows(xu, xy, &rows[k0..], nb, lay.nf, dl, dp, &mut self.packed[k0 * dp..mb * dp]);
            if !uniform {
                for ((dst, src), &a) in self.scaled.chunks_exact_mut(dp).zip(self.packed.chunks_exact(dp)).zip(alpha) {
                    for (q, &p) in dst.iter_mut().zip(src) {
                        *q = a * p;
                    }
                }
            }
            let q = if uniform { &self.packed[..mb * dp] } else { &self.scaled[..mb * dp] };
            crate::kernels::syrk_upper(h, d, &self.packed[..mb * dp], q, dp, mb, scale);
        }
    }

    /// Upper triangle of the unweighted `J^T J` from lagged dot products (no 1/N).
    fn gram(&mut self, lay: &Layout, xu: &[f64], xy: &[f64], h: &mut [f64]) {
        let n = xu.len();
        let d = lay.dim();
        // self.corr holds R_uu, R_yy, R_uy, R_yu at every lag difference that occurs
        // (lag_u - lag_y ranges over [d - nf, d + nb - 2]).
        for c in 0..d {
            let (sc, gc, lc) = lay.col(c);
            for e in c..d {
                let (se, ge, le) = lay.col(e);
                // Order the pair so the first member has the larger lag.
                let (sa, la, sb, lb) = if lc >= le { (sc, lc, se, le) } else { (se, le, sc, lc) };
                let lag = la - lb;
                let a = if sa == Seq::U { xu } else { xy };
                let b = if sb == Seq::U { xu } else { xy };
                let full = self.corr[lag][match (sa, sb) {
                    (Seq::U, Seq::U) => 0,
                    (Seq::Y, Seq::Y) => 1,
                    (Seq::U, Seq::Y) => 2,
                    (Seq::Y, Seq::U) => 3,
                }];
                // Terms s in [N - la, N - 1 - lag] belong to t >= N and must not count (summed
                // over zipped slices: the same additions in the same order, no bounds check
                // per term).
                if la >= n {
                    // The column is entirely shifted out of the record.
                    h[c * d + e] = 0.0;
                    continue;
                }
                let tail = a[n - la..n - lag].iter().zip(&b[n - la + lag..]).fold(0.0, |t, (x, y)| t + x * y);
                h[c * d + e] = gc * ge * (full - tail);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seqs(n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let mut s = 12345u64;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let xu: Vec<f64> = (0..n).map(|_| next()).collect();
        let xy: Vec<f64> = (0..n).map(|_| next()).collect();
        let r: Vec<f64> = (0..n).map(|_| next()).collect();
        (xu, xy, r)
    }

    fn explicit(lay: &Layout, xu: &[f64], xy: &[f64], w: &[f64], r: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let d = lay.dim();
        let n = xu.len();
        let mut h = vec![0.0; d * d];
        let mut g = vec![0.0; d];
        let mut row = vec![0.0; d];
        for t in 0..n {
            lay.row(xu, xy, t, &mut row);
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
    fn lagged_build_matches_explicit_jacobian() {
        for &(nb, nf, delay, n) in &[
            (3, 2, 1, 50),
            (7, 4, 1, 300),
            (12, 12, 1, 500),
            (12, 12, 1, 2000),
            (2, 5, 3, 40),
            (4, 0, 0, 30),
            (5, 9, 2, 12),
        ] {
            let lay = Layout::siso(nb, nf, delay);
            let (xu, xy, r) = seqs(n);
            let d = lay.dim();
            // few reweighted rows (correction path), many (direct path), none; IRLS-like
            // weights and Gauss-Newton ones (0 or 1: a uniform weight in either path); at the
            // larger n both paths have enough rows to be packed into a matrix product.
            for (frac, gauss_newton) in [(0.0, false), (0.1, false), (0.9, false), (0.1, true), (0.9, true)] {
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
                let (he, ge) = explicit(&lay, &xu, &xy, &w, &r);
                let mut ne = NormalEquations::default();
                let mut h = vec![0.0; d * d];
                let mut g = vec![0.0; d];
                ne.build(&lay, &xu, &xy, Some(&w), &r, &mut h, &mut g);
                for k in 0..d * d {
                    assert!(
                        (h[k] - he[k]).abs() < 1e-12,
                        "h[{k}] {} vs {} ({nb},{nf},{delay},{n},{frac})",
                        h[k],
                        he[k]
                    );
                }
                for k in 0..d {
                    assert!((g[k] - ge[k]).abs() < 1e-12);
                }
            }
        }
    }
}
