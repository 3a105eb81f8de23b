use super::logm::{eigenvalues, logm, norm1};
use super::*;

/// `exp(a)` by scaling and squaring with a degree-20 Taylor sum (`||a / 2^s|| <= 1/2`):
/// the forward map of the tests, independent of [`logm`].
fn expm(a: &Mat<f64>) -> Mat<f64> {
    let n = a.nrows();
    let s = norm1(a).log2().ceil().max(0.0) as i32 + 1;
    let b = Mat::from_fn(n, n, |i, j| a[(i, j)] / 2f64.powi(s));
    let mut sum = Mat::<f64>::identity(n, n);
    let mut term = Mat::<f64>::identity(n, n);
    for k in 1..=20 {
        let next = &term * &b;
        term = Mat::from_fn(n, n, |i, j| next[(i, j)] / k as f64);
        sum = Mat::from_fn(n, n, |i, j| sum[(i, j)] + term[(i, j)]);
    }
    for _ in 0..s {
        sum = &sum * &sum;
    }
    sum
}

/// c2d of `exp(-delay s) num(s)/den(s)` (monic den): num, den in z of the form
/// `ModelOut::num_den` gives (equal length, the delay as poles at the origin).
fn c2d(c: &ContinuousModel, ts: f64) -> (Vec<f64>, Vec<f64>) {
    let n = c.den.len() - 1;
    // To x = s Ts: the coefficient of s^(n-i) times Ts^-(n-i), over Ts^-n.
    let to_x = |p: &[f64]| -> Vec<f64> {
        let mut q = vec![0.0; n + 1 - p.len()];
        q.extend_from_slice(p);
        q.iter().enumerate().map(|(i, v)| v * ts.powi(i as i32)).collect()
    };
    let (num, den) = (to_x(&c.num), to_x(&c.den));
    let (mut nz, mut dz) = match c.method {
        Method::Zoh => {
            let d = num[0];
            let cc: Vec<f64> = (0..n).map(|i| num[i + 1] - d * den[i + 1]).collect();
            let m = Mat::from_fn(n + 1, n + 1, |i, j| match (i, j) {
                (0, j) if j < n => -den[j + 1],
                (0, j) if j == n => 1.0,
                (i, _) if i == n => 0.0,
                (i, j) if i == j + 1 => 1.0,
                _ => 0.0,
            });
            let e = expm(&m);
            let ad = Mat::from_fn(n, n, |i, j| e[(i, j)]);
            let closed = Mat::from_fn(n, n, |i, j| e[(i, j)] - e[(i, n)] * cc[j]);
            let dz: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&eigenvalues(&ad).unwrap())).collect();
            let cz: Vec<f64> = std::iter::once(1.0).chain(poly_from_roots(&eigenvalues(&closed).unwrap())).collect();
            ((0..=n).map(|i| cz[i] - dz[i] + d * dz[i]).collect::<Vec<_>>(), dz)
        }
        Method::Tustin => {
            // x = 2 (z - 1)/(z + 1): c x^(n-j) -> c 2^(n-j) (z - 1)^(n-j) (z + 1)^j.
            let map = |p: &[f64]| -> Vec<f64> {
                let mut out = vec![0.0; n + 1];
                for (j, &cf) in p.iter().enumerate() {
                    let mut term = vec![cf * 2f64.powi((n - j) as i32)];
                    for _ in 0..n - j {
                        term = poly_mul(&term, &[1.0, -1.0]);
                    }
                    for _ in 0..j {
                        term = poly_mul(&term, &[1.0, 1.0]);
                    }
                    out.iter_mut().zip(&term).for_each(|(o, t)| *o += t);
                }
                out
            };
            let (nz, dz) = (map(&num), map(&den));
            (nz.iter().map(|v| v / dz[0]).collect(), dz.iter().map(|v| v / dz[0]).collect())
        }
    };
    let k = c.delay_samples as usize;
    nz.splice(0..0, std::iter::repeat_n(0.0, k));
    dz.resize(dz.len() + k, 0.0);
    (nz, dz)
}

fn close(what: &str, got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: {got:?} vs {want:?}");
    let scale = want.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    for (g, w) in got.iter().zip(want) {
        assert!((g - w).abs() <= tol * scale, "{what}: {got:?} vs {want:?}");
    }
}

/// a/(z - p) with p = exp(-Ts/tau) and a = K (1 - p) is the ZOH sampling of K/(tau s + 1):
/// the inverse gives back (K/tau)/(s + 1/tau), and a delay of d samples (the model's `nk`)
/// gives d - 1 samples of dead time: the hold's own sample belongs to the system.
#[test]
fn a_first_order_lag_comes_back_exactly() {
    let (ts, tau, gain) = (0.1f64, 0.5, 2.0);
    let p = (-ts / tau).exp();
    for delay in [1usize, 3] {
        let mut num = vec![0.0; delay + 1];
        num[delay] = gain * (1.0 - p);
        let mut den = vec![0.0; delay + 1];
        den[0] = 1.0;
        den[1] = -p;
        let c = to_continuous(&num, &den, ts, Method::Zoh).unwrap();
        close("num", &c.num, &[gain / tau], 1e-13);
        close("den", &c.den, &[1.0, 1.0 / tau], 1e-13);
        assert_eq!(c.delay_samples, delay as u32 - 1);
        assert!((c.input_delay - (delay - 1) as f64 * ts).abs() < 1e-15);
    }
    // Tustin: a/(z - p) -> a (1 - x/2) / ((1 + x/2) - p (1 - x/2)), x = s Ts.
    let c = to_continuous(&[0.0, 1.0], &[1.0, -0.5], 0.2, Method::Tustin).unwrap();
    // (1 - 0.1 s)/(0.5 + 0.15 s) = (-2/3 s + 20/3)/(s + 10/3).
    close("tustin num", &c.num, &[-2.0 / 3.0, 20.0 / 3.0], 1e-14);
    close("tustin den", &c.den, &[1.0, 10.0 / 3.0], 1e-14);
}

/// A lightly damped 4th-order model (two modes at 0.99 and 0.95 radius) with a delay of 3
/// (two samples of dead time and the hold's one): c2d(d2c(G)) is G to 1e-9, by both maps;
/// and an integrator (a pole at z = 1) maps too.
#[test]
fn c2d_after_d2c_is_the_model() {
    let f = crate::oe::poly_from_poles(&[(0.99, 0.3), (0.95, 1.1)], &[]);
    let b = [0.02, -0.011, 0.004, 0.007];
    let ts = 1e-3;
    let m = super::super::model::InputModel { b: b.to_vec(), f: f.clone(), delay: 3, input_level: 0.0 };
    let (num, den) = m.num_den();
    for method in [Method::Zoh, Method::Tustin] {
        let c = to_continuous(&num, &den, ts, method).unwrap();
        assert_eq!(c.delay_samples, 2, "{method}: {c:?}");
        assert_eq!(c.den.len(), 5);
        let (nz, dz) = c2d(&c, ts);
        close(&format!("{method} num"), &nz, &num, 1e-9);
        close(&format!("{method} den"), &dz, &den, 1e-9);
    }
    // Order 8: three resonances and two real poles, delay 1, a short sample time.
    let f = crate::oe::poly_from_poles(&[(0.985, 0.45), (0.97, 1.3), (0.9, 2.2)], &[0.8, 0.5]);
    let b = [0.02, 0.05, -0.03, 0.04, 0.01, -0.02, 0.03, 0.015];
    let num: Vec<f64> = std::iter::once(0.0).chain(b).collect();
    let den: Vec<f64> = std::iter::once(1.0).chain(f).collect();
    for method in [Method::Zoh, Method::Tustin] {
        let c = to_continuous(&num, &den, 1e-4, method).unwrap();
        let (nz, dz) = c2d(&c, 1e-4);
        close(&format!("order 8 {method} num"), &nz, &num, 1e-9);
        close(&format!("order 8 {method} den"), &dz, &den, 1e-9);
    }
    // A pole at z = 1 and one at 0.5, with a direct feedthrough (delay 0).
    let (num, den) = (vec![0.3, 0.1, -0.05], vec![1.0, -1.5, 0.5]);
    let c = to_continuous(&num, &den, 0.5, Method::Zoh).unwrap();
    assert!(c.den.last().unwrap().abs() < 1e-12, "an integrator: {c:?}");
    let (nz, dz) = c2d(&c, 0.5);
    close("integrator num", &nz, &num, 1e-9);
    close("integrator den", &dz, &den, 1e-9);
}

/// A fractional dead time: the ZOH of exp(-0.4 Ts s)/(s + 1) is z^-1 (b1 z + b2)/(z - p),
/// an OE(2,1) with delay 1: it comes back as one sample of dead time and a biproper system
/// that samples to the same model.
#[test]
fn a_fractional_delay_comes_back_as_a_whole_sample_and_a_feedthrough() {
    let (ts, a) = (0.1f64, 0.4);
    let p = (-ts).exp();
    let (b1, b2) = (1.0 - (-(1.0 - a) * ts).exp(), (-(1.0 - a) * ts).exp() - p);
    let (num, den) = (vec![0.0, b1, b2], vec![1.0, -p, 0.0]);
    let c = to_continuous(&num, &den, ts, Method::Zoh).unwrap();
    assert_eq!(c.delay_samples, 1);
    assert_eq!(c.den.len(), 2);
    assert_eq!(c.num.len(), 2, "biproper: {c:?}");
    let (nz, dz) = c2d(&c, ts);
    close("num", &nz, &num, 1e-12);
    close("den", &dz, &den, 1e-12);
}

#[test]
fn poles_without_an_equivalent_are_named() {
    // A pole on the negative real axis.
    let e = to_continuous(&[0.0, 1.0], &[1.0, 0.5], 1.0, Method::Zoh).unwrap_err();
    assert_eq!(e, NoEquivalent::PoleOnNegativeAxis(Pole(-0.5, 0.0)));
    assert!(e.to_string().contains("z = -0.500000 on the negative real axis"), "{e}");
    assert!(to_continuous(&[0.0, 1.0], &[1.0, 0.5], 1.0, Method::Tustin).is_ok());
    // Near the origin.
    let e = to_continuous(&[0.0, 1.0], &[1.0, -1e-12], 1.0, Method::Zoh).unwrap_err();
    assert!(matches!(e, NoEquivalent::PoleAtOrigin(_)), "{e}");
    // At the origin beyond the delay: OE(2,1) with F = 1 + 0 q^-1, G = (b1 z + b2)/z^2.
    let e = to_continuous(&[0.0, 1.0, 0.5], &[1.0, 0.0, 0.0], 1.0, Method::Zoh).unwrap_err();
    assert_eq!(e, NoEquivalent::PoleAtOrigin(Pole(0.0, 0.0)));
    // Exactly at the origin and within the delay: an FIR gain with dead time.
    let c = to_continuous(&[0.0, 0.0, 2.0], &[1.0, 0.0, 0.0], 0.1, Method::Zoh).unwrap();
    assert_eq!((c.num, c.den, c.delay_samples), (vec![2.0], vec![1.0], 2));
    // Tustin: z = -1.
    let e = to_continuous(&[0.0, 1.0], &[1.0, 1.0], 1.0, Method::Tustin).unwrap_err();
    assert!(e.to_string().contains("s = infinity"), "{e}");
    // Not a model.
    assert_eq!(to_continuous(&[0.0, 0.0], &[1.0, 0.5], 1.0, Method::Zoh), Err(NoEquivalent::ZeroGain));
    assert_eq!(to_continuous(&[1.0], &[1.0], 0.0, Method::Zoh), Err(NoEquivalent::BadSampleTime(0.0)));
    assert_eq!(to_continuous(&[f64::NAN], &[1.0], 1.0, Method::Zoh), Err(NoEquivalent::NotFinite));
}

/// The logarithm inverts the exponential on block lower triangular matrices with eigenvalues
/// far from 1 and a pair 0.14 from the negative real axis; and a rotation by pi - 1e-6 in the
/// modal form (a pair 1e-6 from the axis) comes back as its angle.
#[test]
fn logm_inverts_expm() {
    let rows = [
        [-3.0, 0.0, 0.0, 0.0, 0.0],
        [0.2, -0.1, 2.0, 0.0, 0.0],
        [0.5, -2.0, -0.4, 0.0, 0.0],
        [1.0, 0.3, -0.2, -1.0, 3.0],
        [0.4, 0.1, 0.7, -3.0, -1.0],
    ];
    let a = Mat::from_fn(5, 5, |i, j| rows[i][j]);
    let l = logm(&expm(&a), &[1, 2, 2]).unwrap();
    for i in 0..5 {
        for j in 0..5 {
            assert!((l[(i, j)] - a[(i, j)]).abs() < 1e-12, "{i},{j}: {} vs {}", l[(i, j)], a[(i, j)]);
        }
    }
    let (r, theta) = (0.5f64, std::f64::consts::PI - 1e-6);
    let m = Mat::from_fn(2, 2, |i, j| r * [[theta.cos(), theta.sin()], [-theta.sin(), theta.cos()]][i][j]);
    let l = logm(&m, &[2]).unwrap();
    let want = [[r.ln(), theta], [-theta, r.ln()]];
    for i in 0..2 {
        for j in 0..2 {
            assert!((l[(i, j)] - want[i][j]).abs() < 1e-14, "{i},{j}: {} vs {}", l[(i, j)], want[i][j]);
        }
    }
    // A real eigenvalue below zero has no real logarithm.
    assert!(logm(&Mat::from_fn(1, 1, |_, _| -0.5), &[1]).is_none());
}

/// `C (zI - A)^-1 B + D` at the complex point `z` (re, im), by the real system of twice the
/// size.
fn ss_at(a: &Mat<f64>, b: &[f64], c: &[f64], d: f64, z: (f64, f64)) -> (f64, f64) {
    let n = b.len();
    let m = Mat::from_fn(2 * n, 2 * n, |i, j| {
        let (bi, bj, i, j) = (i / n, j / n, i % n, j % n);
        let diag = if i == j { 1.0 } else { 0.0 };
        match (bi, bj) {
            (0, 0) | (1, 1) => z.0 * diag - a[(i, j)],
            (0, 1) => -z.1 * diag,
            _ => z.1 * diag,
        }
    });
    let rhs = Mat::from_fn(2 * n, 1, |i, _| if i < n { b[i] } else { 0.0 });
    let x = crate::dense::Lu::new(m.as_ref()).solve(rhs.as_ref());
    ((0..n).map(|i| c[i] * x[(i, 0)]).sum::<f64>() + d, (0..n).map(|i| c[i] * x[(i + n, 0)]).sum::<f64>())
}

/// A 9th-order model (four resonances from 150 Hz to 3 kHz and a real pole) at Ts = 1e-4,
/// where the coefficients in s span 1e32: its state space sampled by `expm` (as
/// python-control's `sample_system` and MATLAB's `c2d` do) is the model to 1e-8 up to 0.9 of
/// Nyquist, and its zeros, poles and gain are the same transfer function; under Tustin the
/// state space at `s = (2/Ts)(z - 1)/(z + 1)` is the model.
#[test]
fn a_high_order_at_a_short_sample_time_samples_back_through_the_state_space() {
    let ts = 1e-4;
    let w = |hz: f64| 2.0 * std::f64::consts::PI * hz;
    let pairs: Vec<(f64, f64)> = [(150.0, 0.02), (600.0, 0.05), (1500.0, 0.03), (3000.0, 0.1)]
        .iter()
        .map(|&(hz, zeta)| ((-zeta * w(hz) * ts).exp(), w(hz) * (1.0f64 - zeta * zeta).sqrt() * ts))
        .collect();
    let f = crate::oe::poly_from_poles(&pairs, &[(-w(80.0) * ts).exp()]);
    let b = [
        -6.298_561_554_130_746e-6,
        9.086_510_511_615_43e-5,
        1.053_323_930_991_902_4e-3,
        -9.276_683_991_606_616e-4,
        -1.780_034_412_456_275_5e-3,
        1.847_505_729_116_503_2e-3,
        1.308_839_778_784_672_6e-4,
        -2.919_420_233_436_333_5e-4,
        -1.189_418_248_677_595_1e-5,
    ];
    let num: Vec<f64> = std::iter::once(0.0).chain(b).collect();
    let den: Vec<f64> = std::iter::once(1.0).chain(f).collect();
    let model = |z: (f64, f64)| {
        let eval = |p: &[f64]| {
            p.iter().fold((0.0, 0.0), |acc: (f64, f64), &k| (acc.0 * z.0 - acc.1 * z.1 + k, acc.0 * z.1 + acc.1 * z.0))
        };
        let (nz, dz) = (eval(&num), eval(&den));
        let d = dz.0 * dz.0 + dz.1 * dz.1;
        ((nz.0 * dz.0 + nz.1 * dz.1) / d, (nz.1 * dz.0 - nz.0 * dz.1) / d)
    };
    let near = |what: &str, got: (f64, f64), want: (f64, f64), tol: f64| {
        let err = (got.0 - want.0).hypot(got.1 - want.1) / want.0.hypot(want.1);
        assert!(err <= tol, "{what}: {got:?} vs {want:?} ({err:e})");
    };
    let frequencies: Vec<f64> = (1..=30).map(|k| 0.9 * k as f64 / 30.0 * std::f64::consts::PI / ts).collect();
    for method in [Method::Zoh, Method::Tustin] {
        let c = to_continuous(&num, &den, ts, method).unwrap();
        let ss = &c.state_space;
        let n = ss.b.len();
        assert_eq!(n, 9);
        let a = Mat::from_fn(n, n, |i, j| ss.a[i][j]);
        for &wk in &frequencies {
            let z = ((wk * ts).cos(), (wk * ts).sin());
            let s = (0.0, wk);
            // The factors and the state space are one transfer function.
            let zpk = {
                let prod = |r: &[(f64, f64)]| {
                    r.iter().fold((1.0f64, 0.0f64), |acc, q| {
                        let (x, y) = (s.0 - q.0, s.1 - q.1);
                        (acc.0 * x - acc.1 * y, acc.0 * y + acc.1 * x)
                    })
                };
                let (nz, dz) = (prod(&c.zeros), prod(&c.poles));
                let d = dz.0 * dz.0 + dz.1 * dz.1;
                (c.gain * (nz.0 * dz.0 + nz.1 * dz.1) / d, c.gain * (nz.1 * dz.0 - nz.0 * dz.1) / d)
            };
            near(&format!("{method} zpk vs ss at {wk}"), zpk, ss_at(&a, &ss.b, &ss.c, ss.d, s), 1e-10);
            let sampled = match method {
                Method::Zoh => {
                    let m = Mat::from_fn(n + 1, n + 1, |i, j| match (i < n, j < n) {
                        (true, true) => ss.a[i][j] * ts,
                        (true, false) => ss.b[i] * ts,
                        _ => 0.0,
                    });
                    let e = expm(&m);
                    let ad = Mat::from_fn(n, n, |i, j| e[(i, j)]);
                    let bd: Vec<f64> = (0..n).map(|i| e[(i, n)]).collect();
                    ss_at(&ad, &bd, &ss.c, ss.d, z)
                }
                Method::Tustin => {
                    // s = (2/Ts)(z - 1)/(z + 1).
                    let (p, q) = ((z.0 - 1.0, z.1), (z.0 + 1.0, z.1));
                    let d = q.0 * q.0 + q.1 * q.1;
                    let s = (2.0 / ts * (p.0 * q.0 + p.1 * q.1) / d, 2.0 / ts * (p.1 * q.0 - p.0 * q.1) / d);
                    ss_at(&a, &ss.b, &ss.c, ss.d, s)
                }
            };
            near(&format!("{method} sampled at {wk}"), sampled, model(z), 1e-8);
        }
    }
}
