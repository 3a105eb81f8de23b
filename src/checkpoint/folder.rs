//! The checkpoint's folders and files: where a run's (or a shard's) parts go, part names,
//! making a folder ready ([`open`]) and deleting one safely ([`remove`]), and the leftovers of
//! killed processes.

use super::{JOB_FILE, MANIFEST, Manifest, PARTS_DIR};
use crate::error::{Error, Result};
use crate::export;
use crate::job::ValidJob;
use crate::shard::Shard;
use std::path::{Path, PathBuf};

/// Path of part number `n`.
pub fn part_path(parts: &Path, n: u64) -> PathBuf {
    parts.join(format!("part-{n:06}.parquet"))
}

/// The number of a part file name (`part-000012.parquet` -> 12).
pub(super) fn part_number(name: &str) -> Option<u64> {
    let digits = name.strip_prefix("part-")?.strip_suffix(".parquet")?;
    (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())).then(|| digits.parse().ok()).flatten()
}

/// Checkpoint folder of a run: `<out>/parts` for a whole run, `<out>/parts/shard-I-of-N`
/// for a shard.
pub fn folder(out: &Path, shard: Option<Shard>) -> PathBuf {
    let parts = out.join(PARTS_DIR);
    match shard {
        Some(s) => parts.join(s.folder_name()),
        None => parts,
    }
}

/// Delete temporary files (`<name>.tmp-<pid>`) that a killed process left in `dir` while
/// writing one of `names` (any name when empty). Best effort: a leftover is harmless, it is
/// never read.
pub(super) fn remove_temporaries(dir: &Path, names: &[&str]) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some((base, _)) = name.to_str().and_then(|n| n.split_once(".tmp-")) else { continue };
        if names.is_empty() || names.contains(&base) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// Delete a checkpoint folder. It is first renamed to `<name>.deleted-<pid>` next to it, which
/// is atomic, so a crash in the middle of the deletion leaves a folder that is never read as a
/// checkpoint (the next [`open`] deletes it) instead of a manifest-less or partial one.
pub(super) fn remove_folder(dir: &Path) -> Result<()> {
    if !dir.exists() {
        return Ok(());
    }
    let name = dir.file_name().and_then(|n| n.to_str()).unwrap_or(PARTS_DIR);
    let doomed = dir.with_file_name(format!("{name}.deleted-{}", std::process::id()));
    let target = if std::fs::rename(dir, &doomed).is_ok() { doomed } else { dir.to_path_buf() };
    std::fs::remove_dir_all(&target).map_err(|e| Error::output(&target, format!("cannot delete checkpoint: {e}")))
}

/// Delete leftovers of [`remove_folder`] calls that a crash interrupted: `<name>.deleted-*`
/// in `parent`. Best effort.
pub(super) fn remove_deleted_leftovers(parent: &Path, name: &str) {
    let Ok(entries) = std::fs::read_dir(parent) else { return };
    let prefix = format!("{name}.deleted-");
    for entry in entries.flatten() {
        if entry.file_name().to_str().is_some_and(|n| n.starts_with(&prefix)) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Delete the whole checkpoint of `out`, shard folders included (a finished run or merge no
/// longer needs it; `--force` of a whole run discards it).
pub fn remove(out: &Path) -> Result<()> {
    remove_folder(&out.join(PARTS_DIR))
}

/// Make the checkpoint folder of this run ([`folder`]) ready, after [`inspect`] accepted it
/// (or with `force`): with `force` delete what is there first (a whole run: all of `parts/`;
/// a shard: its own folder only, since the other shards may be running); create the folder;
/// delete temporary files of killed writers (its parts, and for a whole run the result files
/// in `out`); write the manifest unless the folder already has it, and the job file.
pub fn open(out: &Path, shard: Option<Shard>, manifest: &Manifest, job: &ValidJob, force: bool) -> Result<()> {
    let dir = folder(out, shard);
    match shard {
        None => {
            if force {
                remove(out)?;
            }
            remove_deleted_leftovers(out, PARTS_DIR);
        }
        Some(s) => {
            if force {
                remove_folder(&dir)?;
            }
            remove_deleted_leftovers(&out.join(PARTS_DIR), &s.folder_name());
        }
    }
    std::fs::create_dir_all(&dir).map_err(|e| Error::output(&dir, format!("cannot create checkpoint folder: {e}")))?;
    remove_temporaries(&dir, &[]);
    if shard.is_none() {
        // A shard must not: a merge may be writing them (or another shard's run may).
        remove_temporaries(out, &crate::export::RESULT_FILES);
    }
    let path = dir.join(MANIFEST);
    if !path.exists() {
        export::json::write_json(&path, manifest)?;
    }
    // Rewritten each time: the paths are the latest run's (the manifest, checked above, says
    // the rest is the same job).
    job.write_as_run(&dir.join(JOB_FILE))
}

/// The shard checkpoint folders in `parts`, ordered by (N, I). Other entries are ignored.
pub fn shard_folders(parts: &Path) -> Result<Vec<(PathBuf, Shard)>> {
    let Ok(entries) = std::fs::read_dir(parts) else { return Ok(Vec::new()) };
    let mut found = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::input(parts, format!("cannot list checkpoint: {e}")))?;
        if let Some(s) = entry.file_name().to_str().and_then(Shard::from_folder_name)
            && entry.path().is_dir()
        {
            found.push((entry.path(), s));
        }
    }
    found.sort_by_key(|(_, s)| (s.count, s.index));
    Ok(found)
}
