//! SIGINT/SIGTERM during a command-line sweep: the first asks the workers to stop handing out
//! cells, a second exits at once (the parts on disk are complete either way).
//!
//! Only the program that owns the process arms this, for one run: the `oesweep` command does
//! around its `run`. The library itself never touches signal dispositions, so a program that
//! embeds it (a notebook, a service, the Python package) keeps its own Ctrl-C.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicPtr, Ordering};

const SIGNALS: [libc::c_int; 2] = [libc::SIGINT, libc::SIGTERM];

/// The stop flag of the armed run, for the handler (null while none is armed).
static ARMED: AtomicPtr<AtomicBool> = AtomicPtr::new(std::ptr::null_mut());

/// Async-signal-safe: one atomic swap, then `_exit` on a second signal.
extern "C" fn on_signal(_: libc::c_int) {
    let flag = ARMED.load(Ordering::SeqCst);
    // SAFETY: a non-null pointer came from `Arc::into_raw` in `arm` and is never freed (see there).
    if !flag.is_null() && unsafe { (*flag).swap(true, Ordering::SeqCst) } {
        // SAFETY: `_exit` is async-signal-safe.
        unsafe { libc::_exit(130) };
    }
}

/// SIGINT/SIGTERM set a stop flag while this value lives; a second signal exits at once with
/// code 130. Dropping it puts back the dispositions that were there before, so the next Ctrl-C
/// does whatever it did before the run.
pub struct StopOnSignal {
    previous: Vec<(libc::c_int, libc::sigaction)>,
    armed_before: *mut AtomicBool,
}

impl StopOnSignal {
    /// Arm the handlers for `flag`. If that fails (it should not), the run goes on without
    /// them and the signals keep what they had.
    pub fn arm(flag: Arc<AtomicBool>) -> StopOnSignal {
        // Never freed: a handler running on another thread while the guard is dropped may
        // still read it. One flag per armed run, a run per command.
        let raw = Arc::into_raw(flag).cast_mut();
        let armed_before = ARMED.swap(raw, Ordering::SeqCst);
        let mut previous = Vec::new();
        for sig in SIGNALS {
            // SAFETY: plain sigaction calls on zero-initialised structs; the handler only
            // does async-signal-safe work.
            unsafe {
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
                act.sa_flags = libc::SA_RESTART;
                libc::sigemptyset(&mut act.sa_mask);
                let mut old: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(sig, &act, &mut old) == 0 {
                    previous.push((sig, old));
                } else {
                    eprintln!(
                        "warning: cannot install a handler for signal {sig}: {}",
                        std::io::Error::last_os_error()
                    );
                }
            }
        }
        StopOnSignal { previous, armed_before }
    }
}

impl Drop for StopOnSignal {
    fn drop(&mut self) {
        for (sig, old) in &self.previous {
            // SAFETY: restores a disposition that sigaction itself returned.
            unsafe { libc::sigaction(*sig, old, std::ptr::null_mut()) };
        }
        ARMED.store(self.armed_before, Ordering::SeqCst);
    }
}
