//! `cells.parquet`: the result table, one [`CellRow`] per row.
//!
//! The columns, their order, types and nulls are [`crate::table::COLUMNS`] (docs/JOBS.md "Columns
//! of cells.parquet"); this module only maps that list onto polars. Columns marked optional
//! there are absent from tables of older versions and read as null (or an empty list).
//!
//! Compression is zstd (polars' default). The file is written atomically (see [`crate::export`]),
//! so a sweep can rewrite it as a checkpoint while a reader looks at the previous version.
//! Floats roundtrip bit-exactly; reading checks every column's presence and dtype, so a file
//! from another tool or an older layout fails with a message naming the column. Extra columns
//! are ignored. The footer and every page header are checked before polars decodes anything
//! ([`crate::data::parquet::check_layout`]: polars 0.55.2 trusts their counts, and an absurd
//! allocation aborts the process); a panic of the decoder on a damaged file becomes an input
//! error too.

use crate::error::{Error, Result};
use crate::table::{CellRow, ColumnType, FitKind, RowKey, TableColumn, Value, inputs_of_names, layout};
use polars::prelude::*;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Write rows to `path` atomically: write `<path>.tmp-<pid>` in the same folder, fsync, rename.
pub fn write_cells(path: &Path, rows: &[CellRow]) -> Result<()> {
    stage_cells(path, rows)?.commit()
}

/// [`write_cells`] up to the rename ([`super::stage`]).
pub(crate) fn stage_cells(path: &Path, rows: &[CellRow]) -> Result<super::Staged> {
    let mut df = to_frame(rows).map_err(|e| Error::output(path, format!("cannot build the table: {e}")))?;
    super::stage(path, |file| {
        let mut w = BufWriter::new(file);
        let version = vec![(super::FORMAT_KEY.to_string(), super::FORMAT_VERSION.to_string())];
        ParquetWriter::new(&mut w)
            .with_compression(ParquetCompression::Zstd(None))
            .with_key_value_metadata(Some(KeyValueMetadata::from_static(version)))
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
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let (df, m) = read_frame(file)?;
        from_frame(&df, m)
    }));
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
/// Returns the frame and the table's number of inputs (`nb` or `nb_1 ..`, [`inputs_of_names`]).
fn read_frame(file: File) -> std::result::Result<(DataFrame, usize), String> {
    let unreadable = |e: PolarsError| format!("not a readable Parquet file: {e}");
    let len = file.metadata().map_err(|e| format!("cannot read: {e}"))?.len();
    let mut reader = ParquetReader::new(file.try_clone().map_err(|e| format!("cannot read: {e}"))?);
    crate::data::parquet::check_layout(&mut reader, &file, len)?;
    let meta = reader.get_metadata().map_err(unreadable)?;
    let declared = meta.key_value_metadata().iter().flatten().find(|kv| kv.key == super::FORMAT_KEY);
    super::check_format(declared.map(|kv| kv.value.as_deref().unwrap_or(""))).map_err(|m| format!("metadata: {m}"))?;
    let schema = reader.schema().map_err(unreadable)?;
    let m = inputs_of_names(|n| schema.contains(n))?;
    let columns = layout(m);
    if let Some(c) = columns.iter().find(|c| !c.optional() && !schema.contains(&c.name)) {
        return Err(format!("missing column `{}` (not a table written by oesweep)", c.name));
    }
    let names = columns.iter().filter(|c| schema.contains(&c.name)).map(|c| c.name.clone()).collect();
    Ok((reader.with_columns(Some(names)).finish().map_err(unreadable)?, m))
}

fn dtype(ty: ColumnType) -> DataType {
    match ty {
        ColumnType::Str => DataType::String,
        ColumnType::U32 => DataType::UInt32,
        ColumnType::F64 => DataType::Float64,
        ColumnType::Bool => DataType::Boolean,
        ColumnType::ListF64 => DataType::List(Box::new(DataType::Float64)),
        ColumnType::ListListF64 => DataType::List(Box::new(DataType::List(Box::new(DataType::Float64)))),
    }
}

/// A list column of `Float64` lists.
fn float_lists(name: PlSmallStr, lists: &[Option<Vec<f64>>]) -> ListChunked {
    let len: usize = lists.iter().flatten().map(Vec::len).sum();
    let mut builder = ListPrimitiveChunkedBuilder::<Float64Type>::new(name, lists.len(), len, DataType::Float64);
    for l in lists {
        match l {
            Some(l) => builder.append_slice(l),
            None => builder.append_null(),
        }
    }
    builder.finish()
}

/// One column of the frame from the rows' values.
fn to_column(c: &TableColumn, rows: &[CellRow]) -> PolarsResult<Column> {
    let name: PlSmallStr = c.name.as_str().into();
    let values = rows.iter().map(|r| c.get(r));
    Ok(match c.ty {
        ColumnType::Str => {
            Column::new(name, values.map(|v| if let Value::Str(x) = v { x } else { None }).collect::<Vec<_>>())
        }
        ColumnType::U32 => {
            Column::new(name, values.map(|v| if let Value::U32(x) = v { x } else { None }).collect::<Vec<_>>())
        }
        ColumnType::F64 => {
            Column::new(name, values.map(|v| if let Value::F64(x) = v { x } else { None }).collect::<Vec<_>>())
        }
        ColumnType::Bool => {
            Column::new(name, values.map(|v| if let Value::Bool(x) = v { x } else { None }).collect::<Vec<_>>())
        }
        ColumnType::ListF64 => {
            let lists: Vec<Option<Vec<f64>>> =
                values.map(|v| if let Value::ListF64(x) = v { x } else { None }).collect();
            float_lists(name, &lists).into_column()
        }
        ColumnType::ListListF64 => {
            let inner = DataType::List(Box::new(DataType::Float64));
            let mut builder = polars::chunked_array::builder::get_list_builder(&inner, rows.len(), rows.len(), name);
            for v in values {
                match v {
                    Value::ListListF64(Some(lists)) => {
                        let lists: Vec<Option<Vec<f64>>> = lists.into_iter().map(Some).collect();
                        builder.append_series(&float_lists(PlSmallStr::EMPTY, &lists).into_series())?
                    }
                    _ => builder.append_null(),
                }
            }
            builder.finish().into_column()
        }
    })
}

/// The frame of rows of one number of inputs (none: one input's layout).
fn to_frame(rows: &[CellRow]) -> PolarsResult<DataFrame> {
    let m = rows.first().map_or(1, |r| r.key.m());
    if let Some(r) = rows.iter().find(|r| r.key.m() != m) {
        polars_bail!(ComputeError: "rows of {m} and of {} inputs in one table ({})", r.key.m(), r.key);
    }
    let columns = layout(m).iter().map(|c| to_column(c, rows)).collect::<PolarsResult<Vec<_>>>()?;
    DataFrame::new(rows.len(), columns)
}

/// Look up a column by name and check its dtype. Errors name the column.
fn column<'a>(df: &'a DataFrame, c: &TableColumn) -> std::result::Result<&'a Column, String> {
    let name = c.name.as_str();
    let col = df.column(name).map_err(|_| format!("missing column `{name}`"))?;
    let expected = dtype(c.ty);
    if *col.dtype() != expected {
        return Err(format!("column `{name}` has type {}, expected {expected}", col.dtype()));
    }
    // A corrupt file can decode into columns of different lengths; indexing them would panic.
    if col.len() != df.height() {
        return Err(format!("column `{name}` has {} values for {} rows (corrupt file)", col.len(), df.height()));
    }
    Ok(col)
}

/// The values of a column, one per row (checked: the decoded values must match the frame's
/// height, see [`column`]).
fn values(df: &DataFrame, c: &TableColumn) -> std::result::Result<Vec<Value>, String> {
    let name = c.name.as_str();
    let col = column(df, c)?;
    let dtype_err = |e: PolarsError| format!("column `{name}`: {e}");
    let values: Vec<Value> = match c.ty {
        ColumnType::Str => col.str().map_err(dtype_err)?.iter().map(|s| Value::Str(s.map(str::to_string))).collect(),
        ColumnType::U32 => col.u32().map_err(dtype_err)?.iter().map(Value::U32).collect(),
        ColumnType::F64 => col.f64().map_err(dtype_err)?.iter().map(Value::F64).collect(),
        ColumnType::Bool => col.bool().map_err(dtype_err)?.iter().map(Value::Bool).collect(),
        ColumnType::ListF64 => col
            .list()
            .map_err(dtype_err)?
            .series_iter()
            .enumerate()
            .map(|(i, s)| s.map(|s| floats(&s, name, i)).transpose().map(Value::ListF64))
            .collect::<std::result::Result<_, String>>()?,
        ColumnType::ListListF64 => col
            .list()
            .map_err(dtype_err)?
            .series_iter()
            .enumerate()
            .map(|(i, s)| {
                s.map(|s| {
                    s.list()
                        .map_err(dtype_err)?
                        .series_iter()
                        .map(|l| {
                            let l = l.ok_or_else(|| format!("column `{name}`, row {i}: null inside the list"))?;
                            floats(&l, name, i)
                        })
                        .collect::<std::result::Result<Vec<_>, String>>()
                })
                .transpose()
                .map(Value::ListListF64)
            })
            .collect::<std::result::Result<_, String>>()?,
    };
    if values.len() != df.height() {
        return Err(format!("column `{name}` has {} values for {} rows (corrupt file)", values.len(), df.height()));
    }
    Ok(values)
}

/// The values of one list of Float64 (row `i` of column `name`), without nulls.
fn floats(s: &Series, name: &str, i: usize) -> std::result::Result<Vec<f64>, String> {
    s.f64()
        .map_err(|e| format!("column `{name}`: {e}"))?
        .iter()
        .collect::<Option<Vec<f64>>>()
        .ok_or_else(|| format!("column `{name}`, row {i}: null inside the list"))
}

fn from_frame(df: &DataFrame, m: usize) -> std::result::Result<Vec<CellRow>, String> {
    let columns = layout(m);
    let present: Vec<&TableColumn> =
        columns.iter().filter(|c| !c.optional() || df.column(c.name.as_str()).is_ok()).collect();
    // Check the whole schema first so the message names the first missing column in table order.
    for c in &present {
        column(df, c)?;
    }
    let mut rows = vec![CellRow::empty(RowKey::blank(FitKind::Huber, m)); df.height()];
    for c in present {
        for (i, v) in values(df, c)?.into_iter().enumerate() {
            c.set(&mut rows[i], v).map_err(|e| format!("{e} (row {i})"))?;
        }
    }
    if let Some((i, why)) = rows.iter().enumerate().find_map(|(i, r)| r.shape_error().map(|w| (i, w))) {
        return Err(format!("row {i} ({}): {why}", rows[i].key));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(nf: u32) -> CellRow {
        CellRow::failed(RowKey::siso(FitKind::Huber, 3, nf, 1, Some(0)), Some(0.1), "x".into())
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
