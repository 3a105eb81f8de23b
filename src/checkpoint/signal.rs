//! SIGINT/SIGTERM during a sweep: the first asks the workers to stop handing out cells, a
//! second exits at once (the parts on disk are complete either way).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// SIGINT/SIGTERM -> a stop flag, while this value lives; a second signal exits at once with
/// code 130. Once it is dropped every signal exits at once with code 130: the handlers stay
/// installed, because unregistering them would leave the signals ignored rather than restore
/// their default action.
pub struct StopOnSignal {
    flag: Arc<AtomicBool>,
}

impl StopOnSignal {
    /// Install the handlers. If that fails (it should not), the sweep runs without them and the
    /// signals keep their default action.
    pub fn install() -> StopOnSignal {
        use signal_hook::consts::{SIGINT, SIGTERM};
        let flag = Arc::new(AtomicBool::new(false));
        for sig in [SIGINT, SIGTERM] {
            // Registered first, so it sees the flag before the second action sets it: the first
            // signal only sets the flag, a later one exits.
            let r = signal_hook::flag::register_conditional_shutdown(sig, 130, Arc::clone(&flag))
                .and_then(|_| signal_hook::flag::register(sig, Arc::clone(&flag)));
            if let Err(e) = r {
                eprintln!("warning: cannot install a handler for signal {sig}: {e}");
            }
        }
        StopOnSignal { flag }
    }

    pub fn flag(&self) -> &AtomicBool {
        &self.flag
    }
}

impl Drop for StopOnSignal {
    fn drop(&mut self) {
        // Arms the conditional shutdown: the next signal exits instead of setting a flag that
        // nobody reads any more.
        self.flag.store(true, std::sync::atomic::Ordering::SeqCst);
    }
}
