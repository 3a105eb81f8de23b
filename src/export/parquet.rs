//! `cells.parquet`: the result table, one [`CellRow`] per row.
//!
//! Columns, in this order, named after the fields of [`CellRow`]:
//!
//! | column | dtype | nulls |
//! |---|---|---|
//! | `method` | String (`"ls"` / `"huber"`) | no |
//! | `nb`, `nf`, `delay` | UInt32 | no |
//! | `k_index` | UInt32 | yes |
//! | `k`, `sigma`, `gamma`, `criterion`, `l1c`, `fit`, `fit_val`, `fit_band` | Float64 | yes |
//! | `iterations` | UInt32 | yes |
//! | `termination` | String | yes |
//! | `converged` | Boolean | no |
//! | `status` | String (`"ok"` / `"failed"`) | no |
//! | `reason` | String | yes |
//! | `max_pole_radius` | Float64 | yes |
//! | `reflections` | UInt32 | yes |
//! | `start` | String | no |
//! | `seconds` | Float64 | no |
//! | `b`, `f` | List(Float64) | no (a failed cell has empty lists) |
//! | `offset` | Float64 | yes (null: the model has no offset) |
//! | `b_std`, `f_std` | List(Float64) | no (empty for a failed cell) |
//! | `offset_std`, `max_rel_std`, `resid_white_p`, `resid_indep_p` | Float64 | yes |
//!
//! The columns from `offset` on are optional on reading (null or empty when absent): tables of
//! older versions lack them.
//!
//! Compression is zstd (polars' default). The file is written atomically (see [`crate::export`]),
//! so a sweep can rewrite it as a checkpoint while a reader looks at the previous version.
//! Floats roundtrip bit-exactly; reading checks every column's presence and dtype, so a file
//! from another tool or an older layout fails with a message naming the column. Extra columns
//! are ignored. A panic of the Parquet decoder on a damaged file becomes an input error too;
//! what cannot be caught is an allocation failure: polars 0.55.2 may try to allocate an absurd
//! size when a *data page header* is damaged, which aborts the process.

use crate::error::{Error, Result};
use crate::table::{CellRow, Method};
use polars::prelude::*;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Write rows to `path` atomically: write `<path>.tmp-<pid>` in the same folder, fsync, rename.
pub fn write_cells(path: &Path, rows: &[CellRow]) -> Result<()> {
    let mut df = to_frame(rows).map_err(|e| Error::output(path, format!("cannot build the table: {e}")))?;
    super::write_atomically(path, |file| {
        let mut w = BufWriter::new(file);
        ParquetWriter::new(&mut w)
            .with_compression(ParquetCompression::Zstd(None))
            .finish(&mut df)
            .map_err(|e| format!("cannot write Parquet: {e}"))?;
        w.flush().map_err(|e| format!("cannot write Parquet: {e}"))
    })
}

/// Read a table written by [`write_cells`] (any row order): exact roundtrip of every field
/// (f64 bit-exact, `None` <-> null). Fails with [`Error::Input`] naming the file, and the column
/// when one is missing, has the wrong dtype, or holds a null where the row type has no `Option`.
pub fn read_cells(path: &Path) -> Result<Vec<CellRow>> {
    let file = File::open(path).map_err(|e| Error::input(path, format!("cannot open: {e}")))?;
    // The Parquet decoder trusts the file's metadata and can panic on a corrupt file; a bad file
    // must be an input error, not a crash of the sweep or the report.
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| from_frame(&read_frame(file)?)));
    match read {
        Ok(result) => result.map_err(|msg| Error::input(path, msg)),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown failure".into());
            Err(Error::input(path, format!("not a readable Parquet file: the reader failed ({what})")))
        }
    }
}

/// Read our columns only: the names are checked against the file's schema first so a missing
/// one is named, and extra columns (possibly of types this build cannot decode) are skipped.
fn read_frame(file: File) -> std::result::Result<DataFrame, String> {
    let unreadable = |e: PolarsError| format!("not a readable Parquet file: {e}");
    let mut reader = ParquetReader::new(file);
    let schema = reader.schema().map_err(unreadable)?;
    if let Some((name, _)) = COLUMNS.iter().find(|(name, _)| !schema.contains(name)) {
        return Err(format!("missing column `{name}` (not a table written by oesweep)"));
    }
    let names = COLUMNS
        .iter()
        .chain(OPTIONAL.iter().filter(|(name, _)| schema.contains(name)))
        .map(|(name, _)| name.to_string())
        .collect();
    reader.with_columns(Some(names)).finish().map_err(unreadable)
}

/// Column names in table order; the single source for writing and for the schema check.
const COLUMNS: [(&str, Kind); 24] = [
    ("method", Kind::Str),
    ("nb", Kind::U32),
    ("nf", Kind::U32),
    ("delay", Kind::U32),
    ("k_index", Kind::U32),
    ("k", Kind::F64),
    ("sigma", Kind::F64),
    ("gamma", Kind::F64),
    ("criterion", Kind::F64),
    ("l1c", Kind::F64),
    ("fit", Kind::F64),
    ("fit_val", Kind::F64),
    ("fit_band", Kind::F64),
    ("iterations", Kind::U32),
    ("termination", Kind::Str),
    ("converged", Kind::Bool),
    ("status", Kind::Str),
    ("reason", Kind::Str),
    ("max_pole_radius", Kind::F64),
    ("reflections", Kind::U32),
    ("start", Kind::Str),
    ("seconds", Kind::F64),
    ("b", Kind::ListF64),
    ("f", Kind::ListF64),
];

/// Columns written after [`COLUMNS`] that tables of older versions lack: null when absent.
const OPTIONAL: [(&str, Kind); 7] = [
    ("offset", Kind::F64),
    ("b_std", Kind::ListF64),
    ("f_std", Kind::ListF64),
    ("offset_std", Kind::F64),
    ("max_rel_std", Kind::F64),
    ("resid_white_p", Kind::F64),
    ("resid_indep_p", Kind::F64),
];

#[derive(Clone, Copy)]
enum Kind {
    Str,
    U32,
    F64,
    Bool,
    ListF64,
}

impl Kind {
    fn dtype(self) -> DataType {
        match self {
            Kind::Str => DataType::String,
            Kind::U32 => DataType::UInt32,
            Kind::F64 => DataType::Float64,
            Kind::Bool => DataType::Boolean,
            Kind::ListF64 => DataType::List(Box::new(DataType::Float64)),
        }
    }
}

fn list_column(name: &str, rows: &[CellRow], get: impl Fn(&CellRow) -> &[f64]) -> Column {
    let values: usize = rows.iter().map(|r| get(r).len()).sum();
    let mut builder =
        ListPrimitiveChunkedBuilder::<Float64Type>::new(name.into(), rows.len(), values, DataType::Float64);
    for r in rows {
        builder.append_slice(get(r));
    }
    builder.finish().into_column()
}

fn to_frame(rows: &[CellRow]) -> PolarsResult<DataFrame> {
    // One closure per column keeps the order next to COLUMNS; checked against it below.
    fn col<'a, T>(name: &str, rows: &'a [CellRow], get: impl Fn(&'a CellRow) -> T) -> Column
    where
        Series: NamedFrom<Vec<T>, [T]>,
    {
        Column::new(name.into(), rows.iter().map(get).collect::<Vec<T>>())
    }
    let columns = vec![
        col("method", rows, |r| r.method.as_str()),
        col("nb", rows, |r| r.nb),
        col("nf", rows, |r| r.nf),
        col("delay", rows, |r| r.delay),
        col("k_index", rows, |r| r.k_index),
        col("k", rows, |r| r.k),
        col("sigma", rows, |r| r.sigma),
        col("gamma", rows, |r| r.gamma),
        col("criterion", rows, |r| r.criterion),
        col("l1c", rows, |r| r.l1c),
        col("fit", rows, |r| r.fit),
        col("fit_val", rows, |r| r.fit_val),
        col("fit_band", rows, |r| r.fit_band),
        col("iterations", rows, |r| r.iterations),
        col("termination", rows, |r| r.termination.as_deref()),
        col("converged", rows, |r| r.converged),
        col("status", rows, |r| r.status.as_str()),
        col("reason", rows, |r| r.reason.as_deref()),
        col("max_pole_radius", rows, |r| r.max_pole_radius),
        col("reflections", rows, |r| r.reflections),
        col("start", rows, |r| r.start.as_str()),
        col("seconds", rows, |r| r.seconds),
        list_column("b", rows, |r| &r.b),
        list_column("f", rows, |r| &r.f),
        col("offset", rows, |r| r.offset),
        list_column("b_std", rows, |r| &r.b_std),
        list_column("f_std", rows, |r| &r.f_std),
        col("offset_std", rows, |r| r.offset_std),
        col("max_rel_std", rows, |r| r.max_rel_std),
        col("resid_white_p", rows, |r| r.resid_white_p),
        col("resid_indep_p", rows, |r| r.resid_indep_p),
    ];
    debug_assert!(
        columns
            .iter()
            .zip(COLUMNS.iter().chain(&OPTIONAL))
            .all(|(c, &(name, kind))| c.name().as_str() == name && *c.dtype() == kind.dtype())
            && columns.len() == COLUMNS.len() + OPTIONAL.len()
    );
    DataFrame::new(rows.len(), columns)
}

/// Look up a column by name and check its dtype. Errors name the column.
fn column<'a>(df: &'a DataFrame, name: &str, kind: Kind) -> std::result::Result<&'a Column, String> {
    let c = df.column(name).map_err(|_| format!("missing column `{name}`"))?;
    let expected = kind.dtype();
    if *c.dtype() != expected {
        return Err(format!("column `{name}` has type {}, expected {expected}", c.dtype()));
    }
    // A corrupt file can decode into columns of different lengths; indexing them would panic.
    if c.len() != df.height() {
        return Err(format!("column `{name}` has {} values for {} rows (corrupt file)", c.len(), df.height()));
    }
    Ok(c)
}

fn dtype_err(name: &str, e: PolarsError) -> String {
    format!("column `{name}`: {e}")
}

/// The decoded values of a column must match the frame's height (see [`column`]).
fn checked<T>(df: &DataFrame, name: &str, values: Vec<T>) -> std::result::Result<Vec<T>, String> {
    if values.len() == df.height() {
        Ok(values)
    } else {
        Err(format!("column `{name}` has {} values for {} rows (corrupt file)", values.len(), df.height()))
    }
}

fn opt_f64(df: &DataFrame, name: &str) -> std::result::Result<Vec<Option<f64>>, String> {
    checked(df, name, column(df, name, Kind::F64)?.f64().map_err(|e| dtype_err(name, e))?.iter().collect())
}

fn opt_u32(df: &DataFrame, name: &str) -> std::result::Result<Vec<Option<u32>>, String> {
    checked(df, name, column(df, name, Kind::U32)?.u32().map_err(|e| dtype_err(name, e))?.iter().collect())
}

fn opt_str(df: &DataFrame, name: &str) -> std::result::Result<Vec<Option<String>>, String> {
    let values = column(df, name, Kind::Str)?.str().map_err(|e| dtype_err(name, e))?;
    checked(df, name, values.iter().map(|s| s.map(str::to_string)).collect())
}

fn opt_bool(df: &DataFrame, name: &str) -> std::result::Result<Vec<Option<bool>>, String> {
    checked(df, name, column(df, name, Kind::Bool)?.bool().map_err(|e| dtype_err(name, e))?.iter().collect())
}

fn opt_list(df: &DataFrame, name: &str) -> std::result::Result<Vec<Option<Vec<f64>>>, String> {
    let lists = column(df, name, Kind::ListF64)?.list().map_err(|e| dtype_err(name, e))?;
    let values = lists
        .series_iter()
        .enumerate()
        .map(|(i, s)| {
            s.map(|s| {
                let values = s.f64().map_err(|e| dtype_err(name, e))?;
                values
                    .iter()
                    .collect::<Option<Vec<f64>>>()
                    .ok_or_else(|| format!("column `{name}`, row {i}: null inside the list"))
            })
            .transpose()
        })
        .collect::<std::result::Result<Vec<_>, String>>()?;
    checked(df, name, values)
}

/// A value the row type requires (no `Option`): a null is a malformed file.
fn required<T>(name: &str, i: usize, v: Option<T>) -> std::result::Result<T, String> {
    v.ok_or_else(|| format!("column `{name}`, row {i}: null in a column that must not have nulls"))
}

fn from_frame(df: &DataFrame) -> std::result::Result<Vec<CellRow>, String> {
    // Check the whole schema first so the message names the first missing column in table order.
    for &(name, kind) in &COLUMNS {
        column(df, name, kind)?;
    }
    let method = opt_str(df, "method")?;
    let nb = opt_u32(df, "nb")?;
    let nf = opt_u32(df, "nf")?;
    let delay = opt_u32(df, "delay")?;
    let k_index = opt_u32(df, "k_index")?;
    let k = opt_f64(df, "k")?;
    let sigma = opt_f64(df, "sigma")?;
    let gamma = opt_f64(df, "gamma")?;
    let criterion = opt_f64(df, "criterion")?;
    let l1c = opt_f64(df, "l1c")?;
    let fit = opt_f64(df, "fit")?;
    let fit_val = opt_f64(df, "fit_val")?;
    let fit_band = opt_f64(df, "fit_band")?;
    let iterations = opt_u32(df, "iterations")?;
    let mut termination = opt_str(df, "termination")?;
    let converged = opt_bool(df, "converged")?;
    let mut status = opt_str(df, "status")?;
    let mut reason = opt_str(df, "reason")?;
    let max_pole_radius = opt_f64(df, "max_pole_radius")?;
    let reflections = opt_u32(df, "reflections")?;
    let mut start = opt_str(df, "start")?;
    let seconds = opt_f64(df, "seconds")?;
    let mut b = opt_list(df, "b")?;
    let mut f = opt_list(df, "f")?;
    // Optional columns: absent in tables of older versions.
    let optional_f64 = |name: &str| -> std::result::Result<Vec<Option<f64>>, String> {
        if df.column(name).is_ok() {
            column(df, name, Kind::F64)?;
            opt_f64(df, name)
        } else {
            Ok(vec![None; df.height()])
        }
    };
    let optional_list = |name: &str| -> std::result::Result<Vec<Option<Vec<f64>>>, String> {
        if df.column(name).is_ok() {
            column(df, name, Kind::ListF64)?;
            opt_list(df, name)
        } else {
            Ok(vec![Some(Vec::new()); df.height()])
        }
    };
    let offset = optional_f64("offset")?;
    let mut b_std = optional_list("b_std")?;
    let mut f_std = optional_list("f_std")?;
    let offset_std = optional_f64("offset_std")?;
    let max_rel_std = optional_f64("max_rel_std")?;
    let resid_white_p = optional_f64("resid_white_p")?;
    let resid_indep_p = optional_f64("resid_indep_p")?;

    (0..df.height())
        .map(|i| {
            let method = match required("method", i, method[i].as_deref())? {
                "ls" => Method::Ls,
                "huber" => Method::Huber,
                other => return Err(format!("column `method`, row {i}: unknown method {other:?}")),
            };
            Ok(CellRow {
                method,
                nb: required("nb", i, nb[i])?,
                nf: required("nf", i, nf[i])?,
                delay: required("delay", i, delay[i])?,
                k_index: k_index[i],
                k: k[i],
                sigma: sigma[i],
                gamma: gamma[i],
                criterion: criterion[i],
                l1c: l1c[i],
                fit: fit[i],
                fit_val: fit_val[i],
                fit_band: fit_band[i],
                iterations: iterations[i],
                termination: termination[i].take(),
                converged: required("converged", i, converged[i])?,
                status: required("status", i, status[i].take())?,
                reason: reason[i].take(),
                max_pole_radius: max_pole_radius[i],
                reflections: reflections[i],
                start: required("start", i, start[i].take())?,
                seconds: required("seconds", i, seconds[i])?,
                b: required("b", i, b[i].take())?,
                f: required("f", i, f[i].take())?,
                offset: offset[i],
                b_std: b_std[i].take().unwrap_or_default(),
                f_std: f_std[i].take().unwrap_or_default(),
                offset_std: offset_std[i],
                max_rel_std: max_rel_std[i],
                resid_white_p: resid_white_p[i],
                resid_indep_p: resid_indep_p[i],
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(nf: u32) -> CellRow {
        CellRow::failed(Method::Huber, 3, nf as usize, 1, Some((0, 0.1)), "x".into())
    }

    #[test]
    fn export_parquet_empty_table_roundtrips() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.parquet");
        write_cells(&path, &[]).unwrap();
        assert!(read_cells(&path).unwrap().is_empty());
    }

    #[test]
    fn export_parquet_wrong_dtype_names_column() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.parquet");
        let mut df = to_frame(&[row(2)]).unwrap();
        df.replace("nf", Column::new("nf".into(), vec![2.0f64])).unwrap();
        ParquetWriter::new(File::create(&path).unwrap()).finish(&mut df).unwrap();
        let err = read_cells(&path).unwrap_err().to_string();
        assert!(err.contains("`nf`") && err.contains("c.parquet"), "{err}");
    }

    #[test]
    fn export_parquet_null_in_required_column_names_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.parquet");
        let mut df = to_frame(&[row(2)]).unwrap();
        df.replace("start", Column::new("start".into(), vec![None::<&str>])).unwrap();
        ParquetWriter::new(File::create(&path).unwrap()).finish(&mut df).unwrap();
        let err = read_cells(&path).unwrap_err().to_string();
        assert!(err.contains("`start`") && err.contains("row 0"), "{err}");
    }

    #[test]
    fn export_parquet_unknown_method_is_rejected() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.parquet");
        let mut df = to_frame(&[row(2)]).unwrap();
        df.replace("method", Column::new("method".into(), vec!["arx"])).unwrap();
        ParquetWriter::new(File::create(&path).unwrap()).finish(&mut df).unwrap();
        let err = read_cells(&path).unwrap_err().to_string();
        assert!(err.contains("`method`") && err.contains("arx"), "{err}");
    }
}
