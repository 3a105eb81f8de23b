//! `export::continuous` (METHOD.md 18) against known solutions: the zeros, poles and gain of
//! systems whose ZOH sampling is known in closed form, the Tustin map's zero at `s = +2/Ts`,
//! and the refusals of poles on the negative real axis (or at `z = -1` under Tustin) that name
//! the pole, whether the copies of a repeated one are exact, split by the root finder, or a
//! pair within rounding of the axis.

use oesweep::export::continuous::{ContinuousModel, Method, NoEquivalent, Pole, to_continuous};
use oesweep::oe::poly_from_roots;

type C = (f64, f64);

fn mul(a: C, b: C) -> C {
    (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0)
}

fn div(a: C, b: C) -> C {
    let d = b.0 * b.0 + b.1 * b.1;
    ((a.0 * b.0 + a.1 * b.1) / d, (a.1 * b.0 - a.0 * b.1) / d)
}

fn cexp(a: C) -> C {
    let m = a.0.exp();
    (m * a.1.cos(), m * a.1.sin())
}

fn abs(a: C) -> f64 {
    a.0.hypot(a.1)
}

/// `p(s)` for real coefficients in descending powers.
fn polyval(p: &[f64], s: C) -> C {
    p.iter().fold((0.0, 0.0), |acc, &c| {
        let m = mul(acc, s);
        (m.0 + c, m.1)
    })
}

/// `gain prod(s - zeros)/prod(s - poles)`.
fn zpk_at(c: &ContinuousModel, s: C) -> C {
    let prod = |roots: &[C]| roots.iter().fold((1.0, 0.0), |acc, r| mul(acc, (s.0 - r.0, s.1 - r.1)));
    let h = div(prod(&c.zeros), prod(&c.poles));
    (c.gain * h.0, c.gain * h.1)
}

/// The roots `want` are `got` in some order, each to `tol` of its modulus (or of 1 near zero).
fn same_roots(what: &str, got: &[C], want: &[C], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: {got:?} vs {want:?}");
    let mut left: Vec<C> = got.to_vec();
    for w in want {
        let i = (0..left.len())
            .min_by(|&i, &j| {
                abs((left[i].0 - w.0, left[i].1 - w.1)).total_cmp(&abs((left[j].0 - w.0, left[j].1 - w.1)))
            })
            .unwrap();
        let g = left.swap_remove(i);
        assert!(abs((g.0 - w.0, g.1 - w.1)) <= tol * abs(*w).max(1.0), "{what}: {got:?} vs {want:?}");
    }
}

fn close(what: &str, got: f64, want: f64, tol: f64) {
    assert!((got - want).abs() <= tol * want.abs(), "{what}: {got} vs {want}");
}

/// `num(z)/den(z)` (monic den, equal lengths) of the ZOH sampling of `gain prod(s - zeros)/
/// prod(s - poles)` with distinct poles and fewer zeros, through its partial fractions:
/// `r/(s - p)` samples to `r (e^(p Ts) - 1)/p / (z - e^(p Ts))`.
fn zoh_sampled(zeros: &[C], poles: &[C], gain: f64, ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = poles.len();
    let discrete: Vec<C> = poles.iter().map(|&p| cexp((p.0 * ts, p.1 * ts))).collect();
    let mut num = vec![(0.0, 0.0); n + 1];
    for (i, &p) in poles.iter().enumerate() {
        let mut r = (gain, 0.0);
        for z in zeros {
            r = mul(r, (p.0 - z.0, p.1 - z.1));
        }
        for q in poles.iter().enumerate().filter(|&(j, _)| j != i).map(|(_, q)| q) {
            r = div(r, (p.0 - q.0, p.1 - q.1));
        }
        let e = discrete[i];
        let weight = mul(r, div((e.0 - 1.0, e.1), p));
        // weight prod_{j != i} (z - e_j): degree n - 1, into num[1..].
        let others: Vec<C> = discrete.iter().enumerate().filter(|&(j, _)| j != i).map(|(_, &d)| d).collect();
        let mut c = vec![(1.0, 0.0)];
        for d in others {
            let mut next = vec![(0.0, 0.0); c.len() + 1];
            for (k, &ck) in c.iter().enumerate() {
                next[k].0 += ck.0;
                next[k].1 += ck.1;
                let m = mul(ck, d);
                next[k + 1].0 -= m.0;
                next[k + 1].1 -= m.1;
            }
            c = next;
        }
        for (k, ck) in c.iter().enumerate() {
            let m = mul(weight, *ck);
            num[k + 1].0 += m.0;
            num[k + 1].1 += m.1;
        }
    }
    let den: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&discrete)).collect();
    (num.iter().map(|c| c.0).collect(), den)
}

/// A discrete pole `a` of the ZOH comes back as `ln(a)/Ts`, with the gain of the lag it samples
/// from; Tustin's `a/(z - p)` as the bilinear images of the pole and of the hold's zero at
/// infinity, `s = +2/Ts`.
#[test]
fn a_first_order_pole_maps_to_its_logarithm_and_tustin_adds_a_zero_at_two_over_ts() {
    for (a, ts) in [(0.9f64, 0.1), (0.3, 1e-3), (0.999, 1e-4)] {
        let b = 2.0 * (1.0 - a);
        let c = to_continuous(&[0.0, b], &[1.0, -a], ts, Method::Zoh).unwrap();
        assert!(c.zeros.is_empty(), "{c:?}");
        same_roots("zoh pole", &c.poles, &[(a.ln() / ts, 0.0)], 1e-14);
        // r/(s - l), l = ln(a)/Ts, samples to r (a - 1)/l / (z - a): r = b l/(a - 1).
        close("zoh gain", c.gain, b * a.ln() / ts / (a - 1.0), 1e-12);
        // Tustin: a/(z - p) = -(Ts/(1 + p)) a/2 ... : its DC gain b/(1 - a) at s = 0 too.
        let t = to_continuous(&[0.0, b], &[1.0, -a], ts, Method::Tustin).unwrap();
        same_roots("tustin pole", &t.poles, &[(2.0 / ts * (a - 1.0) / (a + 1.0), 0.0)], 1e-14);
        same_roots("tustin zero", &t.zeros, &[(2.0 / ts, 0.0)], 1e-14);
        close("tustin dc", zpk_at(&t, (0.0, 0.0)).0, b / (1.0 - a), 1e-13);
    }
    // (1 - 0.1 s)/(0.5 + 0.15 s) = (-2/3)(s - 10)/(s + 10/3) at Ts = 0.2.
    let t = to_continuous(&[0.0, 1.0], &[1.0, -0.5], 0.2, Method::Tustin).unwrap();
    close("tustin gain", t.gain, -2.0 / 3.0, 1e-14);
    same_roots("tustin zero", &t.zeros, &[(10.0, 0.0)], 1e-14);
    same_roots("tustin pole", &t.poles, &[(-10.0 / 3.0, 0.0)], 1e-14);
}

/// Systems whose ZOH sampling is known in closed form come back as their own zeros, poles and
/// gain: a resonance with a zero, and a fourth order with a right-half-plane zero, at sample
/// times from 1e-1 down to 1e-4 of their time scales; the state space is the same transfer
/// function.
#[test]
fn known_continuous_systems_come_back_as_their_zeros_poles_and_gain() {
    let cases: Vec<(Vec<C>, Vec<C>, f64, f64)> = vec![
        (vec![(-3.0, 0.0)], vec![(-0.5, 4.0), (-0.5, -4.0)], 2.0, 0.05),
        (vec![(-3.0, 0.0)], vec![(-0.5, 4.0), (-0.5, -4.0)], 2.0, 1e-4),
        (
            vec![(40.0, 0.0), (-5.0, 30.0), (-5.0, -30.0)],
            vec![(-2.0, 60.0), (-2.0, -60.0), (-30.0, 0.0), (-10.0, 0.0)],
            7.0,
            1e-3,
        ),
    ];
    for (zeros, poles, gain, ts) in cases {
        let (num, den) = zoh_sampled(&zeros, &poles, gain, ts);
        let c = to_continuous(&num, &den, ts, Method::Zoh).unwrap();
        assert_eq!(c.delay_samples, 0);
        same_roots("poles", &c.poles, &poles, 1e-8);
        same_roots("zeros", &c.zeros, &zeros, 1e-6);
        close("gain", c.gain, gain, 1e-6);
        // The transfer function, the factors and the state space agree on the imaginary axis.
        for w in [0.0, 1.0, 4.0, 50.0, 0.3 / ts] {
            let s = (0.0, w);
            let tf = div(polyval(&c.num, s), polyval(&c.den, s));
            let (zpk, ss) = (zpk_at(&c, s), state_space_at(&c, s));
            assert!(abs((tf.0 - zpk.0, tf.1 - zpk.1)) <= 1e-8 * abs(zpk), "{w}: {tf:?} vs {zpk:?}");
            assert!(abs((ss.0 - zpk.0, ss.1 - zpk.1)) <= 1e-10 * abs(zpk), "{w}: {ss:?} vs {zpk:?}");
        }
    }
}

/// `C (sI - A)^-1 B + D` by complex Gaussian elimination with partial pivoting.
fn state_space_at(c: &ContinuousModel, s: C) -> C {
    let ss = &c.state_space;
    let n = ss.b.len();
    let mut m: Vec<Vec<C>> = (0..n)
        .map(|i| {
            let mut row: Vec<C> =
                (0..n).map(|j| (if i == j { s.0 } else { 0.0 } - ss.a[i][j], if i == j { s.1 } else { 0.0 })).collect();
            row.push((ss.b[i], 0.0));
            row
        })
        .collect();
    for k in 0..n {
        let p = (k..n).max_by(|&i, &j| abs(m[i][k]).total_cmp(&abs(m[j][k]))).unwrap();
        m.swap(k, p);
        let pivot = m[k].clone();
        for row in m.iter_mut().skip(k + 1) {
            let f = div(row[k], pivot[k]);
            for (r, p) in row.iter_mut().zip(&pivot).skip(k) {
                let t = mul(f, *p);
                *r = (r.0 - t.0, r.1 - t.1);
            }
        }
    }
    let mut x = vec![(0.0, 0.0); n];
    for k in (0..n).rev() {
        let mut v = m[k][n];
        for j in k + 1..n {
            let t = mul(m[k][j], x[j]);
            v = (v.0 - t.0, v.1 - t.1);
        }
        x[k] = div(v, m[k][k]);
    }
    ss.c.iter().zip(&x).fold((ss.d, 0.0), |acc, (&ci, xi)| (acc.0 + ci * xi.0, acc.1 + ci * xi.1))
}

/// `prod (z - r)` in descending powers, real.
fn den_of(roots: &[C]) -> Vec<f64> {
    std::iter::once(1.0).chain(poly_from_roots(roots)).collect()
}

/// A pole on the negative real axis, single or repeated, has no real ZOH equivalent of the
/// model's order: exact copies (however the root finder splits them), copies split by 1e-9 to
/// 1e-5 on the axis or off it, and a triple pole, are all refused with the same message naming
/// the pole; pairs 2e-4 rad and more off the axis map to their logarithms, keeping the DC gain
/// to 1e-8. Tustin refuses `z = -1` the same way.
#[test]
fn poles_on_the_negative_real_axis_are_refused_by_name_however_they_split() {
    let others = [(0.9, 0.2), (0.9, -0.2), (0.7, 0.0)];
    let with = |pair: &[C]| -> Vec<f64> { den_of(&[pair, &others[..]].concat()) };
    let message = |den: &[f64]| -> String {
        let num = vec![0.0; den.len() - 2].into_iter().chain([0.3, 0.1]).collect::<Vec<_>>();
        let e = to_continuous(&num, den, 1e-3, Method::Zoh).unwrap_err();
        assert!(matches!(e, NoEquivalent::PoleOnNegativeAxis(Pole(re, 0.0)) if (re + 0.5).abs() <= 2e-5), "{e}");
        e.to_string()
    };
    let want = message(&den_of(&[(-0.5, 0.0)]));
    assert!(want.contains("z = -0.500000 on the negative real axis"), "{want}");
    // (z + 0.5)^2 and ^3 by their exact coefficients, with and without other poles.
    for den in [vec![1.0, 1.0, 0.25], vec![1.0, 1.5, 0.75, 0.125], with(&[(-0.5, 0.0), (-0.5, 0.0)])] {
        assert_eq!(message(&den), want, "{den:?}");
    }
    for split in [1e-9, 1e-8, 1e-7, 1e-6, 1e-5] {
        // Two real poles 2e-6 or more apart are two poles, either of which the message may name.
        let on_axis = message(&with(&[(-0.5 - split, 0.0), (-0.5 + split, 0.0)]));
        assert!(split > 1e-7 || on_axis == want, "{split} on the axis: {on_axis}");
        assert_eq!(message(&with(&[(-0.5, split), (-0.5, -split)])), want, "{split} off the axis");
        assert_eq!(message(&den_of(&[(-0.5, split), (-0.5, -split), (-0.5, 0.0)])), want, "{split}, triple");
    }
    for off in [1e-4, 1e-3, 1e-2] {
        let pair = [(-0.5, off), (-0.5, -off)];
        let den = with(&pair);
        let num: Vec<f64> = [0.0, 0.0, 0.0, 0.3, 0.1].to_vec();
        let ts = 1e-3;
        let c = to_continuous(&num, &den, ts, Method::Zoh).unwrap_or_else(|e| panic!("{off}: {e}"));
        let logs: Vec<C> = [&pair[..], &others[..]]
            .concat()
            .iter()
            .map(|&(re, im)| (abs((re, im)).ln() / ts, im.atan2(re) / ts))
            .collect();
        same_roots(&format!("{off}: poles"), &c.poles, &logs, 1e-9);
        let dc = polyval(&num, (1.0, 0.0)).0 / polyval(&den, (1.0, 0.0)).0;
        close(&format!("{off}: DC gain"), zpk_at(&c, (0.0, 0.0)).0, dc, 1e-8);
        close(&format!("{off}: DC gain of the state space"), state_space_at(&c, (0.0, 0.0)).0, dc, 1e-8);
    }
    // Tustin: z = -1, single, as exact copies or split.
    let tustin = |den: &[f64]| {
        let num = vec![0.0; den.len() - 1].into_iter().chain([1.0]).collect::<Vec<_>>();
        to_continuous(&num, den, 0.1, Method::Tustin).unwrap_err().to_string()
    };
    let want = tustin(&[1.0, 1.0]);
    assert!(want.contains("z = -1.000000: the Tustin map sends z = -1 to s = infinity"), "{want}");
    for den in [vec![1.0, 2.0, 1.0], den_of(&[(-1.0, 1e-8), (-1.0, -1e-8), (0.5, 0.0)]), den_of(&[(-1.0, 0.0); 3])] {
        assert_eq!(tustin(&den), want, "{den:?}");
    }
}
