//! The manifest: what job and data a checkpoint belongs to, and the first difference when a
//! resume does not match.

use super::FORMAT;
use crate::error::{Error, Result};
use crate::job::{Job, ValidJob};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use sha2::{Digest, Sha256};
use std::collections::BTreeSet;
use std::path::PathBuf;

pub(super) fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// The part of a normalised job that identifies it (its paths left out; see [`Manifest`]) and
/// the SHA-256 of that as compact JSON.
pub(super) fn job_identity(job: &Job) -> (Value, String) {
    let mut job = serde_json::to_value(job).expect("a job serialises");
    let obj = job.as_object_mut().expect("a job is a JSON object");
    obj.remove("output");
    for field in ["data", "validation"] {
        match obj.get_mut(field) {
            Some(Value::Object(spec)) => {
                spec.remove("path");
            }
            // A list of records (experiments): each without its path.
            Some(Value::Array(specs)) => {
                for spec in specs.iter_mut().filter_map(Value::as_object_mut) {
                    spec.remove("path");
                }
            }
            _ => {}
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
    /// The kernels that computed the rows ([`crate::kernels::Flavour::name`]): the flavours
    /// round differently, so one table takes rows of one.
    pub kernels: String,
}

impl Manifest {
    /// The manifest of a validated job whose inputs have been loaded (so the validation
    /// column is resolved). Reads the data files again to hash their bytes.
    pub fn of_job(vj: &ValidJob) -> Result<Manifest> {
        let (job, job_sha256) = job_identity(&vj.job);
        let mut data = Vec::new();
        // One role per record: `data`, `validation` for one record each (as always), else
        // `data[i]`, `validation[i]`.
        let specs = vj.job.data.named("data").chain(vj.job.validation.iter().flat_map(|v| v.named("validation")));
        for (role, spec) in specs {
            // A file named twice (estimation and validation rows of one record) is hashed once.
            let (bytes, sha256) = match data.iter().find(|d: &&DataHash| d.path == spec.path) {
                Some(d) => (d.bytes, d.sha256.clone()),
                None => {
                    let bytes =
                        std::fs::read(&spec.path).map_err(|e| Error::input(&spec.path, format!("cannot read: {e}")))?;
                    (bytes.len() as u64, sha256_hex(&bytes))
                }
            };
            data.push(DataHash { role: role.to_string(), path: spec.path.clone(), bytes, sha256 });
        }
        Ok(Manifest {
            format: FORMAT,
            oesweep_version: env!("CARGO_PKG_VERSION").to_string(),
            job_sha256,
            job,
            data,
            kernels: crate::kernels::flavour().name().to_string(),
        })
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
        let mut roles: Vec<&str> = self.data.iter().chain(&now.data).map(|d| d.role.as_str()).collect();
        roles.dedup();
        for role in roles {
            let name = if role.starts_with("data") { "estimation data" } else { "validation data" };
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

    /// Why the rows of the parts (`self`) cannot join those of `now` because other kernels
    /// computed them; None when the same did.
    pub fn kernel_mix(&self, now: &Manifest) -> Option<String> {
        (self.kernels != now.kernels).then(|| {
            format!(
                "its rows were computed with the {} kernels, the others of this table with the {} kernels; \
                 the two round differently in the last bits and a table takes rows of one kind only \
                 (compute all cells on CPUs of one kind)",
                self.kernels, now.kernels
            )
        })
    }
}

/// A JSON value shortened for a one-line message.
pub(super) fn short(v: &Value) -> String {
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
pub(super) fn first_difference(path: &str, a: &Value, b: &Value) -> Option<(String, String, String)> {
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
