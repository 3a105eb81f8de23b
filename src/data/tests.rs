//! Unit tests of the record readers' shared rules.
use super::*;

#[test]
fn extension_picks_the_format() {
    assert_eq!(Format::of(Path::new("a/b.parquet")), Format::Parquet);
    assert_eq!(Format::of(Path::new("b.PQ")), Format::Parquet);
    assert_eq!(Format::of(Path::new("b.Mat")), Format::Mat);
    assert_eq!(Format::of(Path::new("b.csv")), Format::Text);
    assert_eq!(Format::of(Path::new("b.dat")), Format::Text);
    assert_eq!(Format::of(Path::new("parquet")), Format::Text);
}

#[test]
fn column_refs_from_the_command_line_and_json() {
    assert_eq!(ColumnRef::parse("3"), ColumnRef::Position(3));
    assert_eq!(ColumnRef::parse("u"), ColumnRef::name("u"));
    assert_eq!(ColumnRef::parse("+3"), ColumnRef::name("+3"));
    assert_eq!(serde_json::from_str::<ColumnRef>("2").unwrap(), ColumnRef::Position(2));
    assert_eq!(serde_json::from_str::<ColumnRef>("\"2\"").unwrap(), ColumnRef::name("2"));
    assert_eq!(serde_json::from_str::<Header>("\"auto\"").unwrap(), Header::Auto);
    assert_eq!(serde_json::from_str::<Header>("false").unwrap(), Header::No);
    assert!(serde_json::from_str::<Header>("\"yes\"").is_err());
}

#[test]
fn min_samples_rule() {
    assert_eq!(min_samples(1, 1, 1), 20);
    assert_eq!(min_samples(12, 12, 1), 1 + 12 + 96);
    assert_eq!(min_samples(9, 12, 2), 2 + 12 + 84);
}

#[test]
fn constant_detection_is_relative() {
    assert_eq!(constant_value(&[3.0, 3.0, 3.0]), Some(3.0));
    assert!(constant_value(&[1e6, 1e6 + 1e-7]).is_some());
    assert!(constant_value(&[0.0, 1e-9]).is_none());
    assert!(constant_value(&[1e6, 1e6 + 1e-3]).is_none());
}

#[test]
fn row_ranges() {
    let p = Path::new("r.csv");
    assert_eq!(row_range(p, None, 5).unwrap(), 0..5);
    assert_eq!(row_range(p, Some([2, 5]), 5).unwrap(), 1..5);
    let m = row_range(p, Some([2, 6]), 5).unwrap_err().to_string();
    assert!(m.contains("rows [2, 6] reach past the end of the file: it has 5 data rows"), "{m}");
    assert!(check_rows([0, 3]).is_err() && check_rows([4, 3]).is_err() && check_rows([3, 3]).is_ok());
}
