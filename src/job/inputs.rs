//! The records a job names, read beside the checked job: the one loader of the estimation and
//! validation records, for a run, a merge, the report and `oesweep fit`.

use super::{Records, ValidJob};
use crate::data::{self, Levels, Offset, Record};
use crate::error::Result;

/// The records a job names, read and checked, with their levels taken out.
pub struct Inputs {
    pub est: Record,
    pub val: Option<Record>,
    /// The levels taken out of both records (the job's `offset`).
    pub levels: Levels,
    /// Things the user should know about the data (printed once, kept in selection.json).
    pub warnings: Vec<String>,
}

/// Read the job's data files and check them against the largest orders of the grid.
pub fn load_inputs(vj: &ValidJob) -> Result<Inputs> {
    read_inputs(&vj.job.data, vj.job.validation.as_ref(), vj.job.offset, vj.largest())
}

/// The one loader of records, for a job and for `oesweep fit`: read the estimation and the
/// validation record as their specs say (the validation output column resolved, see
/// [`resolve_validation`]), check both against the largest model `(nb, nf, delay)`, and take
/// out the levels of `offset` ([`Levels::of`], computed here only).
pub fn read_inputs(
    data: &Records,
    validation: Option<&Records>,
    offset: Offset,
    (nb_max, nf_max, delay_max): (usize, usize, usize),
) -> Result<Inputs> {
    // Each experiment long enough on its own: the simulation restarts in every one.
    let concat = |specs: &Records| -> Result<Record> {
        let records = read_experiments(specs)?;
        if records.len() > 1 {
            for rec in &records {
                let need = data::min_samples(nb_max, nf_max, delay_max);
                if rec.len() < need {
                    data::check_for_model(rec, nb_max, nf_max, delay_max)?;
                }
            }
        }
        Ok(Record::concat(records))
    };
    let est = concat(data)?;
    let val = validation.map(concat).transpose()?;
    inputs_of_records(est, val, offset, (nb_max, nf_max, delay_max))
}

/// The records of `data` or `validation` as read, one per experiment.
fn read_experiments(specs: &Records) -> Result<Vec<Record>> {
    specs.specs.iter().map(|s| data::read_record_with(&s.path, &s.u_col(), &s.y_col(), &s.read_options())).collect()
}

/// [`read_inputs`] of records already in memory: checked against the largest model, levels
/// taken out, the data's warnings.
pub fn inputs_of_records(
    mut est: Record,
    mut val: Option<Record>,
    offset: Offset,
    (nb_max, nf_max, delay_max): (usize, usize, usize),
) -> Result<Inputs> {
    data::check_for_model(&est, nb_max, nf_max, delay_max)?;
    if let Some(rec) = &val {
        data::check_for_model(rec, nb_max, nf_max, delay_max)?;
    }
    let levels = Levels::of(offset, &est);
    let mut warnings: Vec<String> = data::levels::offset_warning(offset, &est).into_iter().collect();
    warnings.extend(integrating_warning(&est));
    levels.apply(&mut est);
    if let Some(v) = val.as_mut() {
        levels.apply(v);
    }
    Ok(Inputs { est, val, levels, warnings })
}

/// Slope of log |G| against log f towards 0 Hz below which the plant looks integrating: an
/// integrator gives -1, a plant with a static gain 0 (METHOD.md 7.2).
const INTEGRATING_SLOPE: f64 = -0.7;

/// A warning when the estimation record's spectral estimate rises like 1/f towards 0 Hz.
fn integrating_warning(est: &Record) -> Option<String> {
    let spectrum =
        crate::spectral::estimate_within(&est.u, &est.y, &est.seams, 1.0, crate::spectral::SpectrumMethod::Welch)
            .ok()?;
    let slope = crate::spectral::low_frequency_slope(&spectrum)?;
    (slope < INTEGRATING_SLOPE).then(|| {
        format!(
            "the spectral estimate of {} rises like f^{slope:.2} towards 0 Hz: the plant looks integrating (or \
             unstable), and an output-error model forces a stable model onto it (identify from the differenced \
             output, or in closed loop)",
            est.path.display()
        )
    })
}

/// The records of a checked job, as read from the files (levels not taken out): for the
/// report's plots, which show the data in its own units.
/// A list of records is one record of several experiments ([`Record::concat`]).
pub fn read_records(data: &Records, validation: Option<&Records>) -> Result<(Record, Option<Record>)> {
    let est = Record::concat(read_experiments(data)?);
    let val = validation.map(|v| read_experiments(v).map(Record::concat)).transpose()?;
    Ok((est, val))
}
