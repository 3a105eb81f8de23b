//! `oesweep export --to mat`: the model as a MAT-file (level 5, MATLAB 7 format, written by the
//! `matrw` crate). One input's variables are rows and scalars; a several-input model's per-input
//! variables are 1 x m cell arrays (`num`, `den`, `b`, `B`, `F`, and `numc`, `denc`, `zc`, `pc`
//! with `--continuous`) or 1 x m rows (`delay`, `u0`, `kc`, `input_delay`).

use super::continuous::ContinuousModel;
use super::model::ModelOut;
use crate::error::{Error, Result};
use matrw::{CellArray, MatFile, MatVariable, MatlabType, NumericArray};
use std::path::Path;

impl ModelOut {
    /// Write the MAT-file of `oesweep export --to mat`: `num`, `den`, `Ts`, `delay`, `b`, `B`
    /// (with the delay's leading zeros), `F` (with its leading 1), `offset` (NaN: none), `u0`
    /// and `covariance` (empty when not known); per input for several inputs (module docs).
    pub fn write_mat(&self, path: &Path) -> Result<()> {
        self.write_mat_with(path, &[])
    }

    /// [`Self::write_mat`] with each input's continuous equivalent as `numc`, `denc`
    /// (descending powers of s), `zc`, `pc` (zeros and poles in rad/s, one a row: real and
    /// imaginary part), `kc` (gain) and `input_delay` (seconds).
    pub fn write_mat_with(&self, path: &Path, continuous: &[ContinuousModel]) -> Result<()> {
        let bad = |e: matrw::MatrwError| Error::output(path, format!("cannot build a MAT variable: {e}"));
        let array = |dim: Vec<usize>, v: Vec<f64>| -> Result<MatVariable> {
            NumericArray::new(dim, MatlabType::from(v), None).map(MatVariable::NumericArray).map_err(bad)
        };
        let row = |v: &[f64]| array(vec![1, v.len()], v.to_vec());
        let scalar = |v: f64| array(vec![1, 1], vec![v]);
        // One input: the variable itself; several: a 1 x m cell array of them, or a row of scalars.
        let several = self.m() > 1;
        let per_input = |vars: Vec<MatVariable>| -> Result<MatVariable> {
            if several {
                CellArray::new(vec![1, vars.len()], vars).map(MatVariable::CellArray).map_err(bad)
            } else {
                Ok(vars.into_iter().next().expect("one input"))
            }
        };
        let rows = |vs: Vec<Vec<f64>>| -> Result<MatVariable> {
            per_input(vs.iter().map(|v| row(v)).collect::<Result<Vec<_>>>()?)
        };
        let scalars = |v: Vec<f64>| if several { row(&v) } else { scalar(v[0]) };
        let (num, den): (Vec<_>, Vec<_>) = self.num_den().into_iter().unzip();
        let parts = &self.inputs;
        let b_full = parts.iter().map(|p| {
            let mut b = vec![0.0; p.delay as usize];
            b.extend_from_slice(&p.b);
            b
        });
        let f_full = parts.iter().map(|p| std::iter::once(1.0).chain(p.f.iter().copied()).collect());
        let n = self.parameters.len();
        let mut mat = MatFile::new();
        mat.insert("num", rows(num)?);
        mat.insert("den", rows(den)?);
        mat.insert("Ts", scalar(self.ts)?);
        mat.insert("delay", scalars(parts.iter().map(|p| p.delay as f64).collect())?);
        mat.insert("b", rows(parts.iter().map(|p| p.b.clone()).collect())?);
        mat.insert("B", rows(b_full.collect())?);
        mat.insert("F", rows(f_full.collect())?);
        mat.insert("offset", scalar(self.offset.unwrap_or(f64::NAN))?);
        mat.insert("u0", scalars(parts.iter().map(|p| p.input_level).collect())?);
        // Symmetric, so row-major and MATLAB's column-major order agree.
        let cov = match &self.covariance {
            Some(c) if c.len() == n * n => array(vec![n, n], c.clone())?,
            _ => array(vec![0, 0], Vec::new())?,
        };
        mat.insert("covariance", cov);
        if !continuous.is_empty() {
            mat.insert("numc", rows(continuous.iter().map(|c| c.num.clone()).collect())?);
            mat.insert("denc", rows(continuous.iter().map(|c| c.den.clone()).collect())?);
            // Complex numbers as two columns, real and imaginary part: matrw stores each part of
            // a complex array in the smallest type that holds it and then miscounts the bytes.
            let columns = |v: &[(f64, f64)]| {
                let (mut re, im): (Vec<f64>, Vec<f64>) = v.iter().copied().unzip();
                re.extend(im);
                array(vec![v.len(), 2], re)
            };
            mat.insert("zc", per_input(continuous.iter().map(|c| columns(&c.zeros)).collect::<Result<Vec<_>>>()?)?);
            mat.insert("pc", per_input(continuous.iter().map(|c| columns(&c.poles)).collect::<Result<Vec<_>>>()?)?);
            mat.insert("kc", scalars(continuous.iter().map(|c| c.gain).collect())?);
            mat.insert("input_delay", scalars(continuous.iter().map(|c| c.input_delay).collect())?);
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
