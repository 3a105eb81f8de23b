//! Test hooks: fault injection and pause points, compiled only with the cargo feature
//! `failpoints` (which the test suite turns on, see `Cargo.toml`), and live only in a process
//! that called [`enable`]: the `oesweep-testhooks` binary does, the `oesweep` binary never does.
//! Cargo unifies the feature into the library that `cargo test` links into `oesweep` too, so
//! the feature alone cannot keep a user's binary honest; the switch does. In a build without
//! the feature the functions here are empty. Either way `oesweep` never reads
//! `OESWEEP_FAILPOINT`, so a user's run cannot be made to fail by an environment variable.
//!
//! `OESWEEP_FAILPOINT` holds one of:
//! - `panic:NB,NF,K_INDEX`: that Huber cell panics inside its worker, as a bug in the numerics
//!   would (tests/fault_isolation.rs);
//! - `pause_cell:NB,NF,K_INDEX:MARKER`: the worker that reaches that Huber cell creates the file
//!   MARKER and waits, before fitting it, until MARKER is deleted; meanwhile every other worker
//!   waits too before its next cell. The sweep cannot end, nor move on, while it waits;
//! - `pause_part:N:MARKER`: the checkpoint writer, right after its N-th part of this run is
//!   durable, creates MARKER and waits until MARKER is deleted. No part is written while it
//!   waits (and the run cannot end), so a test that kills the process then knows exactly which
//!   rows were saved;
//! - `pause_merge:MARKER`: a whole run, once its result files are written and before it
//!   deletes the checkpoint, creates MARKER and waits until MARKER is deleted: a kill there
//!   leaves complete results beside a complete checkpoint;
//! - `kernels:generic`: the process runs the baseline kernels on a CPU with AVX2 and FMA, as a
//!   node of another CPU family would ([`crate::kernels::Flavour`]; tests/kernel_flavour.rs);
//! - `threads:refused`: every worker pool the process builds is refused, as a system at its
//!   thread limit would refuse it ([`crate::pool::local`]; tests/nested_check.rs).
//!
//! A pause also ends when the process receives SIGINT or SIGTERM: its own handler is
//! registered after the command armed [`crate::checkpoint::StopOnSignal`] and calls that one
//! first, so by the time a pause sees the signal the run's stop flag is set too, and a test can
//! interrupt a paused run and know that no further cell starts.
//!
//! The pauses are what make the kill/resume tests deterministic: a test waits for the marker
//! (a state), not for a time.

#[cfg(feature = "failpoints")]
mod hooks {
    use std::path::{Path, PathBuf};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::{Arc, OnceLock};

    #[derive(Debug, PartialEq)]
    pub(super) enum Hook {
        Panic((usize, usize, usize)),
        PauseCell((usize, usize, usize), PathBuf),
        PausePart(u64, PathBuf),
        PauseMerge(PathBuf),
        GenericKernels,
        RefusedThreads,
    }

    fn cell(s: &str) -> Option<(usize, usize, usize)> {
        let mut it = s.split(',').map(|x| x.trim().parse::<usize>().ok());
        let c = (it.next()??, it.next()??, it.next()??);
        it.next().is_none().then_some(c)
    }

    pub(super) fn parse(v: &str) -> Option<Hook> {
        let (kind, rest) = v.split_once(':')?;
        match kind {
            "panic" => Some(Hook::Panic(cell(rest)?)),
            "pause_cell" => {
                let (c, marker) = rest.split_once(':')?;
                Some(Hook::PauseCell(cell(c)?, PathBuf::from(marker)))
            }
            "pause_merge" => Some(Hook::PauseMerge(PathBuf::from(rest))),
            "kernels" if rest == "generic" => Some(Hook::GenericKernels),
            "threads" if rest == "refused" => Some(Hook::RefusedThreads),
            "pause_part" => {
                let (n, marker) = rest.split_once(':')?;
                Some(Hook::PausePart(n.trim().parse().ok()?, PathBuf::from(marker)))
            }
            _ => None,
        }
    }

    /// Set once, first thing, by the `oesweep-testhooks` binary ([`super::enable`]).
    pub(super) static ENABLED: AtomicBool = AtomicBool::new(false);

    pub(super) fn hook() -> Option<&'static Hook> {
        static HOOK: OnceLock<Option<Hook>> = OnceLock::new();
        HOOK.get_or_init(|| {
            if !ENABLED.load(Ordering::SeqCst) {
                return None;
            }
            let v = std::env::var("OESWEEP_FAILPOINT").ok()?;
            let h = parse(&v);
            if h.is_none() {
                eprintln!("warning: OESWEEP_FAILPOINT={v:?} is not a failpoint; ignored");
            }
            h
        })
        .as_ref()
    }

    /// Set while a `pause_cell` pause holds the workers.
    static PAUSED: AtomicBool = AtomicBool::new(false);

    /// Set by SIGINT/SIGTERM once a pause has begun (the handler is installed then).
    fn signalled() -> &'static Arc<AtomicBool> {
        static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
        FLAG.get_or_init(|| {
            let flag = Arc::new(AtomicBool::new(false));
            for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
                signal_hook::flag::register(sig, Arc::clone(&flag)).expect("failpoint: signal handler");
            }
            flag
        })
    }

    fn released(marker: &Path) -> bool {
        !marker.exists() || signalled().load(Ordering::SeqCst)
    }

    /// Create `marker`, then wait until somebody deletes it or a stop signal arrives. With
    /// `hold_workers`, every worker waits in [`wait_if_paused`] meanwhile.
    pub(super) fn pause(marker: &Path, hold_workers: bool) {
        signalled();
        if hold_workers {
            PAUSED.store(true, Ordering::SeqCst);
        }
        std::fs::write(marker, std::process::id().to_string()).expect("failpoint: cannot create the pause marker");
        while !released(marker) {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        PAUSED.store(false, Ordering::SeqCst);
    }

    /// Wait while another worker's `pause_cell` pause lasts. On the flag, not the marker: the
    /// pausing worker raises it before it creates the marker, and a worker that looked at the
    /// marker in between would see none and go on.
    pub(super) fn wait_if_paused() {
        while PAUSED.load(Ordering::SeqCst) {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
    }
}

/// Switch the hooks on for this process: `OESWEEP_FAILPOINT` is read from now on. Only the
/// `oesweep-testhooks` binary calls it, before anything else.
#[cfg(feature = "failpoints")]
pub fn enable() {
    hooks::ENABLED.store(true, std::sync::atomic::Ordering::SeqCst);
}

/// Called by a worker before it fits Huber cell (nb, nf, k_index).
#[inline]
pub fn before_cell(nb: usize, nf: usize, k_index: usize) {
    #[cfg(feature = "failpoints")]
    match hooks::hook() {
        Some(hooks::Hook::Panic(c)) if *c == (nb, nf, k_index) => {
            panic!("failpoint OESWEEP_FAILPOINT hit at OE({nb},{nf}) k index {k_index}")
        }
        Some(hooks::Hook::PauseCell(c, marker)) if *c == (nb, nf, k_index) => hooks::pause(marker, true),
        Some(hooks::Hook::PauseCell(..)) => hooks::wait_if_paused(),
        _ => {}
    }
    #[cfg(not(feature = "failpoints"))]
    let _ = (nb, nf, k_index);
}

/// Called by a whole run between writing its result files and deleting its checkpoint.
#[inline]
pub fn before_checkpoint_removal() {
    #[cfg(feature = "failpoints")]
    if let Some(hooks::Hook::PauseMerge(marker)) = hooks::hook() {
        hooks::pause(marker, false);
    }
}

/// True when the process must run the baseline kernels whatever its CPU (asked once, by
/// [`crate::kernels::flavour`]).
pub fn generic_kernels() -> bool {
    #[cfg(feature = "failpoints")]
    {
        matches!(hooks::hook(), Some(hooks::Hook::GenericKernels))
    }
    #[cfg(not(feature = "failpoints"))]
    {
        false
    }
}

/// Why the process must not build a worker pool (asked by [`crate::pool::local`] before each
/// build); None: build it.
pub fn refused_threads() -> Option<String> {
    #[cfg(feature = "failpoints")]
    {
        matches!(hooks::hook(), Some(hooks::Hook::RefusedThreads))
            .then(|| "the system refused them (test hook OESWEEP_FAILPOINT=threads:refused)".to_string())
    }
    #[cfg(not(feature = "failpoints"))]
    {
        None
    }
}

/// Called by the checkpoint writer once its `n`-th part of this run (1-based) is durable.
#[inline]
pub fn after_part(n: u64) {
    #[cfg(feature = "failpoints")]
    if let Some(hooks::Hook::PausePart(at, marker)) = hooks::hook()
        && *at == n
    {
        hooks::pause(marker, false);
    }
    #[cfg(not(feature = "failpoints"))]
    let _ = n;
}

#[cfg(all(test, feature = "failpoints"))]
mod tests {
    use super::hooks::{Hook, parse};
    use std::path::PathBuf;

    #[test]
    fn failpoint_grammar() {
        assert_eq!(parse("panic:2,2,1"), Some(Hook::Panic((2, 2, 1))));
        assert_eq!(parse("pause_cell:5, 4,0:/tmp/a:b"), Some(Hook::PauseCell((5, 4, 0), PathBuf::from("/tmp/a:b"))));
        assert_eq!(parse("pause_part:1:/tmp/m"), Some(Hook::PausePart(1, PathBuf::from("/tmp/m"))));
        assert_eq!(parse("pause_merge:/tmp/m"), Some(Hook::PauseMerge(PathBuf::from("/tmp/m"))));
        assert_eq!(parse("kernels:generic"), Some(Hook::GenericKernels));
        assert_eq!(parse("threads:refused"), Some(Hook::RefusedThreads));
        for bad in [
            "kernels:avx2",
            "threads:0",
            "panic:2,2",
            "panic:2,2,1,4",
            "pause_part:x:/m",
            "pause_cell:1,1,1",
            "stop:1",
            "",
        ] {
            assert_eq!(parse(bad), None, "{bad}");
        }
    }
}
