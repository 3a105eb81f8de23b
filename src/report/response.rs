//! The report's sections on the picks' responses: the Bode plots (one per pick, and per input of
//! a several-input model) and the residuals and simulated outputs (paper Figs. 9, 11, 13, 14).

use super::figures::{self, Picked, Response};
use super::html::Section;
use super::{FIGURE_PREFIX, OUTPUT_WINDOW, Review, figure, inputs};
use crate::error::Result;
use crate::estimate::InitialState;

/// The picks' frequency responses against the spectral estimate (paper Figs. 11 and 13), with
/// the gain band of the covariance the run computed. Several inputs: one figure per pick and
/// input, each input's filter against that input's estimate `H_i = (P^-1 s)_i` of the record
/// ([`crate::spectral::estimate_inputs`]) with the multiple coherence below.
pub(super) fn bode_section(s: &Review, m1: Option<Picked>, m2: Option<Picked>) -> Result<Section> {
    let folder = &s.folder;
    let picks: Vec<Picked> = m1.into_iter().chain(m2).collect();
    let mut figs = Vec::new();
    let mut notes = Vec::new();
    // The covariance the run computed for a pick (selection.json).
    let covariance_of = |p: &Picked| {
        let pick = if p.name == "M1" { &s.selection.m1 } else { &s.selection.m2 };
        pick.as_ref().and_then(|q| q.covariance.clone())
    };
    if s.job.m > 1 {
        // One estimate per input, H_i = (P^-1 s)_i (METHOD.md 19), drawn on that input's figure.
        let est = &s.est;
        let ests = match crate::spectral::estimate_inputs(
            &est.u,
            s.job.m,
            &est.y,
            &est.seams,
            &est.missing,
            s.ts(),
            s.job.job.spectrum,
        ) {
            Ok(e) => Some(e),
            Err(e) => {
                notes.push(format!("No spectral estimate of the estimation record: {e}"));
                None
            }
        };
        for p in &picks {
            let structure = p.model.key.structure();
            let (b, f) = (structure.split_b(&p.model.fit.b), structure.split_f(&p.model.fit.f));
            let cov = covariance_of(p);
            for (i, o) in structure.inputs().iter().enumerate() {
                let file = format!("{FIGURE_PREFIX}bode-{}-u{}.svg", p.name.to_lowercase(), i + 1);
                let block = cov.as_deref().and_then(|c| inputs::input_block(c, &structure, i));
                let gain = |w: f64| {
                    crate::estimate::evidence::gain_std(&b[i], &f[i], o.delay, block.as_deref().unwrap_or(&[]), w)
                };
                let gain_band: Option<&dyn Fn(f64) -> (f64, f64)> = block.is_some().then_some(&gain);
                let name = s.input_name(i);
                let band_fit = p.model.fit.fit_band_inputs.as_ref().and_then(|v| v.get(i).copied());
                let response = Response { b: &b[i], f: &f[i], delay: o.delay, input: Some(&name), band_fit };
                let e = ests.as_ref().and_then(|e| e.get(i));
                let drawn = figures::bode_figure((e, s.ts()), s.job.job.band_hz, *p, response, gain_band, &file);
                figs.push(figure(folder, &file, drawn)?);
            }
        }
    } else {
        match crate::spectral::estimate_within(
            &s.est.u,
            &s.est.y,
            &s.est.seams,
            &s.est.missing,
            s.ts(),
            s.job.job.spectrum,
        ) {
            Ok(est) => {
                for p in &picks {
                    let file = format!("{FIGURE_PREFIX}bode-{}.svg", p.name.to_lowercase());
                    let cov = covariance_of(p);
                    let m = p.model;
                    let gain = |w: f64| {
                        crate::estimate::evidence::gain_std(
                            &m.fit.b,
                            &m.fit.f,
                            m.key.delay as usize,
                            cov.as_deref().unwrap_or(&[]),
                            w,
                        )
                    };
                    let gain_band: Option<&dyn Fn(f64) -> (f64, f64)> = cov.is_some().then_some(&gain);
                    let response = Response {
                        b: &m.fit.b,
                        f: &m.fit.f,
                        delay: m.key.delay as usize,
                        input: None,
                        band_fit: m.fit.fit_band,
                    };
                    let drawn =
                        figures::bode_figure((Some(&est), s.ts()), s.job.job.band_hz, *p, response, gain_band, &file);
                    figs.push(figure(folder, &file, drawn)?);
                }
            }
            Err(e) => notes.push(format!("No spectral estimate of the estimation record: {e}")),
        }
    }
    if picks.is_empty() {
        notes.push("No pick, so no frequency response to show.".into());
    }
    Ok(Section {
        id: "bode",
        heading: "Frequency response of the picks".into(),
        intro_html: String::new(),
        figures: figs,
        notes,
    })
}

/// Residuals and simulated outputs of the M2 pick (the paper's final model, else M1) and the
/// least-squares fit of its orders (paper Figs. 9 and 14). Several inputs: the residuals'
/// cross-correlation with each input in a figure of its own.
pub(super) fn residual_sections(s: &Review, pick: Option<Picked>) -> Result<[Section; 2]> {
    let folder = &s.folder;
    let mut res_figs = Vec::new();
    let mut out_figs = Vec::new();
    let mut notes = Vec::new();
    match pick {
        Some(p) => match s.ls_row(p.model) {
            Some(ls) => {
                let file = "report-residuals.svg";
                let zero = InitialState::Zero;
                let (y_ls, y_h) = (s.output_of_row(ls, &s.est, zero), s.output_of_row(p.model, &s.est, zero));
                res_figs.push(figure(folder, file, figures::residual_figure(&s.est, (ls, &y_ls), (p, &y_h), file))?);
                // Where the record has gaps or cuts: the residuals over time, with them.
                if !(s.est.missing.is_empty() && s.est.seams.is_empty()) {
                    let file = format!("{FIGURE_PREFIX}residuals-time.svg");
                    res_figs.push(figure(folder, &file, figures::gaps_figure(&s.est, s.ts(), (p, &y_h), &file))?);
                }
                // The residual tests' correlation functions, on psi_g(e) and the input less u0.
                let loss = crate::estimate::Loss::Huber { gamma: p.model.gamma() };
                let r: Vec<f64> = s.est.y.iter().zip(&y_h).map(|(y, yh)| loss.psi(y - yh)).collect();
                let ps = (p.model.evidence.resid_white_p, p.model.evidence.resid_indep_p);
                for i in 0..s.job.m {
                    let u: Vec<f64> = s.est.input(i).iter().map(|v| v - s.u0s[i]).collect();
                    let (acf, ccf) =
                        crate::estimate::residual_tests::correlation_functions(&r, &u, &s.est.seams, &s.est.missing);
                    let (file, scope) = if s.job.m == 1 {
                        ("report-resid-corr.svg".to_string(), String::new())
                    } else {
                        (format!("{FIGURE_PREFIX}resid-corr-u{}.svg", i + 1), format!(", input {}", s.input_name(i)))
                    };
                    let drawn =
                        figures::resid_corr_figure(&acf, &ccf, r.len() - s.est.missing.len(), ps, p, &scope, &file);
                    res_figs.push(figure(folder, &file, drawn)?);
                }
                let records = [("estimation", Some(&s.est)), ("validation", s.val.as_ref())];
                for (name, rec) in records {
                    if let Some(rec) = rec {
                        let file = format!("{FIGURE_PREFIX}output-{name}.svg");
                        let (y_ls, y_h) = (
                            s.output_of_row(ls, rec, s.job.job.initial_state),
                            s.output_of_row(p.model, rec, s.job.job.initial_state),
                        );
                        out_figs.push(figure(
                            folder,
                            &file,
                            figures::output_figure(rec, s.ts(), name, (ls, &y_ls), (p, &y_h), OUTPUT_WINDOW, &file),
                        )?);
                    }
                }
            }
            None => notes.push(format!(
                "The table has no usable least-squares row of {}: no residual or output figure.",
                p.model.key.short_label()
            )),
        },
        None => notes.push("No pick, so no residuals or simulated outputs to show.".into()),
    }
    let residuals = Section {
        id: "residuals",
        heading: "Residuals: least squares against Huber".into(),
        intro_html: String::new(),
        figures: res_figs,
        notes: notes.clone(),
    };
    let outputs = Section {
        id: "outputs",
        heading: "Simulated outputs".into(),
        intro_html: String::new(),
        figures: out_figs,
        notes,
    };
    Ok([residuals, outputs])
}
