//! Shared helpers of the integration tests: deterministic signals and test systems.
#![allow(dead_code)]

pub mod mat;

use oesweep::oe;

/// True under `CI=true`, where a test that cannot run on this machine is a failure rather than
/// a skip: the CI machine is chosen to run them all.
pub fn under_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true")
}

/// A test that cannot run here: says so and returns, or fails under `CI=true` ([`under_ci`]).
pub fn cannot_run(why: &str) {
    assert!(!under_ci(), "this test cannot run here (a failure under CI=true): {why}");
    eprintln!("SKIPPED: {why}");
}

// The LCG and the binary input of the Monte Carlo examples: one home for both.
#[path = "../../examples/common/mod.rs"]
mod shared;
pub use shared::Lcg;

/// Random binary (+/-amp) input that holds each level for `hold` samples.
pub fn binary_input(n: usize, hold: usize, amp: f64, seed: u64) -> Vec<f64> {
    shared::binary(n, hold, -amp, amp, &mut Lcg(seed))
}

/// F with the given poles, as (radius, angle) pairs (each a conjugate pair) plus real poles.
pub fn f_from_poles(pairs: &[(f64, f64)], real: &[f64]) -> Vec<f64> {
    oe::poly_from_poles(pairs, real)
}

/// A known OE(2,2) system.
pub fn oe22() -> (Vec<f64>, Vec<f64>) {
    (vec![0.5, 0.3], f_from_poles(&[(0.9, 0.5)], &[]))
}

/// A known OE(10,10) system: two lightly damped resonances and real poles.
pub fn oe1010() -> (Vec<f64>, Vec<f64>) {
    let f = f_from_poles(&[(0.985, 0.45), (0.97, 1.3), (0.9, 2.2)], &[0.8, 0.5, -0.3, 0.6]);
    let b = vec![0.02, 0.05, -0.03, 0.04, 0.01, -0.02, 0.03, 0.015, -0.01, 0.005];
    (b, f)
}

/// A stand-in for the DaISy heat exchanger record (97-002: flow -> outlet temperature, 4000
/// samples, Ts = 1 s), whose stable fits have their slowest pole at 0.978 (tau = 45 s) and fit
/// 78 %: a plant with poles 0.978 and 0.85 and unit gain, a random binary input held 20
/// samples, white noise of 10 % of the output's RMS and a random walk (steps 0.7 % of it) in
/// the output, about a level of 20.
pub fn drifting_exchanger(seed: u64) -> (Vec<f64>, Vec<f64>) {
    let n = 4000;
    let f = f_from_poles(&[], &[0.978, 0.85]);
    let b = [1.0 + f.iter().sum::<f64>()];
    let u = binary_input(n, 20, 1.0, seed);
    let y0 = oe::simulate_vec(&b, &f, 1, &u);
    let rms = (y0.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
    let mut rng = Lcg(seed + 1);
    let mut drift = 0.0;
    let y = y0
        .iter()
        .map(|v| {
            drift += 0.007 * rms * rng.normal();
            v + 0.1 * rms * rng.normal() + drift + 20.0
        })
        .collect();
    (u, y)
}

/// Spikes and noise of [`simulate`].
pub struct Noise<'a> {
    pub amplitude: f64,
    pub std: f64,
    pub spike_probability: f64,
    pub spike_range: &'a str,
}

/// Run `oesweep simulate` of the system file `system` into `out` (CSV with u, y, y0).
pub fn simulate(system: &std::path::Path, out: &std::path::Path, n: usize, seed: u64, noise: &Noise) {
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(["simulate", "--system", system.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(["--n", &n.to_string(), "--seed", &seed.to_string(), "--amplitude", &noise.amplitude.to_string()])
        .args(["--noise-std", &noise.std.to_string(), "--outlier-prob", &noise.spike_probability.to_string()])
        .args(["--outlier-range", noise.spike_range])
        .output()
        .expect("oesweep runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The bundled piezo-like system file.
pub fn piezo_system() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data/piezo_system.json")
}

/// Every path under `root` with its contents (`None` for a folder): "nothing written" is this
/// snapshot unchanged. `skip_locks`: leave out the output folder's lock files
/// (`.oesweep*.lock`), which a command that must lock before it reads (merge) signs with its pid.
pub fn snapshot(root: &std::path::Path, skip_locks: bool) -> Snapshot {
    fn walk(root: &std::path::Path, dir: &std::path::Path, skip_locks: bool, out: &mut Snapshot) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let p = entry.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy();
            if skip_locks && name.starts_with(".oesweep") && name.ends_with(".lock") {
                continue;
            }
            let rel = p.strip_prefix(root).unwrap().to_path_buf();
            if p.is_dir() {
                out.insert(rel, None);
                walk(root, &p, skip_locks, out);
            } else {
                out.insert(rel, Some(std::fs::read(&p).unwrap_or_default()));
            }
        }
    }
    let mut out = Snapshot::new();
    walk(root, root, skip_locks, &mut out);
    out
}

/// What [`snapshot`] gives.
pub type Snapshot = std::collections::BTreeMap<std::path::PathBuf, Option<Vec<u8>>>;

/// A job `name` over `n` samples of simulated piezo data (`est.csv` in `dir`, written once: noise
/// and 3 % spikes) on the grid nb x nf x `ks` log-spaced k in [`k_from`, 2], writing to `out`;
/// the job file is `dir/out.json`.
pub fn piezo_job(
    dir: &std::path::Path,
    out: &str,
    name: &str,
    n: usize,
    (nb, nf): ([usize; 2], [usize; 2]),
    (k_from, ks): (f64, usize),
) -> std::path::PathBuf {
    if !dir.join("est.csv").exists() {
        let noise = Noise { amplitude: 1.0, std: 0.05, spike_probability: 0.03, spike_range: "1,3" };
        simulate(&piezo_system(), &dir.join("est.csv"), n, 1, &noise);
    }
    let job = serde_json::json!({
        "name": name,
        "data": {"path": "est.csv", "ts": 1e-4},
        "grid": {"nb": nb, "nf": nf, "k": {"from": k_from, "to": 2.0, "count": ks, "spacing": "log"}},
        "output": out,
    });
    let p = dir.join(format!("{out}.json"));
    std::fs::write(&p, job.to_string()).unwrap();
    p
}

/// `jobs/piezo-demo.json` with its records by absolute path (set `output` before writing it).
pub fn demo_job() -> serde_json::Value {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut job: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("jobs/piezo-demo.json")).unwrap()).unwrap();
    for key in ["data", "validation"] {
        let path = root.join("jobs").join(job[key]["path"].as_str().unwrap());
        job[key]["path"] = serde_json::json!(path);
    }
    job
}

/// The table of a results folder without the wall-clock column.
pub fn table_without_seconds(out: &std::path::Path) -> Vec<oesweep::table::CellRow> {
    let mut rows = oesweep::export::parquet::read_cells(&out.join("cells.parquet")).unwrap();
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

/// How a run of the `oesweep` binary ended.
pub struct Outcome {
    pub code: Option<i32>,
    /// The signal that ended it (a panic's abort, or the kill after the time limit).
    pub signal: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

/// Runs the `oesweep` binary in `cwd` (so that nothing lands in the repository even if a
/// relative path escaped resolution), stdin closed, its pipes read on threads (a chatty child
/// must not block on a full pipe). `limit` is a safety net against a hang, not a measurement:
/// a child still running then is killed (`signal` 9) and the caller's checks fail on it.
pub fn run_oesweep<S: AsRef<std::ffi::OsStr>>(
    cwd: &std::path::Path,
    args: &[S],
    limit: std::time::Duration,
) -> Outcome {
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_oesweep"))
        .args(args)
        .current_dir(cwd)
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("binary starts");
    let read = |mut pipe: Box<dyn std::io::Read + Send>| {
        std::thread::spawn(move || {
            let mut s = Vec::new();
            pipe.read_to_end(&mut s).ok();
            String::from_utf8_lossy(&s).into_owned()
        })
    };
    let out = read(Box::new(child.stdout.take().unwrap()));
    let err = read(Box::new(child.stderr.take().unwrap()));
    let t0 = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > limit {
            child.kill().ok();
            break child.wait().unwrap();
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    Outcome { code: status.code(), signal: status.signal(), stdout: out.join().unwrap(), stderr: err.join().unwrap() }
}

/// A copy of the folder `from` (files and subfolders) at `to`.
pub fn copy_tree(from: &std::path::Path, to: &std::path::Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// `bytes` (a Parquet file) with the first data page of `column` (its path in the schema, e.g.
/// `u` or `theta.list.element`) declaring -(n+1) values instead of its n: the damage to a page
/// header that made polars 0.55 reserve 2^61 bytes and abort. The header keeps its length (the
/// zigzag varints of n and -(n+1) are as long), so every other offset of the file stays true.
pub fn negate_page_values(bytes: &[u8], column: &str) -> Vec<u8> {
    use polars::prelude::{ParquetReader, SerReader};
    use polars_parquet_format::thrift::protocol::{TCompactInputProtocol, TCompactOutputProtocol};
    use polars_parquet_format::{PageHeader, PageType};
    let mut reader = ParquetReader::new(std::io::Cursor::new(bytes.to_vec()));
    let meta = reader.get_metadata().unwrap().clone();
    let chunk = meta.row_groups[0]
        .parquet_columns()
        .iter()
        .find(|c| c.descriptor().path_in_schema.join(".") == column)
        .unwrap_or_else(|| panic!("no column {column}"));
    let mut pos = chunk.byte_range().start as usize;
    loop {
        let mut cursor = std::io::Cursor::new(&bytes[pos..]);
        let mut header =
            PageHeader::read_from_in_protocol(&mut TCompactInputProtocol::new(&mut cursor, usize::MAX)).unwrap();
        let len = cursor.position() as usize;
        if header.type_ == PageType::DATA_PAGE {
            let h = header.data_page_header.as_mut().unwrap();
            h.num_values = -(h.num_values + 1);
            let mut out = Vec::new();
            header.write_to_out_protocol(&mut TCompactOutputProtocol::new(&mut out)).unwrap();
            assert_eq!(out.len(), len, "the header changed its length");
            let mut damaged = bytes.to_vec();
            damaged[pos..pos + len].copy_from_slice(&out);
            return damaged;
        }
        pos += len + header.compressed_page_size as usize;
    }
}

/// A small, fully specified random source (an LCG, Box-Muller for Gaussian draws), so that
/// records with gaps are the same on every machine.
pub struct Draws(pub u64);

impl Draws {
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn gauss(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
    }
}

/// Sorted indices of `share` of `n` samples (METHOD.md 21): half in bursts of 20, half at
/// random.
pub fn output_gaps(n: usize, share: f64, r: &mut Draws) -> Vec<usize> {
    let mut gone = vec![false; n];
    let target = (share * n as f64) as usize;
    let mut count = 0;
    while count < target / 2 {
        let start = (r.uniform() * (n - 20) as f64) as usize;
        for g in &mut gone[start..start + 20] {
            count += usize::from(!*g);
            *g = true;
        }
    }
    while count < target {
        let t = (r.uniform() * n as f64) as usize;
        count += usize::from(!gone[t]);
        gone[t] = true;
    }
    (0..n).filter(|&t| gone[t]).collect()
}

/// A stand-in `sbatch` in `dir/bin` for `oesweep slurm`: it logs `OESWEEP=$OESWEEP` and its
/// arguments, one line per call, to `dir/sbatch.log` and answers as `--parsable` does
/// (`id;cluster`, the ids 4101, 4102, .. in the order of the calls). Returns the PATH that finds
/// it first, and the log.
pub fn fake_sbatch(dir: &std::path::Path) -> (String, std::path::PathBuf) {
    use std::os::unix::fs::PermissionsExt;
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let log = dir.join("sbatch.log");
    let script = format!(
        "#!/bin/sh\necho \"OESWEEP=$OESWEEP $*\" >> {log}\nn=$(wc -l < {log})\necho \"$((4100 + n));cluster\"\n",
        log = log.display()
    );
    std::fs::write(bin.join("sbatch"), script).unwrap();
    std::fs::set_permissions(bin.join("sbatch"), std::fs::Permissions::from_mode(0o755)).unwrap();
    (format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default()), log)
}
