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
fn row_ranges() {
    let p = Path::new("r.csv");
    assert_eq!(row_range(p, None, 5).unwrap(), 0..5);
    assert_eq!(row_range(p, Some([2, 5]), 5).unwrap(), 1..5);
    let m = row_range(p, Some([2, 6]), 5).unwrap_err().to_string();
    assert!(m.contains("rows [2, 6] reach past the end of the file: it has 5 data rows"), "{m}");
    assert!(check_rows([0, 3]).is_err() && check_rows([4, 3]).is_err() && check_rows([3, 3]).is_ok());
}

#[test]
fn observed_ranges_cut_experiments_at_missing_outputs() {
    assert_eq!(observed_ranges(10, &[], &[]), vec![0..10]);
    assert_eq!(observed_ranges(10, &[4], &[0, 3, 4, 9]), vec![1..3, 5..9]);
    assert_eq!(observed_ranges(6, &[3], &[2]), vec![0..2, 3..6]);
    assert_eq!(observed_ranges(3, &[], &[0, 1, 2]), Vec::<std::ops::Range<usize>>::new());
}
