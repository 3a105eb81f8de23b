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
//! file, the program version); `--force` deletes the parts and starts over.
//!
//! **The end.** The rows read from the parts at the start plus the rows of this run (the
//! sweep keeps them in memory too; this run's parts hold the same rows) are sorted into
//! `cells.parquet`, and the reducer runs on the whole. Only then is the parts folder deleted,
//! by renaming it away first ([`remove`]): a crash before that rename leaves a checkpoint in
//! which every cell is done, and the next run just merges again.
//!
//! **Signals.** [`StopOnSignal`] turns SIGINT/SIGTERM into a flag the sweep's workers check
//! before each cell; a second signal exits at once with code 130 (the parts on disk are
//! complete either way).

use crate::error::{Error, Result};
use crate::export;
use crate::job::{Job, ValidJob};
use crate::plan::Plan;
use crate::shard::Shard;
use crate::table::{CellRow, Method, RowKey, huber_key, ls_key};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::{BTreeSet, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Folder of the checkpoint inside the output folder.
pub const PARTS_DIR: &str = "parts";
/// Manifest file inside a checkpoint folder.
pub const MANIFEST: &str = "manifest.json";
/// The normalised job (paths included) inside a checkpoint folder: what `oesweep merge`
/// needs to rebuild the plan and write `job.json` without the job file.
pub const JOB_FILE: &str = "job.json";
/// A part is written at the latest when this many rows are waiting.
pub const BATCH_ROWS: usize = 500;
/// A part is written at the latest this many seconds after its first row finished.
pub const BATCH_SECONDS: f64 = 3.0;
/// Layout version of the parts folder; a different one is never resumed.
const FORMAT: u32 = 1;

/// Path of part number `n`.
pub fn part_path(parts: &Path, n: u64) -> PathBuf {
    parts.join(format!("part-{n:06}.parquet"))
}

/// The number of a part file name (`part-000012.parquet` -> 12).
fn part_number(name: &str) -> Option<u64> {
    let digits = name.strip_prefix("part-")?.strip_suffix(".parquet")?;
    (!digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit())).then(|| digits.parse().ok()).flatten()
}

fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
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

/// The part of a normalised job that identifies it (its paths left out; see [`Manifest`]) and
/// the SHA-256 of that as compact JSON.
fn job_identity(job: &Job) -> (Value, String) {
    let mut job = serde_json::to_value(job).expect("a job serialises");
    let obj = job.as_object_mut().expect("a job is a JSON object");
    obj.remove("output");
    for field in ["data", "validation"] {
        if let Some(Value::Object(spec)) = obj.get_mut(field) {
            spec.remove("path");
        }
    }
    let sha = sha256_hex(&serde_json::to_vec(&job).expect("JSON serialises"));
    (job, sha)
}

/// Hash of one data file.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DataHash {
    /// `"data"` (estimation record) or `"validation"`.
    pub role: String,
    /// Where it was read from (informative only: not compared).
    pub path: PathBuf,
    pub bytes: u64,
    pub sha256: String,
}

/// `parts/manifest.json`: the identity of the job the parts belong to.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub format: u32,
    pub oesweep_version: String,
    /// SHA-256 of `job` serialised as compact JSON.
    pub job_sha256: String,
    /// The normalised job without its paths (`output`, `data.path`, `validation.path`).
    pub job: Value,
    pub data: Vec<DataHash>,
}

impl Manifest {
    /// The manifest of a validated job whose inputs have been loaded (so the validation
    /// column is resolved). Reads the data files again to hash their bytes.
    pub fn of_job(vj: &ValidJob) -> Result<Manifest> {
        let (job, job_sha256) = job_identity(&vj.job);
        let mut data = Vec::new();
        let specs = std::iter::once(("data", &vj.job.data)).chain(vj.job.validation.iter().map(|v| ("validation", v)));
        for (role, spec) in specs {
            let bytes = std::fs::read(&spec.path).map_err(|e| Error::input(&spec.path, format!("cannot read: {e}")))?;
            data.push(DataHash {
                role: role.to_string(),
                path: spec.path.clone(),
                bytes: bytes.len() as u64,
                sha256: sha256_hex(&bytes),
            });
        }
        Ok(Manifest { format: FORMAT, oesweep_version: env!("CARGO_PKG_VERSION").to_string(), job_sha256, job, data })
    }

    /// What differs between the manifest of the parts (`self`) and the current one, in words;
    /// None when the parts belong to the current job.
    pub fn difference(&self, now: &Manifest) -> Option<String> {
        if self.format != now.format {
            return Some(format!(
                "it was written in checkpoint format {}, this oesweep reads format {}",
                self.format, now.format
            ));
        }
        if self.oesweep_version != now.oesweep_version {
            return Some(format!(
                "it was written by oesweep {}, this is oesweep {}",
                self.oesweep_version, now.oesweep_version
            ));
        }
        if self.job_sha256 != now.job_sha256 {
            return Some(match first_difference("", &self.job, &now.job) {
                Some((field, then, now)) => format!("job field '{field}' differs (was {then}, now {now})"),
                None => "the job differs".to_string(),
            });
        }
        for role in ["data", "validation"] {
            let name = if role == "data" { "estimation data" } else { "validation data" };
            match (self.data.iter().find(|d| d.role == role), now.data.iter().find(|d| d.role == role)) {
                (Some(a), Some(b)) if a.sha256 != b.sha256 || a.bytes != b.bytes => {
                    return Some(format!(
                        "{name} {} is not the data of the interrupted run (different contents)",
                        b.path.display()
                    ));
                }
                (Some(_), None) | (None, Some(_)) => return Some(format!("{name} was added or removed")),
                _ => {}
            }
        }
        None
    }
}

/// A JSON value shortened for a one-line message.
fn short(v: &Value) -> String {
    let s = if v.is_null() { "absent".to_string() } else { v.to_string() };
    if s.chars().count() <= 60 {
        return s;
    }
    match v.as_array() {
        Some(a) => format!("[{}, ..., {}] ({} values)", a[0], a[a.len() - 1], a.len()),
        None => format!("{}...", s.chars().take(57).collect::<String>()),
    }
}

/// The first leaf (in key order) where `a` and `b` differ: (dotted path, a, b). Arrays count
/// as leaves, so a changed k list is reported as `grid.k`.
fn first_difference(path: &str, a: &Value, b: &Value) -> Option<(String, String, String)> {
    if a == b {
        return None;
    }
    if let (Value::Object(x), Value::Object(y)) = (a, b) {
        let keys: BTreeSet<&String> = x.keys().chain(y.keys()).collect();
        for key in keys {
            let p = if path.is_empty() { key.clone() } else { format!("{path}.{key}") };
            let d = first_difference(&p, x.get(key).unwrap_or(&Value::Null), y.get(key).unwrap_or(&Value::Null));
            if d.is_some() {
                return d;
            }
        }
        return None;
    }
    Some((path.to_string(), short(a), short(b)))
}

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
        self.rows.iter().filter(|r| r.method == Method::Huber).count()
    }
}

/// Error about the parts folder, with the way out.
fn refuse(path: &Path, why: impl std::fmt::Display) -> Error {
    Error::input(path, format!("{why}; rerun with --force to delete the checkpoint and start over"))
}

/// Part files of `parts`, sorted by number.
fn list_parts(parts: &Path) -> Result<Vec<(u64, PathBuf)>> {
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
    if !parts.exists() {
        return Ok(Existing { next_part: 1, ..Default::default() });
    }
    if !parts.is_dir() {
        return Err(refuse(parts, "exists but is not a checkpoint folder"));
    }
    let files = list_parts(parts)?;
    let manifest_path = parts.join(MANIFEST);
    if !manifest_path.exists() {
        if files.is_empty() {
            // Killed between creating the folder and writing the manifest: nothing was saved.
            return Ok(Existing { next_part: 1, ..Default::default() });
        }
        return Err(refuse(&manifest_path, "missing, so the parts next to it cannot be matched to this job"));
    }
    let text =
        std::fs::read_to_string(&manifest_path).map_err(|e| refuse(&manifest_path, format!("cannot read: {e}")))?;
    let stored: Manifest =
        serde_json::from_str(&text).map_err(|e| refuse(&manifest_path, format!("not a checkpoint manifest: {e}")))?;
    if let Some(what) = stored.difference(now) {
        return Err(refuse(parts, format!("holds an interrupted run of a different job: {what}")));
    }

    let huber_keys: HashSet<RowKey> =
        plan.cells().iter().map(|c| huber_key(plan.pairs[c.pair].nb, plan.pairs[c.pair].nf, c.k_index)).collect();
    let ls_keys: HashSet<RowKey> = plan.pairs.iter().map(|p| ls_key(p.nb, p.nf)).collect();
    let mut seen = HashSet::new();
    let mut out =
        Existing { parts: files.len(), next_part: files.last().map_or(1, |(n, _)| n + 1), ..Default::default() };
    for (_, path) in &files {
        // Parts are written atomically, so a bad one was damaged from outside; the Parquet
        // reader may panic on some damage, which must still end as a one-line error.
        let read = std::panic::catch_unwind(|| export::parquet::read_cells(path))
            .unwrap_or_else(|_| Err(Error::input(path, "not a readable Parquet file")));
        let rows = read.map_err(|e| match e {
            Error::Input { path, msg } => refuse(&path, msg),
            other => other,
        })?;
        for (i, row) in rows.into_iter().enumerate() {
            let key = row.key();
            let k_ok = match (row.k_index, row.k) {
                (Some(ki), Some(k)) => plan.ks.get(ki as usize).is_some_and(|&pk| pk.to_bits() == k.to_bits()),
                (None, None) => true,
                _ => false,
            };
            let known = if row.method == Method::Huber { huber_keys.contains(&key) } else { ls_keys.contains(&key) };
            if !(known && k_ok && row.delay as usize == plan.delay) {
                return Err(refuse(
                    path,
                    format!(
                        "row {i} ({} nb={} nf={} k_index={:?}) is not a cell of this job",
                        row.method.as_str(),
                        row.nb,
                        row.nf,
                        row.k_index
                    ),
                ));
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

/// Delete temporary files (`<name>.tmp-<pid>`) that a killed process left in `dir` while
/// writing one of `names` (any name when empty). Best effort: a leftover is harmless, it is
/// never read.
fn remove_temporaries(dir: &Path, names: &[&str]) {
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
fn remove_folder(dir: &Path) -> Result<()> {
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
fn remove_deleted_leftovers(parent: &Path, name: &str) {
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
pub fn open(out: &Path, shard: Option<Shard>, manifest: &Manifest, job: &Job, force: bool) -> Result<()> {
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
        remove_temporaries(out, &["cells.parquet", "selection.json", "job.json"]);
    }
    let path = dir.join(MANIFEST);
    if !path.exists() {
        export::json::write_json(&path, manifest)?;
    }
    // Rewritten each time: the paths are the latest run's (the manifest, checked above, says
    // the rest is the same job).
    export::json::write_json(&dir.join(JOB_FILE), job)
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

/// [`inspect`] for a whole run: the rows of `<out>/parts` and of every shard folder in it
/// (first row of each key; folders in the order of [`shard_folders`]). Parts are numbered on
/// from the whole run's own folder.
pub fn inspect_all(out: &Path, now: &Manifest, plan: &Plan) -> Result<Existing> {
    let parts = out.join(PARTS_DIR);
    let mut all = inspect(&parts, now, plan)?;
    let mut seen: HashSet<RowKey> = all.rows.iter().map(CellRow::key).collect();
    for (dir, _) in shard_folders(&parts)? {
        let more = inspect(&dir, now, plan)?;
        all.parts += more.parts;
        all.duplicates += more.duplicates;
        for row in more.rows {
            if seen.insert(row.key()) {
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
    pub job: Job,
    /// Its plan.
    pub plan: Plan,
    /// One row per key found, sorted as in `cells.parquet`.
    pub rows: Vec<CellRow>,
    /// The checkpoint folders read (the whole run's `parts/` first, then the shards') and how
    /// many part files each held.
    pub folders: Vec<(PathBuf, Option<Shard>, usize)>,
    /// Rows found in more than one folder (identical but for `seconds`; kept once).
    pub duplicates: usize,
}

fn read_json_file<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not a checkpoint file of oesweep: {e}")))
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
    let manifest: Manifest = read_json_file(&reference.join(MANIFEST))?;
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
    let job: Job = read_json_file(&job_path)?;
    if job_identity(&job).1 != manifest.job_sha256 {
        return Err(Error::input(&job_path, "is not the job of the manifest next to it"));
    }
    let plan = Plan::from_normalised(&job);
    let mut found: std::collections::HashMap<RowKey, (CellRow, usize)> = std::collections::HashMap::new();
    let (mut folders, mut duplicates) = (Vec::new(), 0);
    for (dir, shard) in dirs {
        let existing = inspect(&dir, &manifest, &plan)?;
        duplicates += existing.duplicates;
        for row in existing.rows {
            match found.get(&row.key()) {
                None => {
                    found.insert(row.key(), (row, folders.len()));
                }
                Some((first, at)) => {
                    let same = CellRow { seconds: 0.0, ..row.clone() } == CellRow { seconds: 0.0, ..first.clone() };
                    if !same {
                        return Err(Error::input(
                            &dir,
                            format!(
                                "{} row nb={} nf={} k_index={:?} differs from the one in {}",
                                row.method.as_str(),
                                row.nb,
                                row.nf,
                                row.k_index,
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
    Ok(Gathered { job, plan, rows, folders, duplicates })
}

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
                            saved.huber_rows += buf.iter().filter(|r| r.method == Method::Huber).count();
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

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

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
            w.sender().send(CellRow::failed(Method::Huber, 1, nf, 1, Some((0, 0.5)), "x".into())).unwrap();
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
        w.sender().send(CellRow::failed(Method::Ls, 1, 1, 1, None, "x".into())).unwrap();
        std::thread::sleep(Duration::from_millis(500));
        assert_eq!(list_parts(dir.path()).unwrap().len(), 1, "written before the end");
        assert_eq!(w.finish().parts, 1);
    }
}
