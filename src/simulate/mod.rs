//! Example data: a PRBS input through a known OE system, plus noise and outliers.
//!
//! The paper's record (METHOD.md section 1) cannot be shipped, so tests, benchmarks and demos
//! run on data made here: a maximum-length PRBS input (as in the paper: 10-bit shift register,
//! +/-10 V), the noise-free output `y0 = q^-d B/F u` of a system read from a JSON file, and a
//! measured output `y = y0 + e + spikes` with Gaussian or Student-t noise `e` and optional
//! large spikes (the paper's observation outliers).
//!
//! A system of several inputs (`{"inputs": [{"b": .., "f": .., "delay": ..}, ..]}`, METHOD.md
//! 19) gives `y0 = sum_i q^-d_i B_i/F_i u_i`: input 1 is the PRBS above, and every further
//! input a random binary signal (each sample +/-amplitude with probability 1/2, from its own
//! random stream of the seed), so the inputs are uncorrelated and no two are collinear at any
//! frequency (two phases of one PRBS would be, at every line of its spectrum).
//!
//! Everything is deterministic: the same system and options give bit-identical records on every
//! machine, because the random numbers come from our own xoshiro256** generator rather than
//! from a crate whose stream may change between versions. The seed picks both the PRBS phase
//! and the noise, so estimation and validation records made with two seeds differ.
//!
//! `jobs/data/piezo_system.json` is a piezo-like OE(10, 10) system of our own design
//! (Ts = 100 us), built directly in the z-domain so that every pole and zero is significant
//! (no near-zero coefficient, no near pole-zero cancellation, which would blur the "true" order):
//! - resonances at 700 Hz (damping 0.025, pole radius 0.9891), 2100 Hz (0.03, radius 0.9612)
//!   and 3300 Hz (0.05, radius 0.9015);
//! - real poles 0.85, 0.5, 0.3, 0.1;
//! - zeros: anti-resonances at 1300 Hz (radius 0.85) and 2700 Hz (radius 0.9), real zeros
//!   -1.8 (outside the unit circle, like the sampling zeros of a fast-sampled continuous
//!   system), -0.8, -0.6, 0.65, 0.7;
//! - delay 1, gain scaled to exactly 1 at DC. The magnitude peaks are about 9.7 (700 Hz),
//!   0.67 (2.1 kHz) and 0.08 (3.3 kHz); a +/-10 V PRBS gives an output of standard deviation
//!   about 10 (micro-metres, say) with peaks near 45.

use std::fs;
use std::io::{BufWriter, Write};
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::oe;

mod gaps;
mod prbs;

use crate::rng::Xoshiro256;
pub use gaps::{GapOptions, punch, simulate_csv};
pub use prbs::{PRBS_BITS, prbs};

/// An OE system `y = q^-delay B(q^-1)/F(q^-1) u` as stored in a system JSON file:
/// `{"b": [b_1, ..., b_nB], "f": [f_1, ..., f_nF], "delay": 1}` (`f` without the leading 1 of
/// the monic F; `delay` defaults to 1).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SystemSpec {
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    #[serde(default = "one")]
    pub delay: usize,
}

fn one() -> usize {
    1
}

/// A system file of several inputs: `{"inputs": [SystemSpec, ...]}`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SeveralInputs {
    inputs: Vec<SystemSpec>,
}

/// Reads and checks a system JSON file: valid JSON of the right shape (serde's message gives
/// line and column), at least one B coefficient, and a stable F (a simulation through an
/// unstable F diverges, so such a file is always a mistake).
pub fn read_system(path: &Path) -> Result<SystemSpec> {
    let text = fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot open file: {e}")))?;
    let sys: SystemSpec =
        serde_json::from_str(&text).map_err(|e| Error::input(path, format!("invalid system file: {e}")))?;
    check_system(&sys).map_err(|msg| Error::input(path, msg))?;
    Ok(sys)
}

/// [`read_system`] of a file of one input (as there) or of several, `{"inputs": [{"b": ..,
/// "f": .., "delay": ..}, ..]}` (1 to [`crate::oe::MAX_INPUTS`] entries, each checked as one
/// input's and named in a message by its number): every input's system, in order.
pub fn read_systems(path: &Path) -> Result<Vec<SystemSpec>> {
    let text = fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot open file: {e}")))?;
    let several = matches!(serde_json::from_str(&text), Ok(serde_json::Value::Object(o)) if o.contains_key("inputs"));
    if !several {
        return Ok(vec![read_system(path)?]);
    }
    let file: SeveralInputs =
        serde_json::from_str(&text).map_err(|e| Error::input(path, format!("invalid system file: {e}")))?;
    check_systems(&file.inputs).map_err(|msg| Error::input(path, msg))?;
    Ok(file.inputs)
}

/// The checks of [`read_systems`] of several inputs, as a message without the file name.
fn check_systems(inputs: &[SystemSpec]) -> std::result::Result<(), String> {
    if !(1..=oe::MAX_INPUTS).contains(&inputs.len()) {
        return Err(format!("`inputs` has {} entries: give 1 to {}", inputs.len(), oe::MAX_INPUTS));
    }
    for (i, sys) in inputs.iter().enumerate() {
        check_system(sys).map_err(|m| format!("input {}: {m}", i + 1))?;
    }
    Ok(())
}

/// The checks of [`read_system`], as a message without the file name.
fn check_system(sys: &SystemSpec) -> std::result::Result<(), String> {
    if sys.b.is_empty() {
        return Err("b is empty: B needs at least one coefficient".into());
    }
    if let Some(i) = sys.b.iter().position(|v| !v.is_finite()) {
        return Err(format!("b[{}] is not a finite number", i + 1));
    }
    if let Some(i) = sys.f.iter().position(|v| !v.is_finite()) {
        return Err(format!("f[{}] is not a finite number", i + 1));
    }
    if !oe::is_stable(&sys.f) {
        return Err(format!(
            "F is unstable (largest pole radius {:.6}): the simulated output would diverge",
            oe::max_pole_radius(&sys.f)
        ));
    }
    Ok(())
}

/// Noise of the simulated measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NoiseKind {
    /// Gaussian, standard deviation `noise_std`.
    Gaussian,
    /// Student-t with `dof` degrees of freedom and scale `noise_std` (the noise is `noise_std`
    /// times a standard t variable, so its standard deviation is
    /// `noise_std * sqrt(dof / (dof - 2))` for dof > 2 and infinite otherwise): heavy-tailed
    /// innovations, the case the Huber criterion is built for.
    StudentT { dof: f64 },
}

/// Observation outliers: each sample independently, with `probability`, gets a spike of
/// magnitude uniform in `[min, max]` and random sign added to its output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outliers {
    pub probability: f64,
    pub min: f64,
    pub max: f64,
}

/// Most samples [`generate`] makes (`simulate --n`): ten million, hours of a fast actuator's
/// record and about 600 MB of CSV, beyond any record a sweep fits; a typo such as `--n 1e15`
/// must be an error, not an allocation that aborts the process.
pub const MAX_SAMPLES: usize = 10_000_000;

/// Settings of [`generate`].
#[derive(Debug, Clone, PartialEq)]
pub struct SimOptions {
    /// Number of samples N.
    pub n: usize,
    /// PRBS shift-register length (the paper: 10).
    pub bits: u32,
    /// PRBS level (the paper: 10 V).
    pub amplitude: f64,
    /// Picks the PRBS phase, the noise and the outliers.
    pub seed: u64,
    /// Noise standard deviation (Gaussian) or scale (Student-t); 0 for no noise.
    pub noise_std: f64,
    pub noise: NoiseKind,
    pub outliers: Option<Outliers>,
}

/// A simulated record: input, measured output, and the noise-free output `y0`.
#[derive(Debug, Clone, PartialEq)]
pub struct SimRecord {
    /// The input; several inputs: their columns one after the other (as
    /// [`crate::data::Record::u`]), `m` of them.
    pub u: Vec<f64>,
    pub m: usize,
    pub y: Vec<f64>,
    pub y0: Vec<f64>,
}

// Independent random streams of one seed. Keeping outliers on their own stream means that
// switching outliers on or off leaves the noise realisation unchanged, so records with and
// without spikes differ exactly by the spikes.
const NOISE_STREAM: u64 = 1;
const OUTLIER_STREAM: u64 = 2;
/// Input i >= 2 of a several-input system (0-based i >= 1) draws from stream `INPUT_STREAM + i`.
const INPUT_STREAM: u64 = 2;

fn check_options(opts: &SimOptions) -> Result<()> {
    let bad = |msg: String| Err(Error::Invalid(msg));
    if !(1..=MAX_SAMPLES).contains(&opts.n) {
        return bad(format!("the number of samples must be between 1 and {MAX_SAMPLES}, got {}", opts.n));
    }
    if !(opts.amplitude.is_finite() && opts.amplitude > 0.0) {
        return bad(format!("PRBS amplitude must be a positive number, got {}", opts.amplitude));
    }
    if !(opts.noise_std.is_finite() && opts.noise_std >= 0.0) {
        return bad(format!("noise standard deviation must be >= 0, got {}", opts.noise_std));
    }
    if let NoiseKind::StudentT { dof } = opts.noise
        && !(dof.is_finite() && dof > 0.0)
    {
        return bad(format!("Student-t degrees of freedom must be positive, got {dof}"));
    }
    if let Some(o) = &opts.outliers {
        if !(0.0..=1.0).contains(&o.probability) {
            return bad(format!("outlier probability must be in [0, 1], got {}", o.probability));
        }
        if !(o.min.is_finite() && o.max.is_finite() && 0.0 <= o.min && o.min <= o.max) {
            return bad(format!(
                "outlier magnitudes must satisfy 0 <= min <= max, got min {} and max {}",
                o.min, o.max
            ));
        }
    }
    Ok(())
}

/// Simulates `sys` driven by a PRBS: `u = prbs(bits, amplitude, seed, n)`,
/// `y0 = q^-d B/F u` (zero initial conditions), `y = y0 + noise + spikes`.
/// Fails (`Error::Invalid`) on out-of-range options, an empty B or an unstable F.
pub fn generate(sys: &SystemSpec, opts: &SimOptions) -> Result<SimRecord> {
    check_system(sys).map_err(|m| Error::Invalid(format!("system: {m}")))?;
    generate_inputs(std::slice::from_ref(sys), opts)
}

/// [`generate`] of a system of several inputs (one: [`generate`]'s record, to the bit):
/// input 1 the PRBS, every further input a random binary signal of the same amplitude (see
/// the module docs), `y0 = sum_i q^-d_i B_i/F_i u_i`.
pub fn generate_inputs(systems: &[SystemSpec], opts: &SimOptions) -> Result<SimRecord> {
    check_systems(systems).map_err(|m| Error::Invalid(format!("system: {m}")))?;
    check_options(opts)?;
    let m = systems.len();
    let mut u = prbs(opts.bits, opts.amplitude, opts.seed, opts.n)?;
    for i in 1..m {
        let mut rng = Xoshiro256::new(opts.seed, INPUT_STREAM + i as u64);
        u.extend((0..opts.n).map(|_| if rng.uniform() < 0.5 { -opts.amplitude } else { opts.amplitude }));
    }
    let mut y0 = oe::simulate_vec(&systems[0].b, &systems[0].f, systems[0].delay, &u[..opts.n]);
    for (sys, ui) in systems.iter().zip(u.chunks_exact(opts.n)).skip(1) {
        for (a, b) in y0.iter_mut().zip(oe::simulate_vec(&sys.b, &sys.f, sys.delay, ui)) {
            *a += b;
        }
    }
    let mut y = y0.clone();

    if opts.noise_std > 0.0 {
        let mut rng = Xoshiro256::new(opts.seed, NOISE_STREAM);
        match opts.noise {
            NoiseKind::Gaussian => {
                // Marsaglia's polar method yields two normals per accepted point.
                let mut spare: Option<f64> = None;
                for v in y.iter_mut() {
                    let z = match spare.take() {
                        Some(z) => z,
                        None => {
                            let (a, b, w) = rng.disc();
                            let m = (-2.0 * w.ln() / w).sqrt();
                            spare = Some(b * m);
                            a * m
                        }
                    };
                    *v += opts.noise_std * z;
                }
            }
            NoiseKind::StudentT { dof } => {
                // Bailey (1994), polar method: T = U sqrt(dof (W^(-2/dof) - 1) / W).
                for v in y.iter_mut() {
                    let (a, _, w) = rng.disc();
                    let t = a * (dof * (w.powf(-2.0 / dof) - 1.0) / w).sqrt();
                    *v += opts.noise_std * t;
                }
            }
        }
    }

    if let Some(o) = &opts.outliers {
        let mut rng = Xoshiro256::new(opts.seed, OUTLIER_STREAM);
        for v in y.iter_mut() {
            // Draw all three numbers for every sample so that the spike positions do not
            // depend on the magnitudes (changing min/max moves no spike).
            let (hit, mag, sign) = (rng.uniform(), rng.uniform(), rng.uniform());
            if hit < o.probability {
                let m = o.min + (o.max - o.min) * mag;
                *v += if sign < 0.5 { -m } else { m };
            }
        }
    }
    Ok(SimRecord { u, m, y, y0 })
}

/// Shortest text that parses back to exactly `x`. `{}` alone is shortest-roundtrip too but
/// never uses an exponent (1e-300 would take 300 digits), so tiny and huge values use `{:e}`.
/// NaN, a sample [`punch`] took out, is an empty field: a missing sample as loggers write it.
fn fmt_f64(out: &mut impl Write, x: f64) -> std::io::Result<()> {
    let a = x.abs();
    if x.is_nan() {
        Ok(())
    } else if x == 0.0 || (1e-5..1e16).contains(&a) {
        write!(out, "{x}")
    } else {
        write!(out, "{x:e}")
    }
}

/// Writes a simulated record as CSV with header `u,y,y0` (several inputs: `u1,u2,..,y,y0`), in
/// full precision (reading it back with [`crate::data::read_columns`] gives bit-identical
/// values). Written atomically
/// ([`crate::export::write_atomically`]), so a reader never sees half a file; a missing parent
/// folder is created.
pub fn write_csv(path: &Path, rec: &SimRecord) -> Result<()> {
    let fail = |what: &str, e: std::io::Error| Error::output(path, format!("{what}: {e}"));
    let n = rec.y.len();
    if rec.u.len() != rec.m * n || rec.y0.len() != n {
        return Err(Error::output(
            path,
            format!("columns of different lengths (u {} of {} inputs, y {n}, y0 {})", rec.u.len(), rec.m, rec.y0.len()),
        ));
    }
    let header = match rec.m {
        1 => "u".to_string(),
        m => (1..=m).map(|i| format!("u{i}")).collect::<Vec<_>>().join(","),
    };
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    fs::create_dir_all(dir).map_err(|e| fail("cannot create the folder", e))?;
    crate::export::write_atomically(path, |file| {
        let mut w = BufWriter::new(file);
        let mut rows = || -> std::io::Result<()> {
            writeln!(w, "{header},y,y0")?;
            for i in 0..n {
                for input in rec.u.chunks_exact(n) {
                    fmt_f64(&mut w, input[i])?;
                    w.write_all(b",")?;
                }
                fmt_f64(&mut w, rec.y[i])?;
                w.write_all(b",")?;
                fmt_f64(&mut w, rec.y0[i])?;
                w.write_all(b"\n")?;
            }
            w.flush()
        };
        rows().map_err(|e| format!("cannot write: {e}"))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn piezo_path() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data/piezo_system.json")
    }

    fn opts(seed: u64) -> SimOptions {
        SimOptions {
            n: 5000,
            bits: 10,
            amplitude: 10.0,
            seed,
            noise_std: 0.1,
            noise: NoiseKind::Gaussian,
            outliers: Some(Outliers { probability: 0.05, min: 5.0, max: 20.0 }),
        }
    }

    #[test]
    fn generation_is_deterministic_and_seed_dependent() {
        let sys = read_system(&piezo_path()).unwrap();
        let a = generate(&sys, &opts(7)).unwrap();
        let b = generate(&sys, &opts(7)).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.y), bits(&b.y));
        assert_eq!(bits(&a.u), bits(&b.u));
        assert_eq!(bits(&a.y0), bits(&b.y0));
        let c = generate(&sys, &opts(8)).unwrap();
        assert_ne!(a.u, c.u);
        assert_ne!(a.y, c.y);
        // Same PRBS phase (seed + period) still gets different noise.
        let d = generate(&sys, &opts(7 + 1023)).unwrap();
        assert_eq!(a.u, d.u);
        assert_ne!(a.y, d.y);
        // The noise-free output is the OE simulation.
        assert_eq!(a.y0, oe::simulate_vec(&sys.b, &sys.f, sys.delay, &a.u));
    }

    #[test]
    fn outlier_fraction_and_magnitudes() {
        let sys = read_system(&piezo_path()).unwrap();
        let mut o = opts(3);
        o.n = 20000;
        o.noise_std = 0.0;
        let r = generate(&sys, &o).unwrap();
        let spikes: Vec<f64> = r.y.iter().zip(&r.y0).map(|(y, y0)| y - y0).filter(|d| *d != 0.0).collect();
        let frac = spikes.len() as f64 / o.n as f64;
        // 5 standard errors of a binomial proportion at p = 0.05, N = 20000 is 0.0077.
        assert!((frac - 0.05).abs() < 0.0077, "outlier fraction {frac}");
        assert!(spikes.iter().all(|d| (5.0 - 1e-9..=20.0 + 1e-9).contains(&d.abs())));
        let pos = spikes.iter().filter(|d| **d > 0.0).count() as f64 / spikes.len() as f64;
        assert!((pos - 0.5).abs() < 0.1, "positive spikes {pos}");
    }

    #[test]
    fn outliers_do_not_change_the_noise() {
        let sys = read_system(&piezo_path()).unwrap();
        let with = generate(&sys, &opts(11)).unwrap();
        let without = generate(&sys, &SimOptions { outliers: None, ..opts(11) }).unwrap();
        let differ = with.y.iter().zip(&without.y).filter(|(a, b)| (*a - *b).abs() > 1.0).count();
        let same = with.y.iter().zip(&without.y).filter(|(a, b)| a == b).count();
        assert_eq!(differ + same, with.y.len());
        assert!(differ > 150 && differ < 350, "{differ} spikes");
    }

    fn noise(kind: NoiseKind, std: f64) -> Vec<f64> {
        let sys = SystemSpec { b: vec![1.0, 0.5], f: vec![-0.5], delay: 1 };
        let o =
            SimOptions { n: 20000, bits: 10, amplitude: 1.0, seed: 42, noise_std: std, noise: kind, outliers: None };
        let r = generate(&sys, &o).unwrap();
        r.y.iter().zip(&r.y0).map(|(y, y0)| y - y0).collect()
    }

    #[test]
    fn gaussian_noise_has_the_requested_std() {
        let e = noise(NoiseKind::Gaussian, 0.3);
        let n = e.len() as f64;
        let mean = e.iter().sum::<f64>() / n;
        let std = (e.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        // Standard error of the std is 0.3 / sqrt(2N) = 0.0015; mean's is 0.0021.
        assert!((std - 0.3).abs() < 0.01, "std {std}");
        assert!(mean.abs() < 0.01, "mean {mean}");
        // Tails: about 4.55% beyond 2 sigma.
        let tail = e.iter().filter(|x| x.abs() > 0.6).count() as f64 / n;
        assert!((tail - 0.0455).abs() < 0.008, "tail {tail}");
    }

    #[test]
    fn student_t_noise_has_the_requested_scale() {
        let e = noise(NoiseKind::StudentT { dof: 3.0 }, 0.5);
        let mut a: Vec<f64> = e.iter().map(|x| x.abs()).collect();
        a.sort_by(f64::total_cmp);
        // Median of |T| for 3 degrees of freedom is t_{0.75}(3) = 0.7649.
        let med = a[a.len() / 2] / 0.5;
        assert!((med - 0.7649).abs() < 0.03, "median |t| {med}");
        // Heavy tails: P(|T| > 5) = 0.0154 for 3 dof (Gaussian: 6e-7).
        let tail = a.iter().filter(|x| **x > 2.5).count() as f64 / a.len() as f64;
        assert!((tail - 0.0154).abs() < 0.005, "tail {tail}");
    }

    #[test]
    fn options_are_checked() {
        let sys = read_system(&piezo_path()).unwrap();
        let cases: Vec<(SimOptions, &str)> = vec![
            (SimOptions { n: 0, ..opts(1) }, "between 1 and"),
            (SimOptions { n: MAX_SAMPLES + 1, ..opts(1) }, "between 1 and 10000000"),
            (SimOptions { bits: 40, ..opts(1) }, "not supported"),
            (SimOptions { amplitude: 0.0, ..opts(1) }, "amplitude"),
            (SimOptions { noise_std: -1.0, ..opts(1) }, "noise standard deviation"),
            (SimOptions { noise: NoiseKind::StudentT { dof: 0.0 }, ..opts(1) }, "degrees of freedom"),
            (
                SimOptions { outliers: Some(Outliers { probability: 1.5, min: 1.0, max: 2.0 }), ..opts(1) },
                "probability",
            ),
            (SimOptions { outliers: Some(Outliers { probability: 0.1, min: 3.0, max: 2.0 }), ..opts(1) }, "min <= max"),
        ];
        for (o, want) in cases {
            let e = generate(&sys, &o).unwrap_err();
            assert!(matches!(e, Error::Invalid(_)));
            assert!(e.to_string().contains(want), "{e} should mention {want}");
        }
        let unstable = SystemSpec { b: vec![1.0], f: vec![-1.5], delay: 1 };
        let e = generate(&unstable, &opts(1)).unwrap_err();
        assert!(e.to_string().contains("F is unstable"), "{e}");
    }

    #[test]
    fn csv_roundtrip_is_bit_exact() {
        let sys = read_system(&piezo_path()).unwrap();
        let mut r = generate(&sys, &opts(5)).unwrap();
        // Values where plain `{}` would be long or lossy-looking.
        r.y[0] = 1e-300;
        r.y[1] = -0.0;
        r.y[2] = 1.7976931348623157e308;
        r.y[3] = 5e-324;
        r.y[4] = 0.1 + 0.2;
        r.y[5] = -123_456_789.123_456_78;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/sim.csv");
        write_csv(&p, &r).unwrap();
        let cols = crate::data::read_columns(&p, &["u", "y", "y0"]).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&cols[0]), bits(&r.u));
        assert_eq!(bits(&cols[1]), bits(&r.y));
        assert_eq!(bits(&cols[2]), bits(&r.y0));
        // No temporary file is left behind.
        let left: Vec<_> = fs::read_dir(p.parent().unwrap()).unwrap().collect();
        assert_eq!(left.len(), 1);
    }

    #[test]
    fn piezo_system_file_is_a_stable_oe_10_10() {
        let sys = read_system(&piezo_path()).unwrap();
        assert_eq!(sys.b.len(), 10);
        assert_eq!(sys.f.len(), 10);
        assert_eq!(sys.delay, 1);
        assert!(oe::is_stable(&sys.f));
        let r = oe::max_pole_radius(&sys.f);
        assert!((0.98..0.99).contains(&r), "largest pole radius {r}");
        let (re, im) = oe::freq_response(&sys.b, &sys.f, sys.delay, 0.0);
        assert!((re - 1.0).abs() < 1e-9 && im.abs() < 1e-12, "DC gain {re}");
        // The 700 Hz resonance (w = 2 pi 700 Ts) dominates.
        let w = 2.0 * std::f64::consts::PI * 700.0 * 1e-4;
        let (re, im) = oe::freq_response(&sys.b, &sys.f, sys.delay, w);
        let peak = re.hypot(im);
        assert!(peak > 8.0 && peak < 12.0, "gain at 700 Hz {peak}");
    }

    #[test]
    fn several_inputs_sum_their_contributions_from_uncorrelated_inputs() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("two.json");
        let text = r#"{"inputs": [{"b": [0.5, 0.3], "f": [-1.2, 0.5]}, {"b": [0.4], "f": [-0.8], "delay": 2}]}"#;
        fs::write(&p, text).unwrap();
        let sys = read_systems(&p).unwrap();
        assert_eq!((sys.len(), sys[0].delay, sys[1].delay), (2, 1, 2));
        let o = SimOptions { n: 4000, outliers: None, ..opts(3) };
        let r = generate_inputs(&sys, &o).unwrap();
        let (u1, u2) = r.u.split_at(o.n);
        assert_eq!((r.m, u1), (2, &generate(&sys[0], &o).unwrap().u[..]), "input 1 is the one-input PRBS");
        let sum: Vec<f64> = oe::simulate_vec(&sys[0].b, &sys[0].f, 1, u1)
            .iter()
            .zip(oe::simulate_vec(&sys[1].b, &sys[1].f, 2, u2))
            .map(|(a, b)| a + b)
            .collect();
        assert_eq!(r.y0, sum);
        assert!(u2.iter().all(|v| v.abs() == 10.0));
        let corr = u1.iter().zip(u2).map(|(a, b)| a * b).sum::<f64>() / (100.0 * o.n as f64);
        assert!(corr.abs() < 0.05, "correlation of the inputs {corr}");
        let csv = dir.path().join("two.csv");
        write_csv(&csv, &r).unwrap();
        let cols = crate::data::read_columns(&csv, &["u1", "u2", "y", "y0"]).unwrap();
        assert_eq!((&cols[0][..], &cols[1][..], &cols[2], &cols[3]), (u1, u2, &r.y, &r.y0));
        // One input in a list is the one-input file's system.
        fs::write(&p, r#"{"inputs": [{"b": [1, 0.5], "f": [-0.9]}]}"#).unwrap();
        assert_eq!(read_systems(&p).unwrap(), vec![SystemSpec { b: vec![1.0, 0.5], f: vec![-0.9], delay: 1 }]);
        for (text, want) in [
            (r#"{"inputs": [{"b": [1], "f": []}, {"b": [1], "f": [-1.5]}]}"#, "input 2: F is unstable"),
            (r#"{"inputs": []}"#, "`inputs` has 0 entries: give 1 to 8"),
            (r#"{"inputs": [{"b": [1], "f": []}], "delay": 1}"#, "unknown field `delay`"),
        ] {
            fs::write(&p, text).unwrap();
            let e = read_systems(&p).unwrap_err().to_string();
            assert!(e.contains("two.json") && e.contains(want), "{e}");
        }
    }

    #[test]
    fn system_file_errors() {
        let dir = tempfile::tempdir().unwrap();
        let case = |name: &str, text: &str| {
            let p = dir.path().join(name);
            fs::write(&p, text).unwrap();
            let e = read_system(&p).unwrap_err().to_string();
            assert!(e.contains(name), "{e}");
            e
        };
        let e = case("syntax.json", "{\n  \"b\": [1.0,\n  \"f\": []\n}");
        assert!(e.contains("invalid system file") && e.contains("line 3"), "{e}");
        let e = case("unknown.json", r#"{"b": [1], "f": [], "gain": 2}"#);
        assert!(e.contains("unknown field `gain`"), "{e}");
        let e = case("empty_b.json", r#"{"b": [], "f": [0.5]}"#);
        assert!(e.contains("b is empty"), "{e}");
        let e = case("unstable.json", r#"{"b": [1], "f": [-2.5, 1.5]}"#);
        assert!(e.contains("F is unstable (largest pole radius 1.5"), "{e}");
        let e = case("missing_f.json", r#"{"b": [1]}"#);
        assert!(e.contains("missing field `f`"), "{e}");
        let p = dir.path().join("default_delay.json");
        fs::write(&p, r#"{"b": [1, 0.5], "f": [-0.9]}"#).unwrap();
        assert_eq!(read_system(&p).unwrap().delay, 1);
        let e = read_system(&dir.path().join("nope.json")).unwrap_err().to_string();
        assert!(e.contains("nope.json: cannot open file"), "{e}");
    }
}
