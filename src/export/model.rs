//! One chosen model in the forms the next tool takes (`oesweep export`): JSON with `num`, `den`
//! and `dt` as python-control's `tf` and `scipy.signal.dlti` take them, a MATLAB/Octave script
//! that builds the `tf` (and the `idpoly` where the System Identification Toolbox is present),
//! and a MAT-file (level 5, MATLAB 7 format, written by the `matrw` crate).
//!
//! The model is `y_t = q^-d B(q^-1)/F(q^-1) (u_t - u0) + offset`. As a transfer function in z
//! with both polynomials in descending powers of z and of one length L = max(d + nB, nF + 1):
//!
//! ```text
//! num = [0 x d, b_1, ..., b_nB, 0 ...]       den = [1, f_1, ..., f_nF, 0 ...]
//! ```
//!
//! so that `num(z)/den(z) = z^-d B(z^-1)/F(z^-1)` (the common factor z^-(L-1) cancels).
//! With `--continuous`, each form also carries the model's continuous-time equivalent
//! ([`super::continuous`]).

use super::continuous::{self, ContinuousModel, Method, NoEquivalent};
use crate::error::{Error, Result};
use std::fmt::Write;
use std::path::Path;

/// A model as it leaves the tool.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelOut {
    /// What the model is and which rule picked it, e.g. "OE(9,9) delay 1 at k = 0.05 (paper_m2)".
    pub name: String,
    pub delay: u32,
    /// Null for a least-squares model.
    pub k: Option<f64>,
    pub ts: f64,
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    /// The output offset in the data's units (None: the model has none).
    pub offset: Option<f64>,
    /// The input level u0 taken out before the model (0 without one).
    pub input_level: f64,
    /// Row-major covariance over `[b, f]`, plus the offset when it was estimated (`dim` says).
    pub covariance: Option<Vec<f64>>,
    /// Names of the covariance's rows: b1.., f1.., and "offset" when estimated.
    pub parameters: Vec<String>,
    /// The variance of the noise the model leaves (sigma^2 of the least-squares fit of its
    /// structure): MATLAB's `idpoly` wants one.
    pub noise_variance: Option<f64>,
}

/// Names of a model's parameters in the covariance's order: b1.., f1.., and "offset" when
/// it was estimated.
/// The names of theta's entries for a structure: `b1.., f1.., offset` for one input, and for
/// several `u1.b1, .., u1.f1, .., u2.b1, .., offset` (input i's coefficients prefixed `u<i>.`).
pub fn structure_parameter_names(s: &crate::oe::Structure, offset: bool) -> Vec<String> {
    if let Some(o) = s.single() {
        return parameter_names(o.nb, o.nf, offset);
    }
    let mut names = Vec::new();
    for (i, o) in s.inputs().iter().enumerate() {
        names.extend(parameter_names(o.nb, o.nf, false).into_iter().map(|n| format!("u{}.{n}", i + 1)));
    }
    if offset {
        names.push("offset".into());
    }
    names
}

pub fn parameter_names(nb: usize, nf: usize, offset: bool) -> Vec<String> {
    let mut names: Vec<String> = (1..=nb).map(|i| format!("b{i}")).collect();
    names.extend((1..=nf).map(|j| format!("f{j}")));
    if offset {
        names.push("offset".into());
    }
    names
}

impl ModelOut {
    /// The model of a JSON document of [`Self::to_json_text`]'s form (the Python package's
    /// `Model.export`): `num`, `den` are not needed, `b`, `f`, `delay` and `dt` are.
    pub fn from_json_text(text: &str) -> std::result::Result<ModelOut, String> {
        let d: DocIn = serde_json::from_str(text).map_err(|e| format!("not a model: {e}"))?;
        let n = d.parameters.len();
        let covariance = match d.covariance {
            Some(rows) if rows.len() == n && rows.iter().all(|r| r.len() == n) => Some(rows.concat()),
            Some(_) => return Err(format!("the covariance is not {n} x {n}, one row per parameter")),
            None => None,
        };
        Ok(ModelOut {
            name: d.model,
            delay: d.delay,
            k: d.k,
            ts: d.dt,
            b: d.b,
            f: d.f,
            offset: d.offset,
            input_level: d.input_level,
            covariance,
            parameters: d.parameters,
            noise_variance: d.noise_variance,
        })
    }

    /// `num`, `den` in descending powers of z, of equal length (module docs).
    pub fn num_den(&self) -> (Vec<f64>, Vec<f64>) {
        let d = self.delay as usize;
        let len = (d + self.b.len()).max(self.f.len() + 1);
        let mut num = vec![0.0; len];
        num[d..d + self.b.len()].copy_from_slice(&self.b);
        let mut den = vec![0.0; len];
        den[0] = 1.0;
        den[1..=self.f.len()].copy_from_slice(&self.f);
        (num, den)
    }

    /// The continuous-time equivalent by `method` ([`super::continuous`]).
    pub fn to_continuous(&self, method: Method) -> std::result::Result<ContinuousModel, NoEquivalent> {
        let (num, den) = self.num_den();
        continuous::to_continuous(&num, &den, self.ts, method)
    }

    fn covariance_rows(&self) -> Option<Vec<Vec<f64>>> {
        let n = self.parameters.len();
        self.covariance.as_ref().filter(|c| c.len() == n * n).map(|c| c.chunks(n).map(<[f64]>::to_vec).collect())
    }

    /// The JSON document of `oesweep export --to json` as text, its fields in the order of
    /// [`Doc`] (num, den and dt first).
    pub fn to_json_text(&self) -> String {
        self.to_json_text_with(None)
    }

    /// [`Self::to_json_text`] with the continuous equivalent as a `continuous` object (`method`,
    /// `num`, `den`, `input_delay`, `delay_samples`, `zeros` and `poles` as `[re, im]` pairs,
    /// `gain`, `state_space` with `a` by rows, `b`, `c`, `d`) after the discrete fields.
    pub fn to_json_text_with(&self, continuous: Option<&ContinuousModel>) -> String {
        let doc = Doc { continuous, ..self.doc() };
        serde_json::to_string_pretty(&doc).expect("JSON of numbers") + "\n"
    }

    /// The same document as a value (its map sorts the keys).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self.doc()).expect("JSON of numbers")
    }

    fn doc(&self) -> Doc<'_> {
        let (num, den) = self.num_den();
        Doc {
            model: &self.name,
            num,
            den,
            dt: self.ts,
            b: &self.b,
            f: &self.f,
            delay: self.delay,
            k: self.k,
            offset: self.offset,
            input_level: self.input_level,
            parameters: &self.parameters,
            covariance: self.covariance_rows(),
            noise_variance: self.noise_variance,
            continuous: None,
        }
    }

    /// A MATLAB/Octave script that defines the coefficients and builds `G = tf(num, den, Ts)`,
    /// and `sys = idpoly(...)` with its covariance where the System Identification Toolbox is
    /// installed.
    pub fn to_matlab(&self) -> String {
        self.to_matlab_with(None)
    }

    /// [`Self::to_matlab`] that also builds the continuous equivalent as `Gc` (a `tf`) and `Gz`
    /// (a `zpk`, well-conditioned), with its dead time as `InputDelay` in MATLAB (Octave's `tf`
    /// and `zpk` have none, so there `input_delay` stands beside them).
    pub fn to_matlab_with(&self, continuous: Option<&ContinuousModel>) -> String {
        let (num, den) = self.num_den();
        let row = |v: &[f64]| v.iter().map(|x| matlab_number(*x)).collect::<Vec<_>>().join(", ");
        let mut s = String::new();
        let _ = writeln!(s, "% {} from oesweep", self.name);
        let _ =
            writeln!(s, "% y(t) = q^-nk B(q)/F(q) (u(t) - u0) + offset, B = b1 + b2 q^-1 + ..., F = 1 + f1 q^-1 + ...");
        let _ = writeln!(s, "Ts = {};", matlab_number(self.ts));
        let _ = writeln!(s, "nk = {};", self.delay);
        let _ = writeln!(s, "b = [{}];", row(&self.b));
        let _ = writeln!(s, "F = [1, {}];", row(&self.f));
        let _ = writeln!(s, "u0 = {};", matlab_number(self.input_level));
        let _ = writeln!(s, "offset = {};", self.offset.map_or("0".to_string(), matlab_number));
        match self.covariance_rows() {
            Some(rows) => {
                let rows: Vec<String> = rows.iter().map(|r| row(r)).collect();
                let _ = writeln!(s, "% over [{}]", self.parameters.join(", "));
                let _ = writeln!(s, "covariance = [{}];", rows.join("; ...\n  "));
            }
            None => {
                let _ = writeln!(s, "covariance = []; % not known");
            }
        }
        let _ = writeln!(s, "num = [{}];", row(&num));
        let _ = writeln!(s, "den = [{}];", row(&den));
        let _ = writeln!(s, "B = [zeros(1, nk), b];");
        let _ = writeln!(s, "if exist('OCTAVE_VERSION', 'builtin')");
        let _ = writeln!(s, "  pkg load control");
        let _ = writeln!(s, "end");
        let _ = writeln!(s, "G = tf(num, den, Ts);");
        let _ = writeln!(s, "if exist('idpoly')");
        let _ = writeln!(
            s,
            "  sys = idpoly(1, B, 1, 1, F, {}, Ts);",
            self.noise_variance.map_or("1".to_string(), matlab_number)
        );
        let _ = writeln!(s, "  sys.Structure.B.Free(1:nk) = false;");
        let np = self.b.len() + self.f.len();
        let _ = writeln!(s, "  if ~isempty(covariance)");
        let _ = writeln!(s, "    sys = setcov(sys, covariance(1:{np}, 1:{np}));");
        let _ = writeln!(s, "  end");
        let _ = writeln!(s, "end");
        if let Some(c) = continuous {
            let _ =
                writeln!(s, "% continuous-time equivalent ({}): Gc(s) = exp(-input_delay s) numc(s)/denc(s)", c.method);
            let _ = writeln!(s, "numc = [{}];", row(&c.num));
            let _ = writeln!(s, "denc = [{}];", row(&c.den));
            let _ =
                writeln!(s, "input_delay = {}; % seconds, {} samples", matlab_number(c.input_delay), c.delay_samples);
            let complex_row = |v: &[(f64, f64)]| v.iter().map(|&z| matlab_complex(z)).collect::<Vec<_>>().join(", ");
            let _ =
                writeln!(s, "% the same as zeros, poles (rad/s) and gain: well-conditioned where numc, denc are not");
            let _ = writeln!(s, "% (high orders, short sample times; docs/METHOD.md 18): prefer Gz");
            let _ = writeln!(s, "zc = [{}];", complex_row(&c.zeros));
            let _ = writeln!(s, "pc = [{}];", complex_row(&c.poles));
            let _ = writeln!(s, "kc = {};", matlab_number(c.gain));
            let _ = writeln!(s, "if exist('OCTAVE_VERSION', 'builtin')");
            let _ = writeln!(s, "  Gc = tf(numc, denc); % Octave's tf has no dead time");
            let _ = writeln!(s, "  Gz = zpk(zc, pc, kc);");
            let _ = writeln!(s, "else");
            let _ = writeln!(s, "  Gc = tf(numc, denc, 'InputDelay', input_delay);");
            let _ = writeln!(s, "  Gz = zpk(zc, pc, kc, 'InputDelay', input_delay);");
            let _ = writeln!(s, "end");
        }
        s
    }

    /// Write the MAT-file of `oesweep export --to mat`: `num`, `den`, `Ts`, `delay`, `b`, `B`
    /// (with the delay's leading zeros), `F` (with its leading 1), `offset` (NaN: none), `u0`
    /// and `covariance` (empty when not known).
    pub fn write_mat(&self, path: &Path) -> Result<()> {
        self.write_mat_with(path, None)
    }

    /// [`Self::write_mat`] with the continuous equivalent as `numc`, `denc` (descending powers
    /// of s), `zc`, `pc` (zeros and poles in rad/s, one a row: real and imaginary part), `kc`
    /// (gain) and `input_delay` (seconds).
    pub fn write_mat_with(&self, path: &Path, continuous: Option<&ContinuousModel>) -> Result<()> {
        use matrw::{MatFile, MatVariable, MatlabType, NumericArray};
        let (num, den) = self.num_den();
        let array = |dim: Vec<usize>, v: Vec<f64>| -> Result<MatVariable> {
            NumericArray::new(dim, MatlabType::from(v), None)
                .map(MatVariable::NumericArray)
                .map_err(|e| Error::output(path, format!("cannot build a MAT variable: {e}")))
        };
        let row = |v: &[f64]| array(vec![1, v.len()], v.to_vec());
        let scalar = |v: f64| array(vec![1, 1], vec![v]);
        let mut b_full = vec![0.0; self.delay as usize];
        b_full.extend_from_slice(&self.b);
        let f_full: Vec<f64> = std::iter::once(1.0).chain(self.f.iter().copied()).collect();
        let n = self.parameters.len();
        let mut mat = MatFile::new();
        mat.insert("num", row(&num)?);
        mat.insert("den", row(&den)?);
        mat.insert("Ts", scalar(self.ts)?);
        mat.insert("delay", scalar(self.delay as f64)?);
        mat.insert("b", row(&self.b)?);
        mat.insert("B", row(&b_full)?);
        mat.insert("F", row(&f_full)?);
        mat.insert("offset", scalar(self.offset.unwrap_or(f64::NAN))?);
        mat.insert("u0", scalar(self.input_level)?);
        // Symmetric, so row-major and MATLAB's column-major order agree.
        let cov = match &self.covariance {
            Some(c) if c.len() == n * n => array(vec![n, n], c.clone())?,
            _ => array(vec![0, 0], Vec::new())?,
        };
        mat.insert("covariance", cov);
        if let Some(c) = continuous {
            mat.insert("numc", row(&c.num)?);
            mat.insert("denc", row(&c.den)?);
            // Complex numbers as two columns, real and imaginary part: matrw stores each part of
            // a complex array in the smallest type that holds it and then miscounts the bytes.
            let columns = |v: &[(f64, f64)]| {
                let (mut re, im): (Vec<f64>, Vec<f64>) = v.iter().copied().unzip();
                re.extend(im);
                array(vec![v.len(), 2], re)
            };
            mat.insert("zc", columns(&c.zeros)?);
            mat.insert("pc", columns(&c.poles)?);
            mat.insert("kc", scalar(c.gain)?);
            mat.insert("input_delay", scalar(c.input_delay)?);
        }
        // matrw writes to a path: a temporary sibling renamed into place, as every result file.
        let tmp = super::temporary_path(path)?;
        let tmp_str = tmp.to_str().ok_or_else(|| Error::output(path, "the path is not UTF-8"))?;
        let written = matrw::save_matfile_v7(tmp_str, mat, false)
            .map_err(|e| e.to_string())
            .and_then(|()| std::fs::rename(&tmp, path).map_err(|e| e.to_string()));
        written.map_err(|e| {
            let _ = std::fs::remove_file(&tmp);
            Error::output(path, format!("cannot write the MAT-file: {e}"))
        })
    }
}

/// The JSON document of a model (README, `oesweep export`).
#[derive(serde::Serialize)]
struct Doc<'a> {
    model: &'a str,
    num: Vec<f64>,
    den: Vec<f64>,
    dt: f64,
    b: &'a [f64],
    f: &'a [f64],
    delay: u32,
    k: Option<f64>,
    offset: Option<f64>,
    input_level: f64,
    parameters: &'a [String],
    covariance: Option<Vec<Vec<f64>>>,
    noise_variance: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    continuous: Option<&'a ContinuousModel>,
}

/// What [`ModelOut::from_json_text`] reads of a [`Doc`].
#[derive(serde::Deserialize)]
struct DocIn {
    #[serde(default)]
    model: String,
    dt: f64,
    b: Vec<f64>,
    f: Vec<f64>,
    delay: u32,
    #[serde(default)]
    k: Option<f64>,
    #[serde(default)]
    offset: Option<f64>,
    #[serde(default)]
    input_level: f64,
    #[serde(default)]
    parameters: Vec<String>,
    #[serde(default)]
    covariance: Option<Vec<Vec<f64>>>,
    #[serde(default)]
    noise_variance: Option<f64>,
}

/// `re+imi` as MATLAB reads a complex number inside brackets (no spaces), `re` when `im` is zero.
fn matlab_complex((re, im): (f64, f64)) -> String {
    if im == 0.0 {
        matlab_number(re)
    } else {
        format!("{}{}{}i", matlab_number(re), if im < 0.0 { "-" } else { "+" }, matlab_number(im.abs()))
    }
}

/// Shortest text that reads back as exactly `x` in MATLAB (NaN and Inf by their names).
fn matlab_number(x: f64) -> String {
    if x.is_nan() {
        "NaN".into()
    } else if x.is_infinite() {
        if x > 0.0 { "Inf".into() } else { "-Inf".into() }
    } else {
        format!("{x:e}").replace("e0", "")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> ModelOut {
        ModelOut {
            name: "OE(2,1) delay 2 at k = 0.5 (test)".into(),
            delay: 2,
            k: Some(0.5),
            ts: 1e-3,
            b: vec![0.5, -0.25],
            f: vec![-0.8],
            offset: Some(1.5),
            input_level: 0.25,
            covariance: Some(vec![4.0, 1.0, 0.5, 0.1, 1.0, 3.0, 0.2, 0.0, 0.5, 0.2, 2.0, 0.0, 0.1, 0.0, 0.0, 1.0]),
            parameters: vec!["b1".into(), "b2".into(), "f1".into(), "offset".into()],
            noise_variance: Some(0.01),
        }
    }

    /// The JSON document reads back as the model it was written from (the Python package's
    /// `Model.export` relies on it); a covariance of the wrong shape is refused.
    #[test]
    fn the_json_document_reads_back_as_the_model() {
        let m = model();
        assert_eq!(ModelOut::from_json_text(&m.to_json_text()).unwrap(), m);
        let mut doc = m.to_json();
        doc["covariance"] = serde_json::json!([[1.0, 2.0], [2.0, 1.0]]);
        let err = ModelOut::from_json_text(&doc.to_string()).unwrap_err();
        assert!(err.contains("not 4 x 4"), "{err}");
        assert!(ModelOut::from_json_text("{}").unwrap_err().starts_with("not a model"));
    }

    #[test]
    fn num_and_den_simulate_like_the_model() {
        let m = model();
        let (num, den) = m.num_den();
        assert_eq!(num, vec![0.0, 0.0, 0.5, -0.25]);
        assert_eq!(den, vec![1.0, -0.8, 0.0, 0.0]);
        // den(q) y = num(q) u as a difference equation (scipy's lfilter) against oe::simulate.
        let u: Vec<f64> = (0..50).map(|t| ((t * 7 % 11) as f64 - 5.0) / 3.0).collect();
        let mut y = vec![0.0; u.len()];
        for t in 0..u.len() {
            let mut v = 0.0;
            for (i, c) in num.iter().enumerate() {
                if t >= i {
                    v += c * u[t - i];
                }
            }
            for (i, c) in den.iter().enumerate().skip(1) {
                if t >= i {
                    v -= c * y[t - i];
                }
            }
            y[t] = v;
        }
        let want = crate::oe::simulate_vec(&m.b, &m.f, 2, &u);
        for (a, b) in y.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn numbers_round_trip_through_the_script() {
        for x in [0.1, 1.0 / 3.0, -2.5e-17, 123456.789, 1e300] {
            assert_eq!(matlab_number(x).parse::<f64>().unwrap(), x, "{}", matlab_number(x));
        }
        let s = model().to_matlab();
        assert!(s.contains("G = tf(num, den, Ts);") && s.contains("nk = 2;"), "{s}");
        assert!(s.contains("covariance = [4, 1, 5e-1, 1e-1; ...\n  1, 3,"), "{s}");
        let j = model().to_json();
        assert_eq!(j["covariance"][1][1], 3.0);
        assert_eq!(j["dt"], 1e-3);
    }
}
