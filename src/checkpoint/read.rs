//! Reading checkpoints: the parts of one folder checked against the job ([`inspect`]), all
//! folders of a whole run ([`inspect_all`]), and everything a merge needs ([`gather`]). Reads
//! only; a problem is one bad-input error naming the file, with the way out (`--force`).

use super::folder::{part_number, shard_folders};
use super::manifest::job_identity;
use super::{JOB_FILE, MANIFEST, Manifest, PARTS_DIR};
use crate::error::{Error, Result};
use crate::export;
use crate::job::ValidJob;
use crate::plan::Plan;
use crate::shard::Shard;
use crate::table::{CellRow, RowKey};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// Rows of an earlier run of the same job, found in the parts folder.
#[derive(Debug, Default)]
pub struct Existing {
    /// One row per key, first occurrence in part order.
    pub rows: Vec<CellRow>,
    /// Number of part files read.
    pub parts: usize,
    /// Number to give the next part.
    pub next_part: u64,
    /// Rows dropped because an earlier part already had their key (0 unless parts were
    /// copied in by hand).
    pub duplicates: usize,
}

impl Existing {
    pub fn huber_rows(&self) -> usize {
        crate::table::huber_rows(&self.rows)
    }
}

/// What a checkpoint is read for: the way out of a refusal differs (`run` has `--force`,
/// `merge` has not).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Purpose {
    Resume,
    Merge,
}

/// Error about a checkpoint folder, with the way out for `purpose`.
pub(super) fn refuse(path: &Path, why: impl std::fmt::Display, purpose: Purpose) -> Error {
    let way_out = match purpose {
        Purpose::Resume => "rerun with --force to delete the checkpoint and start over",
        Purpose::Merge => {
            "run that folder's cells again (`oesweep run JOB --shard I/N --force` for a shard folder) and merge again"
        }
    };
    Error::input(path, format!("{why}; {way_out}"))
}

/// The manifest at `path`. One written before checkpoints recorded their kernel flavour (its
/// rows cannot be matched to a flavour) gets a message that says so and what to do, rather
/// than serde's "missing field".
pub(super) fn read_manifest(path: &Path, purpose: Purpose) -> Result<Manifest> {
    let text = std::fs::read_to_string(path).map_err(|e| refuse(path, format!("cannot read: {e}"), purpose))?;
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| refuse(path, format!("not a checkpoint manifest: {e}"), purpose))?;
    if value.is_object() && value.get("job_sha256").is_some() && value.get("kernels").is_none() {
        let why = "was written by an earlier build of oesweep that did not record which kernels computed its rows, \
                   so they cannot join this build's";
        let way_out = match purpose {
            Purpose::Resume => {
                "start again with --force (deletes the checkpoint) or resume with the build that wrote it"
            }
            Purpose::Merge => "merge with the build that wrote it, or run the job again with --force",
        };
        return Err(Error::input(path, format!("{why}: {way_out}")));
    }
    serde_json::from_value(value).map_err(|e| refuse(path, format!("not a checkpoint manifest: {e}"), purpose))
}

/// Part files of `parts`, sorted by number.
pub(super) fn list_parts(parts: &Path) -> Result<Vec<(u64, PathBuf)>> {
    let entries = std::fs::read_dir(parts).map_err(|e| Error::input(parts, format!("cannot list checkpoint: {e}")))?;
    let mut found = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::input(parts, format!("cannot list checkpoint: {e}")))?;
        if let Some(n) = entry.file_name().to_str().and_then(part_number) {
            found.push((n, entry.path()));
        }
    }
    found.sort();
    Ok(found)
}

/// Read the checkpoint in `parts` (writes nothing). No folder: nothing to resume. A folder of
/// another job, a missing or unreadable manifest next to parts, an unreadable part or a row
/// that is not a cell of `plan`: an [`Error::Input`] naming the file and the difference.
pub fn inspect(parts: &Path, now: &Manifest, plan: &Plan) -> Result<Existing> {
    inspect_for(parts, now, plan, Purpose::Resume)
}

fn inspect_for(parts: &Path, now: &Manifest, plan: &Plan, purpose: Purpose) -> Result<Existing> {
    if !parts.exists() {
        return Ok(Existing { next_part: 1, ..Default::default() });
    }
    if !parts.is_dir() {
        return Err(refuse(parts, "exists but is not a checkpoint folder", purpose));
    }
    let files = list_parts(parts)?;
    let manifest_path = parts.join(MANIFEST);
    if !manifest_path.exists() {
        if files.is_empty() {
            // Killed between creating the folder and writing the manifest: nothing was saved.
            return Ok(Existing { next_part: 1, ..Default::default() });
        }
        return Err(refuse(&manifest_path, "missing, so the parts next to it cannot be matched to this job", purpose));
    }
    let stored = read_manifest(&manifest_path, purpose)?;
    if let Some(why) = stored.kernel_mix(now) {
        return Err(refuse(parts, why, purpose));
    }
    if let Some(what) = stored.difference(now) {
        return Err(refuse(parts, format!("holds an interrupted run of a different job: {what}"), purpose));
    }

    let huber_keys: HashSet<RowKey> =
        plan.cells().iter().map(|c| RowKey::huber(&plan.pairs[c.pair], c.k_index)).collect();
    let ls_keys: HashSet<RowKey> = plan.pairs.iter().map(RowKey::ls).collect();
    let mut seen = HashSet::new();
    let mut out =
        Existing { parts: files.len(), next_part: files.last().map_or(1, |(n, _)| n + 1), ..Default::default() };
    for (_, path) in &files {
        // Parts are written atomically, so a bad one was damaged from outside; the Parquet
        // reader may panic on some damage, which must still end as a one-line error.
        let read = std::panic::catch_unwind(|| export::parquet::read_cells(path))
            .unwrap_or_else(|_| Err(Error::input(path, "not a readable Parquet file")));
        let rows = read.map_err(|e| match e {
            Error::Input { path, msg } => refuse(&path, msg, purpose),
            other => other,
        })?;
        for (i, row) in rows.into_iter().enumerate() {
            let key = row.key;
            let k_ok = match (key.k_index, row.k) {
                (Some(ki), Some(k)) => plan.ks.get(ki as usize).is_some_and(|&pk| pk.to_bits() == k.to_bits()),
                (None, None) => true,
                _ => false,
            };
            let known = if row.is_huber() { huber_keys.contains(&key) } else { ls_keys.contains(&key) };
            if !(known && k_ok) {
                return Err(refuse(path, format!("row {i} ({key}) is not a cell of this job"), purpose));
            }
            if seen.insert(key) {
                out.rows.push(row);
            } else {
                out.duplicates += 1;
            }
        }
    }
    Ok(out)
}

/// [`inspect`] for a whole run: the rows of `<out>/parts` and of every shard folder in it
/// (first row of each key; folders in the order of [`shard_folders`]). Parts are numbered on
/// from the whole run's own folder.
pub fn inspect_all(out: &Path, now: &Manifest, plan: &Plan) -> Result<Existing> {
    let parts = out.join(PARTS_DIR);
    let mut all = inspect(&parts, now, plan)?;
    let mut seen: HashSet<RowKey> = all.rows.iter().map(|r| r.key).collect();
    for (dir, _) in shard_folders(&parts)? {
        let more = inspect(&dir, now, plan)?;
        all.parts += more.parts;
        all.duplicates += more.duplicates;
        for row in more.rows {
            if seen.insert(row.key) {
                all.rows.push(row);
            } else {
                all.duplicates += 1;
            }
        }
    }
    Ok(all)
}

/// Everything the checkpoint folders of an output folder hold, for `oesweep merge`.
#[derive(Debug)]
pub struct Gathered {
    /// The normalised job, read from a checkpoint folder's [`JOB_FILE`].
    pub job: ValidJob,
    /// Its plan.
    pub plan: Plan,
    /// One row per key found, sorted as in `cells.parquet`.
    pub rows: Vec<CellRow>,
    /// The checkpoint folders read (the whole run's `parts/` first, then the shards') and how
    /// many part files each held.
    pub folders: Vec<(PathBuf, Option<Shard>, usize)>,
    /// Rows found in more than one folder (identical but for `seconds`; kept once).
    pub duplicates: usize,
    /// The kernel flavour that computed the rows (`kernels::Flavour::name`; one for all, or the
    /// gathering refused them).
    pub kernels: String,
}

/// Read every checkpoint folder of `out` (writes nothing). All must belong to one job (the
/// same manifest), written by this version of oesweep (a merge must not mix programs), and
/// the job file must be the job of the manifest. A cell found in two folders (say, a shard run
/// again with another N) must have the same row there but for `seconds`, else the folder is
/// refused: the computation is deterministic, so a difference means the files are not what
/// they claim to be.
pub fn gather(out: &Path) -> Result<Gathered> {
    let parts = out.join(PARTS_DIR);
    if !parts.is_dir() {
        return Err(Error::input(&parts, "no checkpoint to merge (no parts folder)"));
    }
    let mut dirs: Vec<(PathBuf, Option<Shard>)> = vec![(parts.clone(), None)];
    dirs.extend(shard_folders(&parts)?.into_iter().map(|(d, s)| (d, Some(s))));
    let Some(reference) = dirs.iter().map(|(d, _)| d).find(|d| d.join(MANIFEST).exists()) else {
        return Err(Error::input(&parts, "holds no checkpoint manifest, so there is nothing to merge"));
    };
    let manifest = read_manifest(&reference.join(MANIFEST), Purpose::Merge)?;
    let version = env!("CARGO_PKG_VERSION");
    if manifest.oesweep_version != version {
        return Err(Error::input(
            reference,
            format!(
                "was written by oesweep {}, this is oesweep {version}: merge with that version",
                manifest.oesweep_version
            ),
        ));
    }
    let job_path = reference.join(JOB_FILE);
    let (job, _) = crate::job::read_as_run(&job_path)?;
    if job_identity(&job.job).1 != manifest.job_sha256 {
        return Err(Error::input(&job_path, "is not the job of the manifest next to it"));
    }
    let plan = Plan::from_job(&job);
    // The merge lays the job out in N shards to name the ones to rerun: a folder renamed to
    // an absurd N must be refused, not laid out.
    for (dir, shard) in &dirs {
        if let Some(s) = shard {
            crate::shard::check_count(s.count, &plan).map_err(|m| Error::input(dir, m))?;
        }
    }
    let mut found: std::collections::HashMap<RowKey, (CellRow, usize)> = std::collections::HashMap::new();
    let (mut folders, mut duplicates) = (Vec::new(), 0);
    for (dir, shard) in dirs {
        let existing = inspect_for(&dir, &manifest, &plan, Purpose::Merge)?;
        duplicates += existing.duplicates;
        for row in existing.rows {
            match found.get(&row.key) {
                None => {
                    found.insert(row.key, (row, folders.len()));
                }
                Some((first, at)) => {
                    if !row.same_result(first) {
                        return Err(Error::input(
                            &dir,
                            format!(
                                "row {} differs from the one in {}",
                                row.key,
                                folders.get(*at).map_or(dir.clone(), |(d, _, _): &(PathBuf, _, _)| d.clone()).display()
                            ),
                        ));
                    }
                    duplicates += 1;
                }
            }
        }
        folders.push((dir, shard, existing.parts));
    }
    let mut rows: Vec<CellRow> = found.into_values().map(|(r, _)| r).collect();
    crate::table::sort_rows(&mut rows);
    Ok(Gathered { job, plan, rows, folders, duplicates, kernels: manifest.kernels })
}
