//! The information criteria against the number of parameters (METHOD.md 14): per criterion,
//! the smallest value over the rows with nB + nF parameters, minus the criterion's smallest
//! value over the table, on a log scale of (difference + 1) so the minimum and the steep
//! small orders share one axis.

use super::super::plot::*;
use super::Figure;
use crate::table::CellRow;
use plotters::prelude::*;
use std::collections::BTreeMap;

/// A criterion's column of a row.
type Column = fn(&CellRow) -> Option<f64>;

/// The criteria drawn, with the rows they belong to.
const CRITERIA: [(&str, Column); 4] = [
    ("AIC (least squares)", |r| r.fit.aic),
    ("BIC (least squares)", |r| r.fit.bic),
    ("robust AIC (Huber, best k)", |r| r.fit.raic),
    ("robust BIC (Huber, best k)", |r| r.fit.rbic),
];

/// Per criterion: nB + nF -> the smallest value at that count, less the overall smallest.
fn lines(rows: &[CellRow]) -> Vec<(&'static str, Vec<(u32, f64)>)> {
    CRITERIA
        .iter()
        .map(|(name, value)| {
            let mut best: BTreeMap<u32, f64> = BTreeMap::new();
            for r in rows.iter().filter(|r| r.ok()) {
                if let Some(v) = value(r).filter(|v| v.is_finite()) {
                    let e = best.entry(r.parameters()).or_insert(v);
                    *e = e.min(v);
                }
            }
            let min = best.values().copied().fold(f64::INFINITY, f64::min);
            (*name, best.into_iter().map(|(p, v)| (p, v - min)).collect())
        })
        .filter(|(_, pts): &(&str, Vec<(u32, f64)>)| !pts.is_empty())
        .collect()
}

/// The figure, or None when the table has no criteria (files of older versions).
pub fn criteria_figure(rows: &[CellRow], file: &str) -> Option<std::result::Result<Figure, String>> {
    let lines = lines(rows);
    if lines.is_empty() {
        return None;
    }
    let shown = |d: f64| (d + 1.0).log10();
    let xs: Vec<u32> = lines.iter().flat_map(|(_, p)| p.iter().map(|(x, _)| *x)).collect();
    let (x_lo, x_hi) = (xs.iter().copied().min().unwrap_or(0), xs.iter().copied().max().unwrap_or(1));
    let y_hi = lines.iter().flat_map(|(_, p)| p.iter().map(|(_, d)| shown(*d))).fold(1.0, f64::max);
    let title_text = "Information criteria against the number of parameters nB + nF";
    let svg = render((1000, 520), |root| {
        let body = title(root, title_text, 17.0)?;
        let (plot_area, side) = body.split_horizontally(740);
        let mut chart = ChartBuilder::on(&plot_area)
            .margin(12)
            .x_label_area_size(52)
            .y_label_area_size(84)
            .build_cartesian_2d(int_axis(x_lo, x_hi.max(x_lo + 1), 20), log_axis(0.0, y_hi * 1.05))?;
        chart
            .configure_mesh()
            .x_desc("nB + nF")
            .y_desc("criterion − its smallest value + 1, log scale")
            .label_style(text(14.0))
            .axis_desc_style(text(15.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;
        let mut entries = Vec::new();
        for (i, (name, pts)) in lines.iter().enumerate() {
            let colour = palette(i);
            let pts: Vec<(f64, f64)> = pts.iter().map(|&(p, d)| (p as f64, shown(d))).collect();
            chart.draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            entries.push((Mark::Line { colour, width: 2, dashed: false }, name.to_string()));
        }
        legend(&side, 6, 40, 1, &entries, 14.0)?;
        Ok(())
    });
    Some(svg.map(|svg| {
        Figure {
            file: file.into(),
            alt: title_text.into(),
            caption: "For each criterion, the smallest value among the models with nB + nF parameters (the robust \
                  ones over every k), less its smallest value in the table: each line reaches 1 at the parameter \
                  count its rule picks. A line that still falls at the grid's largest count says the grid may be \
                  too small."
                .into(),
            svg,
        }
    }))
}
