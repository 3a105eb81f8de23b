//! The nonparametric frequency response of a record, `oesweep spectrum` (METHOD.md 11; several
//! inputs: METHOD.md 19, [`spectral::estimate_inputs`]).

use crate::data::{self, ColumnRef, ReadOptions};
use crate::error::{Error, Result};
use crate::job;
use crate::spectral;
use serde::Serializer;
use std::path::PathBuf;

/// A nonparametric frequency response, `oesweep spectrum`.
#[derive(Clone, Debug)]
pub struct SpectrumRequest {
    pub data: PathBuf,
    /// The input columns, one per input.
    pub u: Vec<ColumnRef>,
    pub y: ColumnRef,
    pub rows: Option<[usize; 2]>,
    pub ts: f64,
    pub method: spectral::SpectrumMethod,
}

/// Report of [`spectrum`] (`spectrum --json` prints it): per usable bin (the inputs have power
/// there) the frequency, `G_spec` and the coherence, and an approximate 95 % band of `|G_spec|`
/// ([`spectral::SpectralEstimate::magnitude_band`]). `re`, `im`, `mag_lower` and `mag_upper`
/// hold one list per input (one input's JSON: the list itself); `coherence` is the multiple
/// coherence of several inputs.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SpectrumReport {
    pub data: PathBuf,
    pub n: usize,
    /// The input columns' names (several inputs only in the JSON).
    #[serde(skip_serializing_if = "one")]
    pub u: Vec<String>,
    pub method: spectral::SpectrumMethod,
    /// Output samples the robust method replaced.
    pub replaced: usize,
    pub segment: usize,
    pub segments: usize,
    pub freq_hz: Vec<f64>,
    #[serde(serialize_with = "per_input")]
    pub re: Vec<Vec<f64>>,
    #[serde(serialize_with = "per_input")]
    pub im: Vec<Vec<f64>>,
    pub coherence: Vec<f64>,
    #[serde(serialize_with = "per_input")]
    pub mag_lower: Vec<Vec<f64>>,
    #[serde(serialize_with = "per_input")]
    pub mag_upper: Vec<Vec<f64>>,
}

fn one(names: &[String]) -> bool {
    names.len() <= 1
}

/// One input's list as it is, several inputs' as a list of lists.
fn per_input<S: Serializer>(lists: &[Vec<f64>], s: S) -> std::result::Result<S::Ok, S::Error> {
    match lists {
        [single] => s.collect_seq(single),
        several => s.collect_seq(several),
    }
}

/// The spectral estimate of one record (see [`SpectrumRequest`]).
pub fn spectrum(req: &SpectrumRequest) -> Result<SpectrumReport> {
    job::check_sampling_period(req.ts).map_err(|m| Error::Invalid(format!("--ts {m}")))?;
    if let Some(r) = req.rows {
        data::check_rows(r).map_err(|m| Error::Invalid(format!("--rows {m}")))?;
    }
    let opts = ReadOptions { rows: req.rows, ..ReadOptions::default() };
    let rec = data::read_record_inputs(&req.data, &req.u, &req.y, &opts)?;
    spectrum_of(&rec, req.ts, req.method)
}

/// [`spectrum`] of a record in memory (the Python package's arrays), `ts` checked as `ts`.
pub fn spectrum_arrays(rec: &data::Record, ts: f64, method: spectral::SpectrumMethod) -> Result<SpectrumReport> {
    job::check_sampling_period(ts).map_err(|m| Error::Invalid(format!("ts {m}")))?;
    spectrum_of(rec, ts, method)
}

fn spectrum_of(rec: &data::Record, ts: f64, method: spectral::SpectrumMethod) -> Result<SpectrumReport> {
    let ests = spectral::estimate_inputs(&rec.u, rec.inputs(), &rec.y, &rec.seams, &rec.missing, ts, method)
        .map_err(|e| Error::data(&rec.path, e.to_string()))?;
    let est = &ests[0];
    let bins: Vec<usize> = (0..est.freq_hz.len()).filter(|&k| est.re[k].is_finite()).collect();
    let at = |v: &[f64]| bins.iter().map(|&k| v[k]).collect::<Vec<f64>>();
    let band = |e: &spectral::SpectralEstimate, side: fn((f64, f64)) -> f64| {
        bins.iter().map(|&k| e.magnitude_band(k).map_or(f64::NAN, side)).collect()
    };
    Ok(SpectrumReport {
        data: rec.path.clone(),
        n: rec.len(),
        u: rec.u_names.clone(),
        method,
        replaced: est.replaced,
        segment: est.segment,
        segments: est.segments,
        freq_hz: at(&est.freq_hz),
        re: ests.iter().map(|e| at(&e.re)).collect(),
        im: ests.iter().map(|e| at(&e.im)).collect(),
        coherence: at(&est.coherence),
        mag_lower: ests.iter().map(|e| band(e, |b| b.0)).collect(),
        mag_upper: ests.iter().map(|e| band(e, |b| b.1)).collect(),
    })
}
