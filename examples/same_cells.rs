//! `cargo run --release --example same_cells -- A.parquet B.parquet`: exit 0 when two
//! `cells.parquet` tables hold the same rows in the same order, every column bit for bit except
//! `seconds` (wall time, the one column that differs between identical runs); else print the
//! first difference and exit 1. Used by tests/slurm_cluster.sh, which should not need Python.

use oesweep::export::parquet::read_cells;
use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [a, b] = &args[..] else {
        eprintln!("usage: same_cells A.parquet B.parquet");
        return ExitCode::from(2);
    };
    let read = |p: &str| match read_cells(Path::new(p)) {
        Ok(mut rows) => {
            rows.iter_mut().for_each(|r| r.fit.seconds = 0.0);
            Some(rows)
        }
        Err(e) => {
            eprintln!("error: {e}");
            None
        }
    };
    let (Some(x), Some(y)) = (read(a), read(b)) else { return ExitCode::from(2) };
    if x.len() != y.len() {
        eprintln!("{a}: {} rows, {b}: {} rows", x.len(), y.len());
        return ExitCode::from(1);
    }
    // CellRow's PartialEq compares f64 by value; compare the bits too (NaN, -0.0).
    let bits = |r: &oesweep::table::CellRow| serde_json::to_string(r).expect("row serialises");
    if let Some((i, (p, q))) = x.iter().zip(&y).enumerate().find(|(_, (p, q))| p != q || bits(p) != bits(q)) {
        eprintln!("row {i} differs:\n  {a}: {p:?}\n  {b}: {q:?}");
        return ExitCode::from(1);
    }
    println!("{} rows identical (seconds aside)", x.len());
    ExitCode::SUCCESS
}
