//! Checkpoints: an interrupted sweep resumes where it stopped, loses no finished cell and never
//! writes a cell twice.
//!
//! Layout, inside the job's output folder while a sweep runs:
//!
//! ```text
//! parts/manifest.json          what job and data the parts belong to
//! parts/job.json               the normalised job (with its paths), for `oesweep merge`
//! parts/part-000001.parquet    finished rows (the columns of cells.parquet), in batches
//! parts/part-000002.parquet
//! parts/shard-0-of-4/          the same three kinds of file for `run --shard 0/4`
//! parts/shard-1-of-4/          ...
//! ```
//!
//! **Shards** ([`crate::shard`]) run as separate processes, possibly on several nodes at once,
//! into the same output folder. Each has its own checkpoint folder, so part numbers, temporary
//! files, manifests and `--force` deletions of one shard never touch another's files; they
//! are the same rules as a whole run's, one folder down. A shard does not merge: `oesweep
//! merge` ([`gather`]) reads every folder, checks that all belong to the same job, and writes
//! the result files as a whole run would. A whole run resumes from shard folders too (the
//! cells of a failed shard can be finished on one machine), and its merge deletes them all.
//!
//! **One writer, in batches.** The workers send every finished row (Huber cells and the `ls`
//! fits of the pairs) over a channel to one writer thread ([`Writer`]), which buffers them and
//! writes a part every [`BATCH_SECONDS`] after the first buffered row or every [`BATCH_ROWS`]
//! rows, whichever comes first. A part per row would cost a file and an fsync per cell (tens
//! of files a second on the demo job); one file at the end would lose the night. Batches bound
//! the loss to a few seconds of work and the number of files to one per few seconds or per
//! 500 rows. The workers never wait on the disk, and one thread owns the numbering, so parts
//! are numbered in the order they were written.
//!
//! **Temporary name + rename.** Each part goes through [`crate::export::parquet::write_cells`]:
//! written to `part-NNNNNN.parquet.tmp-<pid>` in the same folder, fsynced, renamed into place.
//! A crash at any instant leaves complete parts only, plus at most one stray `*.tmp-*` file,
//! which is never read and is deleted when the run is resumed.
//!
//! **Never twice.** A row leaves the writer's buffer only after the rename that made it
//! durable, so it is in exactly one part or in none (then it is computed again). A resumed run
//! skips every cell found in the parts, so it never computes, and never writes, such a cell
//! again. Reading keeps the first row of a key anyway (parts in number order), so even a part
//! copied in by hand cannot produce two rows for one cell.
//!
//! **The manifest** is written (atomically) before the first part and ties the parts to one
//! job. It holds the SHA-256 of the normalised job (after validation: resolved columns and
//! sampling periods, k as an explicit list, every default filled in) serialised as JSON, and
//! of the bytes of each data file (estimation, validation), plus the program version and the
//! job itself so that a mismatch can be named. The job's paths are left out of its hash: the
//! output folder is where the parts are, and the data files are identified by their contents,
//! so a moved project folder still resumes while a changed data file does not. A resume whose
//! manifest differs is refused with one line naming the first difference (a job field, a data
//! file, the program version); `--force` deletes the parts and starts over. It also names
//! the kernels that computed the rows ([`crate::kernels::Flavour`]): the AVX2+FMA and the
//! generic build round differently, so a resume or a merge that would put rows of both into
//! one table is refused with one line naming the two.
//!
//! **The end.** The rows read from the parts at the start plus the rows of this run (the
//! sweep keeps them in memory too; this run's parts hold the same rows) are sorted into
//! `cells.parquet`, and the reducer runs on the whole. Only then is the parts folder deleted,
//! by renaming it away first ([`remove`]): a crash before that rename leaves a checkpoint in
//! which every cell is done, and the next run just merges again.
//!
//! **Signals.** [`StopOnSignal`], armed by the command line around its run (never by the
//! library), turns SIGINT/SIGTERM into the stop flag the sweep's workers check before each
//! cell; a second signal exits at once with code 130 (the parts on disk are complete either
//! way). Dropped, it puts back the dispositions it found.
//!
//! Files: [`manifest`] (what a checkpoint belongs to), [`read`] (inspecting and gathering
//! parts), [`writer`] (the writer thread), [`folder`] (folders, names, deletion), [`signal`]
//! (stop on SIGINT/SIGTERM).

mod folder;
mod manifest;
mod read;
mod signal;
mod writer;

pub use folder::{folder, open, part_path, remove, shard_folders};
pub use manifest::{DataHash, Manifest};
pub use read::{Existing, Gathered, gather, inspect, inspect_all};
pub use signal::StopOnSignal;
pub use writer::{Saved, Writer};

/// Folder of the checkpoint inside the output folder.
pub const PARTS_DIR: &str = "parts";
/// Manifest file inside a checkpoint folder.
pub const MANIFEST: &str = "manifest.json";
/// The normalised job (paths included) inside a checkpoint folder: what `oesweep merge`
/// needs to rebuild the plan and write `job.json` without the job file.
pub use crate::export::JOB_FILE;
/// A part is written at the latest when this many rows are waiting.
pub const BATCH_ROWS: usize = 500;
/// A part is written at the latest this many seconds after its first row finished.
pub const BATCH_SECONDS: f64 = 3.0;
/// Largest `--checkpoint-every`: about 32 years, which already means "by row count only" (a
/// part every [`BATCH_ROWS`] rows, the tests' way of saying never by time); far above it the
/// interval overflows the clock's arithmetic (`1e20` seconds panicked).
pub const MAX_BATCH_SECONDS: f64 = 1e9;
/// Layout version of the parts folder; a different one is never resumed.
pub(crate) const FORMAT: u32 = 1;

#[cfg(test)]
mod tests {
    use super::folder::part_number;
    use super::manifest::first_difference;
    use super::read::list_parts;
    use super::*;
    use crate::export;
    use crate::table::{CellRow, FitKind, RowKey};
    use serde_json::json;
    use std::path::Path;
    use std::time::{Duration, Instant};

    #[test]
    fn checkpoint_part_names_roundtrip() {
        let p = part_path(Path::new("x"), 12);
        assert_eq!(p, Path::new("x/part-000012.parquet"));
        assert_eq!(part_number("part-000012.parquet"), Some(12));
        assert_eq!(part_number("part-1234567.parquet"), Some(1234567));
        for bad in ["part-.parquet", "part-12.parquet.tmp-5", "part-1a.parquet", "manifest.json"] {
            assert_eq!(part_number(bad), None, "{bad}");
        }
    }

    #[test]
    fn checkpoint_difference_names_the_field() {
        let a = json!({"grid": {"k": [0.1, 0.2], "nb": [1, 2]}, "name": "x"});
        let b = json!({"grid": {"k": [0.1, 0.3], "nb": [1, 2]}, "name": "x"});
        let (field, then, now) = first_difference("", &a, &b).unwrap();
        assert_eq!((field.as_str(), then.as_str(), now.as_str()), ("grid.k", "[0.1,0.2]", "[0.1,0.3]"));
        let c = json!({"grid": {"k": [0.1, 0.2], "nb": [1, 2]}, "name": "x", "band_hz": [0, 5]});
        assert_eq!(first_difference("", &a, &c).unwrap().0, "band_hz");
        assert!(first_difference("", &a, &a).is_none());
        let long_a = json!({"k": (0..20).map(|i| i as f64 / 7.0).collect::<Vec<_>>()});
        let long_b = json!({"k": (0..19).map(|i| i as f64 / 7.0).collect::<Vec<_>>()});
        let (_, then, now) = first_difference("", &long_a, &long_b).unwrap();
        assert!(then.ends_with("(20 values)") && now.ends_with("(19 values)"), "{then} / {now}");
    }

    #[test]
    fn checkpoint_writer_batches_by_rows_and_flushes_at_the_end() {
        let dir = tempfile::tempdir().unwrap();
        let w = Writer::start(dir.path().to_path_buf(), 7, Duration::from_secs(3600), 4);
        for nf in 0..10 {
            w.sender()
                .send(CellRow::failed(RowKey::siso(FitKind::Huber, 1, nf, 1, Some(0)), Some(0.5), "x".into()))
                .unwrap();
        }
        let saved = w.finish();
        assert!(saved.error.is_none());
        assert_eq!((saved.parts, saved.rows, saved.huber_rows, saved.unsaved), (3, 10, 10, 0));
        let files = list_parts(dir.path()).unwrap();
        assert_eq!(files.iter().map(|(n, _)| *n).collect::<Vec<_>>(), vec![7, 8, 9]);
        let sizes: Vec<usize> = files.iter().map(|(_, p)| export::parquet::read_cells(p).unwrap().len()).collect();
        assert_eq!(sizes, vec![4, 4, 2]);
    }

    #[test]
    fn checkpoint_writer_flushes_on_time() {
        let dir = tempfile::tempdir().unwrap();
        let w = Writer::start(dir.path().to_path_buf(), 1, Duration::from_millis(50), 1000);
        w.sender().send(CellRow::failed(RowKey::siso(FitKind::Ls, 1, 1, 1, None), None, "x".into())).unwrap();
        // The part appears while the writer still runs (the sender is alive, the batch of 1000
        // is far from full), so only the timer can have written it. The test waits for that
        // state, however slow the machine; the bound only keeps a broken writer from hanging
        // the suite and says nothing about the timer's precision.
        let waited = Instant::now();
        while list_parts(dir.path()).unwrap().is_empty() {
            assert!(waited.elapsed() < Duration::from_secs(600), "the timer never wrote the part");
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(list_parts(dir.path()).unwrap().len(), 1, "written before the end");
        assert_eq!(w.finish().parts, 1);
    }
}
