//! The full-product sweep of several inputs (issue 46, landing 3): a two-input record swept
//! over the product of the inputs' order grids picks every input's true orders; the table is
//! the same on 1 and 2 threads and after a resume; `cells.parquet` has the per-input order
//! columns `nb_1 .. nf_2 .. delay_2` (plain integers a filter takes) and reads back equal.

mod common;

use common::*;
use oesweep::data::{Levels, Record};
use oesweep::estimate::{InitialState, SolverOptions};
use oesweep::export::parquet::{read_cells, write_cells};
use oesweep::job::StartStrategy;
use oesweep::oe::{self, Orders, Structure};
use oesweep::plan::{Plan, embed, one_input_orders, sub_structures};
use oesweep::progress::Progress;
use oesweep::reduce::{FitBasis, ReduceOptions, select};
use oesweep::sweep::{self, Context, Control};
use oesweep::table::{CellRow, RowKey};

/// Per input (b, f, delay): OE(2,2) with delay 1 and OE(1,1) with delay 2.
fn system() -> Vec<(Vec<f64>, Vec<f64>, usize)> {
    vec![(vec![1.0, 0.5], vec![-1.5, 0.7], 1), (vec![0.8], vec![-0.9], 2)]
}

/// A record of the two inputs (input after input) with low Gaussian noise and a few spikes.
fn record(n: usize, seed: u64) -> Record {
    let mut u = Vec::new();
    let mut y = vec![0.0; n];
    for (i, (b, f, d)) in system().iter().enumerate() {
        let ui = binary_input(n, 4 + 3 * i, 1.0, seed * 10 + i as u64);
        for (t, v) in oe::simulate_vec(b, f, *d, &ui).into_iter().enumerate() {
            y[t] += v;
        }
        u.extend_from_slice(&ui);
    }
    let mut rng = Lcg(seed + 100);
    for (t, v) in y.iter_mut().enumerate() {
        *v += 0.01 * rng.normal() + if t % 97 == 13 { 1.0 } else { 0.0 };
    }
    Record {
        path: "simulated".into(),
        u,
        y,
        u_names: vec!["u1".into(), "u2".into()],
        y_name: "y".into(),
        seams: Vec::new(),
        missing: Vec::new(),
    }
}

/// nB, nF in 1..2 for each input at its true delay, two k.
fn plan() -> Plan {
    let per_input: Vec<Vec<Orders>> =
        system().iter().map(|(_, _, d)| one_input_orders(&[1, 2], &[1, 2], &[*d])).collect();
    Plan::product(&per_input, vec![0.5, 1.5], StartStrategy::Chains)
}

fn context<'a>(est: &'a Record, val: &'a Record) -> Context<'a> {
    Context {
        est,
        val: Some(val),
        band: None,
        solver: SolverOptions::default(),
        levels: Levels::none(),
        initial_state: InitialState::default(),
        profile: None,
    }
}

fn sweep_rows(plan: &Plan, est: &Record, val: &Record, threads: usize, done: Vec<CellRow>) -> Vec<CellRow> {
    sweep_with(plan, est, val, threads, Control { done, ..Control::none() })
}

fn sweep_with(plan: &Plan, est: &Record, val: &Record, threads: usize, control: Control) -> Vec<CellRow> {
    let ctx = context(est, val);
    let out = sweep::run(plan, &ctx, threads, &Progress::new(0, true), control).expect("the sweep runs");
    assert!(!out.interrupted);
    let mut rows = out.rows;
    for r in &mut rows {
        r.fit.seconds = 0.0;
    }
    rows
}

fn o(nb: usize, nf: usize, delay: usize) -> Orders {
    Orders { nb, nf, delay }
}

#[test]
fn the_product_plan_of_one_input_is_the_one_input_plan_and_of_two_the_product() {
    let one = Plan::product(&[one_input_orders(&[1, 2], &[1, 2, 3], &[0, 1])], vec![1.0], StartStrategy::Chains);
    let want: Vec<Structure> = [0, 1]
        .iter()
        .flat_map(|&d| {
            [1, 2].into_iter().flat_map(move |b| [1, 2, 3].into_iter().map(move |f| Structure::siso(b, f, d)))
        })
        .collect();
    assert_eq!(one.pairs, want);
    let p = plan();
    assert_eq!((p.pairs.len(), p.n_cells(), p.m()), (16, 32, 2));
    // Input 1 slowest.
    assert_eq!(p.pairs[0], Structure::new(&[o(1, 1, 1), o(1, 1, 2)]).unwrap());
    assert_eq!(p.pairs[1], Structure::new(&[o(1, 1, 1), o(1, 2, 2)]).unwrap());
    assert_eq!(p.pairs[4], Structure::new(&[o(1, 2, 1), o(1, 1, 2)]).unwrap());
    // Every pair's sub-models drop one order of one input; each is found in the plan.
    let s = Structure::new(&[o(2, 2, 1), o(1, 2, 2)]).unwrap();
    let subs = sub_structures(&s);
    assert_eq!(
        subs,
        vec![
            Structure::new(&[o(1, 2, 1), o(1, 2, 2)]).unwrap(),
            Structure::new(&[o(2, 1, 1), o(1, 2, 2)]).unwrap(),
            Structure::new(&[o(2, 2, 1), o(0, 2, 2)]).unwrap(),
            Structure::new(&[o(2, 2, 1), o(1, 1, 2)]).unwrap(),
        ]
    );
    let at = p.pairs.iter().position(|q| *q == s).unwrap();
    assert_eq!(p.ls_sub_models()[at].len(), 3, "(0, 2) of input 2 is not in the grid");
    // A sub-model's theta lands on its inputs' leading coefficients, the rest zero.
    let sub = subs[3];
    let theta = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];
    assert_eq!(embed(&theta, &sub, &s, true), vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 0.0, 7.0]);
}

#[test]
fn a_two_input_sweep_picks_the_true_orders_and_is_the_same_on_any_thread_count() {
    let (est, val) = (record(1500, 1), record(1500, 2));
    let plan = plan();
    let rows = sweep_rows(&plan, &est, &val, 1, Vec::new());
    assert_eq!(rows.len(), 16 + 32);
    assert!(rows.iter().all(|r| r.ok() && r.key.m() == 2), "every fit usable");
    let truth = Structure::new(&[o(2, 2, 1), o(1, 1, 2)]).unwrap();
    for r in rows.iter().filter(|r| r.key.structure() == truth) {
        let theta: Vec<f64> = r.fit.b.iter().chain(&r.fit.f).copied().collect();
        let want = [1.0, 0.5, 0.8, -1.5, 0.7, -0.9];
        for (g, w) in theta.iter().zip(want) {
            assert!((g - w).abs() < 0.05, "{}: {theta:?}", r.key);
        }
    }
    let sel = select(&rows, &ReduceOptions::new(FitBasis::Validation));
    let m1 = sel.m1.as_ref().expect("an M1 pick");
    assert_eq!(m1.model.key.structure(), truth, "{}", m1.rule);
    let m2 = sel.m2.as_ref().expect("an M2 pick");
    assert_eq!(m2.model.key.structure(), truth, "{}", m2.rule);
    // The pick's JSON holds every input's orders and reads back.
    let json = serde_json::to_value(m1).unwrap();
    assert_eq!((json["nb_1"].as_u64(), json["nb_2"].as_u64(), json["delay_2"].as_u64()), (Some(2), Some(1), Some(2)));
    assert_eq!(json["b"], serde_json::json!([m1.model.fit.b[..2], m1.model.fit.b[2..]]));
    let back: oesweep::reduce::Candidate = serde_json::from_value(json).unwrap();
    assert_eq!(back.key, m1.model.key);

    let two = sweep_rows(&plan, &est, &val, 2, Vec::new());
    assert!(two == rows, "the table of 2 threads differs from 1 thread's");

    // A resumed run (half the rows done) gives the same table.
    let done: Vec<CellRow> = rows.iter().filter(|r| r.key.nb == 1).cloned().collect();
    let resumed = sweep_rows(&plan, &est, &val, 2, done);
    assert!(resumed == rows, "a resumed run's table differs");
}

#[test]
fn shards_of_a_two_input_plan_merged_give_the_whole_runs_table() {
    let (est, val) = (record(800, 7), record(800, 8));
    let plan = plan();
    let whole = sweep_rows(&plan, &est, &val, 1, Vec::new());
    let mut merged = Vec::new();
    for index in 0..3 {
        let (own, _) = oesweep::shard::plan_of(&plan, oesweep::shard::Shard { index, count: 3 });
        assert!(own.pairs.len() < plan.pairs.len());
        merged.extend(sweep_with(&own, &est, &val, 1, Control { nested: false, ..Control::none() }));
    }
    sweep::nested_pass(&plan, &context(&est, &val), &mut merged, 1).unwrap();
    oesweep::table::sort_rows(&mut merged);
    for r in &mut merged {
        r.fit.seconds = 0.0;
    }
    assert!(merged == whole, "the merged shards' table differs from the whole run's");
}

#[test]
fn a_two_input_table_has_order_columns_per_input_and_reads_back_equal() {
    let (est, val) = (record(600, 3), record(600, 4));
    let per_input = vec![one_input_orders(&[1], &[1, 2], &[1]), one_input_orders(&[1], &[1], &[2])];
    let plan = Plan::product(&per_input, vec![1.0], StartStrategy::Chains);
    let mut rows = sweep_rows(&plan, &est, &val, 1, Vec::new());
    rows.push(CellRow::failed(RowKey::huber(&plan.pairs[0], 7), Some(3.0), "a failed cell".into()));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cells.parquet");
    write_cells(&path, &rows).unwrap();
    assert_eq!(read_cells(&path).unwrap(), rows);

    use polars::prelude::*;
    let df = ParquetReader::new(std::fs::File::open(&path).unwrap()).finish().unwrap();
    for name in ["nb_1", "nb_2", "nf_1", "nf_2", "delay_1", "delay_2"] {
        assert_eq!(df.column(name).unwrap().dtype(), &DataType::UInt32, "{name}");
    }
    assert!(df.column("nb").is_err() && df.column("nf").is_err());
    let b = df.column("b").unwrap();
    assert_eq!(b.dtype(), &DataType::List(Box::new(DataType::List(Box::new(DataType::Float64)))));
    let nf_1 = df.column("nf_1").unwrap().u32().unwrap().equal(2u32);
    let huber = df.column("method").unwrap().str().unwrap().equal("huber");
    let picked = df.filter(&(nf_1 & huber)).unwrap();
    assert_eq!(picked.height(), 1);

    // An edited file whose coefficients do not fit the orders is refused with one line.
    let mut bad = rows.clone();
    let i = bad.iter().position(|r| r.ok() && r.key.nf == 2).unwrap();
    bad[i].key = bad[i].key.with(0, o(1, 1, 1));
    write_cells(&path, &bad).unwrap();
    let err = read_cells(&path).unwrap_err().to_string();
    assert!(err.contains("`f`") && err.contains("cells.parquet") && !err.contains('\n'), "{err}");
}

#[test]
fn the_reducer_names_the_input_at_the_grids_edge() {
    use oesweep::reduce::doubts::{GridBounds, pick_warnings, pick_warnings_per_input};
    let (est, val) = (record(600, 5), record(600, 6));
    let per_input = vec![one_input_orders(&[2], &[1, 2], &[1]), one_input_orders(&[1], &[1, 2], &[2])];
    let plan = Plan::product(&per_input, vec![1.0], StartStrategy::Chains);
    let rows = sweep_rows(&plan, &est, &val, 1, Vec::new());
    let sel = select(&rows, &ReduceOptions::new(FitBasis::Estimation));
    let grid = GridBounds { nb: (1, 2), nf: (1, 2), delay: (0, 3) };
    let warnings = pick_warnings(&sel, &rows, &grid, &[]);
    assert!(warnings.iter().any(|w| w.contains("input 1's largest nB")), "{warnings:?}");
    assert!(warnings.iter().all(|w| w.contains("OE(2,")), "{warnings:?}");
    // Per-input ranges: input 2's nF went up to 5, so only input 1 is on an edge.
    let grids = [grid, GridBounds { nb: (1, 1), nf: (1, 5), delay: (2, 2) }];
    let warnings = pick_warnings_per_input(&sel, &rows, &grids, &[]);
    assert!(warnings.iter().any(|w| w.contains("input 1's largest nB")), "{warnings:?}");
    assert!(warnings.iter().all(|w| !w.contains("input 2's")), "{warnings:?}");
}
