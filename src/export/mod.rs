//! Result files: the cell table (`parquet`) and JSON documents such as the model selection (`json`).
//!
//! Every file is written atomically: the bytes go to `<path>.tmp-<pid>` in the same folder, are
//! fsynced, and the temporary file is renamed over `path`. A reader (or a resumed sweep) therefore
//! sees either the previous complete file or the new complete file, never a torn one, even if the
//! process is killed mid-write. The temporary file lives in the target folder because a rename is
//! only atomic within one file system.

pub mod continuous;
pub mod json;
mod mat;
mod matlab;
pub mod model;
pub mod parquet;

/// The result table of a finished run (or merge).
pub const CELLS_FILE: &str = "cells.parquet";
/// The picks and what the run says about the data ([`crate::reduce::Selection`]).
pub const SELECTION_FILE: &str = "selection.json";
/// The normalised job as run (also the name of the job file kept in a checkpoint folder).
pub const JOB_FILE: &str = "job.json";
/// The files a finished run leaves in its output folder.
pub const RESULT_FILES: [&str; 3] = [CELLS_FILE, SELECTION_FILE, JOB_FILE];
/// The review page ([`crate::report`]).
pub const REPORT_FILE: &str = "report.html";

/// Layout version of the result files, kept as `format_version` in selection.json, job.json
/// and the key-value metadata of cells.parquet (and of a checkpoint's parts). Raised when a
/// reader of the previous layout would misread the new one; a file of a newer format is
/// refused ([`check_format`]), one without the field (before 0.1.0 had it) reads as format 1.
pub const FORMAT_VERSION: u32 = 1;
/// The key of [`FORMAT_VERSION`] in every result file.
pub const FORMAT_KEY: &str = "format_version";

/// The format version a result file declares (`None`: written before the field existed) must
/// be one this program reads. Returns what is wrong; the caller names the file.
pub fn check_format(declared: Option<&str>) -> std::result::Result<(), String> {
    let Some(text) = declared else { return Ok(()) };
    match text.trim().parse::<u64>() {
        Ok(v) if (1..=FORMAT_VERSION as u64).contains(&v) => Ok(()),
        Ok(v) if v > FORMAT_VERSION as u64 => Err(format!(
            "{FORMAT_KEY} {v} is newer than this oesweep {} reads (up to {FORMAT_VERSION}): read it with a newer oesweep",
            env!("CARGO_PKG_VERSION")
        )),
        _ => Err(format!("{FORMAT_KEY} '{}' is not a format version of oesweep", crate::data::one_line(text))),
    }
}

use crate::error::{Error, Result};
use std::ffi::OsString;
use std::fs::File;
use std::path::{Path, PathBuf};

/// Temporary sibling of `path` used while writing it.
fn temporary_path(path: &Path) -> Result<PathBuf> {
    let name = path.file_name().ok_or_else(|| Error::output(path, "not a file path"))?;
    let mut tmp: OsString = name.to_os_string();
    tmp.push(format!(".tmp-{}", std::process::id()));
    Ok(path.with_file_name(tmp))
}

/// Write `path` atomically: `write` fills a temporary file in the same folder, which is fsynced
/// and renamed over `path`. On any failure the temporary file is removed and `path` is untouched.
/// `write` reports failures as a message; the returned error names `path`.
pub(crate) fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut File) -> std::result::Result<(), String>,
) -> Result<()> {
    stage(path, write)?.commit()
}

/// The first half of [`write_atomically`]: the temporary file written and fsynced, not yet in
/// place. Several files are staged side by side and committed in a fixed order.
pub(crate) fn stage(path: &Path, write: impl FnOnce(&mut File) -> std::result::Result<(), String>) -> Result<Staged> {
    let staged = Staged { tmp: temporary_path(path)?, path: path.to_path_buf(), committed: false };
    let tmp = &staged.tmp;
    let result = (|| {
        let mut file = File::create(tmp).map_err(|e| format!("cannot create {}: {e}", tmp.display()))?;
        write(&mut file)?;
        // Without the fsync a crash after the rename could leave an empty or partial file under
        // the final name on some file systems.
        file.sync_all().map_err(|e| format!("cannot flush {}: {e}", tmp.display()))
    })();
    // On failure `staged` is dropped, which removes the temporary file.
    result.map(|()| staged).map_err(|msg| Error::output(path, msg))
}

/// A file written by [`stage`]: [`Staged::commit`] renames it into place; dropped uncommitted,
/// it is removed and its path left untouched.
#[must_use = "a staged file is removed unless committed"]
pub(crate) struct Staged {
    tmp: PathBuf,
    path: PathBuf,
    committed: bool,
}

impl Staged {
    /// Renames the file over its path (durably, see [`sync_parent`]).
    pub(crate) fn commit(mut self) -> Result<()> {
        std::fs::rename(&self.tmp, &self.path)
            .map_err(|e| Error::output(&self.path, format!("cannot rename {} into place: {e}", self.tmp.display())))?;
        self.committed = true;
        sync_parent(&self.path);
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.committed {
            // Best effort: the file may not exist if creating it failed.
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Make the rename durable by fsyncing the folder. Best effort: not every platform or file
/// system allows opening a directory, and the file content itself is already safe.
fn sync_parent(path: &Path) {
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let Ok(dir) = File::open(parent) {
        let _ = dir.sync_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn export_temporary_path_is_a_sibling() {
        let tmp = temporary_path(Path::new("out/cells.parquet")).unwrap();
        assert_eq!(tmp.parent(), Some(Path::new("out")));
        assert_eq!(tmp.file_name().unwrap().to_str().unwrap(), format!("cells.parquet.tmp-{}", std::process::id()));
        assert!(temporary_path(Path::new("/")).is_err());
    }

    #[test]
    fn export_failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.txt");
        std::fs::write(&path, "old").unwrap();
        let err = write_atomically(&path, |_| Err("boom".to_string())).unwrap_err();
        assert!(err.to_string().contains("a.txt") && err.to_string().contains("boom"), "{err}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn export_staged_files_appear_only_when_committed() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        std::fs::write(&b, "old").unwrap();
        let write = |text: &'static str| {
            move |f: &mut File| std::io::Write::write_all(f, text.as_bytes()).map_err(|e| e.to_string())
        };
        let (staged_a, staged_b) = (stage(&a, write("new a")).unwrap(), stage(&b, write("new b")).unwrap());
        assert!(!a.exists() && std::fs::read_to_string(&b).unwrap() == "old", "nothing in place before the commit");
        staged_a.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        // Dropped uncommitted (a later piece failed): the old file stays, no temporary is left.
        drop(staged_b);
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn export_missing_folder_is_an_output_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("no/such/a.txt");
        let err = write_atomically(&path, |_| Ok(())).unwrap_err();
        assert!(matches!(err, Error::Output { .. }) && err.to_string().contains("a.txt"), "{err}");
    }
}
