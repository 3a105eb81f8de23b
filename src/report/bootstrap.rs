//! The report's section on the bootstrap of the watched picks (the job's `uncertainty`,
//! METHOD.md 17.3).

use super::html::{Section, esc};
use super::plot;
use crate::reduce::Selection;

/// The bootstrap of the watched picks (the job's `uncertainty`, METHOD.md 17.3): per model its
/// parameters' percentile intervals beside the sandwich std, and the intervals of G.
pub(super) fn bootstrap_section(sel: &Selection) -> Section {
    use std::fmt::Write as _;
    let mut h = String::new();
    for p in &sel.bootstrap {
        let b = &p.intervals;
        let rules = p.rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
        let k = p.k.map_or("least squares".to_string(), |k| format!("k = {}", crate::text::k(k)));
        let pct = plot::trimmed(100.0 * b.level, 3);
        let _ = writeln!(
            h,
            "<h3>OE({},{}) delay {} {k} (picked by {})</h3>\n<p class=\"meta\">{} replicates ({} failed, {} on the \
             stability boundary), residual blocks of {} samples, seed {}.</p>",
            p.nb,
            p.nf,
            p.delay,
            esc(&rules),
            b.replicates,
            b.failed,
            b.boundary,
            b.block,
            b.seed
        );
        let _ = writeln!(
            h,
            "<div class=\"params\"><div><table>\n<tr><th class=\"l\">parameter</th><th>value</th><th>std \
             (sandwich)</th><th>std (bootstrap)</th><th>{pct} % interval</th></tr>"
        );
        for (i, iv) in b.parameters.iter().enumerate() {
            let name = p.parameters.get(i).map_or("", String::as_str);
            let value = p.values.get(i).map_or(String::new(), |v| plot::sig(*v, 6));
            let std = p.sandwich_std.get(i).copied().flatten().map_or("-".to_string(), |s| plot::sig(s, 2));
            let _ = writeln!(
                h,
                "<tr><td class=\"l\">{}</td><td>{value}</td><td>{std}</td><td>{}</td><td>[{}, {}]</td></tr>",
                esc(name),
                plot::sig(iv.std, 2),
                plot::sig(iv.lower, 6),
                plot::sig(iv.upper, 6)
            );
        }
        h.push_str("</table></div>\n");
        // One table per input's response (one input: G's).
        let several = b.magnitude.len() > 1;
        for (i, (mags, phases)) in b.magnitude.iter().zip(&b.phase_deg).enumerate() {
            let g = if several { format!("G<sub>{}</sub>", i + 1) } else { "G".to_string() };
            let _ = writeln!(
                h,
                "<div><table>\n<tr><th>f [Hz]</th><th>|{g}| interval</th><th>phase{} interval [°]</th></tr>",
                if several { format!(" of {g}") } else { String::new() }
            );
            for ((w, m), ph) in b.frequencies.iter().zip(mags).zip(phases) {
                let _ = writeln!(
                    h,
                    "<tr><td>{}</td><td>[{}, {}]</td><td>[{:.1}, {:.1}]</td></tr>",
                    plot::sig(w / (std::f64::consts::TAU * p.ts), 4),
                    plot::sig(m.lower, 4),
                    plot::sig(m.upper, 4),
                    ph.lower,
                    ph.upper
                );
            }
            h.push_str("</table></div>");
        }
        h.push_str("</div>\n");
    }
    h.push_str(
        "<p class=\"meta\">A parametric residual-block bootstrap of the whole estimation (starts included): each \
         replicate is the picked model's simulated output plus circular blocks of its residuals, estimated again \
         from the start. Where the intervals are much wider than ± 2 sandwich std, or lopsided, the local \
         covariance does not describe the uncertainty (METHOD.md 17.3).</p>\n",
    );
    Section { id: "bootstrap", heading: "Bootstrap of the picks".into(), intro_html: h, figures: vec![], notes: vec![] }
}
