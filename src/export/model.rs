//! One chosen model in the forms the next tool takes (`oesweep export`): JSON with `num`, `den`
//! and `dt` as python-control's `tf` and `scipy.signal.dlti` take them, a MATLAB/Octave script
//! that builds the `tf` (and the `idpoly` where the System Identification Toolbox is present;
//! [`super::matlab`]), and a MAT-file (level 5, MATLAB 7 format, [`super::mat`]).
//!
//! The model is `y_t = sum_i q^-d_i B_i(q^-1)/F_i(q^-1) (u_i,t - u0_i) + offset` with one
//! [`InputModel`] per input (one input: `q^-d B/F (u_t - u0) + offset`). Each input's filter as
//! a transfer function in z, with both polynomials in descending powers of z and of one length
//! L = max(d + nB, nF + 1):
//!
//! ```text
//! num = [0 x d, b_1, ..., b_nB, 0 ...]       den = [1, f_1, ..., f_nF, 0 ...]
//! ```
//!
//! so that `num(z)/den(z) = z^-d B(z^-1)/F(z^-1)` (the common factor z^-(L-1) cancels).
//! With `--continuous`, each form also carries each input's continuous-time equivalent
//! ([`super::continuous`]), every input's filter converted on its own.
//!
//! The documents follow `selection.json`'s rule: a one-input model's fields are scalars and flat
//! lists, a several-input model's `num`, `den`, `b`, `f`, `delay`, `input_level` (and
//! `continuous`) hold one entry per input.

use super::continuous::{self, ContinuousModel, Method};

/// One input's part of a model: `q^-delay B/F (u - input_level)`.
#[derive(Clone, Debug, PartialEq)]
pub struct InputModel {
    pub b: Vec<f64>,
    pub f: Vec<f64>,
    pub delay: u32,
    /// The input level u0 taken out before the model (0 without one).
    pub input_level: f64,
}

impl InputModel {
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
}

/// A model as it leaves the tool.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelOut {
    /// What the model is and which rule picked it, e.g. "OE(9,9) delay 1 at k = 0.05 (paper_m2)".
    pub name: String,
    /// Null for a least-squares model.
    pub k: Option<f64>,
    pub ts: f64,
    /// Every input's filter, in the job's order of the inputs (one for a single-input model).
    pub inputs: Vec<InputModel>,
    /// The output offset in the data's units (None: the model has none).
    pub offset: Option<f64>,
    /// Row-major covariance over theta `[b_1, f_1, ..., b_m, f_m]`, plus the offset when it was
    /// estimated (`parameters` names the rows).
    pub covariance: Option<Vec<f64>>,
    /// Names of the covariance's rows: b1.., f1.. (several inputs: u1.b1.., u1.f1.., u2.b1..),
    /// and "offset" when estimated.
    pub parameters: Vec<String>,
    /// The variance of the noise the model leaves (sigma^2 of the least-squares fit of its
    /// structure): MATLAB's `idpoly` wants one.
    pub noise_variance: Option<f64>,
}

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

/// Names of a model's parameters in the covariance's order: b1.., f1.., and "offset" when
/// it was estimated.
pub fn parameter_names(nb: usize, nf: usize, offset: bool) -> Vec<String> {
    let mut names: Vec<String> = (1..=nb).map(|i| format!("b{i}")).collect();
    names.extend((1..=nf).map(|j| format!("f{j}")));
    if offset {
        names.push("offset".into());
    }
    names
}

/// A field of one value for a one-input model and a list (one per input) for several.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
enum Each<T> {
    One(T),
    Several(Vec<T>),
}

impl<T> Each<T> {
    /// One value for one input, a list for several.
    fn of(mut items: Vec<T>) -> Self {
        if items.len() == 1 { Each::One(items.remove(0)) } else { Each::Several(items) }
    }

    /// The values for `m` inputs: a list must have `m` entries; one value serves one input (or
    /// every input, where `shared`).
    fn for_inputs(self, m: usize, field: &str, shared: bool) -> std::result::Result<Vec<T>, String>
    where
        T: Clone,
    {
        match self {
            Each::One(v) if m == 1 || shared => Ok(vec![v; m]),
            Each::One(_) => Err(format!("'{field}' is one input's: a model of {m} inputs has one entry per input")),
            Each::Several(v) if v.len() == m => Ok(v),
            Each::Several(v) => Err(format!("'{field}' has {} entries for {m} inputs", v.len())),
        }
    }

    fn len(&self) -> usize {
        match self {
            Each::One(_) => 1,
            Each::Several(v) => v.len(),
        }
    }
}

impl ModelOut {
    /// Number of inputs m.
    pub fn m(&self) -> usize {
        self.inputs.len()
    }

    /// The model of a JSON document of [`Self::to_json_text`]'s form (the Python package's
    /// `Model.export`): `num`, `den` are not needed, `b`, `f`, `delay` and `dt` are (one entry per
    /// input for several inputs, as `delay` says).
    pub fn from_json_text(text: &str) -> std::result::Result<ModelOut, String> {
        let d: DocIn = serde_json::from_str(text).map_err(|e| format!("not a model: {e}"))?;
        let n = d.parameters.len();
        let covariance = match d.covariance {
            Some(rows) if rows.len() == n && rows.iter().all(|r| r.len() == n) => Some(rows.concat()),
            Some(_) => return Err(format!("the covariance is not {n} x {n}, one row per parameter")),
            None => None,
        };
        let m = d.delay.len();
        if m == 0 {
            return Err("'delay' is an empty list: give one per input".into());
        }
        let (b, f) = (d.b.for_inputs(m, "b", false)?, d.f.for_inputs(m, "f", false)?);
        let (delay, level) =
            (d.delay.for_inputs(m, "delay", false)?, d.input_level.for_inputs(m, "input_level", true)?);
        let inputs = (0..m)
            .map(|i| InputModel { b: b[i].clone(), f: f[i].clone(), delay: delay[i], input_level: level[i] })
            .collect();
        Ok(ModelOut {
            name: d.model,
            k: d.k,
            ts: d.dt,
            inputs,
            offset: d.offset,
            covariance,
            parameters: d.parameters,
            noise_variance: d.noise_variance,
        })
    }

    /// Every input's `num`, `den` ([`InputModel::num_den`]).
    pub fn num_den(&self) -> Vec<(Vec<f64>, Vec<f64>)> {
        self.inputs.iter().map(InputModel::num_den).collect()
    }

    /// Every input's continuous-time equivalent by `method` ([`super::continuous`]), each
    /// input's filter converted on its own. The error says why one has none (naming the input
    /// of a several-input model).
    pub fn to_continuous(&self, method: Method) -> std::result::Result<Vec<ContinuousModel>, String> {
        let several = self.m() > 1;
        self.inputs
            .iter()
            .enumerate()
            .map(|(i, part)| {
                let (num, den) = part.num_den();
                continuous::to_continuous(&num, &den, self.ts, method)
                    .map_err(|e| if several { format!("input {}: {e}", i + 1) } else { e.to_string() })
            })
            .collect()
    }

    pub(super) fn covariance_rows(&self) -> Option<Vec<Vec<f64>>> {
        let n = self.parameters.len();
        self.covariance.as_ref().filter(|c| c.len() == n * n).map(|c| c.chunks(n).map(<[f64]>::to_vec).collect())
    }

    /// The JSON document of `oesweep export --to json` as text, its fields in the order of
    /// [`Doc`] (num, den and dt first).
    pub fn to_json_text(&self) -> String {
        self.to_json_text_with(&[])
    }

    /// [`Self::to_json_text`] with each input's continuous equivalent as a `continuous` object
    /// (`method`, `num`, `den`, `input_delay`, `delay_samples`, `zeros` and `poles` as `[re, im]`
    /// pairs, `gain`, `state_space` with `a` by rows, `b`, `c`, `d`) after the discrete fields;
    /// a list of one such object per input for several inputs. None when `continuous` is empty.
    pub fn to_json_text_with(&self, continuous: &[ContinuousModel]) -> String {
        let continuous = (!continuous.is_empty()).then(|| Each::of(continuous.iter().collect()));
        let doc = Doc { continuous, ..self.doc() };
        serde_json::to_string_pretty(&doc).expect("JSON of numbers") + "\n"
    }

    /// The same document as a value (its map sorts the keys).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::to_value(self.doc()).expect("JSON of numbers")
    }

    fn doc(&self) -> Doc<'_> {
        let (num, den) = self.num_den().into_iter().unzip();
        let each = |f: fn(&InputModel) -> &[f64]| Each::of(self.inputs.iter().map(f).collect());
        Doc {
            model: &self.name,
            num: Each::of(num),
            den: Each::of(den),
            dt: self.ts,
            b: each(|p| &p.b),
            f: each(|p| &p.f),
            delay: Each::of(self.inputs.iter().map(|p| p.delay).collect()),
            k: self.k,
            offset: self.offset,
            input_level: Each::of(self.inputs.iter().map(|p| p.input_level).collect()),
            parameters: &self.parameters,
            covariance: self.covariance_rows(),
            noise_variance: self.noise_variance,
            continuous: None,
        }
    }
}

/// The JSON document of a model (README, `oesweep export`).
#[derive(serde::Serialize)]
struct Doc<'a> {
    model: &'a str,
    num: Each<Vec<f64>>,
    den: Each<Vec<f64>>,
    dt: f64,
    b: Each<&'a [f64]>,
    f: Each<&'a [f64]>,
    delay: Each<u32>,
    k: Option<f64>,
    offset: Option<f64>,
    input_level: Each<f64>,
    parameters: &'a [String],
    covariance: Option<Vec<Vec<f64>>>,
    noise_variance: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    continuous: Option<Each<&'a ContinuousModel>>,
}

/// What [`ModelOut::from_json_text`] reads of a [`Doc`].
#[derive(serde::Deserialize)]
struct DocIn {
    #[serde(default)]
    model: String,
    dt: f64,
    b: Each<Vec<f64>>,
    f: Each<Vec<f64>>,
    delay: Each<u32>,
    #[serde(default)]
    k: Option<f64>,
    #[serde(default)]
    offset: Option<f64>,
    #[serde(default = "no_level")]
    input_level: Each<f64>,
    #[serde(default)]
    parameters: Vec<String>,
    #[serde(default)]
    covariance: Option<Vec<Vec<f64>>>,
    #[serde(default)]
    noise_variance: Option<f64>,
}

fn no_level() -> Each<f64> {
    Each::One(0.0)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn model() -> ModelOut {
        ModelOut {
            name: "OE(2,1) delay 2 at k = 0.5 (test)".into(),
            k: Some(0.5),
            ts: 1e-3,
            inputs: vec![InputModel { b: vec![0.5, -0.25], f: vec![-0.8], delay: 2, input_level: 0.25 }],
            offset: Some(1.5),
            covariance: Some(vec![4.0, 1.0, 0.5, 0.1, 1.0, 3.0, 0.2, 0.0, 0.5, 0.2, 2.0, 0.0, 0.1, 0.0, 0.0, 1.0]),
            parameters: vec!["b1".into(), "b2".into(), "f1".into(), "offset".into()],
            noise_variance: Some(0.01),
        }
    }

    /// Two inputs: OE(2,1) delay 2 and OE(1,2) delay 0, without a covariance.
    pub(crate) fn two_inputs() -> ModelOut {
        ModelOut {
            name: "OE(2,1 d2; 1,2 d0) at k = 0.5 (test)".into(),
            inputs: vec![
                InputModel { b: vec![0.5, -0.25], f: vec![-0.8], delay: 2, input_level: 0.25 },
                InputModel { b: vec![1.5], f: vec![-1.2, 0.5], delay: 0, input_level: -1.0 },
            ],
            covariance: None,
            parameters: ["u1.b1", "u1.b2", "u1.f1", "u2.b1", "u2.f1", "u2.f2"].map(String::from).to_vec(),
            ..model()
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

    /// A several-input document has one entry per input in `num`, `den`, `b`, `f`, `delay`
    /// and `input_level`, and reads back; a list that does not match the inputs is refused.
    #[test]
    fn a_several_input_document_has_one_entry_per_input_and_reads_back() {
        let m = two_inputs();
        let j = m.to_json();
        assert_eq!(j["num"], serde_json::json!([[0.0, 0.0, 0.5, -0.25], [1.5, 0.0, 0.0]]));
        assert_eq!(j["den"], serde_json::json!([[1.0, -0.8, 0.0, 0.0], [1.0, -1.2, 0.5]]));
        assert_eq!(j["b"], serde_json::json!([[0.5, -0.25], [1.5]]));
        assert_eq!(j["delay"], serde_json::json!([2, 0]));
        assert_eq!(j["input_level"], serde_json::json!([0.25, -1.0]));
        assert_eq!(ModelOut::from_json_text(&m.to_json_text()).unwrap(), m);
        let mut bad = j.clone();
        bad["b"] = serde_json::json!([0.5, -0.25]);
        let err = ModelOut::from_json_text(&bad.to_string()).unwrap_err();
        assert!(err.contains("'b' is one input's: a model of 2 inputs"), "{err}");
        let mut bad = j.clone();
        bad["f"] = serde_json::json!([[-0.8], [-1.2, 0.5], [0.1]]);
        assert!(ModelOut::from_json_text(&bad.to_string()).unwrap_err().contains("'f' has 3 entries for 2 inputs"));
        // One level serves every input.
        let mut shared = j;
        shared["input_level"] = serde_json::json!(0.5);
        let back = ModelOut::from_json_text(&shared.to_string()).unwrap();
        assert_eq!([back.inputs[0].input_level, back.inputs[1].input_level], [0.5, 0.5]);
    }

    /// Each input's continuous equivalent is its own filter's; a several-input failure names
    /// the input.
    #[test]
    fn each_input_is_converted_on_its_own() {
        let m = two_inputs();
        let c = m.to_continuous(Method::Tustin).unwrap();
        assert_eq!(c.len(), 2);
        for (part, got) in m.inputs.iter().zip(&c) {
            let (num, den) = part.num_den();
            assert_eq!(got, &continuous::to_continuous(&num, &den, m.ts, Method::Tustin).unwrap());
        }
        let mut neg = m.clone();
        neg.inputs[1].f = vec![0.5];
        let err = neg.to_continuous(Method::Zoh).unwrap_err();
        assert!(err.starts_with("input 2: "), "{err}");
        let text = m.to_json_text_with(&c);
        let back: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back["continuous"].as_array().map(Vec::len), Some(2));
        assert_eq!(back["continuous"][1]["method"], "tustin");
    }

    #[test]
    fn num_and_den_simulate_like_the_model() {
        let m = model();
        let (num, den) = m.inputs[0].num_den();
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
        let want = crate::oe::simulate_vec(&m.inputs[0].b, &m.inputs[0].f, 2, &u);
        for (a, b) in y.iter().zip(&want) {
            assert!((a - b).abs() < 1e-12);
        }
    }
}
