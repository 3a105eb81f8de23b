//! One solver iteration's kernels for 1, 2 and 4 fits side by side (`kernels::simulate_filtered_lanes`,
//! `kernels/lanes.rs`), at OE(4,4), OE(10,10) and OE(14,15) on the bundled N = 5000 record,
//! reported per fit: every benchmark times L fits and reports the time divided by L.
//!
//! One Levenberg-Marquardt iteration of one fit (`estimate::solver`) is: the trial point's
//! simulation and Jacobian signals (the lane kernel), its criterion, the residual influence and
//! row weights, and the normal equations from lagged correlations (each lane on its own
//! signals: these kernels are already four samples wide within a fit). Left out: the d x d
//! Cholesky solve and the stability test of the trial F (d^3/6 and a root finding, private to
//! the solver). Benchmarks:
//! - `simulate_filtered/OE(nb,nf)/L`: the simulation alone;
//! - `iteration_ls/OE(nb,nf)/L`: least squares (no row weights: the correlations only);
//! - `iteration_huber/OE(nb,nf)/L`: Huber at gamma = sigma_LS with the Gauss-Newton weights,
//!   the spikes at weight 0 (a Huber solution's few reweighted rows; the share is printed).
//!
//! The lanes' models: the pair's least-squares fit on the record, lane l with its poles
//! scaled by 1 - 0.002 l and its B by 1 + 0.01 l (different parameters, one structure).
//!
//! Run: `cargo bench --bench lanes` (about two minutes). The fastest of many single calls,
//! interleaved: `LANES_BEST=1001 cargo bench --bench lanes`. Instruction counts, which the load of
//! a shared machine does not move: `LANES_COUNT=20 LANES_ORDER=10,10 valgrind --tool=callgrind
//! --toggle-collect='*lanes::count*' <the bench binary>`, then `callgrind_annotate --inclusive=yes`
//! gives each `count::<L, KIND>` (valgrind lacks AVX-512, so four lanes run there as two
//! pairs).

use std::hint::black_box;
use std::path::Path;
use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, criterion_group};
use oesweep::estimate::normal::{Layout, NormalEquations};
use oesweep::estimate::{self, Judge, Loss, Problem, SolverOptions, Workspace};
use oesweep::kernels::{Lane, simulate_filtered_lanes};
use oesweep::oe::Structure;

const ORDERS: [(usize, usize); 3] = [(4, 4), (10, 10), (14, 15)];
const DELAY: usize = 1;
const LANES: [usize; 3] = [1, 2, 4];

/// One fit's buffers: its polynomials, signals and normal equations.
struct Fit {
    b: Vec<f64>,
    f: Vec<f64>,
    xu: Vec<f64>,
    yhat: Vec<f64>,
    xy: Vec<f64>,
    r: Vec<f64>,
    w: Vec<f64>,
    h: Vec<f64>,
    g: Vec<f64>,
    ne: NormalEquations,
}

struct Record {
    u: Vec<f64>,
    y: Vec<f64>,
}

/// The pair's least-squares fit and its sigma.
fn least_squares(rec: &Record, nb: usize, nf: usize) -> (Vec<f64>, f64) {
    let prob = Problem {
        u: &rec.u,
        y: &rec.y,
        structure: Structure::siso(nb, nf, DELAY),
        offset: false,
        seams: &[],
        missing: &[],
    };
    let ls = estimate::fit_ls(&prob, &Judge::default(), &SolverOptions::default(), &mut Workspace::new());
    (ls.theta(), ls.sigma)
}

/// `count` fits around theta: lane l's poles scaled by 1 - 0.002 l (`f_j (1 - 0.002 l)^j`)
/// and its B by 1 + 0.01 l.
fn fits(theta: &[f64], nb: usize, nf: usize, n: usize, count: usize) -> Vec<Fit> {
    let d = nb + nf;
    (0..count)
        .map(|l| {
            let rho = 1.0 - 0.002 * l as f64;
            let scale = 1.0 + 0.01 * l as f64;
            Fit {
                b: theta[..nb].iter().map(|v| v * scale).collect(),
                f: theta[nb..].iter().enumerate().map(|(j, v)| v * rho.powi(j as i32 + 1)).collect(),
                xu: vec![0.0; n],
                yhat: vec![0.0; n],
                xy: vec![0.0; n],
                r: vec![0.0; n],
                w: vec![0.0; n],
                h: vec![0.0; d * d],
                g: vec![0.0; d],
                ne: NormalEquations::default(),
            }
        })
        .collect()
}

fn simulate(u: &[f64], fits: &mut [Fit]) {
    let mut lanes: Vec<Lane> =
        fits.iter_mut().map(|f| Lane { b: &f.b, f: &f.f, xu: &mut f.xu, yhat: &mut f.yhat, xy: &mut f.xy }).collect();
    simulate_filtered_lanes(DELAY, u, &mut lanes);
}

/// One iteration's kernels for every fit: the lanes' simulation, then per fit the criterion,
/// the residual influence and weights (as `solver::minimise` forms them) and the normal
/// equations. Returns the criteria's sum (kept from the optimiser).
fn iteration(rec: &Record, lay: &Layout, loss: Loss, fits: &mut [Fit]) -> f64 {
    simulate(&rec.u, fits);
    let mut total = 0.0;
    for fit in fits.iter_mut() {
        total += loss.criterion(&rec.y, &fit.yhat);
        let w = match loss {
            Loss::LeastSquares => {
                for ((r, &y), &yh) in fit.r.iter_mut().zip(&rec.y).zip(&fit.yhat) {
                    *r = y - yh;
                }
                None
            }
            Loss::Huber { gamma } => {
                let rows = fit.r.iter_mut().zip(fit.w.iter_mut()).zip(rec.y.iter().zip(&fit.yhat));
                for ((r, w), (&y, &yh)) in rows {
                    let e = y - yh;
                    *r = e.clamp(-gamma, gamma);
                    *w = if e.abs() <= gamma { 1.0 } else { 0.0 };
                }
                Some(&fit.w[..])
            }
        };
        fit.ne.build(lay, &fit.xu, &fit.xy, w, &fit.r, &mut fit.h, &mut fit.g);
    }
    total
}

/// Times `run` on L fits and reports per fit: criterion sees the time of one call over L.
fn per_fit(bch: &mut criterion::Bencher, lanes: usize, mut run: impl FnMut()) {
    bch.iter_custom(|iters| {
        let start = Instant::now();
        for _ in 0..iters {
            run();
        }
        start.elapsed() / lanes as u32
    });
}

/// An order pair, its least-squares fit (the lanes' starting point) and sigma (their gamma).
type Pair = (usize, usize, Vec<f64>, f64);

/// The bundled record and the pairs of the orders `keep` keeps.
fn setup(keep: impl Fn(usize, usize) -> bool) -> (Record, Vec<Pair>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/data/piezo_est.csv");
    let data = oesweep::data::read_record(&path, "u", "y").expect("bundled estimation data");
    let rec = Record { u: data.u, y: data.y };
    let pairs = ORDERS
        .iter()
        .filter(|&&(nb, nf)| keep(nb, nf))
        .map(|&(nb, nf)| {
            let (theta, sigma) = least_squares(&rec, nb, nf);
            (nb, nf, theta, sigma)
        })
        .collect();
    (rec, pairs)
}

fn lanes(c: &mut Criterion) {
    let (rec, pairs) = setup(|_, _| true);
    let n = rec.u.len();
    for (nb, nf, theta, sigma) in pairs {
        let lay = Layout::siso(nb, nf, DELAY);
        let order = format!("OE({nb},{nf})");
        let huber = Loss::Huber { gamma: sigma };
        {
            let mut probe = fits(&theta, nb, nf, n, 1);
            iteration(&rec, &lay, huber, &mut probe);
            let zeros = probe[0].w.iter().filter(|&&w| w == 0.0).count();
            eprintln!("{order}: {:.1} % of the rows at weight 0 in iteration_huber", 100.0 * zeros as f64 / n as f64);
        }
        for count in LANES {
            let mut batch = fits(&theta, nb, nf, n, count);
            let id = BenchmarkId::new(&order, count);
            let mut group = c.benchmark_group("simulate_filtered");
            group.bench_function(id.clone(), |bch| per_fit(bch, count, || simulate(black_box(&rec.u), &mut batch)));
            group.finish();
            let mut group = c.benchmark_group("iteration_ls");
            group.bench_function(id.clone(), |bch| {
                per_fit(bch, count, || {
                    black_box(iteration(&rec, &lay, Loss::LeastSquares, &mut batch));
                })
            });
            group.finish();
            let mut group = c.benchmark_group("iteration_huber");
            group.bench_function(id, |bch| {
                per_fit(bch, count, || {
                    black_box(iteration(&rec, &lay, huber, &mut batch));
                })
            });
            group.finish();
        }
    }
}

fn config() -> Criterion {
    // The kernels take 10-200 us: 2 s per benchmark gives thousands of calls.
    Criterion::default()
        .sample_size(30)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2))
        .without_plots()
}

/// `REPS` calls of one benchmark's work on `L` fits, for an instruction count under
/// `valgrind --tool=callgrind --toggle-collect='*lanes::count*'` (one symbol per lane count and
/// kind: 0 simulate_filtered, 1 iteration_ls, 2 iteration_huber).
#[inline(never)]
fn count<const L: usize, const KIND: u8>(rec: &Record, lay: &Layout, huber: Loss, batch: &mut [Fit], reps: usize) {
    // L in the body keeps the lane counts' functions apart (identical bodies would be merged).
    assert_eq!(batch.len(), L, "one batch of L fits");
    for _ in 0..reps {
        match KIND {
            0 => simulate(&rec.u, batch),
            1 => _ = black_box(iteration(rec, lay, Loss::LeastSquares, batch)),
            _ => _ = black_box(iteration(rec, lay, huber, batch)),
        }
    }
}

/// `LANES_COUNT=reps cargo bench --bench lanes`: instead of timing, every benchmark's work
/// `reps` times in its own `count` call (what `valgrind --tool=callgrind` counts; load does not
/// move instruction counts, where it moves the times of this shared machine).
/// `LANES_ORDER=nb,nf` counts that order only (one order per valgrind run: the `count` symbols
/// do not name the order).
fn counting(reps: usize) {
    let only = std::env::var("LANES_ORDER").ok();
    let (rec, pairs) = setup(|nb, nf| only.as_ref().is_none_or(|o| *o == format!("{nb},{nf}")));
    let n = rec.u.len();
    for (nb, nf, theta, sigma) in pairs {
        let lay = Layout::siso(nb, nf, DELAY);
        let huber = Loss::Huber { gamma: sigma };
        macro_rules! each {
            ($($l:literal)*) => {$(
                let mut batch = fits(&theta, nb, nf, n, $l);
                count::<$l, 0>(&rec, &lay, huber, &mut batch, reps);
                count::<$l, 1>(&rec, &lay, huber, &mut batch, reps);
                count::<$l, 2>(&rec, &lay, huber, &mut batch, reps);
            )*};
        }
        each!(1 2 4);
    }
}

/// `LANES_BEST=runs cargo bench --bench lanes`: instead of criterion, every benchmark's work
/// timed one call at a time, `runs` rounds with the lane counts and kinds interleaved in each,
/// and the fastest call of each printed per fit: on a machine shared with other work, the
/// fastest of many calls of some tens of microseconds is one no other process interrupted,
/// where criterion's means and medians carry the load.
fn best_of(runs: usize) {
    let (rec, pairs) = setup(|_, _| true);
    let n = rec.u.len();
    for (nb, nf, theta, sigma) in pairs {
        let lay = Layout::siso(nb, nf, DELAY);
        let huber = Loss::Huber { gamma: sigma };
        let mut batches: Vec<Vec<Fit>> = LANES.iter().map(|&l| fits(&theta, nb, nf, n, l)).collect();
        let mut best = [[f64::INFINITY; 3]; LANES.len()];
        for _ in 0..runs {
            for (batch, best) in batches.iter_mut().zip(best.iter_mut()) {
                for (kind, b) in best.iter_mut().enumerate() {
                    let start = Instant::now();
                    match kind {
                        0 => simulate(&rec.u, batch),
                        1 => _ = black_box(iteration(&rec, &lay, Loss::LeastSquares, batch)),
                        _ => _ = black_box(iteration(&rec, &lay, huber, batch)),
                    }
                    *b = b.min(start.elapsed().as_secs_f64() / batch.len() as f64);
                }
            }
        }
        for (l, b) in LANES.iter().zip(&best) {
            println!(
                "OE({nb},{nf}) {l} lanes, per fit: simulate_filtered {:.1} us, iteration_ls {:.1} us, iteration_huber {:.1} us",
                b[0] * 1e6,
                b[1] * 1e6,
                b[2] * 1e6
            );
        }
    }
}

criterion_group! {
    name = benches;
    config = config();
    targets = lanes
}

fn main() {
    if let Ok(runs) = std::env::var("LANES_BEST") {
        return best_of(runs.parse().expect("LANES_BEST: a number of rounds"));
    }
    match std::env::var("LANES_COUNT") {
        Ok(reps) => counting(reps.parse().expect("LANES_COUNT: a number of repetitions")),
        Err(_) => {
            benches();
            Criterion::default().configure_from_args().final_summary();
        }
    }
}
