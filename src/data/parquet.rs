//! Parquet data files through polars (only the `parquet` feature is enabled, so everything
//! here sticks to the eager `ParquetReader` API).

use std::fs::File;
use std::path::Path;

use polars::prelude::{DataType, ParallelStrategy, ParquetReader, SerReader};

use super::gaps::Markers;
use super::{ColumnRef, Columns, input_error, resolve_columns, row_range, sample};
use crate::error::Result;

fn open(path: &Path) -> Result<ParquetReader<File>> {
    let file = File::open(path).map_err(|e| input_error(path, format!("cannot open file: {e}")))?;
    let len = file.metadata().map_err(|e| input_error(path, format!("cannot open file: {e}")))?.len();
    let mut reader =
        ParquetReader::new(file.try_clone().map_err(|e| input_error(path, format!("cannot open file: {e}")))?);
    check_layout(&mut reader, &file, len).map_err(|m| input_error(path, m))?;
    Ok(reader)
}

/// Most values a column chunk of a Parquet file may declare (and most rows a file may hold):
/// 2^27, a gigabyte per f64 column, far beyond any record oesweep reads or table it writes
/// ([`crate::job::MAX_CELLS`] rows). polars reserves memory for the counts it is given before it
/// decodes a value, and an allocation that fails aborts the process, which no `catch_unwind`
/// stops: a damaged count must be refused before polars sees it.
pub(crate) const MAX_VALUES: u64 = 1 << 27;

/// The one check every Parquet read runs before polars decodes anything: the footer's counts and
/// sizes (rows, values per column chunk, byte ranges) against [`MAX_VALUES`] and the file's
/// length `len`, then every page header of every column chunk (read from `file`) against its
/// chunk. Returns what is wrong, as one line.
pub(crate) fn check_layout(reader: &mut ParquetReader<File>, file: &File, len: u64) -> std::result::Result<(), String> {
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
            // A column without repetition (no lists) holds one value, or null, per row.
            if c.descriptor().descriptor.max_rep_level == 0 && values != group.num_rows() as i64 {
                return Err(corrupt(format!(
                    "{values} values in a column of row group {g} of {} rows",
                    group.num_rows()
                )));
            }
        }
    }
    if rows != meta.num_rows as u64 {
        return Err(corrupt(format!("{} rows but row groups of {rows}", meta.num_rows)));
    }
    for (g, group) in meta.row_groups.iter().enumerate() {
        for c in group.parquet_columns() {
            let name = c.descriptor().path_in_schema.join(".");
            check_pages(file, c.byte_range(), c.num_values() as u64).map_err(|what| {
                format!(
                    "not a readable Parquet file: a page of column '{name}' in row group {g} declares {what} (corrupt file?)"
                )
            })?;
        }
    }
    Ok(())
}

/// Walks the page headers of the column chunk at `range` of `file` (thrift, as polars reads
/// them) and checks each count and size against what the chunk holds: polars 0.55 trusts a data
/// page's `num_values` (a negative one becomes a reservation of 2^61 bytes, which aborts) and
/// reserves a page's uncompressed size before it decompresses. A chunk's pages must hold
/// exactly its `values` values within its bytes; a sound writer never writes anything else.
fn check_pages(file: &File, range: std::ops::Range<u64>, values: u64) -> std::result::Result<(), String> {
    use polars_parquet_format::thrift::protocol::TCompactInputProtocol;
    use polars_parquet_format::{PageHeader, PageType};
    use std::os::unix::fs::FileExt;

    let mut chunk = vec![0u8; (range.end - range.start) as usize];
    file.read_exact_at(&mut chunk, range.start).map_err(|e| format!("bytes it cannot read ({e})"))?;
    let size = |what: &str, n: i32, room: u64| match u64::try_from(n) {
        Ok(n) if n <= room => Ok(n),
        _ => Err(format!("{what} {n} where at most {room} fit")),
    };
    let (mut pos, mut seen) = (0usize, 0u64);
    while seen < values {
        let rest = &chunk[pos..];
        let mut cursor = std::io::Cursor::new(rest);
        let header = PageHeader::read_from_in_protocol(&mut TCompactInputProtocol::new(&mut cursor, rest.len()))
            .map_err(|e| format!("an unreadable header ({e})"))?;
        pos += cursor.position() as usize;
        let left = (chunk.len() - pos) as u64;
        let compressed = size("a compressed size of", header.compressed_page_size, left)?;
        // No page expands past what a whole chunk may hold: MAX_VALUES values of 8 bytes each.
        size("an uncompressed size of", header.uncompressed_page_size, 8 * MAX_VALUES)?;
        let count = match header.type_ {
            PageType::DATA_PAGE => {
                let h = header.data_page_header.as_ref().ok_or("a data page without its header")?;
                size("a value count of", h.num_values, values - seen)?
            }
            PageType::DATA_PAGE_V2 => {
                let h = header.data_page_header_v2.as_ref().ok_or("a data page without its header")?;
                let n = size("a value count of", h.num_values, values - seen)?;
                size("a null count of", h.num_nulls, n)?;
                size("a row count of", h.num_rows, n)?;
                let rep = size("repetition levels of", h.repetition_levels_byte_length, compressed)?;
                size("definition levels of", h.definition_levels_byte_length, compressed - rep)?;
                n
            }
            PageType::DICTIONARY_PAGE => {
                let h = header.dictionary_page_header.as_ref().ok_or("a dictionary page without its header")?;
                // A dictionary holds distinct values of its chunk, never more than the chunk.
                size("a dictionary of", h.num_values, values)?;
                0
            }
            _ => 0,
        };
        seen += count;
        pos += compressed as usize;
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

pub(super) fn read_columns(
    path: &Path,
    cols: &[ColumnRef],
    rows: Option<[usize; 2]>,
    markers: &Markers,
) -> Result<Columns> {
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
            // A null is a missing sample, as NaN is.
            v.push(sample(path, &format!("row {row}"), name, x.unwrap_or(f64::NAN), markers)?);
        }
        values.push(v);
    }
    Ok(Columns { names, values })
}
