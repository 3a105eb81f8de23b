//! The records a job names, read beside the checked job: the one loader of the estimation and
//! validation records, for a run, a merge, the report and `oesweep fit`.
//!
//! Records with gaps (METHOD.md 21.1) take their shape here, where the grid is known: a segment
//! between input gaps shorter than the largest model's [`data::min_samples_of`] is left out
//! (the shortest useful segment); the counts ([`RecordGaps`]) go beside the records.

use super::{Records, ValidJob};
use crate::data::{self, Gaps, Levels, Offset, Record, RecordGaps};
use crate::error::Result;
use crate::estimate::integrating::{PoleTest, pole_tests};
use crate::oe::Structure;

/// The records a job names, read and checked, with their levels taken out.
pub struct Inputs {
    pub est: Record,
    pub val: Option<Record>,
    /// The levels taken out of both records (the job's `offset`).
    pub levels: Levels,
    /// Things the user should know about the data (printed once, kept in selection.json).
    pub warnings: Vec<String>,
    /// The integrating-plant test of the estimation record, one per input (METHOD.md 7.3, 19;
    /// None where its regressions are degenerate; empty when the record was not tested): its
    /// warnings wait for the models fitted to the record
    /// ([`crate::estimate::integrating::doubt`], [`crate::estimate::integrating::input_doubt`]).
    pub pole_tests: Vec<Option<PoleTest>>,
}

/// Read the job's data files and check them against the largest orders of the grid.
pub fn load_inputs(vj: &ValidJob) -> Result<Inputs> {
    load_inputs_gaps(vj).map(|(inputs, _)| inputs)
}

/// [`load_inputs`] with the gaps of the records (what was missing and what became of it).
pub fn load_inputs_gaps(vj: &ValidJob) -> Result<(Inputs, RecordGaps)> {
    let delays: Vec<usize> = vj.grids.iter().map(|g| g.delays.iter().copied().min().unwrap_or(0)).collect();
    read_inputs_gaps(&vj.job.data, vj.job.validation.as_ref(), vj.job.offset, &vj.largest_structure(), &delays)
}

/// [`read_inputs_gaps`] without the gaps.
pub fn read_inputs(
    data: &Records,
    validation: Option<&Records>,
    offset: Offset,
    largest: &Structure,
    delays: &[usize],
) -> Result<Inputs> {
    read_inputs_gaps(data, validation, offset, largest, delays).map(|(inputs, _)| inputs)
}

/// The one loader of records, for a job and for `oesweep fit`: read the estimation and the
/// validation record as their specs say (the validation output column resolved, see
/// [`resolve_validation`]), check both against the largest model `largest`
/// ([`data::check_for_structure`]: length, constant columns, collinear inputs), and take out
/// the levels of `offset` ([`Levels::of`], computed here only). `delays`, one per input, are
/// those of the integrating-plant test (each input's smallest in the grid). Records with gaps
/// are shaped with the shortest useful segment of `largest`; their counts are returned beside,
/// and what the user must be told of them (interpolated inputs, segments left out) joins the
/// warnings.
pub fn read_inputs_gaps(
    data: &Records,
    validation: Option<&Records>,
    offset: Offset,
    largest: &Structure,
    delays: &[usize],
) -> Result<(Inputs, RecordGaps)> {
    let concat = |specs: &Records| read_experiments(specs, data::min_samples_of(largest), Some(largest));
    let concat = &concat;
    // The validation record is read beside the estimation record and its integrating-plant
    // test: on a long record these are most of a run's serial start. The errors keep their
    // order (the estimation record's reading, the validation's, then the checks).
    let (est, val, integrating) = std::thread::scope(|s| {
        let val = validation.map(|v| s.spawn(move || concat(v)));
        let est = concat(data);
        let integrating = est
            .as_ref()
            .ok()
            .map(|e| &e.record)
            .filter(|e| e.inputs() == delays.len() && data::check_for_structure(e, largest).is_ok())
            .map(|e| pole_tests(&e.u, e.inputs(), &e.y, &e.seams, delays));
        let val = val.map(|h| h.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)));
        (est, val, integrating)
    });
    let (est, val) = (est?, val.transpose()?);
    let gaps = RecordGaps::of(est.gaps, val.as_ref().map(|v| v.gaps));
    let warnings: Vec<String> = est.warnings.iter().chain(val.iter().flat_map(|v| &v.warnings)).cloned().collect();
    let mut inputs =
        inputs_with(est.record, val.map(|v| v.record), offset, largest, |_| integrating.unwrap_or_default())?;
    inputs.warnings.extend(warnings);
    Ok((inputs, gaps))
}

/// The experiments of `data` or `validation` as one record ([`Record::concat`]), with their
/// gaps together and what to say about them.
struct Read {
    record: Record,
    gaps: Gaps,
    warnings: Vec<String>,
}

/// The records of `data` or `validation` as read, each shaped with the shortest useful segment
/// `shortest` ([`data::gaps::shape`]), and concatenated. With `largest`, each experiment of a
/// list must be long enough for it on its own: the simulation restarts in every one.
fn read_experiments(specs: &Records, shortest: usize, largest: Option<&Structure>) -> Result<Read> {
    let (mut records, mut all, mut warnings) = (Vec::new(), Vec::new(), Vec::new());
    for s in &specs.specs {
        let opts = s.read_options();
        let (rec, gaps) = data::read_record_gaps(&s.path, &s.u_cols(), &s.y_col(), &opts, shortest)?;
        warnings.extend(gaps.warnings(&s.path, opts.interpolate_inputs));
        records.push(rec);
        all.push(gaps);
    }
    if let Some(largest) = largest.filter(|_| records.len() > 1) {
        for rec in records.iter().filter(|r| r.len() < shortest) {
            data::check_for_structure(rec, largest)?;
        }
    }
    Ok(Read { record: Record::concat(records), gaps: Gaps::sum(all), warnings })
}

/// [`read_inputs`] of records already in memory: checked against the largest model, levels
/// taken out, the data's warnings and the integrating-plant test with input delays `delays`
/// (one per input). The records must have the inputs of `largest` (one input: a record of one,
/// and so on).
pub fn inputs_of_records(
    est: Record,
    val: Option<Record>,
    offset: Offset,
    largest: &Structure,
    delays: &[usize],
) -> Result<Inputs> {
    inputs_with(est, val, offset, largest, |est| {
        if est.inputs() == delays.len() {
            pole_tests(&est.u, est.inputs(), &est.y, &est.seams, delays)
        } else {
            Vec::new()
        }
    })
}

/// [`inputs_of_records`] with the integrating-plant test of the estimation record as
/// `integrating` gives it (called once the records passed their checks; taken before the
/// levels come out: the test fits its own constant).
fn inputs_with(
    mut est: Record,
    mut val: Option<Record>,
    offset: Offset,
    largest: &Structure,
    integrating: impl FnOnce(&Record) -> Vec<Option<PoleTest>>,
) -> Result<Inputs> {
    for rec in std::iter::once(&est).chain(&val) {
        if rec.inputs() != largest.m() {
            return Err(crate::error::Error::data(
                &rec.path,
                format!("{} input columns for a model of {} inputs", rec.inputs(), largest.m()),
            ));
        }
        data::check_for_structure(rec, largest)?;
    }
    let levels = Levels::of(offset, &est);
    let warnings: Vec<String> = data::levels::offset_warning(offset, &est).into_iter().collect();
    let pole_tests = integrating(&est);
    levels.apply(&mut est);
    if let Some(v) = val.as_mut() {
        levels.apply(v);
    }
    Ok(Inputs { est, val, levels, warnings, pole_tests })
}

/// The records of a checked job, as read from the files (levels not taken out): for the
/// report's plots, which show the data in its own units.
/// A list of records is one record of several experiments ([`Record::concat`]). Without the
/// grid, segments between input gaps shorter than [`data::gaps::SHORTEST_SEGMENT`] are left
/// out; [`read_records_for`] gives the records as a run of the grid reads them.
pub fn read_records(data: &Records, validation: Option<&Records>) -> Result<(Record, Option<Record>)> {
    read_records_shortest(data, validation, data::gaps::SHORTEST_SEGMENT).map(|(est, val, _)| (est, val))
}

/// [`read_records`] as a run of a grid whose largest model is `largest` reads them (segments
/// shorter than its [`data::min_samples_of`] left out), with their gaps.
pub fn read_records_for(
    data: &Records,
    validation: Option<&Records>,
    largest: &Structure,
) -> Result<(Record, Option<Record>, RecordGaps)> {
    read_records_shortest(data, validation, data::min_samples_of(largest))
}

fn read_records_shortest(
    data: &Records,
    validation: Option<&Records>,
    shortest: usize,
) -> Result<(Record, Option<Record>, RecordGaps)> {
    let est = read_experiments(data, shortest, None)?;
    let val = validation.map(|v| read_experiments(v, shortest, None)).transpose()?;
    let gaps = RecordGaps::of(est.gaps, val.as_ref().map(|v| v.gaps));
    Ok((est.record, val.map(|v| v.record), gaps))
}
