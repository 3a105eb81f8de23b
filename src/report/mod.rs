//! The review report of a finished sweep (being written).

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// Write `report.html` and its figures into `folder`; returns the page's path.
pub fn write_report(folder: &Path) -> Result<PathBuf> {
    Err(Error::Invalid(format!("{}: the report is not implemented yet", folder.display())))
}
