//! Parquet data files through polars (only the `parquet` feature is enabled, so everything
//! here sticks to the eager `ParquetReader` API).

use std::fs::File;
use std::path::Path;

use polars::prelude::{DataType, ParallelStrategy, ParquetReader, SerReader};

use super::{ColumnRef, Columns, check_finite, input_error, resolve_columns, row_range};
use crate::error::Result;

fn open(path: &Path) -> Result<ParquetReader<File>> {
    let file = File::open(path).map_err(|e| input_error(path, format!("cannot open file: {e}")))?;
    let len = file.metadata().map_err(|e| input_error(path, format!("cannot open file: {e}")))?.len();
    let mut reader = ParquetReader::new(file);
    check_footer(&mut reader, len).map_err(|m| input_error(path, m))?;
    Ok(reader)
}

/// Most values a column chunk of a Parquet file may declare (and most rows a file may hold):
/// 2^27, a gigabyte per f64 column, far beyond any record oesweep reads or table it writes
/// ([`crate::job::MAX_CELLS`] rows). polars reserves memory for the footer's counts before it
/// decodes a value, and an allocation that fails aborts the process, which no `catch_unwind`
/// stops: a damaged count must be refused before polars sees it.
pub(crate) const MAX_VALUES: u64 = 1 << 27;

/// The counts and sizes of a Parquet file's footer (rows, values per column chunk, byte
/// ranges) checked against [`MAX_VALUES`] and the file's length `len`. Returns what is wrong.
pub(crate) fn check_footer(reader: &mut ParquetReader<File>, len: u64) -> std::result::Result<(), String> {
    let meta = reader.get_metadata().map_err(|e| format!("not a readable Parquet file: {e}"))?;
    let corrupt = |what: String| format!("not a readable Parquet file: its footer declares {what} (corrupt file?)");
    if meta.num_rows as u64 > MAX_VALUES {
        return Err(corrupt(format!("{} rows, more than {MAX_VALUES}", meta.num_rows)));
    }
    let mut rows: u64 = 0;
    for (g, group) in meta.row_groups.iter().enumerate() {
        rows = rows.saturating_add(group.num_rows() as u64);
        for c in group.parquet_columns() {
            let values = c.num_values();
            if !(0..=MAX_VALUES as i64).contains(&values) {
                return Err(corrupt(format!("{values} values in a column of row group {g}")));
            }
            let range = c.byte_range();
            if c.compressed_size() < 0 || range.start > range.end || range.end > len {
                return Err(corrupt(format!("a column of row group {g} beyond the file's {len} bytes")));
            }
        }
    }
    if rows != meta.num_rows as u64 {
        return Err(corrupt(format!("{} rows but row groups of {rows}", meta.num_rows)));
    }
    Ok(())
}

fn schema_names(path: &Path, reader: &mut ParquetReader<File>) -> Result<Vec<String>> {
    let schema = reader.schema().map_err(|e| input_error(path, format!("not a readable Parquet file: {e}")))?;
    Ok(schema.iter_names().map(|n| n.to_string()).collect())
}

pub(super) fn column_names(path: &Path) -> Result<Vec<String>> {
    let mut reader = open(path)?;
    schema_names(path, &mut reader)
}

pub(super) fn read_columns(path: &Path, cols: &[ColumnRef], rows: Option<[usize; 2]>) -> Result<Columns> {
    let mut reader = open(path)?;
    let all = schema_names(path, &mut reader)?;
    let index = resolve_columns(path, cols, &all, all.len())?;
    let names: Vec<String> = index.iter().map(|&i| all[i].clone()).collect();
    // Project onto the requested columns: other columns may have types this build of
    // polars cannot decode, and they are none of our business.
    let mut unique: Vec<String> = Vec::new();
    for n in &names {
        if !unique.contains(n) {
            unique.push(n.clone());
        }
    }
    // On this thread, not polars' pool: a panic of the decoder is then caught by `guarded`
    // on the thread that knows it is reading (two columns gain nothing from a pool anyway).
    let df = reader
        .with_columns(Some(unique))
        .read_parallel(ParallelStrategy::None)
        .finish()
        .map_err(|e| input_error(path, format!("cannot read Parquet data: {e}")))?;
    let range = row_range(path, rows, df.height())?;
    let mut values = Vec::with_capacity(names.len());
    for name in &names {
        let col = df.column(name).map_err(|e| input_error(path, format!("cannot read column '{name}': {e}")))?;
        let dtype = col.dtype();
        if !dtype.is_primitive_numeric() {
            return Err(input_error(path, format!("column '{name}' has type {dtype:?}, expected numbers")));
        }
        let cast = col.cast(&DataType::Float64).map_err(|e| input_error(path, format!("column '{name}': {e}")))?;
        let ca = cast.f64().map_err(|e| input_error(path, format!("column '{name}': {e}")))?;
        // A corrupt page header can make the decoder return fewer values than the file's
        // row count (found by fuzzing), which would pair u and y samples wrongly.
        if ca.len() != df.height() {
            return Err(input_error(
                path,
                format!(
                    "column '{name}' has {} values but the file has {} rows (corrupt file?)",
                    ca.len(),
                    df.height()
                ),
            ));
        }
        let mut v = Vec::with_capacity(range.len());
        for (i, x) in ca.iter().enumerate().skip(range.start).take(range.len()) {
            let row = i + 1;
            match x {
                Some(x) => v.push(check_finite(path, &format!("row {row}"), name, x)?),
                None => {
                    return Err(input_error(path, format!("row {row}, column '{name}': missing value (null)")));
                }
            }
        }
        values.push(v);
    }
    Ok(Columns { names, values })
}
