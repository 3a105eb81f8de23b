//! A finished run's result files read back (`cells.parquet`, `selection.json`, `job.json`): the
//! one reader of a results folder, for the report and `oesweep export`.

use crate::error::{Error, Result};
use crate::export::{CELLS_FILE, JOB_FILE, RESULT_FILES, SELECTION_FILE};
use crate::job::ValidJob;
use crate::reduce::Selection;
use crate::table::CellRow;
use std::path::{Path, PathBuf};

/// What a finished run (or merge) wrote.
pub struct Results {
    pub folder: PathBuf,
    pub rows: Vec<CellRow>,
    pub selection: Selection,
    /// The job as run (`job.json`) and the program version that ran it.
    pub job: ValidJob,
    pub version: Option<String>,
}

/// Read a results folder; a missing folder or file is an [`Error::Input`] naming it.
pub fn read_results(folder: &Path) -> Result<Results> {
    if !folder.is_dir() {
        return Err(Error::input(folder, "no such results folder (`oesweep run JOB` writes one)"));
    }
    let missing: Vec<&str> = RESULT_FILES.iter().copied().filter(|f| !folder.join(f).is_file()).collect();
    if let Some(first) = missing.first() {
        return Err(Error::input(
            folder.join(first),
            format!(
                "missing: a finished sweep folder holds {}; absent here: {} (`oesweep run JOB` writes them)",
                RESULT_FILES.join(", "),
                missing.join(", ")
            ),
        ));
    }
    let rows = crate::export::parquet::read_cells(&folder.join(CELLS_FILE))?;
    let selection = read_selection(&folder.join(SELECTION_FILE))?;
    let (job, version) = crate::job::read_as_run(&folder.join(JOB_FILE))?;
    Ok(Results { folder: folder.to_path_buf(), rows, selection, job, version })
}

/// selection.json, of a format this program reads ([`crate::export::check_format`]).
fn read_selection(path: &Path) -> Result<Selection> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, format!("cannot read: {e}")))?;
    let bad =
        |e: String| Error::input(path, format!("not the file `oesweep run` writes: {}", crate::data::one_line(&e)));
    let mut v: serde_json::Value = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let obj = v.as_object_mut().ok_or_else(|| bad("not a JSON object".into()))?;
    crate::export::json::take_format(obj).map_err(|m| Error::input(path, m))?;
    let sel: Selection = serde_json::from_value(v).map_err(|e| bad(e.to_string()))?;
    // An edited covariance of the wrong size would index past the model's parameters.
    for (name, pick) in [("m1", &sel.m1), ("m2", &sel.m2)] {
        if let Some(p) = pick
            && let Some(c) = &p.covariance
            && !covariance_fits(c, &p.model.row)
        {
            let n = p.model.row.fit.b.len() + p.model.row.fit.f.len();
            return Err(Error::input(
                path,
                format!(
                    "field '{name}.covariance': {} values do not fit a model of {n} parameters and an offset",
                    c.len()
                ),
            ));
        }
    }
    Ok(sel)
}

/// A covariance (row-major) of the parameters `[b, f]` or `[b, f, offset]` of `row`.
pub fn covariance_fits(c: &[f64], row: &CellRow) -> bool {
    let n = row.fit.b.len() + row.fit.f.len();
    c.len() == n * n || c.len() == (n + 1) * (n + 1)
}
