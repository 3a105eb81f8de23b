//! The commands' standard output. A reader that stops early (`oesweep run JOB | head -5`)
//! closes the pipe, and every later write fails with a broken pipe; Rust ignores SIGPIPE, so
//! `println!` would panic. The disposition of SIGPIPE is left alone (the Python package runs
//! the command line inside its host process): instead the first failed write ends the
//! command's printing, and the command does the rest of its work (the profile, the report)
//! and ends with [`settle`]'s exit code.

use std::cell::RefCell;
use std::io::{ErrorKind, Write};

thread_local! {
    /// The first write to standard output that failed in this thread's command; nothing is
    /// printed after it.
    static FAILED: RefCell<Option<std::io::Error>> = const { RefCell::new(None) };
}

/// Writes `args` to standard output unless a write of the command failed before.
pub(crate) fn write(args: std::fmt::Arguments<'_>) {
    FAILED.with_borrow_mut(|failed| {
        if failed.is_none()
            && let Err(e) = std::io::stdout().lock().write_fmt(args)
        {
            *failed = Some(e);
        }
    });
}

/// The failed write of the command, if any, forgotten (a host may run several commands).
pub(super) fn take_error() -> Option<std::io::Error> {
    FAILED.with_borrow_mut(Option::take)
}

/// The exit code of a command that returned `code`, given how its printing went. A closed pipe
/// keeps `code`: the reader chose to stop reading, the results are written (every command
/// prints after its files are saved), and a failure of the work (1) must still show; 141, the
/// status a shell gives a process killed by SIGPIPE, would make `set -o pipefail` report a
/// failure of a run that succeeded. Any other failed write (a full disk behind `>`) is an
/// error: one line, exit 1 if the command had nothing worse to say.
pub(super) fn settle(code: u8) -> u8 {
    match take_error() {
        None => code,
        Some(e) if e.kind() == ErrorKind::BrokenPipe => code,
        Some(e) => {
            eprintln!("error: writing to standard output: {e}");
            code.max(1)
        }
    }
}
