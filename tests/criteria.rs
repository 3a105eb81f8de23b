//! The information criteria of the least-squares rows (issue 28), computed here independently of
//! the engine: each `ls` row's model is simulated from the table's b, f, offset and the input
//! level of `selection.json`, its residuals give V = (1/N) sum e^2, and AIC, AICc, BIC and FPE
//! follow MATLAB's definitions with np = nB + nF (+ 1 with an estimated offset).

mod common;

use oesweep::export::parquet::read_cells;
use std::path::Path;
use std::process::Command;

/// MATLAB's raw AIC, AICc, BIC and FPE for one output.
fn matlab(v: f64, n: f64, np: f64) -> [f64; 4] {
    let g = n * ((2.0 * std::f64::consts::PI).ln() + 1.0);
    let aic = n * v.ln() + 2.0 * np + g;
    [aic, aic + 2.0 * np * (np + 1.0) / (n - np - 1.0), n * v.ln() + g + np * n.ln(), v * (n + np) / (n - np)]
}

fn check(dir: &Path, offset: &str) {
    let job = serde_json::json!({
        "name": "criteria", "data": {"path": "est.csv", "ts": 1e-3}, "offset": offset,
        "grid": {"nb": [1, 3], "nf": [1, 3], "k": [1.0]}, "output": offset
    });
    let path = dir.join(format!("{offset}.json"));
    std::fs::write(&path, job.to_string()).unwrap();
    let o =
        Command::new(env!("CARGO_BIN_EXE_oesweep")).args(["run", path.to_str().unwrap(), "--quiet"]).output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let out = dir.join(offset);
    let selection: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("selection.json")).unwrap()).unwrap();
    let u0 = selection["input_level"].as_f64().unwrap();
    let rec = oesweep::data::read_record(&dir.join("est.csv"), "u", "y").unwrap();
    let u: Vec<f64> = rec.u.iter().map(|v| v - u0).collect();
    let n = rec.len() as f64;
    let rows = read_cells(&out.join("cells.parquet")).unwrap();
    let ls: Vec<_> = rows.iter().filter(|r| !r.is_huber()).collect();
    assert_eq!(ls.len(), 9);
    for r in ls {
        let mut yhat = vec![0.0; u.len()];
        oesweep::oe::simulate(&r.fit.b, &r.fit.f, r.key.delay as usize, &u, &mut yhat);
        let c = r.fit.offset.unwrap_or(0.0);
        let v = rec.y.iter().zip(&yhat).map(|(y, yh)| (y - yh - c).powi(2)).sum::<f64>() / n;
        let np = (r.key.nb + r.key.nf) as f64 + if offset == "estimate" { 1.0 } else { 0.0 };
        let want = matlab(v, n, np);
        let got = [r.fit.aic, r.fit.aicc, r.fit.bic, r.fit.fpe].map(|x| x.expect("an ls row has its criteria"));
        for (name, (g, w)) in ["aic", "aicc", "bic", "fpe"].iter().zip(got.iter().zip(want)) {
            assert!((g - w).abs() <= 1e-9 * w.abs(), "{offset} OE({},{}) {name}: {g} vs {w}", r.key.nb, r.key.nf);
        }
    }
    // Huber rows have none (their robust criteria are another matter).
    assert!(rows.iter().filter(|r| r.is_huber()).all(|r| r.fit.aic.is_none() && r.fit.fpe.is_none()));
}

#[test]
fn least_squares_rows_carry_matlabs_information_criteria() {
    let dir = tempfile::tempdir().unwrap();
    let noise = common::Noise { amplitude: 1.0, std: 0.1, spike_probability: 0.0, spike_range: "1,2" };
    let (b, f) = common::oe22();
    let sys = dir.path().join("sys.json");
    std::fs::write(&sys, serde_json::json!({"b": b, "f": f, "delay": 1}).to_string()).unwrap();
    common::simulate(&sys, &dir.path().join("est.csv"), 2000, 7, &noise);
    check(dir.path(), "none");
    check(dir.path(), "estimate");
}
