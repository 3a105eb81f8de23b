//! W or L1C over nF, one line per nB, at one k (paper Figs. 10 and 12).

use super::super::plot::*;
use super::{Figure, Picked};
use crate::reduce::{self, Candidate, Curve, local_minima};
use crate::table::CellRow;
use plotters::prelude::*;
use std::collections::BTreeMap;

/// The curves over nF at one k index, one per nB: the reducer's curves
/// ([`crate::reduce::curves`]), so the marked minima are the reducer's.
fn curves_at(rows: &[CellRow], k_index: u32) -> BTreeMap<u32, Vec<&CellRow>> {
    reduce::curves(rows)
        .into_iter()
        .filter(|((_, _, k), _)| *k == Some(k_index))
        .map(|((_, nb, _), c)| (nb, c))
        .collect()
}

/// W (or L1C) as a function of nF, one line per nB, at one k, with the local minima ringed and
/// the pick marked (paper Figs. 10 and 12). `scope` ends the title (several inputs: which
/// input's orders the rows hold).
pub fn curve_figure(
    rows: &[CellRow],
    curve: Curve,
    (k_index, k): (u32, f64),
    min_tolerance: f64,
    pick: Option<Picked<'_>>,
    scope: &str,
    file: &str,
) -> std::result::Result<Figure, String> {
    let curves = curves_at(rows, k_index);
    let raw = |r: &CellRow| curve.value(r);
    // W can span decades over nB when a small order misses a resonance: then plot log10 W.
    let all: Vec<f64> = curves.values().flatten().map(|r| raw(r)).collect();
    let (lo, hi) = padded_range(all.iter().copied(), 0.0).unwrap_or((0.0, 1.0));
    let log = curve == Curve::W && lo > 0.0 && hi / lo > 20.0;
    let shown = |v: f64| match (curve, log) {
        (Curve::W, true) => v.log10(),
        (Curve::W, false) => v,
        (Curve::L1c, _) => 100.0 * v,
    };
    let nfs: Vec<u32> = curves.values().flatten().map(|r| r.key.nf).collect();
    let (nf_lo, nf_hi) = (nfs.iter().copied().min().unwrap_or(0), nfs.iter().copied().max().unwrap_or(1));
    let (ylo, yhi) = padded_range(all.iter().map(|v| shown(*v)), 0.08).unwrap_or((0.0, 1.0));

    let (what, unit_desc, fig_no) = match curve {
        Curve::W => ("criterion W", "W = (1/N) Σ ρ_γ(e_t)  [(output unit)²]", "10"),
        Curve::L1c => ("L1 contribution L1C", "L1C = share of samples with |e_t| > γ  [%]", "12"),
    };
    let title_text =
        format!("{what} versus nF at k = {} (one line per nB; cf. paper Fig. {fig_no}){scope}", crate::text::k(k));
    let mut minima_count = 0;
    let svg = render((1000, 560), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (plot_area, side) = body.split_horizontally(770);
        let mut chart =
            ChartBuilder::on(&plot_area).margin(12).x_label_area_size(52).y_label_area_size(84).build_cartesian_2d(
                int_axis(nf_lo, nf_hi, 20),
                if log { log_axis(ylo, yhi) } else { axis(ylo, yhi, nice_ticks(ylo, yhi, 8)) },
            )?;
        let ydesc = if log { format!("{unit_desc}, log scale") } else { unit_desc.to_string() };
        chart
            .configure_mesh()
            .x_desc("nF, number of poles (order of F)")
            .y_desc(ydesc)
            .label_style(text(14.0))
            .axis_desc_style(text(15.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;

        let mut entries = Vec::new();
        for (i, (nb, c)) in curves.iter().enumerate() {
            let colour = palette(i);
            let pts: Vec<(f64, f64)> = c.iter().map(|r| (r.key.nf as f64, shown(raw(r)))).collect();
            chart.draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            let values: Vec<f64> = c.iter().map(|r| raw(r)).collect();
            let minima = local_minima(&values, curve.tolerance(min_tolerance));
            minima_count += minima.len();
            chart.draw_series(minima.iter().map(|&m| Circle::new(pts[m], 7, colour.stroke_width(2))))?;
            entries.push((Mark::Line { colour, width: 2, dashed: false }, format!("nB = {nb}")));
        }
        if let Some(p) = pick.filter(|p| p.model.k_index() == k_index) {
            let at = (p.model.key.nf as f64, shown(raw_of(p.model, curve)));
            chart.draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Circle::new((0, 0), 11, BLACK.stroke_width(3))
                    + Text::new(p.label(), (14, -24), bold(14.0)),
            ))?;
            entries.push((Mark::Ring(BLACK), format!("{} pick", p.name)));
        }
        entries.push((Mark::Ring(MEASURED), "local minimum over nF".to_string()));
        legend(&side, 6, 40, 1, &entries, 14.0)?;
        Ok(())
    })?;
    let caption = format!(
        "{what} of every Huber cell at k = {} (k index {k_index}) against the number of poles nF, one line per \
         nB. Rings mark the local minima over nF ({minima_count} here; tolerance {min_tolerance}, {}), the \
         candidates the {} pick is chosen from{}.",
        crate::text::k(k),
        if curve == Curve::W { "relative" } else { "absolute on the share" },
        if curve == Curve::W { "M1" } else { "M2" },
        pick.map(|p| format!("; the thick black ring is the pick, {}", p.label())).unwrap_or_default(),
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

fn raw_of(c: &Candidate, curve: Curve) -> f64 {
    match curve {
        Curve::W => c.criterion(),
        Curve::L1c => c.l1c(),
    }
}
