//! MATLAB MAT-files, level 5 (what `save` writes with `-v6` and `-v7`, the default; also
//! Octave's `save -v7` and scipy's `savemat`), through the `matfile` crate. Columns are
//! numeric vector variables chosen by name; a `-v7.3` file is HDF5, which that crate does not
//! read, so it is refused with the command that re-saves it.

use std::path::Path;

use matfile::{MatFile, NumericData};

use super::gaps::Markers;
use super::{ColumnRef, Columns, guarded, input_error, list_columns, row_range, sample};
use crate::error::Result;

/// The HDF5 signature, at byte 512 of a v7.3 MAT-file (after its 512-byte user block).
const HDF5_SIGNATURE: &[u8] = b"\x89HDF\r\n\x1a\n";

fn open(path: &Path) -> Result<MatFile> {
    let bytes = std::fs::read(path).map_err(|e| input_error(path, format!("cannot open file: {e}")))?;
    if bytes.get(512..520) == Some(HDF5_SIGNATURE) || bytes.starts_with(b"MATLAB 7.3 MAT-file") {
        return Err(input_error(
            path,
            "a MATLAB v7.3 (HDF5) MAT-file, which oesweep cannot read: re-save it as a level-5 file, \
             in MATLAB with save('file.mat', 'u', 'y', '-v7'), in Octave with save -v7 file.mat u y",
        ));
    }
    guarded(path, "MAT", || {
        MatFile::parse(&bytes[..]).map_err(|e| {
            input_error(
                path,
                format!(
                    "not a readable MATLAB level-5 MAT-file ({e}); v4 files cannot be read either: re-save with -v7"
                ),
            )
        })
    })
}

pub(super) fn column_names(path: &Path) -> Result<Vec<String>> {
    Ok(open(path)?.arrays().iter().map(|a| a.name().to_string()).collect())
}

pub(super) fn read_columns(
    path: &Path,
    cols: &[ColumnRef],
    rows: Option<[usize; 2]>,
    markers: &Markers,
) -> Result<Columns> {
    let file = open(path)?;
    let mut names = Vec::with_capacity(cols.len());
    let mut values: Vec<Vec<f64>> = Vec::with_capacity(cols.len());
    let mut length: Option<(String, usize)> = None;
    for c in cols {
        let name = match c {
            ColumnRef::Name(n) => n,
            ColumnRef::Position(p) => {
                return Err(input_error(
                    path,
                    format!("column position {p}: the variables of a MAT-file are chosen by name"),
                ));
            }
        };
        let Some(array) = file.find_by_name(name) else {
            let all: Vec<&str> = file.arrays().iter().map(|a| a.name()).collect();
            return Err(input_error(
                path,
                format!(
                    "no numeric variable '{name}' (numeric variables: {}; text, cell, struct and sparse \
                     variables cannot be read)",
                    if all.is_empty() { "none".to_string() } else { list_columns(&all) }
                ),
            ));
        };
        let size = array.size();
        let n: usize = size.iter().product();
        if size.iter().filter(|&&d| d > 1).count() > 1 {
            let shape = size.iter().map(|d| d.to_string()).collect::<Vec<_>>().join("x");
            return Err(input_error(
                path,
                format!("variable '{name}' is a {shape} matrix: give a vector (1xN or Nx1) per signal"),
            ));
        }
        let all = real_values(array.data())
            .ok_or_else(|| input_error(path, format!("variable '{name}' is complex: give real signals")))?;
        debug_assert_eq!(all.len(), n);
        match &length {
            Some((first, len)) if *len != n => {
                return Err(input_error(
                    path,
                    format!("variables '{first}' ({len} samples) and '{name}' ({n} samples) differ in length"),
                ));
            }
            _ => length = Some((name.clone(), n)),
        }
        let range = row_range(path, rows, n)?;
        let mut v = Vec::with_capacity(range.len());
        for i in range {
            v.push(sample(path, &format!("row {}", i + 1), name, all[i], markers)?);
        }
        names.push(name.clone());
        values.push(v);
    }
    Ok(Columns { names, values })
}

/// The values as f64 (None when the variable has an imaginary part).
fn real_values(data: &NumericData) -> Option<Vec<f64>> {
    fn conv<T: Copy + Into<f64>>(real: &[T], imag: &Option<Vec<T>>) -> Option<Vec<f64>> {
        imag.is_none().then(|| real.iter().map(|&x| x.into()).collect())
    }
    match data {
        NumericData::Int8 { real, imag } => conv(real, imag),
        NumericData::UInt8 { real, imag } => conv(real, imag),
        NumericData::Int16 { real, imag } => conv(real, imag),
        NumericData::UInt16 { real, imag } => conv(real, imag),
        NumericData::Int32 { real, imag } => conv(real, imag),
        NumericData::UInt32 { real, imag } => conv(real, imag),
        // 64-bit integers above 2^53 lose their last digits, as in MATLAB's double().
        NumericData::Int64 { real, imag } => imag.is_none().then(|| real.iter().map(|&x| x as f64).collect()),
        NumericData::UInt64 { real, imag } => imag.is_none().then(|| real.iter().map(|&x| x as f64).collect()),
        NumericData::Single { real, imag } => conv(real, imag),
        NumericData::Double { real, imag } => conv(real, imag),
    }
}
