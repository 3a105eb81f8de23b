//! Progress of a sweep on stderr: an indicatif bar on a terminal, otherwise a plain line every
//! few seconds (log files and CI get readable output, not escape sequences).

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

const PLAIN_EVERY: Duration = Duration::from_secs(5);

pub struct Progress {
    bar: Option<ProgressBar>,
    total: AtomicUsize,
    done: AtomicUsize,
    start: Instant,
    last_line: Mutex<Instant>,
    quiet: bool,
}

impl Progress {
    /// `quiet` suppresses all output (tests, benches).
    pub fn new(total: usize, quiet: bool) -> Self {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = ProgressBar::new(total as u64);
            b.set_style(
                ProgressStyle::with_template(
                    "{elapsed_precise} [{bar:40.cyan/blue}] {pos}/{len} cells  {per_sec}  ETA {eta}  {msg}",
                )
                .expect("valid template")
                .progress_chars("=> "),
            );
            b
        });
        let now = Instant::now();
        Progress {
            bar,
            total: AtomicUsize::new(total),
            done: AtomicUsize::new(0),
            start: now,
            last_line: Mutex::new(now),
            quiet,
        }
    }

    pub fn message(&self, msg: &str) {
        match &self.bar {
            Some(b) => b.set_message(msg.to_string()),
            None if !self.quiet => eprintln!("{msg}"),
            None => {}
        }
    }

    /// Count `n` finished cells.
    pub fn inc(&self, n: usize) {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        if let Some(b) = &self.bar {
            b.inc(n as u64);
            return;
        }
        if self.quiet {
            return;
        }
        // try_lock: a worker never waits for another worker's printing.
        if let Ok(mut last) = self.last_line.try_lock()
            && last.elapsed() >= PLAIN_EVERY
        {
            *last = Instant::now();
            let secs = self.start.elapsed().as_secs_f64();
            let rate = done as f64 / secs.max(1e-9);
            let total = self.total.load(Ordering::Relaxed);
            let eta = (total.saturating_sub(done)) as f64 / rate.max(1e-9);
            eprintln!("{done}/{total} cells, {rate:.1} cells/s, {secs:.0} s elapsed, ETA {eta:.0} s");
        }
    }

    /// Count `n` more cells to do (a coordinate search learns its rounds' cells as it goes).
    pub fn grow(&self, n: usize) {
        if let Some(b) = &self.bar {
            b.inc_length(n as u64);
        }
        self.total.fetch_add(n, Ordering::Relaxed);
    }

    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
