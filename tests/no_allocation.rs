//! The solver's iteration loop allocates nothing once its workspace is sized (guide: "no
//! allocation in the iteration loop; one workspace per worker"), pole reflections included:
//! a global allocator counts the allocations of a second, identical minimisation. It counts
//! per thread: the tests run side by side in one process, and each counts only its own.

use oesweep::estimate::{Loss, Problem, SolverMethod, SolverOptions, Workspace, initial_guess, solver};
use oesweep::oe::{Orders, Structure};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    // Const-initialised and without a destructor: reading it allocates nothing.
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

fn count() {
    ALLOCATIONS.with(|c| c.set(c.get() + 1));
}

/// Allocations of this thread so far.
fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

// SAFETY: forwards to the system allocator, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn a_minimisation_with_pole_reflections_allocates_only_its_result() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/data/piezo_est.csv");
    let rec = oesweep::data::read_record(path.as_ref(), "u", "y").unwrap();
    // OE(12,12) from the ARX guess: the least-squares fit reflects unstable trial steps (the
    // piezo's lightly damped modes), and the Huber fit from there runs the weighted paths.
    let prob = Problem {
        u: &rec.u,
        y: &rec.y,
        structure: Structure::siso(12, 12, 1),
        offset: false,
        seams: &[],
        missing: &[],
    };
    let start = initial_guess::initial_guesses(&prob).remove(0);
    for method in [SolverMethod::Lm, SolverMethod::Separable] {
        let opts = SolverOptions { method, ..SolverOptions::default() };
        let mut ws = Workspace::new();
        let run = |ws: &mut Workspace| {
            let ls = solver::minimise(&prob, Loss::LeastSquares, &start, &opts, ws);
            let gamma = 0.1 * (2.0 * ls.criterion).sqrt();
            let h = solver::minimise(&prob, Loss::Huber { gamma }, &ls.theta, &opts.huber(), ws);
            (ls, h)
        };
        let (ls, _) = run(&mut ws);
        assert!(method == SolverMethod::Separable || ls.reflections > 0, "the test needs a fit that reflects poles");
        let before = allocations();
        let (ls2, h2) = run(&mut ws);
        let allocations = allocations() - before;
        // Each minimisation allocates its result's theta, nothing else.
        assert_eq!(allocations, 2, "{method:?}: {allocations} allocations in two sized minimisations");
        assert_eq!(ls2.criterion, ls.criterion);
        assert!(h2.iterations > 0 && ls2.iterations > 0);
    }
}

#[test]
fn a_minimisation_with_missing_outputs_allocates_only_its_result() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/data/piezo_est.csv");
    let rec = oesweep::data::read_record(path.as_ref(), "u", "y").unwrap();
    let complete =
        Problem { u: &rec.u, y: &rec.y, structure: Structure::siso(6, 6, 1), offset: true, seams: &[], missing: &[] };
    let start = initial_guess::initial_guesses(&complete).remove(0);
    // Every 17th output and a burst of 40 missing (METHOD.md 21.2): the least-squares fit runs
    // the weighted path with weight 0 there.
    let missing: Vec<usize> = (0..rec.y.len()).filter(|t| t % 17 == 5 || (1000..1040).contains(t)).collect();
    let mut y = rec.y.clone();
    for &t in &missing {
        y[t] = f64::NAN;
    }
    let prob = Problem { y: &y, missing: &missing, ..complete };
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    let run = |ws: &mut Workspace| {
        let ls = solver::minimise(&prob, Loss::LeastSquares, &start, &opts, ws);
        let gamma = 0.5 * (2.0 * ls.criterion).sqrt();
        let h = solver::minimise(&prob, Loss::Huber { gamma }, &ls.theta, &opts.huber(), ws);
        (ls, h)
    };
    let (ls, _) = run(&mut ws);
    assert!(ls.criterion.is_finite() && ls.iterations > 0, "{ls:?}");
    let before = allocations();
    let (ls2, h2) = run(&mut ws);
    let allocations = allocations() - before;
    assert_eq!(allocations, 2, "{allocations} allocations in two sized minimisations");
    assert_eq!(ls2.criterion, ls.criterion);
    assert!(h2.iterations > 0 && h2.criterion.is_finite());
}

#[test]
fn a_minimisation_of_several_inputs_allocates_only_its_result() {
    // Two inputs, an offset and 5 % spikes: the Huber fit at a small gamma runs both
    // weighted paths of the several inputs' normal equations (from the least-squares fit, which
    // the spikes bias, most rows beyond gamma; at the solution, the spikes).
    let n = 3000;
    let o = |nb, nf, delay| Orders { nb, nf, delay };
    let structure = Structure::new(&[o(2, 2, 1), o(1, 1, 2)]).unwrap();
    let mut s = 5u64;
    let mut next = move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    };
    let u: Vec<f64> = (0..2 * n).map(|_| if next() > 0.0 { 1.0 } else { -1.0 }).collect();
    let zeros = vec![0.0; n];
    let truth = [0.5, 0.3, -1.5, 0.7, 0.8, -0.9, 0.2];
    let clean = Problem { u: &u, y: &zeros, structure, offset: true, seams: &[], missing: &[] }.simulate_vec(&truth);
    let y: Vec<f64> =
        clean.iter().enumerate().map(|(t, v)| v + 0.1 * next() + if t % 20 == 7 { 3.0 } else { 0.0 }).collect();
    let prob = Problem { u: &u, y: &y, structure, offset: true, seams: &[], missing: &[] };
    let start = initial_guess::initial_guesses(&prob).remove(0);
    let opts = SolverOptions::default();
    let mut ws = Workspace::new();
    let run = |ws: &mut Workspace| {
        let ls = solver::minimise(&prob, Loss::LeastSquares, &start, &opts, ws);
        let gamma = 0.1 * (2.0 * ls.criterion).sqrt();
        let h = solver::minimise(&prob, Loss::Huber { gamma }, &ls.theta, &opts.huber(), ws);
        (ls, h)
    };
    let (ls, h) = run(&mut ws);
    let before = allocations();
    let (ls2, h2) = run(&mut ws);
    let allocations = allocations() - before;
    assert_eq!(allocations, 2, "{allocations} allocations in two sized minimisations of several inputs");
    assert_eq!((ls2.criterion, h2.criterion), (ls.criterion, h.criterion));
    assert!(h2.iterations > 0 && ls2.iterations > 0);
}
