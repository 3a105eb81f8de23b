//! The result files of a complete (or `--partial`) table: the picks and what is known of their
//! uncertainty ([`crate::reduce`], [`super::beyond`], [`super::uncertainty`]), then
//! `cells.parquet`, `selection.json` and `job.json`.
//!
//! The pieces that do not depend on each other run side by side on the run's threads: the
//! table's Parquet file beside the picks' work, and within that the look beyond the grid's
//! edge beside the covariances of the picked models (each computed once). Each piece computes
//! what it computed alone, so the files do not depend on the threads. The files are written
//! under temporary names and put in place in a fixed order, as one after the other would be.

use super::{beyond, uncertainty};
use crate::data::RecordGaps;
use crate::error::Result;
use crate::export;
use crate::job::{Inputs, ValidJob};
use crate::reduce::{self, ReduceOptions, Selection};
use crate::table::CellRow;
use std::path::Path;

/// Writes the result files of `rows`, replacing any report of an earlier table. Returns the
/// picks. `read` holds the job's records as the run read them and their gaps (None: a merge
/// that could not read the data files): they give the levels, warnings and gaps selection.json
/// keeps, the picks' covariance the report draws and the bootstrap the job's `uncertainty` may
/// ask for (on `threads` workers, 0: all cores).
pub(super) fn write_results(
    out: &Path,
    job: &ValidJob,
    rows: &[CellRow],
    read: Option<(&Inputs, &RecordGaps)>,
    threads: usize,
) -> Result<Selection> {
    let inputs = read.map(|(inputs, _)| inputs);
    let pool = crate::pool::local(threads, "to write the results")?;
    let (cells, picked) = pool.install(|| {
        rayon::join(
            || export::parquet::stage_cells(&out.join(export::CELLS_FILE), rows),
            || {
                let mut selection = picks(job, rows, inputs);
                // Only a record that missed something: a complete one's file is as it was.
                selection.gaps = read.map(|(_, gaps)| gaps).filter(|g| g.any()).cloned();
                let path = out.join(export::SELECTION_FILE);
                let staged = export::json::stage_json(&path, &export::json::Versioned::new(&selection));
                (selection, staged)
            },
        )
    });
    // The errors in the order of the files written one after the other.
    let (selection, staged_selection) = picked;
    let (cells, staged_selection) = (cells?, staged_selection?);
    // A report of the previous table would describe models this table may not have.
    crate::report::remove_report(out);
    cells.commit()?;
    staged_selection.commit()?;
    job.write_as_run(&out.join(export::JOB_FILE))?;
    Ok(selection)
}

/// The structure of the job's lead pick of `rows` (the step of the coordinate search,
/// [`crate::search`]): the rules alone, without the covariances and the look beyond the edge.
pub fn lead_structure(job: &ValidJob, rows: &[CellRow]) -> Option<crate::oe::Structure> {
    let selection = reduce::select(rows, &reduce_options(job));
    let pick = selection.picks.get(&selection.rule)?.model.as_ref()?;
    Some(pick.key.structure())
}

fn reduce_options(job: &ValidJob) -> ReduceOptions {
    ReduceOptions {
        basis: reduce::choose_basis(job.job.validation.is_some(), job.job.band_hz.is_some()),
        settings: job.job.selection,
    }
}

/// The picks of `rows` with their warnings, the covariances of M1 and M2 and the bootstrap
/// the job asks for, on the current rayon pool.
fn picks(job: &ValidJob, rows: &[CellRow], inputs: Option<&Inputs>) -> Selection {
    let sel_opts = reduce_options(job);
    let mut selection = reduce::select(rows, &sel_opts);
    selection.offset = Some(job.job.offset);
    if job.m == 1 {
        selection.input_level = inputs.map(|i| i.levels.u0(0));
    } else {
        selection.input_levels = inputs.map(|i| (0..job.m).map(|k| i.levels.u0(k)).collect());
    }
    selection.initial_state = Some(job.job.initial_state);
    selection.warnings = inputs.map(|i| i.warnings.clone()).unwrap_or_default();
    selection.warnings.extend(inputs.map(|i| uncertainty::integrating_doubts(&selection, i)).unwrap_or_default());
    let bounds = |v: &[usize]| (v[0] as u32, v[v.len() - 1] as u32);
    // Each input's grid (one input: the job's): the edge warnings and the look beyond name
    // the input on the edge.
    let grids: Vec<_> = job
        .grids
        .iter()
        .map(|g| reduce::doubts::GridBounds { nb: bounds(&g.nb), nf: bounds(&g.nf), delay: bounds(&g.delays) })
        .collect();
    let rbic_pick = selection.picks.get(&reduce::Rule::Rbic).and_then(|p| p.model.as_ref());
    let (beyond, models) = rayon::join(
        || match (rbic_pick, inputs) {
            (Some(pick), Some(inputs)) => beyond::beyond_edges(pick, rows, &grids, inputs, job),
            _ => Vec::new(),
        },
        || inputs.map(|i| uncertainty::PickModels::of(&selection, i)),
    );
    selection.warnings.extend(reduce::doubts::pick_warnings_per_input(&selection, rows, &grids, &beyond));
    let uncertainty = &job.job.uncertainty;
    if let (Some(inputs), Some(models)) = (inputs, &models)
        && !uncertainty.is_local()
    {
        selection.bootstrap =
            uncertainty::bootstrap_picks(&selection, models, inputs, uncertainty, &job.job.solver, job.ts());
    }
    if inputs.is_none() && !uncertainty.is_local() {
        selection.warnings.push(
            "the job asks for the bootstrap of the picks, but their data files could not be read again: no \
             bootstrap intervals"
                .into(),
        );
    }
    let bootstrapped = !selection.bootstrap.is_empty();
    if let (Some(inputs), Some(models)) = (inputs, &models) {
        selection.warnings.extend(uncertainty::pick_doubts(&selection, models, inputs, bootstrapped));
        for pick in [selection.m1.as_mut(), selection.m2.as_mut()].into_iter().flatten() {
            pick.covariance = models.covariance(&pick.model, inputs);
        }
    }
    selection
}
