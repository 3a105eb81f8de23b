//! The kernels one Levenberg-Marquardt iteration is made of, at the paper's M2 size OE(12,12)
//! on the bundled N = 5000 record (METHOD.md 2-3).
//!
//! An iteration simulates the model (FIR + one 1/F pass), filters u and yhat through 1/F for
//! the Jacobian, builds the normal equations from lagged dot products, solves a d x d system
//! and simulates the trial point. The d x d solve is private to the solver, so instead of
//! timing it alone, `one_iteration` times a whole `minimise` capped at one iteration; the
//! difference to the sum of the kernels is the solve plus bookkeeping.
//!
//! Run: `cargo bench --bench kernels` (under a minute).

use oesweep::oe::Structure;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use oesweep::estimate::normal::{Layout, NormalEquations, SeveralForm};
use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace, solver};
use oesweep::oe;

const NB: usize = 12;
const NF: usize = 12;
const DELAY: usize = 1;
/// The paper's k for M2.
const K: f64 = 0.0875;

/// The bundled estimation record and the two points the Huber phase runs between: theta_LS
/// (its start) and theta_H (its solution), with gamma = K sigma_LS.
struct Setup {
    u: Vec<f64>,
    y: Vec<f64>,
    theta_ls: Vec<f64>,
    theta_h: Vec<f64>,
    gamma: f64,
}

fn setup() -> Setup {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data/piezo_est.csv");
    let rec = oesweep::data::read_record(&path, "u", "y").expect("bundled estimation data");
    let (u, y) = (rec.u, rec.y);
    let prob =
        Problem { u: &u, y: &y, structure: Structure::siso(NB, NF, DELAY), offset: false, seams: &[], missing: &[] };
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    let ls = estimate::fit_ls(&prob, &Judge::default(), &opts, &mut ws);
    let gamma = K * ls.sigma;
    let theta_ls = ls.theta();
    let theta_h = solver::minimise(&prob, Loss::Huber { gamma }, &theta_ls, &opts, &mut ws).theta;
    Setup { u, y, theta_ls, theta_h, gamma }
}

/// Inputs of `NormalEquations::build` at `theta`, as the solver forms them: the 1/F-filtered
/// u and yhat, and the residuals e.
fn jacobian_sequences(s: &Setup, theta: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (b, f) = theta.split_at(NB);
    let yhat = oe::simulate_vec(b, f, DELAY, &s.u);
    let e: Vec<f64> = s.y.iter().zip(&yhat).map(|(y, yh)| y - yh).collect();
    let mut xu = s.u.clone();
    oe::inv_f_in_place(f, &mut xu);
    let mut xy = yhat;
    oe::inv_f_in_place(f, &mut xy);
    (xu, xy, e)
}

/// Exact Gauss-Newton Huber weights (1 on the L2 set, 0 on the L1 set) and psi_g(e).
fn huber_weights(e: &[f64], gamma: f64) -> (Vec<f64>, Vec<f64>) {
    let w = e.iter().map(|x| if x.abs() <= gamma { 1.0 } else { 0.0 }).collect();
    let r = e.iter().map(|x| x.clamp(-gamma, gamma)).collect();
    (w, r)
}

fn filters(c: &mut Criterion, s: &Setup) {
    let (b, f) = s.theta_h.split_at(NB);
    let mut out = vec![0.0; s.u.len()];
    c.bench_function("simulate", |bch| bch.iter(|| oe::simulate(black_box(b), black_box(f), DELAY, &s.u, &mut out)));
    // What a solver trial step filters: (1/F)u, yhat and (1/F)yhat in one fused pass (against
    // `simulate` plus a second `inv_f` done separately).
    let (mut xu, mut xy) = (vec![0.0; s.u.len()], vec![0.0; s.u.len()]);
    c.bench_function("simulate_filtered", |bch| {
        bch.iter(|| oe::simulate_filtered(black_box(b), black_box(f), DELAY, &s.u, &mut xu, &mut out, &mut xy))
    });
    // Filtering in place repeatedly would compound the DC gain of 1/F towards overflow, so each
    // pass starts from a fresh copy of u; the 40 kB copy is ~1 us of the measured time.
    c.bench_function("inv_f", |bch| {
        bch.iter(|| {
            out.copy_from_slice(&s.u);
            oe::inv_f_in_place(black_box(f), &mut out)
        })
    });
}

fn normal_equations(c: &mut Criterion, s: &Setup) {
    let lay = Layout::siso(NB, NF, DELAY);
    let d = lay.dim();
    let (mut h, mut g) = (vec![0.0; d * d], vec![0.0; d]);
    let mut ne = NormalEquations::default();
    let mut group = c.benchmark_group("normal_equations");

    // L2 phase: all weights 1, Gram matrix from lagged dot products only.
    let (xu, xy, e) = jacobian_sequences(s, &s.theta_ls);
    group.bench_function(BenchmarkId::from_parameter("unweighted"), |bch| {
        bch.iter(|| ne.build(&lay, black_box(&xu), black_box(&xy), None, &e, &mut h, &mut g))
    });

    // Huber phase, two regimes of the same build: at its solution only the spikes (~5 %) are
    // in the L1 set and are subtracted from the Gram matrix; at its start, theta_LS, most
    // residuals exceed gamma = k sigma and the L2 rows are summed directly instead.
    for (name, theta) in [("huber_solution", &s.theta_h), ("huber_start", &s.theta_ls)] {
        let (xu, xy, e) = jacobian_sequences(s, theta);
        let (w, r) = huber_weights(&e, s.gamma);
        let zeros = w.iter().filter(|&&x| x == 0.0).count();
        eprintln!("normal_equations/{name}: {:.1} % of rows have weight 0", 100.0 * zeros as f64 / w.len() as f64);
        group.bench_function(BenchmarkId::from_parameter(name), |bch| {
            bch.iter(|| ne.build(&lay, black_box(&xu), black_box(&xy), Some(&w), &r, &mut h, &mut g))
        });
    }
    group.finish();
}

fn one_iteration(c: &mut Criterion, s: &Setup) {
    let prob = Problem {
        u: &s.u,
        y: &s.y,
        structure: Structure::siso(NB, NF, DELAY),
        offset: false,
        seams: &[],
        missing: &[],
    };
    let opts = SolverOptions { max_iterations: 1, ..Default::default() };
    let loss = Loss::Huber { gamma: s.gamma };
    let mut ws = Workspace::new();
    // From theta_LS, as the first iteration of the Huber phase: includes the start-point
    // simulation and criterion that every minimise call pays once.
    c.bench_function("one_iteration", |bch| {
        bch.iter(|| solver::minimise(black_box(&prob), loss, &s.theta_ls, &opts, &mut ws))
    });
}

/// The normal equations of several inputs in both forms (`SeveralForm`): m = 2, 3 inputs of
/// OE(n, n), d = 1, each input's nB + nF = 2, 6, 12, 24, N = 3000, with an offset; all weights
/// 1 (least squares) and 5 % of the rows at weight 0 (a Huber solution's L1 set). The
/// sequences are random: the time does not depend on their values. The two forms of one size
/// run one after the other, so drifts of the machine touch both alike.
fn normal_equations_several(c: &mut Criterion) {
    const N: usize = 3000;
    let mut s = 99u64;
    let mut next = move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let mut group = c.benchmark_group("normal_equations_several");
    for m in [2, 3] {
        let xu: Vec<f64> = (0..m * N).map(|_| next()).collect();
        let xy: Vec<f64> = (0..m * N).map(|_| next()).collect();
        let r: Vec<f64> = (0..N).map(|_| next()).collect();
        let w: Vec<f64> = (0..N).map(|t| if (t * 7919) % 100 < 5 { 0.0 } else { 1.0 }).collect();
        for per_input in [2, 6, 12, 24] {
            let o = oesweep::structure::Orders { nb: per_input / 2, nf: per_input / 2, delay: 1 };
            let lay = Layout::new(Structure::new(&vec![o; m]).expect("m inputs"));
            let d = lay.dim() + 1;
            let (mut h, mut g) = (vec![0.0; d * d], vec![0.0; d]);
            let mut ne = NormalEquations::default();
            for (regime, weights) in [("ls", None), ("huber", Some(&w[..]))] {
                for (name, form) in [("rows", SeveralForm::Rows), ("correlations", SeveralForm::Correlations)] {
                    let id = BenchmarkId::new(name, format!("m{m}_d{per_input}_{regime}"));
                    group.bench_function(id, |bch| {
                        bch.iter(|| {
                            ne.build_several(form, &lay, true, &[], black_box(&xu), &xy, weights, &r, &mut h, &mut g)
                        })
                    });
                }
            }
        }
    }
    group.finish();
}

fn kernels(c: &mut Criterion) {
    normal_equations_several(c);
    let s = setup();
    filters(c, &s);
    normal_equations(c, &s);
    one_iteration(c, &s);
}

fn config() -> Criterion {
    // Kernels take 10-500 us, so 2 s per benchmark already gives thousands of calls.
    Criterion::default()
        .sample_size(30)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        // Plot rendering (plotters backend) took longer than the measurements themselves.
        .without_plots()
}

criterion_group! {
    name = benches;
    config = config();
    targets = kernels
}
criterion_main!(benches);
