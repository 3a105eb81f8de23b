//! The report's section on the pick rules (METHOD.md 7.1): a table rule -> model with the
//! rule's measure, the model's fits and evidence and the rule's reason, and the information
//! criteria against the number of parameters.

use super::html::{Section, esc};
use super::{Review, figure, figures, plot};
use crate::error::Result;
use std::fmt::Write;

pub(super) fn rules_section(s: &Review) -> Result<Section> {
    let sel = &s.selection;
    let basis = sel.basis.column();
    let mut h = String::new();
    if sel.picks.is_empty() {
        h.push_str("<p class=\"note\">This run's selection.json has no pick rules (an older version).</p>\n");
    } else {
        let _ = writeln!(
            h,
            "<table>\n<tr><th class=\"l\">rule</th><th class=\"l\">model</th><th>k</th><th class=\"l\">measure</th>\
             <th>value</th><th>{} [%]</th><th>indep. p</th><th>cancelling pairs</th><th class=\"l\">why</th></tr>",
            esc(basis)
        );
        for (rule, pick) in &sel.picks {
            let lead = if *rule == sel.rule { " (lead)" } else { "" };
            let (model, k, score, p, cancel) = match &pick.model {
                Some(m) => (
                    super::html::orders(&m.key),
                    m.row.k.map_or("–".into(), plot::short),
                    Some(m.score).filter(|v| v.is_finite()).map_or("–".into(), |v| format!("{v:.3}")),
                    m.evidence.resid_indep_p.map_or("–".into(), |p| plot::sig(p, 3)),
                    m.evidence.cancellations.map_or("–".into(), |c| c.to_string()),
                ),
                None => ("none".into(), "–".into(), "–".into(), "–".into(), "–".into()),
            };
            let _ = writeln!(
                h,
                "<tr><td class=\"l\"><b>{}</b>{lead}</td><td class=\"l\">{model}</td><td>{k}</td><td class=\"l\">{}</td>\
                 <td>{}</td><td>{score}</td><td>{p}</td><td>{cancel}</td><td class=\"l\">{}</td></tr>",
                rule.as_str(),
                esc(&pick.measure),
                pick.value.map_or("–".into(), |v| plot::sig(v, 6)),
                esc(&pick.why),
            );
        }
        h.push_str("</table>\n");
        if !sel.rule_why.is_empty() {
            let _ = writeln!(h, "<p class=\"rule\"><b>Lead rule.</b> {}</p>", esc(&sel.rule_why));
        }
        h.push_str(
            "<p class=\"meta\">paper_m1, paper_m2: the paper's rules (local minima of W and L1C over nF); aic, \
             aicc, bic, fpe: the least-squares fits' criteria as MATLAB defines them; raic, rbic: their robust \
             versions on the Huber fits (METHOD.md 14.1); validation: the best fit with the parsimony tie rule; \
             evidence: the same among the models whose residuals are independent of u at 1 % and that have \
             no pole-zero pair cancelling within its confidence region (METHOD.md 7.1).</p>\n",
        );
    }
    let mut figs = Vec::new();
    let file = "report-criteria-np.svg";
    if let Some(drawn) = figures::criteria_figure(&s.rows, file) {
        figs.push(figure(&s.folder, file, drawn)?);
    }
    Ok(Section { id: "rules", heading: "Every pick rule".into(), intro_html: h, figures: figs, notes: vec![] })
}
