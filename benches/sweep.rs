//! Whole-sweep throughput (cells/s) on a small grid, with 1 and 2 worker threads (issue 4).
//!
//! The grid is a slice of the paper's (nB 9..10, nF 8..11, 6 values of k) on the bundled
//! estimation record, with the default solver settings and the default start strategy
//! (`chains`), so cells/s here is what a user's sweep sees (least-squares phase included).
//! Throughput is reported per Huber cell. With `chains` the work is split by order pair, so
//! on this small grid (8 pairs) the 2-thread figure also shows how the last pairs balance.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use oesweep::data::read_record;
use oesweep::estimate::SolverOptions;
use oesweep::job::StartStrategy;
use oesweep::plan::{Plan, Structure};
use oesweep::progress::Progress;
use oesweep::sweep::{self, Context, Control};
use std::path::Path;
use std::time::Duration;

fn sweep_throughput(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let est = read_record(&root.join("jobs/data/piezo_est.csv"), "u", "y").expect("bundled data");
    let pairs: Vec<Structure> = (9..=10).flat_map(|nb| (8..=11).map(move |nf| Structure::siso(nb, nf, 1))).collect();
    let ks = vec![0.05, 0.0875, 0.15, 0.3, 0.6, 1.2];
    let plan = Plan { pairs, ks, start: StartStrategy::default(), ls_support: Vec::new() };
    let ctx = Context {
        est: &est,
        val: None,
        band: None,
        solver: SolverOptions::default(),
        levels: oesweep::data::Levels::none(),
        initial_state: oesweep::estimate::InitialState::Zero,
        profile: None,
    };
    let mut group = c.benchmark_group("sweep");
    group.sample_size(10).measurement_time(Duration::from_secs(20)).warm_up_time(Duration::from_secs(1));
    group.throughput(Throughput::Elements(plan.n_cells() as u64));
    for threads in [1, 2] {
        group.bench_with_input(BenchmarkId::new("threads", threads), &threads, |b, &threads| {
            b.iter(|| {
                let progress = Progress::new(plan.n_cells(), true);
                sweep::run(&plan, &ctx, threads, &progress, Control::none()).expect("the workers start")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, sweep_throughput);
criterion_main!(benches);
