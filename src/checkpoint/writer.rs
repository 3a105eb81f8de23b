//! The checkpoint writer thread: finished rows in, parts out, in batches (see the module
//! documentation of [`super`]).

use super::folder::part_path;
use crate::error::Error;
use crate::export;
use crate::table::CellRow;
use std::path::PathBuf;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What the writer saved, reported by [`Writer::finish`].
#[derive(Debug, Default)]
pub struct Saved {
    pub parts: usize,
    pub rows: usize,
    pub huber_rows: usize,
    /// Rows that could not be written (only after an error).
    pub unsaved: usize,
    /// The last write error, if any.
    pub error: Option<Error>,
}

/// The checkpoint writer thread; see the module documentation.
pub struct Writer {
    tx: Option<mpsc::Sender<CellRow>>,
    thread: Option<JoinHandle<Saved>>,
}

impl Writer {
    /// Start writing parts numbered from `first_part` into `parts` (which [`open`] prepared):
    /// a part at the latest `every` after its first row, or when `rows` rows are waiting.
    pub fn start(parts: PathBuf, first_part: u64, every: Duration, rows: usize) -> Writer {
        let (tx, rx) = mpsc::channel::<CellRow>();
        let thread = std::thread::Builder::new()
            .name("checkpoint".into())
            .spawn(move || {
                let mut saved = Saved::default();
                let mut next = first_part;
                let mut buf: Vec<CellRow> = Vec::new();
                let mut deadline: Option<Instant> = None;
                let mut flush = |buf: &mut Vec<CellRow>, saved: &mut Saved| {
                    if buf.is_empty() {
                        return true;
                    }
                    match export::parquet::write_cells(&part_path(&parts, next), buf) {
                        Ok(()) => {
                            next += 1;
                            saved.parts += 1;
                            saved.rows += buf.len();
                            saved.huber_rows += crate::table::huber_rows(buf);
                            buf.clear();
                            // Rows of a failed write were in this batch: all is saved again.
                            saved.error = None;
                            crate::failpoint::after_part(saved.parts as u64);
                            true
                        }
                        Err(e) => {
                            // Keep the rows and try again with the next batch: a full disk may
                            // get space back. The sweep keeps every row in memory regardless.
                            if saved.error.is_none() {
                                eprintln!("warning: checkpoint not saved ({e}); will retry");
                            }
                            saved.error = Some(e);
                            false
                        }
                    }
                };
                loop {
                    let got = match deadline {
                        None => rx.recv().map_err(|_| RecvTimeoutError::Disconnected),
                        Some(d) => rx.recv_timeout(d.saturating_duration_since(Instant::now())),
                    };
                    match got {
                        Ok(row) => {
                            if buf.is_empty() {
                                deadline = Some(Instant::now() + every);
                            }
                            buf.push(row);
                            if buf.len() >= rows && flush(&mut buf, &mut saved) {
                                deadline = None;
                            }
                        }
                        Err(RecvTimeoutError::Timeout) => {
                            deadline = if flush(&mut buf, &mut saved) { None } else { Some(Instant::now() + every) };
                        }
                        Err(RecvTimeoutError::Disconnected) => {
                            flush(&mut buf, &mut saved);
                            saved.unsaved = buf.len();
                            return saved;
                        }
                    }
                }
            })
            .expect("spawn the checkpoint writer");
        Writer { tx: Some(tx), thread: Some(thread) }
    }

    /// Where the workers send finished rows (`Sender` is `Sync`: share it by reference).
    pub fn sender(&self) -> &mpsc::Sender<CellRow> {
        self.tx.as_ref().expect("writer running")
    }

    /// Write what is still buffered and stop the thread.
    pub fn finish(mut self) -> Saved {
        drop(self.tx.take());
        match self.thread.take().expect("writer running").join() {
            Ok(saved) => saved,
            Err(_) => Saved {
                error: Some(Error::output("checkpoint", "the checkpoint writer panicked")),
                ..Default::default()
            },
        }
    }
}
