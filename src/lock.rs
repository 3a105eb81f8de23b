//! One run per output folder: OS file locks (`flock(2)` through `std::fs::File::try_lock`),
//! which the kernel releases when the process ends, however it ends, so a `kill -9` leaves
//! no lock behind (the lock files themselves stay; they are empty of meaning until locked).
//!
//! The lock files live directly in the output folder, which no run deletes (the checkpoint
//! folders below it are deleted and recreated, so a lock inside them could be taken twice):
//!
//! ```text
//! <out>/.oesweep.lock               exclusive: a whole run, a merge; shared: each shard run
//! <out>/.oesweep-shard-I-of-N.lock  exclusive: the run of shard I/N
//! ```
//!
//! So two whole runs (or a run and a merge) of one folder exclude each other; shards run side
//! by side but a whole run or merge waits for none of them and is refused while any runs; and
//! one shard cannot run twice at once. A refused run is bad input (exit 2, nothing written)
//! with one line naming the folder and, when it can be read, the pid holding the lock.

use crate::error::{Error, Result};
use crate::shard::Shard;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Lock of the whole output folder.
pub const OUTPUT_LOCK: &str = ".oesweep.lock";

/// Lock file of shard `s` in the output folder.
pub fn shard_lock_name(s: Shard) -> String {
    format!(".oesweep-{}.lock", s.folder_name())
}

/// Locks held while this value lives.
#[derive(Debug)]
pub struct RunLock {
    _files: Vec<File>,
}

fn open(path: &Path) -> Result<File> {
    OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .map_err(|e| Error::output(path, format!("cannot open the lock file: {e}")))
}

/// The pid written into a lock file by its last exclusive holder.
fn holder(path: &Path) -> Option<u32> {
    std::fs::read_to_string(path).ok()?.trim().parse().ok()
}

/// Write our pid into an exclusively held lock file (for the message of a refused run).
fn sign(file: &mut File) {
    let _ = file.set_len(0).and_then(|_| writeln!(file, "{}", std::process::id())).and_then(|_| file.flush());
}

fn in_use(out: &Path, what: &str, pid: Option<u32>) -> Error {
    let by = match pid {
        Some(p) => format!(" (pid {p})"),
        None => String::new(),
    };
    Error::locked(out, format!("in use by {what}{by}; wait until it ends, or stop it"))
}

/// Shard runs that hold their lock in `out`, as "shard I/N (pid P)".
fn running_shards(out: &Path) -> Vec<String> {
    let Ok(entries) = std::fs::read_dir(out) else { return Vec::new() };
    let mut found = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(shard) =
            name.strip_prefix(".oesweep-").and_then(|n| n.strip_suffix(".lock")).and_then(Shard::from_folder_name)
        else {
            continue;
        };
        let Ok(f) = File::open(entry.path()) else { continue };
        if let Err(TryLockError::WouldBlock) = f.try_lock_shared() {
            let pid = holder(&entry.path()).map_or(String::new(), |p| format!(" (pid {p})"));
            found.push(format!("shard {shard}{pid}"));
        }
    }
    found.sort();
    found
}

/// Lock the output folder `out` (which must exist) for a whole run or a merge.
pub fn lock_output(out: &Path) -> Result<RunLock> {
    let path: PathBuf = out.join(OUTPUT_LOCK);
    let mut file = open(&path)?;
    match file.try_lock() {
        Ok(()) => {
            sign(&mut file);
            Ok(RunLock { _files: vec![file] })
        }
        Err(TryLockError::WouldBlock) => {
            // Held shared: by shard runs, whose pids are in their own files. Held exclusively:
            // by a whole run or merge, which signed this file.
            let shards = running_shards(out);
            if shards.is_empty() {
                Err(in_use(out, "another oesweep run", holder(&path)))
            } else {
                Err(in_use(out, &format!("running shards: {}", shards.join(", ")), None))
            }
        }
        Err(TryLockError::Error(e)) => Err(Error::output(&path, format!("cannot lock: {e}"))),
    }
}

/// Lock shard `s` of the output folder `out` (which must exist): shared on the folder (other
/// shards may run beside it), exclusive on the shard.
pub fn lock_shard(out: &Path, s: Shard) -> Result<RunLock> {
    let folder_path = out.join(OUTPUT_LOCK);
    let folder = open(&folder_path)?;
    match folder.try_lock_shared() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => return Err(in_use(out, "another oesweep run", holder(&folder_path))),
        Err(TryLockError::Error(e)) => return Err(Error::output(&folder_path, format!("cannot lock: {e}"))),
    }
    let path = out.join(shard_lock_name(s));
    let mut file = open(&path)?;
    match file.try_lock() {
        Ok(()) => {
            sign(&mut file);
            Ok(RunLock { _files: vec![folder, file] })
        }
        Err(TryLockError::WouldBlock) => Err(in_use(out, &format!("another run of shard {s}"), holder(&path))),
        Err(TryLockError::Error(e)) => Err(Error::output(&path, format!("cannot lock: {e}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // flock locks belong to the open file description, so two opens in one process conflict
    // just as two processes do.
    #[test]
    fn a_locked_folder_is_refused_naming_the_holder_and_released_on_drop() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let held = lock_output(out).unwrap();
        let e = lock_output(out).unwrap_err();
        assert!(e.is_bad_input() && matches!(e, Error::Locked { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(
            msg.contains("in use by another oesweep run") && msg.contains(&std::process::id().to_string()),
            "{msg}"
        );
        let s = Shard { index: 1, count: 4 };
        assert!(lock_shard(out, s).unwrap_err().to_string().contains("in use"));
        drop(held);

        let a = lock_shard(out, s).unwrap();
        let b = lock_shard(out, Shard { index: 2, count: 4 }).unwrap();
        let msg = lock_shard(out, s).unwrap_err().to_string();
        assert!(msg.contains("another run of shard 1/4"), "{msg}");
        let msg = lock_output(out).unwrap_err().to_string();
        assert!(msg.contains("running shards: shard 1/4") && msg.contains("shard 2/4"), "{msg}");
        drop((a, b));
        lock_output(out).unwrap();
    }
}
