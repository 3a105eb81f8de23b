//! The continuous equivalent as zeros, poles and gain, and as a state space of scaled sections
//! (METHOD.md 18).
//!
//! The coefficients of `num(s)`, `den(s)` span about `Ts^-n`: at order 9 and `Ts = 1e-4` some
//! 1e32, and a tool that turns them into a companion-form state space (python-control's and
//! scipy's `tf` sampling) loses every digit. The factored forms keep each pole and zero where
//! it is:
//!
//! - ZOH: the poles are the logarithms of the discrete poles over `Ts`, exactly; the zeros the
//!   roots of the numerator in `x = s Ts` (where its coefficients are of order one), over `Ts`;
//!   the gain its leading coefficient times `Ts^(m - n)` (`m` zeros, `n` poles).
//! - Tustin: every discrete pole and zero `c` maps to `(2/Ts)(c - 1)/(c + 1)`; a zero at
//!   `z = -1` goes to infinity; the relative degree `r` of `H` adds `r` zeros at `s = +2/Ts`
//!   (module docs of [`super`]); the gain is the product of the factors
//!   `z - c = ((1 + c)/2 x + 1 - c)/(1 - x/2)` that the map leaves.
//!
//! [`realise`] builds the state space: one section per pair of poles (a complex pair, or two
//! real poles in order) and one for an odd real pole, each given the zeros nearest its poles,
//! in a companion form whose second state is scaled by the pair's modulus (every entry of the
//! order of the poles), normalised to gain one at a reference frequency and with its input and
//! output balanced; the sections in series. Its `A` has entries of the order of the poles, so
//! `expm(A Ts)` (python-control's `sample_system`, MATLAB's `c2d`) is accurate.

use super::NEAR;
use crate::oe::cplx::{C, div, mul};

/// `A`, `B`, `C`, `D` of a single-input single-output continuous system, `A` by rows.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StateSpace {
    pub a: Vec<Vec<f64>>,
    pub b: Vec<f64>,
    pub c: Vec<f64>,
    pub d: f64,
}

/// The roots of a real polynomial as exact conjugate pairs (the upper root first, then its
/// conjugate) and real roots (imaginary part zero). An upper root pairs with the lower root
/// nearest its conjugate when that is nearer than the real axis; a root without a partner is
/// real (a root finder leaves real roots with imaginary parts of either sign at rounding
/// level).
pub(super) fn conjugate_pairs(roots: Vec<C>) -> Vec<C> {
    let (mut upper, mut lower): (Vec<C>, Vec<C>) = roots.iter().filter(|r| r.1 != 0.0).partition(|r| r.1 > 0.0);
    upper.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut out = Vec::with_capacity(roots.len());
    let mut real: Vec<C> = roots.iter().filter(|r| r.1 == 0.0).copied().collect();
    for u in upper {
        let dist = |l: &C| (l.0 - u.0).hypot(l.1 + u.1);
        match (0..lower.len()).min_by(|&i, &j| dist(&lower[i]).total_cmp(&dist(&lower[j]))) {
            Some(i) if dist(&lower[i]) < u.1 => {
                let l = lower.swap_remove(i);
                let (re, im) = ((u.0 + l.0) / 2.0, (u.1 - l.1) / 2.0);
                out.extend([(re, im), (re, -im)]);
            }
            _ => real.push(u),
        }
    }
    real.extend(lower);
    let mut real: Vec<C> = real.into_iter().map(|r| (r.0, 0.0)).collect();
    real.sort_by(|a, b| a.0.total_cmp(&b.0));
    out.extend(real);
    out
}

/// Roots of `p` (descending powers, leading zeros dropped) as [`conjugate_pairs`]; None when
/// the root finder fails.
pub(super) fn roots_of(p: &[f64]) -> Option<Vec<C>> {
    let p: Vec<f64> = p.iter().copied().skip_while(|&c| c == 0.0).collect();
    if p.is_empty() {
        return Some(Vec::new());
    }
    // Roots at the origin exactly, without the root finder.
    let at_origin = p.iter().rev().take_while(|&&c| c == 0.0).count();
    let rest = &p[..p.len() - at_origin];
    let monic: Vec<f64> = rest[1..].iter().map(|c| c / rest[0]).collect();
    let mut roots = crate::oe::poles(&monic);
    if roots.len() != monic.len() {
        return None;
    }
    roots.extend(std::iter::repeat_n((0.0, 0.0), at_origin));
    Some(conjugate_pairs(roots))
}

/// Zeros, poles and gain in s of the ZOH inverse `num_x(x)/prod(x - logs)`, `x = s Ts` (module
/// docs).
pub(super) fn zoh(num_x: &[f64], logs: &[C], ts: f64) -> Option<(Vec<C>, Vec<C>, f64)> {
    let num_x: Vec<f64> = num_x.iter().copied().skip_while(|&c| c == 0.0).collect();
    let zeros: Vec<C> = roots_of(&num_x)?.into_iter().map(|z| (z.0 / ts, z.1 / ts)).collect();
    let poles: Vec<C> = logs.iter().map(|p| (p.0 / ts, p.1 / ts)).collect();
    let gain = num_x.first().map_or(0.0, |lead| lead * ts.powi(zeros.len() as i32 - poles.len() as i32));
    Some((zeros, poles, gain))
}

/// Zeros, poles and gain in s of the Tustin map of `num(z)/den(z)`, `den` monic with the roots
/// `den_roots` (module docs).
pub(super) fn tustin(num: &[f64], den_roots: &[C], ts: f64) -> Option<(Vec<C>, Vec<C>, f64)> {
    let num: Vec<f64> = num.iter().copied().skip_while(|&c| c == 0.0).collect();
    let to_s = |c: C| {
        let x = div((c.0 - 1.0, c.1), (c.0 + 1.0, c.1));
        (2.0 * x.0 / ts, 2.0 * x.1 / ts)
    };
    // The leading coefficients of the factors: (1 + c)/2 for each finite zero and pole, 1 - c
    // for a zero at -1.
    let mut k: C = (num[0], 0.0);
    let mut zeros = Vec::new();
    for c in roots_of(&num)? {
        if (c.0 + 1.0).hypot(c.1) < NEAR {
            k = mul(k, (1.0 - c.0, -c.1));
        } else {
            k = mul(k, ((1.0 + c.0) / 2.0, c.1 / 2.0));
            zeros.push(to_s(c));
        }
    }
    let poles: Vec<C> = den_roots.iter().map(|&p| to_s(p)).collect();
    for p in den_roots {
        k = div(k, ((1.0 + p.0) / 2.0, p.1 / 2.0));
    }
    // (1 - x/2)^r = (-1/2)^r (x - 2)^r.
    let r = den_roots.len() - (num.len() - 1);
    k.0 *= (-0.5f64).powi(r as i32);
    zeros.extend(std::iter::repeat_n((2.0 / ts, 0.0), r));
    let gain = k.0 * ts.powi(zeros.len() as i32 - poles.len() as i32);
    Some((zeros, poles, gain))
}

/// Where [`realise`] gives a continuous system's sections gain one: `s = i w`, `w` the
/// geometric mean of the poles' moduli (`1/Ts` when all are at the origin).
pub(super) fn reference_point(poles: &[C], ts: f64) -> C {
    let moduli: Vec<f64> = poles.iter().map(|p| p.0.hypot(p.1)).filter(|&m| m > 0.0).collect();
    if moduli.is_empty() {
        return (0.0, 1.0 / ts);
    }
    (0.0, (moduli.iter().map(|m| m.ln()).sum::<f64>() / moduli.len() as f64).exp())
}

/// One section of [`realise`]: its poles (one, or a pair of a real polynomial) and zeros (no
/// more than poles).
struct Section {
    poles: Vec<C>,
    zeros: Vec<C>,
}

/// `prod (s - r)` at `s`.
fn product(roots: &[C], s: C) -> C {
    roots.iter().fold((1.0, 0.0), |acc, r| mul(acc, (s.0 - r.0, s.1 - r.1)))
}

/// Real coefficients `[c1, c0]` of `(s - r1)(s - r2)` (`[1, -r1]` padded for one root, `[0, 1]`
/// for none), without the leading one.
fn quadratic(roots: &[C]) -> [f64; 2] {
    match roots {
        [] => [0.0, 1.0],
        [r] => [1.0, -r.0],
        [r1, r2] => [-(r1.0 + r2.0), r1.0 * r2.0 - r1.1 * r2.1],
        _ => unreachable!("a section has at most two zeros"),
    }
}

/// A state space of `gain prod(s - zeros)/prod(s - poles)` (zeros and poles as
/// [`conjugate_pairs`] leaves them), in scaled sections in series (module docs), each of gain
/// one at the point `at`; with `modal_left`, a pair with a negative real part is in the real
/// modal form `[[re, im], [-im, re]]` (module docs of [`super`]: the ZOH's discrete side).
/// Returns the sizes of the sections too: `A` is block lower triangular with blocks of them.
pub(super) fn realise(zeros: &[C], poles: &[C], gain: f64, at: C, modal_left: bool) -> (StateSpace, Vec<usize>) {
    // Sections: each conjugate pair, then the real poles two by two.
    let mut sections: Vec<Section> = Vec::new();
    let mut real = Vec::new();
    let mut i = 0;
    while i < poles.len() {
        if poles[i].1 > 0.0 {
            sections.push(Section { poles: poles[i..i + 2].to_vec(), zeros: Vec::new() });
            i += 2;
        } else {
            real.push(poles[i]);
            i += 1;
        }
    }
    sections.extend(real.chunks(2).map(|c| Section { poles: c.to_vec(), zeros: Vec::new() }));
    // Zeros to the section with room whose poles are nearest: pairs first (they need a whole
    // second-order section; there are as many of those as pairs of zeros can be).
    let near = |s: &Section, z: C| s.poles.iter().map(|p| (p.0 - z.0).hypot(p.1 - z.1)).fold(f64::INFINITY, f64::min);
    let (pairs, singles): (Vec<C>, Vec<C>) = zeros.iter().partition(|z| z.1 != 0.0);
    for (group, size) in pairs.chunks(2).map(|g| (g, 2)).chain(singles.chunks(1).map(|g| (g, 1))) {
        let best = (0..sections.len())
            .filter(|&k| sections[k].poles.len() - sections[k].zeros.len() >= size)
            .min_by(|&a, &b| near(&sections[a], group[0]).total_cmp(&near(&sections[b], group[0])))
            .expect("no more zeros than poles");
        sections[best].zeros.extend_from_slice(group);
    }
    let (mut a, mut b, mut c, mut d) = (Vec::<Vec<f64>>::new(), Vec::new(), Vec::new(), 1.0);
    let mut rest = gain;
    for s in &sections {
        let h = div(product(&s.zeros, at), product(&s.poles, at));
        let g = h.0.hypot(h.1).recip();
        let g = if g.is_finite() && g > 0.0 { g } else { 1.0 };
        rest /= g;
        let modal = modal_left && s.poles[0].1 > 0.0 && s.poles[0].0 < 0.0;
        let (sa, sb, sc, sd) = section(s, g, at.0.hypot(at.1), modal);
        // In series: the section's input is the output so far, c x + d u.
        let (n0, k) = (a.len(), sa.len());
        for row in &mut a {
            row.resize(n0 + k, 0.0);
        }
        for i in 0..k {
            let mut row: Vec<f64> = c.iter().map(|cj| sb[i] * cj).collect();
            row.extend_from_slice(&sa[i]);
            a.push(row);
        }
        b.extend(sb.iter().map(|bi| bi * d));
        c = c.iter().map(|cj| sd * cj).chain(sc.iter().copied()).collect();
        d *= sd;
    }
    // The gain left over, split between the input and the output.
    let root = rest.abs().sqrt();
    b.iter_mut().for_each(|v| *v *= root * rest.signum());
    c.iter_mut().for_each(|v| *v *= root);
    (StateSpace { a, b, c, d: d * rest }, sections.iter().map(|s| s.poles.len()).collect())
}

/// `g prod(s - zeros)/prod(s - poles)` of one section as `(A, B, C, D)`: `(gamma_1 s +
/// gamma_0)/(s^2 + a_1 s + a_0) + D` in the companion form with the second state scaled by
/// `w = sqrt(|a_0|)` (`w_ref` when that is zero), or in the modal form; or `gamma_0/(s - p) + D`;
/// `B` and `C` balanced.
#[allow(clippy::type_complexity)]
fn section(s: &Section, g: f64, w_ref: f64, modal: bool) -> (Vec<Vec<f64>>, Vec<f64>, Vec<f64>, f64) {
    let [a1, a0] = quadratic(&s.poles);
    // The numerator is g (lead s^2 + b1 s + b0) over two poles, g (lead s + b0) over one:
    // `quadratic` pads as that needs.
    let [b1, b0] = quadratic(&s.zeros);
    let d = if s.zeros.len() == s.poles.len() { g } else { 0.0 };
    let (a, b, c) = if s.poles.len() == 2 {
        let (gamma1, gamma0) = (g * b1 - d * a1, g * b0 - d * a0);
        if modal {
            // (sI - A)^-1 B = (w, s - re)/den for A = [[re, w], [-w, re]], B = e2.
            let (re, w) = s.poles[0];
            (vec![vec![re, w], vec![-w, re]], vec![0.0, 1.0], vec![(gamma0 + gamma1 * re) / w, gamma1])
        } else {
            let w = if a0 != 0.0 { a0.abs().sqrt() } else { w_ref };
            (vec![vec![-a1, -a0 / w], vec![w, 0.0]], vec![1.0, 0.0], vec![gamma1, gamma0 / w])
        }
    } else {
        // One pole p = -a0: g (s - z)/(s - p) = g + g (p - z)/(s - p).
        let p = -a0;
        (vec![vec![p]], vec![1.0], vec![g * b0 + d * p])
    };
    // Balance: B t and C / t with |B t| = |C / t|.
    let (nb, nc) = (b.iter().map(|v| v * v).sum::<f64>().sqrt(), c.iter().map(|v| v * v).sum::<f64>().sqrt());
    let t = if nb > 0.0 && nc > 0.0 { (nc / nb).sqrt() } else { 1.0 };
    (a, b.iter().map(|v| v * t).collect(), c.iter().map(|v| v / t).collect(), d)
}
