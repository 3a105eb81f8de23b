//! The report of a several-input run (issue 46): each input's Bode figure draws that input's
//! column of the record's spectral estimate H = P^-1 s (`spectral::estimate_inputs`, METHOD.md
//! 19) as the measured response, with the multiple coherence, the fit band and the input's
//! band fit; "how the picks move with k" is one figure per input, that input's orders.

mod common;

use common::*;
use oesweep::spectral::{self, SpectrumMethod};
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn oesweep(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_oesweep")).current_dir(dir).args(args).output().expect("oesweep runs")
}

fn ok(o: &Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Per input (b, f, delay): input 2's gain is ten times input 1's, so the two inputs'
/// measured responses lie 20 dB apart.
fn system() -> Vec<(Vec<f64>, Vec<f64>, usize)> {
    vec![(vec![0.5, 0.3], vec![-1.2, 0.35], 1), (vec![4.0], vec![-0.6], 0)]
}

const N: usize = 1200;
const ESTIMATION: usize = 900;
const TS: f64 = 0.1;

/// The two inputs (one after the other) and the output of the estimation rows.
fn record(dir: &Path) -> (Vec<f64>, Vec<f64>) {
    let us: Vec<Vec<f64>> = (0..2).map(|i| binary_input(N, 3 + 2 * i, 1.0, 41 + i as u64)).collect();
    let mut y = vec![0.0; N];
    for (u, (b, f, d)) in us.iter().zip(system()) {
        for (t, v) in oesweep::oe::simulate_vec(&b, &f, d, u).into_iter().enumerate() {
            y[t] += v;
        }
    }
    let mut rng = Lcg(5);
    let mut csv = String::from("u,v,y\n");
    for t in 0..N {
        y[t] += 0.02 * rng.normal() + if t % 89 == 7 { 1.0 } else { 0.0 };
        csv.push_str(&format!("{},{},{}\n", us[0][t], us[1][t], y[t]));
    }
    std::fs::write(dir.join("d.csv"), csv).unwrap();
    let u: Vec<f64> = us.iter().flat_map(|c| c[..ESTIMATION].iter().copied()).collect();
    (u, y[..ESTIMATION].to_vec())
}

/// The `cy` of every dot of a figure's first panel (the magnitude), in drawing order: the
/// measured dots are the only circles of radius 2.
fn magnitude_dots(svg: &str, per_panel: usize) -> Vec<f64> {
    let cys: Vec<f64> = svg
        .split("<circle ")
        .skip(1)
        .filter(|c| c.contains("r=\"2\""))
        .map(|c| {
            let at = c.find("cy=\"").expect("a circle has cy") + 4;
            c[at..at + c[at..].find('"').unwrap()].parse().unwrap()
        })
        .collect();
    assert_eq!(cys.len(), 3 * per_panel, "measured dots in the magnitude, phase and coherence panels");
    cys[..per_panel].to_vec()
}

#[test]
fn each_inputs_bode_figure_draws_its_own_measured_response_and_the_picks_move_with_k_per_input() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path();
    let (u, y) = record(root);
    let job = serde_json::json!({
        "name": "two inputs", "data": {"path": "d.csv", "u": ["u", "v"], "y": "y", "ts": TS, "rows": [1, ESTIMATION]},
        "validation": {"rows": [ESTIMATION + 1, N]}, "band_hz": [0, 2],
        "grid": {"nb": [[1, 2], [1, 1]], "nf": [[1, 2], [1, 2]], "k": [1.0, 2.0]}, "delay": [1, 0], "output": "out"
    });
    std::fs::write(root.join("job.json"), job.to_string()).unwrap();
    ok(&oesweep(root, &["run", "job.json", "--quiet", "--report"]));
    let out = root.join("out");
    let page = std::fs::read_to_string(out.join("report.html")).unwrap();
    let selection: Value = serde_json::from_str(&std::fs::read_to_string(out.join("selection.json")).unwrap()).unwrap();

    // The estimate the figures should draw: one per input, the same usable bins for both.
    let ests = spectral::estimate_inputs(&u, 2, &y, &[], &[], TS, SpectrumMethod::Robust).unwrap();
    let usable = |e: &spectral::SpectralEstimate| {
        (0..e.freq_hz.len()).filter(|&k| e.re[k].is_finite() && e.im[k].is_finite() && e.freq_hz[k] > 0.0).count()
    };
    let bins = usable(&ests[0]);
    assert!(bins > 10 && bins == usable(&ests[1]), "{bins} bins");
    // Input 2's measured gain is about ten times input 1's (20 dB).
    let mean_db = |e: &spectral::SpectralEstimate| {
        let v: Vec<f64> = (1..e.freq_hz.len())
            .filter(|&k| e.re[k].is_finite())
            .map(|k| 20.0 * e.re[k].hypot(e.im[k]).log10())
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    assert!(mean_db(&ests[1]) - mean_db(&ests[0]) > 10.0);

    for pick in ["m1", "m2"] {
        let mut dots = Vec::new();
        for (i, name) in [(0, "u"), (1, "v")] {
            let file = format!("report-bode-{pick}-u{}.svg", i + 1);
            assert!(page.contains(&format!("src=\"{file}\"")), "{file} on the page");
            let svg = std::fs::read_to_string(out.join(&file)).unwrap();
            for label in [
                format!("from input {name}"),
                format!("Welch estimate H = P⁻¹ s, input {name}"),
                "multiple coherence".to_string(),
                "fit band 0 to 2 Hz".to_string(),
            ] {
                assert!(svg.contains(&label), "{file} lacks {label:?}");
            }
            dots.push(magnitude_dots(&svg, bins));
            // The caption names the input's own band fit, selection.json's fit_band_i of it.
            let band_fit =
                selection[pick][format!("fit_band_{}", i + 1)].as_f64().expect("the pick's band fit per input");
            // The page escapes the caption's apostrophe.
            assert!(page.contains(&format!("This input&#39;s band fit = {band_fit:.2} %")), "{pick}, input {name}");
        }
        // The dots are each input's own estimate: the same bins, other values.
        assert_ne!(dots[0], dots[1], "{pick}: both inputs' figures draw the same measured response");
    }
    assert!(!page.contains("no per-input spectral estimate"));

    // How the picks move with k: one figure per input, naming the input's orders.
    for (u, name) in [(1, "u"), (2, "v")] {
        let file = format!("report-picks-k-u{u}.svg");
        assert!(page.contains(&format!("src=\"{file}\"")), "{file} on the page");
        let svg = std::fs::read_to_string(out.join(&file)).unwrap();
        // SVG text escapes the apostrophe.
        assert!(svg.contains(&format!("input {name}&apos;s orders")), "{file} names its input");
        assert!(svg.contains("M1 rule (W minima)") && svg.contains("nF"), "{file}");
    }
    assert!(!page.contains("is not drawn for several inputs"));
}
