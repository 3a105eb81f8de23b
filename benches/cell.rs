//! Cost of one sweep cell, phase by phase (METHOD.md 5).
//!
//! A sweep runs the L2 phase once per order pair and the Huber phase once per (order pair, k),
//! so the two are timed separately:
//! - `l2_phase`: `fit_ls`, every start (ARX, IV, damped variants, robust detour) run to its
//!   least-squares minimum;
//! - `huber_phase`: one LM minimisation of W_{N, k sigma} from theta_LS (what `fit_huber`
//!   spends in the solver), the unit the other Huber costs are multiples of;
//! - `huber_multi`: the Huber phase as `oesweep fit` runs it (`fit_huber_multi`: theta_LS plus
//!   the alternative starts the L2 phase leaves, best kept): what one more k costs a cell under
//!   the `ls` start strategy, and what the first (cold) cell of a pair costs under the default
//!   `chains` (whose later cells are warm starts, a few iterations each);
//! - `huber_phase_n`: `huber_phase` on simulated records of growing length, to show that the
//!   cost per iteration is linear in N.
//!
//! Run: `cargo bench --bench cell` (about a minute). Each benchmark reports, on stderr, the
//! iteration count of the fit it times, so time per iteration can be read off.

use oesweep::oe::Structure;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group, criterion_main};
use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, solver};
use oesweep::simulate::{self, NoiseKind, Outliers, SimOptions};

/// Order pairs: the smallest cell of the paper's grid, the paper's M2, and the largest.
const ORDERS: [(usize, usize); 3] = [(7, 4), (12, 12), (14, 15)];
/// The paper's k for M2.
const K: f64 = 0.0875;
/// Record lengths of `huber_phase_n`.
const LENGTHS: [usize; 4] = [2500, 5000, 10000, 20000];

fn data_path(name: &str) -> std::path::PathBuf {
    // Benches run with the package root as working directory, but anchoring on the manifest
    // keeps `cargo bench --manifest-path ...` from elsewhere working too.
    Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data").join(name)
}

fn estimation_record() -> (Vec<f64>, Vec<f64>) {
    let rec = oesweep::data::read_record(&data_path("piezo_est.csv"), "u", "y").expect("bundled estimation data");
    (rec.u, rec.y)
}

/// Records like the bundled one (jobs/data/piezo_est.csv is seed 1, piezo_val.csv seed 2) at
/// other lengths. Fresh seeds rather than a truncated/tiled bundled record, so each length is
/// an honest measurement with its own noise and spikes.
fn simulated_record(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let sys = simulate::read_system(&data_path("piezo_system.json")).expect("bundled system");
    let opts = SimOptions {
        n,
        bits: 10,
        amplitude: 10.0,
        seed,
        noise_std: 0.1,
        noise: NoiseKind::Gaussian,
        outliers: Some(Outliers { probability: 0.05, min: 20.0, max: 60.0 }),
    };
    let rec = simulate::generate(&sys, &opts).expect("simulated record");
    (rec.u, rec.y)
}

fn l2_phase(c: &mut Criterion) {
    let (u, y) = estimation_record();
    let opts = SolverOptions::default();
    let mut group = c.benchmark_group("l2_phase");
    group.sampling_mode(SamplingMode::Flat);
    for (nb, nf) in ORDERS {
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(nb, nf, 1), offset: false, seams: &[], missing: &[] };
        // One workspace per bench, reused across calls, as a sweep worker reuses its own.
        let mut ws = Workspace::new();
        let ls = estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws);
        eprintln!(
            "l2_phase OE({nb},{nf}): {} iterations (winning start), criterion {:.6}, {}",
            ls.iterations, ls.criterion, ls.termination
        );
        group.bench_with_input(BenchmarkId::from_parameter(format!("OE({nb},{nf})")), &prob, |b, prob| {
            b.iter(|| estimate::fit_ls(black_box(prob), &Judge::default(), &opts, &mut ws))
        });
    }
    group.finish();
}

fn huber_phase(c: &mut Criterion) {
    let (u, y) = estimation_record();
    let opts = SolverOptions::default();
    // The settings the sweep's Huber fits run with (solver.huber_tol).
    let hopts = opts.huber();
    let mut group = c.benchmark_group("huber_phase");
    group.sampling_mode(SamplingMode::Flat);
    for (nb, nf) in ORDERS {
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(nb, nf, 1), offset: false, seams: &[], missing: &[] };
        let mut ws = Workspace::new();
        let ls = estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws);
        let loss = Loss::Huber { gamma: K * ls.sigma };
        let theta_ls = ls.theta();
        let sol = solver::minimise(&prob, loss, &theta_ls, &hopts, &mut ws);
        eprintln!(
            "huber_phase OE({nb},{nf}) k={K}: {} iterations, W {:.6}, {}",
            sol.iterations, sol.criterion, sol.termination
        );
        group.bench_with_input(BenchmarkId::from_parameter(format!("OE({nb},{nf})")), &prob, |b, prob| {
            b.iter(|| solver::minimise(black_box(prob), loss, &theta_ls, &hopts, &mut ws))
        });
    }
    group.finish();
}

fn huber_multi(c: &mut Criterion) {
    let (u, y) = estimation_record();
    let opts = SolverOptions::default();
    let mut group = c.benchmark_group("huber_multi");
    group.sampling_mode(SamplingMode::Flat);
    for (nb, nf) in ORDERS {
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(nb, nf, 1), offset: false, seams: &[], missing: &[] };
        let mut ws = Workspace::new();
        let ls = estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws);
        let (h, which) = estimate::fit_huber_multi(&prob, &ls, K, &Judge::default(), &opts, &mut ws);
        eprintln!(
            "huber_multi OE({nb},{nf}) k={K}: {} starts, winner {which} ({} iterations), W {:.6}",
            1 + ls.alternatives.len(),
            h.iterations,
            h.criterion
        );
        group.bench_with_input(BenchmarkId::from_parameter(format!("OE({nb},{nf})")), &prob, |b, prob| {
            b.iter(|| estimate::fit_huber_multi(black_box(prob), &ls, K, &Judge::default(), &opts, &mut ws))
        });
    }
    group.finish();
}

fn huber_phase_n(c: &mut Criterion) {
    let (nb, nf) = (12, 12);
    let opts = SolverOptions::default();
    // The settings the sweep's Huber fits run with (solver.huber_tol).
    let hopts = opts.huber();
    let mut group = c.benchmark_group("huber_phase_n");
    group.sampling_mode(SamplingMode::Flat);
    for (i, n) in LENGTHS.into_iter().enumerate() {
        let (u, y) = simulated_record(n, 101 + i as u64);
        let prob =
            Problem { u: &u, y: &y, structure: Structure::siso(nb, nf, 1), offset: false, seams: &[], missing: &[] };
        let mut ws = Workspace::new();
        let ls = estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws);
        let loss = Loss::Huber { gamma: K * ls.sigma };
        let theta_ls = ls.theta();
        let sol = solver::minimise(&prob, loss, &theta_ls, &hopts, &mut ws);
        eprintln!(
            "huber_phase_n OE({nb},{nf}) N={n}: {} iterations, W {:.6}, {}",
            sol.iterations, sol.criterion, sol.termination
        );
        // Each record needs its own number of iterations, so time per fit alone would mix the
        // growth in N with the luck of the draw. Counting N * iterations as the elements makes
        // criterion's throughput the rate of sample-iterations: flat across N means linear cost.
        group.throughput(Throughput::Elements((n * sol.iterations.max(1)) as u64));
        group.bench_with_input(BenchmarkId::from_parameter(n), &prob, |b, prob| {
            b.iter(|| solver::minimise(black_box(prob), loss, &theta_ls, &hopts, &mut ws))
        });
    }
    group.finish();
}

fn config() -> Criterion {
    // Fits take 5-150 ms: 10 samples over 3 s give medians stable to a few per cent while
    // keeping the whole file under a minute on the 2-core machine. The groups sample flat (the
    // same number of fits in every sample), as criterion advises for millisecond-scale
    // routines: the linear ramp's regression only pays off when per-call overhead matters.
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3))
        // Plot rendering (plotters backend) took longer than the measurements themselves.
        .without_plots()
}

criterion_group! {
    name = benches;
    config = config();
    targets = l2_phase, huber_phase, huber_multi, huber_phase_n
}
criterion_main!(benches);
