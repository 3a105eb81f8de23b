//! The portable kernels: every kernel as a function generic over `FMA` (fused multiply-add or
//! a multiply and an add), and the baseline build of each (`FMA = false`), which any CPU runs.
//! The AVX2 build ([`super::avx2`]) instantiates the same functions with `FMA = true` inside
//! `#[target_feature]` functions, or replaces them with explicit vector code where the
//! compiler's vectorisation fell short; either way in the same operation order per lane.

#[inline(always)]
pub(super) fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    // mul_add without hardware FMA is a slow libm call, so it is used only in the FMA build.
    if FMA { a.mul_add(b, c) } else { a * b + c }
}

#[inline(always)]
pub(super) fn dot_impl<const FMA: bool>(a: &[f64], b: &[f64]) -> f64 {
    // 16 independent accumulators: enough to keep two FMA ports busy through their latency.
    const ACC: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0f64; ACC];
    let mut ca = a.chunks_exact(ACC);
    let mut cb = b.chunks_exact(ACC);
    for (x, y) in (&mut ca).zip(&mut cb) {
        for k in 0..ACC {
            acc[k] = madd::<FMA>(x[k], y[k], acc[k]);
        }
    }
    let mut s = 0.0;
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        s = madd::<FMA>(*x, *y, s);
    }
    let mut w = ACC / 2;
    while w > 0 {
        for k in 0..w {
            acc[k] += acc[k + w];
        }
        w /= 2;
    }
    acc[0] + s
}

/// [`dot_impl`] of `a` and of `b` with one `c`, in one pass: `c` is loaded once for both, and
/// each sum is accumulated exactly as `dot_impl` accumulates it (the same result, bit for bit).
#[inline(always)]
pub(super) fn dot2_impl<const FMA: bool>(a: &[f64], b: &[f64], c: &[f64]) -> (f64, f64) {
    const ACC: usize = 16;
    let n = a.len().min(b.len()).min(c.len());
    let (a, b, c) = (&a[..n], &b[..n], &c[..n]);
    let (mut acc_a, mut acc_b) = ([0.0f64; ACC], [0.0f64; ACC]);
    let (mut ca, mut cb, mut cc) = (a.chunks_exact(ACC), b.chunks_exact(ACC), c.chunks_exact(ACC));
    for ((x, y), z) in (&mut ca).zip(&mut cb).zip(&mut cc) {
        for k in 0..ACC {
            acc_a[k] = madd::<FMA>(x[k], z[k], acc_a[k]);
            acc_b[k] = madd::<FMA>(y[k], z[k], acc_b[k]);
        }
    }
    let (mut sa, mut sb) = (0.0, 0.0);
    for ((x, y), z) in ca.remainder().iter().zip(cb.remainder()).zip(cc.remainder()) {
        sa = madd::<FMA>(*x, *z, sa);
        sb = madd::<FMA>(*y, *z, sb);
    }
    let mut w = ACC / 2;
    while w > 0 {
        for k in 0..w {
            acc_a[k] += acc_a[k + w];
            acc_b[k] += acc_b[k + w];
        }
        w /= 2;
    }
    (acc_a[0] + sa, acc_b[0] + sb)
}

/// Samples per block of [`lagged_dots_impl`]: two blocks (plus the lags) stay in L1.
pub(super) const LAG_BLOCK: usize = 1024;

/// Visit the terms of lagged sums `sum_{s + l < n} ...` block by block: for each block of
/// [`LAG_BLOCK`] samples and each lag `l < lags`, `f(l, s0, end)` with the block's terms
/// `s in [s0, end)`. Each block is read for all lags while it sits in L1.
#[inline(always)]
pub(super) fn blocked_lags(n: usize, lags: usize, mut f: impl FnMut(usize, usize, usize)) {
    let mut s0 = 0;
    while s0 < n {
        let s1 = (s0 + LAG_BLOCK).min(n);
        for l in 0..lags {
            let end = s1.min(n.saturating_sub(l));
            if end <= s0 {
                break;
            }
            f(l, s0, end);
        }
        s0 = s1;
    }
}

/// `out[l] = sum_{s=0}^{n-1-l} a[s] b[s+l]` for `l = 0..out.len()`, n = common length.
///
/// Blocked over s: all lags of one block of `a` and `b` are taken while the block sits in L1.
/// Lag by lag over the whole record (as before) streamed both sequences from L2 once per
/// lag, and that bandwidth, not the multiply-adds, bounded the normal equations. (Sharing
/// loads of `a` between four lags, and a 512-bit build, both measured slower.)
#[inline(always)]
pub(super) fn lagged_dots_impl<const FMA: bool>(a: &[f64], b: &[f64], out: &mut [f64]) {
    let n = a.len().min(b.len());
    out.fill(0.0);
    blocked_lags(n, out.len(), |l, s0, end| out[l] += dot_impl::<FMA>(&a[s0..end], &b[s0 + l..end + l]));
}

/// [`lagged_dots_impl`] of `a` and of `b`, each against the same `c`, in one pass:
/// `out_a[l] = sum_s a[s] c[s+l]`, `out_b[l] = sum_s b[s] c[s+l]` (over the common length, lags
/// `0..out_a.len()`), equal bit for bit to the two calls.
#[inline(always)]
pub(super) fn lagged_dots2_impl<const FMA: bool>(
    a: &[f64],
    b: &[f64],
    c: &[f64],
    out_a: &mut [f64],
    out_b: &mut [f64],
) {
    let n = a.len().min(b.len()).min(c.len());
    out_a.fill(0.0);
    out_b.fill(0.0);
    blocked_lags(n, out_a.len(), |l, s0, end| {
        let (x, y) = dot2_impl::<FMA>(&a[s0..end], &b[s0..end], &c[s0 + l..end + l]);
        out_a[l] += x;
        out_b[l] += y;
    });
}

/// The six correlations of the normal equations at lags `0..out.len()`:
/// `out[l] = [R(u,u), R(y,y), R(u,y), R(y,u), R(u,r), R(y,r)](l)`, `R(a,b)(l) = sum_s a[s] b[s+l]`.
///
/// One pass: per step the five loads `u[s], y[s], u[s+l], y[s+l], r[s+l]` feed six
/// multiply-adds, where six separate dot products load twelve. Blocked over s like
/// [`lagged_dots_impl`].
#[inline(always)]
pub(super) fn correlations_impl<const FMA: bool>(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
    const W: usize = 4;
    let n = u.len().min(y.len()).min(r.len());
    for o in out.iter_mut() {
        *o = [0.0; 6];
    }
    let lags = out.len();
    blocked_lags(n, lags, |l, s0, end| {
        let o = &mut out[l];
        {
            let len = end - s0;
            let (ua, ya) = (&u[s0..end], &y[s0..end]);
            let (ub, yb, rb) = (&u[s0 + l..end + l], &y[s0 + l..end + l], &r[s0 + l..end + l]);
            let mut acc = [[0.0f64; W]; 6];
            let chunks = len / W;
            let it = ua.chunks_exact(W).zip(ya.chunks_exact(W)).zip(ub.chunks_exact(W)).zip(yb.chunks_exact(W));
            for ((((a, b), p), q), z) in it.zip(rb.chunks_exact(W)) {
                for k in 0..W {
                    acc[0][k] = madd::<FMA>(a[k], p[k], acc[0][k]);
                    acc[1][k] = madd::<FMA>(b[k], q[k], acc[1][k]);
                    acc[2][k] = madd::<FMA>(a[k], q[k], acc[2][k]);
                    acc[3][k] = madd::<FMA>(b[k], p[k], acc[3][k]);
                    acc[4][k] = madd::<FMA>(a[k], z[k], acc[4][k]);
                    acc[5][k] = madd::<FMA>(b[k], z[k], acc[5][k]);
                }
            }
            for i in chunks * W..len {
                let (a, b) = (ua[i], ya[i]);
                let (p, q, z) = (ub[i], yb[i], rb[i]);
                acc[0][0] = madd::<FMA>(a, p, acc[0][0]);
                acc[1][0] = madd::<FMA>(b, q, acc[1][0]);
                acc[2][0] = madd::<FMA>(a, q, acc[2][0]);
                acc[3][0] = madd::<FMA>(b, p, acc[3][0]);
                acc[4][0] = madd::<FMA>(a, z, acc[4][0]);
                acc[5][0] = madd::<FMA>(b, z, acc[5][0]);
            }
            for (oj, aj) in o.iter_mut().zip(&acc) {
                *oj += (aj[0] + aj[2]) + (aj[1] + aj[3]);
            }
        }
    });
}

/// `h += alpha v v^T` on the upper triangle of the d x d row-major `h`.
#[inline(always)]
pub(super) fn rank1_upper_impl<const FMA: bool>(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
    for i in 0..d {
        let a = alpha * v[i];
        if a == 0.0 {
            continue;
        }
        let row = &mut h[i * d + i..i * d + d];
        for (hij, vj) in row.iter_mut().zip(&v[i..d]) {
            *hij = madd::<FMA>(a, *vj, *hij);
        }
    }
}

/// `h[i d + j] += scale sum_k q[k dp + i] p[k dp + j]` for `i <= j < d`: the upper triangle
/// of `scale Q^T P` for two m x d matrices stored row by row with stride `dp >= d`.
#[inline(always)]
pub(super) fn syrk_upper_impl<const FMA: bool>(
    h: &mut [f64],
    d: usize,
    p: &[f64],
    q: &[f64],
    dp: usize,
    m: usize,
    scale: f64,
) {
    for i in 0..d {
        for j in i..d {
            let mut s = 0.0;
            for k in 0..m {
                s = madd::<FMA>(q[k * dp + i], p[k * dp + j], s);
            }
            h[i * d + j] = madd::<FMA>(scale, s, h[i * d + j]);
        }
    }
}

/// [`compact`]: branch-free (write every t, advance past the kept ones), since which rows are
/// kept is unpredictable.
#[inline(always)]
pub(super) fn compact_impl(w: &[f64], skip: f64, rows: &mut [u32], mut alpha: Option<&mut [f64]>) -> usize {
    let mut m = 0;
    for (t, &wt) in w.iter().enumerate() {
        rows[m] = t as u32;
        if let Some(a) = alpha.as_deref_mut() {
            a[m] = wt;
        }
        m += (wt != skip) as usize;
    }
    m
}

#[inline(always)]
pub(super) fn inv_f_impl<const M: usize, const FMA: bool>(f: &[f64], x: &mut [f64]) {
    let mut a = [0.0; M];
    a.copy_from_slice(&f[..M]);
    // s[j] holds x_{t-1-j}: the last M outputs, newest first, kept in registers. (Re-reading
    // the history from x instead was slower: wide loads over just-stored scalars stall.)
    let mut s = [0.0; M];
    let mut neg = [0.0; M];
    for j in 0..M {
        neg[j] = -a[j];
    }
    for xt in x.iter_mut() {
        // One serial chain, oldest output first: output t-1-j enters 4(j+1) cycles (j+1 FMA
        // latencies) before output t is due, so every lag allows the one-FMA-per-sample pace
        // and the bound is the FMA ports (M per sample). Summing the older terms in a tree
        // instead put out(t-2) -> out(t) five operations apart, ~10 cycles per sample.
        let mut acc = *xt;
        for j in (0..M).rev() {
            acc = madd::<FMA>(neg[j], s[j], acc);
        }
        for j in (1..M).rev() {
            s[j] = s[j - 1];
        }
        s[0] = acc;
        *xt = acc;
    }
}

#[inline(always)]
pub(super) fn fir_impl<const FMA: bool>(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
    fir_range_impl::<FMA>(b, delay, u, out, 0, u.len())
}

/// `out_t` of [`fir`] for `t` in `t0..t1` only (`u` must hold samples up to `t1 - delay`). Each
/// output sums its taps in the same order whatever the range, so the result does not depend
/// on how a signal is cut into ranges.
#[inline(always)]
pub(super) fn fir_range_impl<const FMA: bool>(
    b: &[f64],
    delay: usize,
    u: &[f64],
    out: &mut [f64],
    t0: usize,
    t1: usize,
) {
    // Blocks of W outputs accumulate every tap in registers: one store per output instead of
    // a load and a store per output and tap (the tap-by-tap loop was store-bound). Sixteen
    // outputs are four independent chains of 256-bit multiply-adds, enough to keep both FMA
    // ports busy through their 4-cycle latency; eight (two chains) ran the FIR at a third of
    // that rate (5.7 against 3.6 us at nB = 10, N = 5000, fastest call; 32 gained no more).
    const W: usize = 16;
    let max_lag = delay + b.len().saturating_sub(1);
    let scalar = |t: usize| {
        let mut acc = 0.0;
        for (i, &bi) in b.iter().enumerate() {
            let lag = delay + i;
            if t >= lag {
                acc = madd::<FMA>(bi, u[t - lag], acc);
            }
        }
        acc
    };
    let head = max_lag.clamp(t0, t1);
    for (t, o) in out[t0..head].iter_mut().enumerate() {
        *o = scalar(t0 + t);
    }
    let mut t = head;
    while t + W <= t1 {
        let mut acc = [0.0; W];
        for (i, &bi) in b.iter().enumerate() {
            let start = t - delay - i;
            let x: &[f64; W] = u[start..start + W].try_into().expect("W samples");
            for k in 0..W {
                acc[k] = madd::<FMA>(bi, x[k], acc[k]);
            }
        }
        out[t..t + W].copy_from_slice(&acc);
        t += W;
    }
    for (t, o) in out[t..t1].iter_mut().enumerate().map(|(i, o)| (t + i, o)) {
        *o = scalar(t);
    }
}

pub(super) fn inv_f_generic(f: &[f64], x: &mut [f64]) {
    for t in 0..x.len() {
        let mut acc = x[t];
        for (j, fj) in f.iter().enumerate().take(t) {
            acc -= fj * x[t - 1 - j];
        }
        x[t] = acc;
    }
}

/// `sum_t f(y_t - yhat_t)` in eight interleaved partial sums: one running sum is a chain of
/// dependent adds (latency-bound), eight overlap and vectorise.
#[inline(always)]
fn sum_over(y: &[f64], yhat: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    const L: usize = 8;
    let n = y.len().min(yhat.len());
    let mut acc = [0.0; L];
    let (cy, cyh) = (y[..n].chunks_exact(L), yhat[..n].chunks_exact(L));
    let (ry, ryh) = (cy.remainder(), cyh.remainder());
    for (a, b) in cy.zip(cyh) {
        for k in 0..L {
            acc[k] += f(a[k] - b[k]);
        }
    }
    let tail: f64 = ry.iter().zip(ryh).map(|(a, b)| f(a - b)).sum();
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

#[inline(always)]
pub(super) fn loss_total_impl(y: &[f64], yhat: &[f64], gamma: Option<f64>) -> f64 {
    match gamma {
        None => sum_over(y, yhat, |e| e * e) * 0.5,
        Some(g) => sum_over(y, yhat, |e| super::huber_rho(g, e)),
    }
}

/// Branch-free and over zipped slices, so it vectorises (the L1/L2 split of consecutive
/// residuals is unpredictable).
#[inline(always)]
pub(super) fn influence_impl(y: &[f64], yhat: &[f64], gamma: Option<f64>, irls: bool, r: &mut [f64], w: &mut [f64]) {
    match gamma {
        None => {
            for ((r, &y), &yh) in r.iter_mut().zip(y).zip(yhat) {
                *r = y - yh;
            }
        }
        Some(gamma) => {
            let rows = r.iter_mut().zip(w.iter_mut()).zip(y.iter().zip(yhat));
            if irls {
                for ((r, w), (&y, &yh)) in rows {
                    let e = y - yh;
                    *r = e.clamp(-gamma, gamma);
                    *w = if e.abs() <= gamma { 1.0 } else { gamma / e.abs() };
                }
            } else {
                for ((r, w), (&y, &yh)) in rows {
                    let e = y - yh;
                    *r = e.clamp(-gamma, gamma);
                    *w = if e.abs() <= gamma { 1.0 } else { 0.0 };
                }
            }
        }
    }
}

/// Rows of the Jacobian packed for [`super::syrk_upper`], see [`super::pack_rows`].
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn pack_rows_impl(
    xu: &[f64],
    xy: &[f64],
    rows: &[u32],
    nb: usize,
    nf: usize,
    delay: usize,
    dp: usize,
    packed: &mut [f64],
) {
    let d = nb + nf;
    for (row, &t) in packed.chunks_exact_mut(dp).zip(rows) {
        let t = t as usize;
        let (ru, rest) = row.split_at_mut(nb);
        let (ry, pad) = rest.split_at_mut(d - nb);
        for (r, &v) in ru.iter_mut().zip(xu[t + 1 - delay - nb..=t - delay].iter().rev()) {
            *r = v;
        }
        for (r, &v) in ry.iter_mut().zip(xy[t - nf..t].iter().rev()) {
            *r = -v;
        }
        pad.fill(0.0);
    }
}

// The baseline build.

pub fn compact(w: &[f64], skip: f64, rows: &mut [u32], alpha: Option<&mut [f64]>) -> usize {
    compact_impl(w, skip, rows, alpha)
}
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    dot_impl::<false>(a, b)
}
pub fn lagged_dots(a: &[f64], b: &[f64], out: &mut [f64]) {
    lagged_dots_impl::<false>(a, b, out)
}
pub fn lagged_dots2(a: &[f64], b: &[f64], c: &[f64], out_a: &mut [f64], out_b: &mut [f64]) {
    lagged_dots2_impl::<false>(a, b, c, out_a, out_b)
}
pub fn rank1_upper(h: &mut [f64], d: usize, v: &[f64], alpha: f64) {
    rank1_upper_impl::<false>(h, d, v, alpha)
}
pub fn correlations(u: &[f64], y: &[f64], r: &[f64], out: &mut [[f64; 6]]) {
    correlations_impl::<false>(u, y, r, out)
}
pub fn syrk_upper(h: &mut [f64], d: usize, p: &[f64], q: &[f64], dp: usize, m: usize, scale: f64) {
    syrk_upper_impl::<false>(h, d, p, q, dp, m, scale)
}
pub fn inv_f(f: &[f64], x: &mut [f64]) {
    inv_f_dispatch!(false, f, x, 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24);
}
pub fn fir(b: &[f64], delay: usize, u: &[f64], out: &mut [f64]) {
    fir_impl::<false>(b, delay, u, out)
}
#[allow(clippy::too_many_arguments)]
pub fn pack_rows(
    xu: &[f64],
    xy: &[f64],
    rows: &[u32],
    nb: usize,
    nf: usize,
    delay: usize,
    dp: usize,
    packed: &mut [f64],
) {
    pack_rows_impl(xu, xy, rows, nb, nf, delay, dp, packed)
}
pub fn loss_total(y: &[f64], yhat: &[f64], gamma: Option<f64>) -> f64 {
    loss_total_impl(y, yhat, gamma)
}
pub fn influence(y: &[f64], yhat: &[f64], gamma: Option<f64>, irls: bool, r: &mut [f64], w: &mut [f64]) {
    influence_impl(y, yhat, gamma, irls, r, w)
}
