//! The solver's iteration loop allocates nothing once its workspace is sized (guide: "no
//! allocation in the iteration loop; one workspace per worker"), pole reflections included:
//! a global allocator counts the allocations of a second, identical minimisation.

use oesweep::estimate::{Loss, Problem, SolverMethod, SolverOptions, Workspace, initial_guess, solver};
use oesweep::oe::Structure;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator, only counting.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
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
    let prob = Problem { u: &rec.u, y: &rec.y, structure: Structure::siso(12, 12, 1), offset: false, seams: &[] };
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
        let before = ALLOCATIONS.load(Ordering::Relaxed);
        let (ls2, h2) = run(&mut ws);
        let allocations = ALLOCATIONS.load(Ordering::Relaxed) - before;
        // Each minimisation allocates its result's theta, nothing else.
        assert_eq!(allocations, 2, "{method:?}: {allocations} allocations in two sized minimisations");
        assert_eq!(ls2.criterion, ls.criterion);
        assert!(h2.iterations > 0 && ls2.iterations > 0);
    }
}
