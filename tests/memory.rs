//! Memory O(N) with a small constant (issue 19): a worker's whole order pair (initial
//! guesses, least-squares phase, the Huber chains over k with their evidence, the judged fits
//! on a validation record) holds at most [`BUDGET`] estimation-record-length vectors of f64 at
//! its peak, whatever N, and with both solvers. A global allocator tracks the live heap; the
//! records themselves are allocated before the baseline (they are shared by all workers).

mod common;

use common::*;
use oesweep::estimate::chains::{CellOutcome, walk_pair};
use oesweep::estimate::{self, InitialState, Judge, PairProblem, Problem, SolverMethod, SolverOptions, Workspace};
use oesweep::oe;
use oesweep::oe::Structure;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// N-length f64 vectors a worker may hold at once (`estimate::Workspace` documents them).
const BUDGET: usize = Workspace::RECORD_VECTORS;

struct Tracking;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

fn grow(bytes: usize) {
    let now = LIVE.fetch_add(bytes, Ordering::SeqCst) + bytes;
    PEAK.fetch_max(now, Ordering::SeqCst);
}

// SAFETY: forwards to the system allocator, only counting bytes.
unsafe impl GlobalAlloc for Tracking {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grow(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Ordering::SeqCst);
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        grow(new_size);
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        LIVE.fetch_sub(layout.size(), Ordering::SeqCst);
        p
    }
}

#[global_allocator]
static GLOBAL: Tracking = Tracking;

/// Peak bytes above the baseline while one worker estimates OE(4,4) with an offset on an
/// N-sample record (validation N/4), in units of N-length f64 vectors.
fn peak_vectors(n: usize, method: SolverMethod) -> f64 {
    let (b, f) = (vec![0.4, 0.2, -0.1, 0.05], oe::poly_from_roots(&[(0.6, 0.5), (0.6, -0.5), (0.8, 0.0), (-0.3, 0.0)]));
    let u = binary_input(n + n / 4, 5, 1.0, 3);
    let y0 = oe::simulate_vec(&b, &f, 1, &u);
    let mut rng = Lcg(9);
    let y: Vec<f64> =
        y0.iter().map(|v| v + 3.0 + 0.02 * rng.normal() + if rng.next() < 0.05 { 2.0 } else { 0.0 }).collect();
    let (ue, ye, uv, yv) = (&u[..n], &y[..n], &u[n..], &y[n..]);
    let prob = Problem { u: ue, y: ye, structure: Structure::siso(4, 4, 1), offset: true, seams: &[], missing: &[] };
    let judge = Judge { validation: Some((uv, yv)), initial_state: InitialState::Estimate, ..Judge::default() };
    let opts = SolverOptions { method, ..SolverOptions::default() };
    let ks: Vec<(usize, f64)> = (0..6).map(|i| (i, 0.05 * 40f64.powf(i as f64 / 5.0))).collect();
    let done = vec![false; ks.len()];

    let base = LIVE.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let mut ws = Workspace::new();
    let ls = estimate::fit_ls(&prob, &judge, &opts, &mut ws);
    assert!(ls.ok());
    let pair = PairProblem { prob: &prob, sigma: ls.sigma, judge: &judge, opts: &opts };
    let cells = walk_pair(&pair, &ls.theta(), &ls.alternatives, &ks, &done, &|| false, &mut ws).unwrap();
    assert!(cells.iter().all(|(_, c)| matches!(c, CellOutcome::Fit { .. })));
    let peak = PEAK.load(Ordering::SeqCst) - base;
    drop((cells, ws, ls));
    peak as f64 / (8 * n) as f64
}

#[test]
fn a_worker_holds_a_fixed_number_of_record_length_buffers() {
    // Once per thread and independent of N: faer's matrix products reserve a 64 MiB packing
    // buffer on a thread's first product (address space only; the pages a small product
    // touches are what counts in the resident set, ~70 MB for a 2-thread 131 072-sample run).
    peak_vectors(1 << 12, SolverMethod::Lm);
    for method in [SolverMethod::Lm, SolverMethod::Separable] {
        let small = peak_vectors(1 << 14, method);
        let large = peak_vectors(1 << 17, method);
        eprintln!("{method:?}: peak {small:.1} N-vectors at N = 16384, {large:.1} at N = 131072");
        assert!(large <= BUDGET as f64, "{method:?}: {large:.1} N-length vectors at N = 131072");
        // O(N): the count does not grow with N (small records carry fixed-size overheads).
        assert!(large <= small + 0.5, "{method:?}: {small:.1} -> {large:.1} vectors as N grew 8x");
    }
}
