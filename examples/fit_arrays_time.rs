//! `cargo run --release --example fit_arrays_time -- FILE NB NF K TS`: the library's own time
//! for one `oesweep.fit` call, the reference of `benches/python_overhead.py`. FILE holds u then
//! y as little-endian float64 (N each). The timed call is what the Python package asks the
//! library for: the record from owned vectors (`Record::from_arrays`) and `engine::fit_arrays`
//! with the Python defaults (delay 1, offset and initial state estimated). One warm-up call,
//! then one timed call; prints its seconds.

use oesweep::data::{Offset, Record};
use oesweep::engine::{self, FitRequest};
use oesweep::estimate::InitialState;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [file, nb, nf, k, ts] = &args[..] else {
        eprintln!("usage: fit_arrays_time FILE NB NF K TS");
        std::process::exit(2);
    };
    let bytes = std::fs::read(file).expect("read FILE");
    let all: Vec<f64> = bytes.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    let (u, y) = all.split_at(all.len() / 2);
    let (nb, nf, k, ts) = (nb.parse().unwrap(), nf.parse().unwrap(), k.parse().unwrap(), ts.parse().unwrap());
    let req = FitRequest::for_arrays(
        oesweep::oe::Structure::siso(nb, nf, 1),
        k,
        ts,
        Offset::Estimate,
        InitialState::Estimate,
    );
    let call = || {
        let (u, y) = (u.to_vec(), y.to_vec());
        let t0 = Instant::now();
        let rec = Record::from_arrays("<u, y arrays>", u, y).unwrap();
        let report = engine::fit_arrays(&req, rec, None).unwrap();
        (t0.elapsed().as_secs_f64(), report.seconds)
    };
    call();
    let (wall, _) = call();
    println!("{wall:.9}");
}
