//! The library leaves its host process as it found it: two runs and a bad data file in one
//! process change neither the SIGINT/SIGTERM dispositions nor the panic hook nor faer's global
//! parallelism, and the command line run in-process (`cli::main_with_args`, as the Python
//! package runs it) leaves the host's own panic hook and signal handlers in place: the very
//! ones, not wrappers that call them.

mod common;

use oesweep::engine::{self, RunEnd, RunOptions};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

/// The flags that say how a handler runs (the C library may add its own, `SA_RESTORER`, to any
/// disposition it sets, the default one too).
const HOW: libc::c_int = libc::SA_SIGINFO | libc::SA_RESTART | libc::SA_NODEFER | libc::SA_RESETHAND | libc::SA_ONSTACK;

/// The handler, flags and mask of SIGINT and SIGTERM as the kernel holds them.
fn dispositions() -> Vec<(libc::sighandler_t, libc::c_int, Vec<bool>)> {
    [libc::SIGINT, libc::SIGTERM]
        .into_iter()
        .map(|sig| {
            // SAFETY: a query (null new action) into a zeroed struct.
            unsafe {
                let mut old: libc::sigaction = std::mem::zeroed();
                assert_eq!(libc::sigaction(sig, std::ptr::null(), &mut old), 0);
                let mask = (1..32).map(|s| libc::sigismember(&old.sa_mask, s) == 1).collect();
                (old.sa_sigaction, old.sa_flags & HOW, mask)
            }
        })
        .collect()
}

static PANICS: AtomicUsize = AtomicUsize::new(0);

type Hook = Box<dyn Fn(&std::panic::PanicHookInfo<'_>) + Sync + Send + 'static>;

/// Where a hook lives: the same box is the same hook, a wrapper around it is another box.
fn address(hook: &Hook) -> usize {
    std::ptr::from_ref(&**hook).cast::<()>() as usize
}

/// The host's own SIGINT/SIGTERM handler, so that "the same afterwards" is this very function
/// with these flags and mask, not the default disposition (no signal is sent: it never runs).
extern "C" fn host_handler(_: libc::c_int) {}

/// Installs [`host_handler`] for SIGINT and SIGTERM; returns the dispositions it replaced.
fn install_host_handlers() -> Vec<(libc::c_int, libc::sigaction)> {
    [libc::SIGINT, libc::SIGTERM]
        .into_iter()
        .map(|sig| {
            // SAFETY: sigaction on zeroed structs; the handler does nothing.
            unsafe {
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = host_handler as extern "C" fn(libc::c_int) as libc::sighandler_t;
                act.sa_flags = libc::SA_RESTART | libc::SA_NODEFER;
                libc::sigemptyset(&mut act.sa_mask);
                libc::sigaddset(&mut act.sa_mask, libc::SIGUSR1);
                let mut old: libc::sigaction = std::mem::zeroed();
                assert_eq!(libc::sigaction(sig, &act, &mut old), 0);
                (sig, old)
            }
        })
        .collect()
}

/// One test, so that nothing else in this process touches the hook or the handlers meanwhile.
#[test]
fn runs_leave_the_host_process_alone() {
    let previous = install_host_handlers();
    let print = std::panic::take_hook();
    // It holds the previous hook, so it is no zero-sized value: its box has an address of its own.
    let hook: Hook = Box::new(move |info| {
        PANICS.fetch_add(1, Ordering::SeqCst);
        print(info);
    });
    let installed = address(&hook);
    std::panic::set_hook(hook);
    let signals = dispositions();
    let parallelism = format!("{:?}", faer::get_global_parallelism());
    let dir = tempfile::tempdir().unwrap();

    for out in ["one", "two"] {
        let o = engine::run(
            &common::piezo_job(dir.path(), out, "host", 1000, ([2, 3], [2, 3]), (0.5, 2)),
            &RunOptions { threads: 2, ..Default::default() },
            &|_| {},
        )
        .unwrap();
        assert!(matches!(o.end, RunEnd::Merged { .. }), "{o:?}");
    }
    // A data file the Parquet reader panics on: an input error, and the host's hook heard it.
    let bad = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_inputs/parquet_reader_panic/job.json");
    let before = PANICS.load(Ordering::SeqCst);
    let e = engine::prepare(&bad).err().expect("a corrupt Parquet file is refused");
    assert!(e.is_bad_input() && e.to_string().contains("the reader failed"), "{e}");
    assert!(PANICS.load(Ordering::SeqCst) > before, "the host's panic hook was bypassed");

    assert_eq!(dispositions(), signals, "SIGINT/SIGTERM dispositions changed");
    assert_eq!(format!("{:?}", faer::get_global_parallelism()), parallelism, "faer's global parallelism changed");
    // A host that turns faer's global parallelism off (faer's high-level calls then panic): every
    // faer routine gets `Par::Seq` from oesweep itself (`dense`), so the run is the same.
    faer::disable_global_parallelism();
    let off = engine::run(
        &common::piezo_job(dir.path(), "off", "host", 1000, ([2, 3], [2, 3]), (0.5, 2)),
        &RunOptions { threads: 2, ..Default::default() },
        &|_| {},
    );
    faer::set_global_parallelism(faer::Par::Seq);
    let off = off.unwrap();
    assert_eq!(off.failed, 0, "{off:?}");
    assert!(
        common::table_without_seconds(&dir.path().join("off"))
            == common::table_without_seconds(&dir.path().join("one")),
        "the run with faer's global parallelism off differs"
    );
    let before = PANICS.load(Ordering::SeqCst);
    let _ = std::panic::catch_unwind(|| panic!("probe"));
    assert_eq!(PANICS.load(Ordering::SeqCst), before + 1, "the host's panic hook was replaced");

    // The command line run in-process, as the Python package runs it: its run arms the signal
    // handlers and puts back the host's, and a bad data file is an input error whose reader's
    // panic reaches the host's hook (the `oesweep` binary's own hook, which leaves it unprinted,
    // is the binary's: `cli::main`).
    for _ in 0..2 {
        let job = common::piezo_job(dir.path(), "cli", "host", 1000, ([2, 3], [2, 3]), (0.5, 2));
        assert_eq!(oesweep::cli::main_with_args(["oesweep", "run", job.to_str().unwrap(), "--quiet", "--force"]), 0);
        assert_eq!(dispositions(), signals, "the command's run left its signal handlers behind");
    }
    // `fit --bootstrap` refits on a pool of its own, of the threads asked for.
    let data = dir.path().join("est.csv");
    let fit = ["oesweep", "fit", "--data", data.to_str().unwrap(), "--nb", "2", "--nf", "2", "--k", "1"];
    assert_eq!(oesweep::cli::main_with_args(fit.into_iter().chain(["--bootstrap", "40", "--threads", "2"])), 0);
    let before = PANICS.load(Ordering::SeqCst);
    assert_eq!(oesweep::cli::main_with_args(["oesweep", "run", bad.to_str().unwrap(), "--quiet"]), 2);
    assert!(PANICS.load(Ordering::SeqCst) > before, "the command replaced the host's panic hook while it ran");
    assert_eq!(dispositions(), signals, "the command changed the signal dispositions");

    // The hook in place now is the very box the host installed, not a wrapper that calls it,
    // and a panic runs it exactly once.
    let now = std::panic::take_hook();
    let same = address(&now) == installed;
    std::panic::set_hook(now);
    assert!(same, "the host's panic hook was replaced (by a wrapper that calls it?)");
    let before = PANICS.load(Ordering::SeqCst);
    let _ = std::panic::catch_unwind(|| panic!("probe"));
    assert_eq!(PANICS.load(Ordering::SeqCst), before + 1, "a panic did not run the host's hook exactly once");

    // Nothing above built rayon's global pool, which is the host's to build (once) as it likes.
    assert!(
        rayon::ThreadPoolBuilder::new().num_threads(1).build_global().is_ok(),
        "the library built rayon's global pool"
    );
    for (sig, old) in previous {
        // SAFETY: puts back a disposition sigaction returned.
        unsafe { libc::sigaction(sig, &old, std::ptr::null_mut()) };
    }
}
