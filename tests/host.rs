//! The library leaves its host process as it found it: two runs and a bad data file in one
//! process change neither the SIGINT/SIGTERM dispositions nor the panic hook nor faer's global
//! parallelism, and the command line's own run puts back the signal handlers it armed.

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

/// One test, so that nothing else in this process touches the hook or the handlers meanwhile.
#[test]
fn runs_leave_the_host_process_alone() {
    let print = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        PANICS.fetch_add(1, Ordering::SeqCst);
        print(info);
    }));
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

    // The command line arms the handlers for its run and puts back what it found.
    use clap::Parser;
    for _ in 0..2 {
        let job = common::piezo_job(dir.path(), "cli", "host", 1000, ([2, 3], [2, 3]), (0.5, 2));
        let cli =
            oesweep::cli::Cli::try_parse_from(["oesweep", "run", job.to_str().unwrap(), "--quiet", "--force"]).unwrap();
        assert_eq!(oesweep::cli::run(cli).unwrap(), 0);
        assert_eq!(dispositions(), signals, "the command's run left its signal handlers behind");
    }
}
