//! The robust spectral estimate (METHOD.md 11) against the true frequency response of a known
//! system whose output carries spikes, and plain Welch on the same records; and the
//! `oesweep spectrum` command.

mod common;

use oesweep::spectral::{self, SpectrumMethod};
use std::process::Command;

/// Band fit of the true system against each estimate of a record with `share` spikes of 5..20
/// (the output's own range is about +/-10). The input is a 13-bit PRBS: a 10-bit one has lines
/// every 1023 samples, between which the 1024-sample bins of Welch see little input power,
/// which costs even a spike-free estimate 6 points.
fn band_fits(share: f64, seed: u64) -> (f64, f64) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.csv");
    let o = Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["simulate", "--system", common::piezo_system().to_str().unwrap(), "--out", path.to_str().unwrap()])
        .args(["--n", "8192", "--bits", "13", "--amplitude", "1", "--noise-std", "0.02", "--seed", &seed.to_string()])
        .args(["--outlier-prob", &share.to_string(), "--outlier-range", "5,20"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rec = oesweep::data::read_record(&path, "u", "y").unwrap();
    let sys: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(common::piezo_system()).unwrap()).unwrap();
    let coef = |k: &str| sys[k].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect::<Vec<f64>>();
    let (b, f, d) = (coef("b"), coef("f"), sys["delay"].as_u64().unwrap() as usize);
    let ts = 1e-4;
    let fit = |m: SpectrumMethod| {
        let est = spectral::estimate(&rec.u, &rec.y, ts, m).unwrap();
        let bins = est.band(0.0, 1500.0);
        spectral::band_fit(&est, &bins, &b, &f, d).unwrap()
    };
    (fit(SpectrumMethod::Robust), fit(SpectrumMethod::Welch))
}

#[test]
fn robust_estimate_is_close_to_the_truth_where_welch_is_not() {
    for seed in [1, 2] {
        let (clean, _) = band_fits(0.0, seed);
        for share in [0.05, 0.15] {
            let (robust, welch) = band_fits(share, seed);
            eprintln!(
                "{share} spikes, seed {seed}: band fit of the true response {robust:.1} % (robust), {welch:.1} % (Welch); {clean:.1} % without spikes"
            );
            assert!(robust >= 90.0, "{share} spikes: robust {robust}");
            assert!(robust >= welch + 20.0, "{share} spikes: robust {robust}, Welch {welch}");
            // The spikes are cleaned out, not merely damped: as good as the record without them.
            assert!((robust - clean).abs() < 1.0, "{share} spikes: robust {robust}, spike-free {clean}");
        }
    }
}

#[test]
fn spectrum_command_prints_json_and_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.csv");
    let noise = common::Noise { amplitude: 1.0, std: 0.02, spike_probability: 0.05, spike_range: "1,3" };
    common::simulate(&common::piezo_system(), &path, 4096, 3, &noise);
    let bin = env!("CARGO_BIN_EXE_oesweep");
    let o = Command::new(bin)
        .args(["spectrum", "--data", path.to_str().unwrap(), "--ts", "1e-4", "--rows", "1:4000", "--json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let n = v["freq_hz"].as_array().unwrap().len();
    assert!(n > 100, "{n} bins");
    for key in ["re", "im", "coherence", "mag_lower", "mag_upper"] {
        assert_eq!(v[key].as_array().unwrap().len(), n, "{key}");
    }
    assert_eq!(v["n"], 4000);
    assert!(v["replaced"].as_u64().unwrap() > 100, "{}", v["replaced"]);
    let (re, im) = (v["re"][10].as_f64().unwrap(), v["im"][10].as_f64().unwrap());
    let mag = re.hypot(im);
    assert!(v["mag_lower"][10].as_f64().unwrap() <= mag && mag <= v["mag_upper"][10].as_f64().unwrap());
    let o = Command::new(bin)
        .args(["spectrum", "--data", path.to_str().unwrap(), "--ts", "1e-4", "--method", "welch"])
        .output()
        .unwrap();
    assert!(o.status.success());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("welch estimate") && text.contains("coherence"), "{text}");
    let o = Command::new(bin).args(["spectrum", "--data", path.to_str().unwrap(), "--ts", "0"]).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
}
