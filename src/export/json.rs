//! JSON result documents (e.g. `selection.json`), written pretty-printed and atomically.
//!
//! serde_json writes non-finite floats as `null`, so a NaN never produces invalid JSON.

use crate::error::Result;
use serde::Serialize;
use std::io::{BufWriter, Write};
use std::path::Path;

/// Write a serde value as pretty JSON (with a trailing newline) atomically: temporary file in the
/// same folder, fsync, rename. Fails with [`crate::Error::Output`] naming `path`.
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    stage_json(path, value)?.commit()
}

/// [`write_json`] up to the rename ([`super::stage`]).
pub(crate) fn stage_json<T: Serialize>(path: &Path, value: &T) -> Result<super::Staged> {
    super::stage(path, |file| {
        // selection.json runs to megabytes (every pick's candidates): written in large blocks.
        let mut w = BufWriter::with_capacity(1 << 20, file);
        serde_json::to_writer_pretty(&mut w, value).map_err(|e| format!("cannot write JSON: {e}"))?;
        w.write_all(b"\n").and_then(|_| w.flush()).map_err(|e| format!("cannot write JSON: {e}"))
    })
}

/// A result document with its format version first ([`super::FORMAT_VERSION`]).
#[derive(Serialize)]
pub struct Versioned<'a, T: Serialize> {
    pub format_version: u32,
    #[serde(flatten)]
    pub doc: &'a T,
}

impl<'a, T: Serialize> Versioned<'a, T> {
    pub fn new(doc: &'a T) -> Self {
        Versioned { format_version: super::FORMAT_VERSION, doc }
    }
}

/// Takes the format version out of a result document read as JSON and checks it
/// ([`super::check_format`]); the rest is the document.
pub fn take_format(obj: &mut serde_json::Map<String, serde_json::Value>) -> std::result::Result<(), String> {
    let declared = obj.remove(super::FORMAT_KEY).map(|v| match v {
        serde_json::Value::String(s) => s,
        other => other.to_string(),
    });
    super::check_format(declared.as_deref())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn export_json_roundtrip_and_replace() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.json");
        write_json(&path, &serde_json::json!({"a": 1})).unwrap();
        write_json(&path, &serde_json::json!({"a": 2, "b": [1.5, f64::NAN]})).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v, serde_json::json!({"a": 2, "b": [1.5, null]}));
        assert!(text.ends_with("}\n"));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
