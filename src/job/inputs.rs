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
    read_inputs(&vj.job.data, vj.job.validation.as_ref(), vj.job.offset, vj.largest(), vj.delays[0])
}

/// The one loader of records, for a job and for `oesweep fit`: read the estimation and the
/// validation record as their specs say (the validation output column resolved, see
/// [`resolve_validation`]), check both against the largest model `(nb, nf, delay)`, and take
/// out the levels of `offset` ([`Levels::of`], computed here only). `delay` is the one of the
/// integrating-plant test (the grid's smallest).
pub fn read_inputs(
    data: &Records,
    validation: Option<&Records>,
    offset: Offset,
    (nb_max, nf_max, delay_max): (usize, usize, usize),
    delay: usize,
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
            .filter(|e| data::check_for_model(e, nb_max, nf_max, delay_max).is_ok())
            .map(|e| integrating_warning(e, delay));
        let val = val.map(|h| h.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic)));
        (est, val, integrating)
    });
    let (est, val) = (est?, val.transpose()?);
    inputs_with(est, val, offset, (nb_max, nf_max, delay_max), |_| integrating.flatten())
}

/// The records of `data` or `validation` as read, one per experiment.
fn read_experiments(specs: &Records) -> Result<Vec<Record>> {
    specs.specs.iter().map(|s| data::read_record_with(&s.path, &s.u_col(), &s.y_col(), &s.read_options())).collect()
}

/// [`read_inputs`] of records already in memory: checked against the largest model, levels
/// taken out, the data's warnings (the integrating-plant test with input delay `delay`).
pub fn inputs_of_records(
    est: Record,
    val: Option<Record>,
    offset: Offset,
    largest: (usize, usize, usize),
    delay: usize,
) -> Result<Inputs> {
    inputs_with(est, val, offset, largest, |est| integrating_warning(est, delay))
}

/// [`inputs_of_records`] with the integrating-plant warning of the estimation record as
/// `integrating` gives it (called once the records passed their checks).
fn inputs_with(
    mut est: Record,
    mut val: Option<Record>,
    offset: Offset,
    (nb_max, nf_max, delay_max): (usize, usize, usize),
    integrating: impl FnOnce(&Record) -> Option<String>,
) -> Result<Inputs> {
    data::check_for_model(&est, nb_max, nf_max, delay_max)?;
    if let Some(rec) = &val {
        data::check_for_model(rec, nb_max, nf_max, delay_max)?;
    }
    let levels = Levels::of(offset, &est);
    let mut warnings: Vec<String> = data::levels::offset_warning(offset, &est).into_iter().collect();
    warnings.extend(integrating(&est));
    levels.apply(&mut est);
    if let Some(v) = val.as_mut() {
        levels.apply(v);
    }
    Ok(Inputs { est, val, levels, warnings })
}

/// A warning when a low-order IV fit of the estimation record has a pole that may be 1, or a
/// real one above it (`estimate::integrating`, METHOD.md 7.3). Taken before the levels come
/// out: the test fits its own constant.
fn integrating_warning(est: &Record, delay: usize) -> Option<String> {
    let test = crate::estimate::integrating::pole_test(&est.u, &est.y, &est.seams, delay)?;
    if !test.integrating {
        return None;
    }
    // Enough decimals that an interval's ends differ.
    let decimals = |w: f64| (-w.log10()).ceil().clamp(3.0, 8.0) as usize + 1;
    let (p, a, sd) = (test.pole, test.a_at_1, test.a_at_1_std);
    let what = match test.interval {
        Some((lo, hi)) => {
            let dp = decimals(hi - lo);
            let place = if lo > 1.0 { ", above 1" } else { " that may be 1" };
            format!("a pole at {:.dp$} (95 % interval {lo:.dp$}..{hi:.dp$}){place}", p.0)
        }
        None => format!(
            "its slowest poles at {:.4} +- {:.4}i and A(1) = {a:.3e} (95 % interval {:.3e}..{:.3e}), 0 for a pole at 1",
            p.0,
            p.1.abs(),
            a - 1.96 * sd,
            a + 1.96 * sd
        ),
    };
    Some(format!(
        "a low-order IV fit of {} has {what}: the plant looks integrating (or unstable), and an output-error \
         model forces a stable model onto it (identify from the differenced output, or in closed loop)",
        est.path.display()
    ))
}

/// The records of a checked job, as read from the files (levels not taken out): for the
/// report's plots, which show the data in its own units.
/// A list of records is one record of several experiments ([`Record::concat`]).
pub fn read_records(data: &Records, validation: Option<&Records>) -> Result<(Record, Option<Record>)> {
    let est = Record::concat(read_experiments(data)?);
    let val = validation.map(|v| read_experiments(v).map(Record::concat)).transpose()?;
    Ok((est, val))
}
