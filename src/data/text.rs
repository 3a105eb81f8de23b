//! Delimited text files through the `csv` crate.
//!
//! Liberal in the layout, strict about the numbers:
//! - the separator is `data.delimiter` or sniffed from the first 20 non-blank lines: a tab, `;`
//!   or `,` that every one of them contains (in that order of preference, so `;` wins over the
//!   decimal commas of a `;`-separated file), else runs of whitespace when the lines have
//!   several whitespace-separated fields (the DaISy layout), else `,`;
//! - RFC 4180 quoting (`"uEst","uVal"`), whitespace around fields, a byte-order mark, CRLF;
//! - a header row, or none: with `header: "auto"` a first line whose fields all parse as
//!   numbers is data;
//! - the width of the file is the header's (or, without one, the first row's) number of fields
//!   without trailing empty ones, so a delimiter at the end of every line (or only of the data
//!   lines) is an empty last column, which is never selected and ignored like any other column
//!   that is not selected (empty, text or with missing values);
//! - blank lines at the end are ignored; a blank line between data lines is an error (it
//!   would silently shift the row numbers that row ranges refer to), and so is a line with
//!   fewer fields than the width or with non-empty fields beyond it;
//! - a selected field that is empty, `NaN` (any case) or one of the record's markers is a
//!   missing sample, read as NaN ([`super::gaps`]); without a header, a first line that ends in
//!   empty fields (its last samples missing) still counts them as columns.

use std::borrow::Cow;
use std::path::Path;

use super::gaps::Markers;
use super::{ColumnRef, Columns, Delimiter, Header, ReadOptions, input_error, resolve_columns, row_range, sample};
use crate::error::Result;

/// Lines looked at to sniff the delimiter.
const SNIFF_LINES: usize = 20;

pub(super) fn column_names(path: &Path, opts: &ReadOptions) -> Result<Vec<String>> {
    let text = read_text(path)?;
    let table = Table::open(path, &text, opts)?;
    Ok(table.header.map(|h| h.names).unwrap_or_default())
}

pub(super) fn read_columns(path: &Path, cols: &[ColumnRef], opts: &ReadOptions) -> Result<Columns> {
    let text = read_text(path)?;
    let table = Table::open(path, &text, opts)?;
    let (names, width) = match &table.header {
        Some(h) => (h.names.clone(), h.width),
        None => {
            if let Some(ColumnRef::Name(n)) = cols.iter().find(|c| matches!(c, ColumnRef::Name(_))) {
                return Err(input_error(
                    path,
                    format!(
                        "no column '{n}': the file has no header row (its first line is numbers), so give \
                         columns by their position (1 = first column)"
                    ),
                ));
            }
            (Vec::new(), table.first_len)
        }
    };
    // Fields that may be filled: the header's, or the whole first line's (trailing empty ones
    // too: they may be missing samples of the first row).
    let room = width;
    let width = table.header.as_ref().map_or(table.first_width, |h| h.width);
    let index = resolve_columns(path, cols, &names, room)?;
    let shown: Vec<String> =
        index.iter().map(|&i| names.get(i).cloned().unwrap_or_else(|| format!("column {}", i + 1))).collect();
    let against = if table.header.is_some() { "the header has" } else { "the first line has" };
    let wanted = |r: usize| opts.rows.is_none_or(|[a, b]| (a..=b).contains(&r));
    let markers = Markers::of(&opts.missing);

    let mut values: Vec<Vec<f64>> = vec![Vec::new(); cols.len()];
    let mut rows = 0usize;
    // A blank line seen after the last data row: an error only if more data follows.
    let mut blank_at: Option<u64> = None;
    let mut next_line = table.data_line;
    let mut reader = table.reader();
    let mut lines = Lines::new(&table.body);
    let mut record = csv::ByteRecord::new();
    loop {
        let more = reader.read_byte_record(&mut record).map_err(|e| csv_error(path, &e))?;
        if !more {
            break;
        }
        let line = lines.of(&record);
        if line < table.data_line {
            continue; // the header
        }
        // The csv reader skips empty lines silently: a gap in the line numbers is one.
        if line > next_line {
            blank_at.get_or_insert(next_line);
        }
        next_line = line + 1 + trimmed(&record).map(|f| f.iter().filter(|&&c| c == b'\n').count() as u64).sum::<u64>();
        if trimmed(&record).all(|f| f.is_empty()) {
            blank_at.get_or_insert(line);
            continue;
        }
        if let Some(b) = blank_at {
            return Err(input_error(path, format!("line {b}: empty line")));
        }
        let fields = record.len();
        let extra_filled = trimmed(&record).skip(room).any(|f| !f.is_empty());
        if fields < width || extra_filled {
            return Err(input_error(
                path,
                format!("line {line}: {fields} field{}, but {against} {width}", if fields == 1 { "" } else { "s" }),
            ));
        }
        rows += 1;
        if !wanted(rows) {
            continue;
        }
        for (k, &j) in index.iter().enumerate() {
            // A line may leave out trailing empty fields of the first line: missing samples.
            let field = record.get(j).map_or(&b""[..], <[u8]>::trim_ascii);
            let v = parse_field(path, line, &shown[k], field, table.delimiter, &markers)?;
            values[k].push(v);
        }
    }
    row_range(path, opts.rows, rows)?;
    Ok(Columns { names: shown, values })
}

/// The whole file as text, without a byte-order mark. Reading it at once and splitting in
/// memory is what makes a 100 000-line file take milliseconds.
fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| input_error(path, format!("cannot open file: {e}")))?;
    match String::from_utf8(bytes) {
        Ok(s) => Ok(match s.strip_prefix('\u{feff}') {
            Some(rest) => rest.to_string(),
            None => s,
        }),
        Err(e) => {
            let good = e.utf8_error().valid_up_to();
            let line = 1 + e.as_bytes()[..good].iter().filter(|&&b| b == b'\n').count();
            Err(input_error(path, format!("line {line}: not valid UTF-8 text (is this a text data file?)")))
        }
    }
}

struct HeaderRow {
    names: Vec<String>,
    /// Number of fields without trailing empty ones.
    width: usize,
}

/// A text file opened for reading: its dialect and header.
struct Table<'a> {
    /// The text the csv reader parses (whitespace runs collapsed for [`Delimiter::Whitespace`];
    /// else the file's text itself, not a copy).
    body: Cow<'a, str>,
    delimiter: Delimiter,
    header: Option<HeaderRow>,
    /// Width of the first non-blank line without its trailing empty fields (the least width of
    /// a line without a header), and with them (the table width without a header).
    first_width: usize,
    first_len: usize,
    /// Line number of the first data line.
    data_line: u64,
}

impl<'a> Table<'a> {
    fn open(path: &Path, text: &'a str, opts: &ReadOptions) -> Result<Table<'a>> {
        if text.trim().is_empty() {
            return Err(input_error(path, "file is empty"));
        }
        let delimiter = opts.delimiter.unwrap_or_else(|| sniff(text));
        let body = match delimiter {
            Delimiter::Whitespace => Cow::Owned(
                text.lines().map(|l| l.split_whitespace().collect::<Vec<_>>().join(" ")).collect::<Vec<_>>().join("\n"),
            ),
            Delimiter::Byte(_) => Cow::Borrowed(text),
        };
        let mut table = Table { body, delimiter, header: None, first_width: 0, first_len: 0, data_line: 1 };
        let mut reader = table.reader();
        let mut lines = Lines::new(&table.body);
        let mut first = csv::ByteRecord::new();
        loop {
            if !reader.read_byte_record(&mut first).map_err(|e| csv_error(path, &e))? {
                return Err(input_error(path, "file is empty"));
            }
            if trimmed(&first).any(|f| !f.is_empty()) {
                break;
            }
        }
        let line = lines.of(&first);
        let width = first.len() - trimmed(&first).rev().take_while(|f| f.is_empty()).count();
        table.first_width = width;
        table.first_len = first.len();
        table.data_line = line;
        // A line of numbers is data, missing samples (empty fields, declared markers) included.
        let markers = Markers::of(&opts.missing);
        let numeric =
            trimmed(&first).take(width).all(|f| f.is_empty() || parse_number(f).is_some() || markers.is_text(f));
        let has_header = match opts.header {
            Header::Yes => true,
            Header::No => false,
            Header::Auto => !numeric,
        };
        if has_header {
            let names =
                trimmed(&first).take(width).map(|f| String::from_utf8_lossy(f).into_owned()).collect::<Vec<_>>();
            table.header = Some(HeaderRow { names, width });
            table.data_line = line + 1;
        }
        Ok(table)
    }

    fn reader(&self) -> csv::Reader<&[u8]> {
        let d = match self.delimiter {
            Delimiter::Byte(b) => b,
            Delimiter::Whitespace => b' ',
        };
        csv::ReaderBuilder::new().delimiter(d).has_headers(false).flexible(true).from_reader(self.body.as_bytes())
    }
}

/// The fields of a record without the ASCII whitespace around them: csv's `Trim::All`, without
/// its copy of every record (a long record's reading spent a fifth of its time there).
fn trimmed(record: &csv::ByteRecord) -> impl DoubleEndedIterator<Item = &[u8]> {
    record.iter().map(<[u8]>::trim_ascii)
}

/// Line numbers of records. The csv reader's own line count skips blank lines and counts a
/// CRLF twice, and its byte position of a record is just after the previous record's first
/// terminator byte: the record starts after the `\r`/`\n` bytes that follow. Positions only
/// grow, so the newlines are counted incrementally.
struct Lines<'a> {
    text: &'a [u8],
    at: usize,
    line: u64,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Lines { text: text.as_bytes(), at: 0, line: 1 }
    }

    /// The 1-based line on which `record` starts.
    fn of(&mut self, record: &csv::ByteRecord) -> u64 {
        let mut start = record.position().map_or(self.at, |p| p.byte() as usize).max(self.at);
        while start < self.text.len() && matches!(self.text[start], b'\r' | b'\n') {
            start += 1;
        }
        self.line += self.text[self.at..start].iter().filter(|&&b| b == b'\n').count() as u64;
        self.at = start;
        self.line
    }
}

/// The separator of a file whose dialect is not given (see the module docs).
fn sniff(text: &str) -> Delimiter {
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).take(SNIFF_LINES).collect();
    for d in [b'\t', b';', b','] {
        if lines.iter().all(|l| count_outside_quotes(l, d) > 0) {
            return Delimiter::Byte(d);
        }
    }
    if lines.iter().all(|l| l.split_whitespace().count() > 1) { Delimiter::Whitespace } else { Delimiter::Byte(b',') }
}

fn count_outside_quotes(line: &str, d: u8) -> usize {
    let mut quoted = false;
    line.bytes()
        .filter(|&b| {
            if b == b'"' {
                quoted = !quoted;
            }
            b == d && !quoted
        })
        .count()
}

fn csv_error(path: &Path, e: &csv::Error) -> crate::error::Error {
    match e.position() {
        Some(p) => input_error(path, format!("line {}: {}", p.line(), e)),
        None => input_error(path, format!("cannot read the file: {e}")),
    }
}

fn parse_number(field: &[u8]) -> Option<f64> {
    std::str::from_utf8(field).ok()?.parse::<f64>().ok()
}

/// One selected field: its number, or NaN for a missing sample (empty, `NaN`, a marker).
fn parse_field(
    path: &Path,
    line: u64,
    col: &str,
    field: &[u8],
    delimiter: Delimiter,
    markers: &Markers,
) -> Result<f64> {
    if field.is_empty() || markers.is_text(field) {
        return Ok(f64::NAN);
    }
    match parse_number(field) {
        // The place is formatted only for an error: this runs for every field of a long record.
        Some(v) if v.is_finite() && !markers.is_value(v) => Ok(v),
        Some(v) => sample(path, &format!("line {line}"), col, v, markers),
        None => {
            let s = String::from_utf8_lossy(field);
            let hint = if s.contains(',') && delimiter != Delimiter::Byte(b',') {
                " (a decimal comma? the decimal mark must be '.')"
            } else {
                " (a missing sample? name its marker in the record's \"missing\")"
            };
            Err(input_error(path, format!("line {line}, column '{col}': '{s}' is not a number{hint}")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniffing() {
        assert_eq!(sniff("u,y\n1,2\n"), Delimiter::Byte(b','));
        assert_eq!(sniff("u;y\n1,5;2,5\n"), Delimiter::Byte(b';'));
        assert_eq!(sniff("u\ty\n1\t2\n"), Delimiter::Byte(b'\t'));
        assert_eq!(sniff("  1.0   2.0\n 3.0 4.0\n"), Delimiter::Whitespace);
        assert_eq!(sniff("\"a,b\";c\n1;2\n"), Delimiter::Byte(b';'));
    }
}
