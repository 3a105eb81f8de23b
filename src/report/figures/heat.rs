//! Heat maps of a quantity over (nB, nF) at one k.

use super::super::plot::*;
use super::{Figure, Picked};
use crate::reduce::FitBasis;
use crate::table::CellRow;
use plotters::prelude::*;

/// Heat maps over (nB, nF) at one k: W, L1C and the fit of the selection's basis, with the picks
/// outlined. `scope` ends the title (several inputs: which input's orders the rows hold).
pub fn heat_figure(
    rows: &[CellRow],
    k_index: u32,
    k: f64,
    basis: FitBasis,
    picks: &[Picked<'_>],
    scope: &str,
    file: &str,
) -> std::result::Result<Figure, String> {
    let cells: Vec<&CellRow> = rows.iter().filter(|r| r.is_huber() && r.key.k_index == Some(k_index)).collect();
    let nbs: Vec<u32> = cells.iter().map(|r| r.key.nb).collect();
    let nfs: Vec<u32> = cells.iter().map(|r| r.key.nf).collect();
    let (nb_lo, nb_hi) = (nbs.iter().copied().min().unwrap_or(1), nbs.iter().copied().max().unwrap_or(1));
    let (nf_lo, nf_hi) = (nfs.iter().copied().min().unwrap_or(0), nfs.iter().copied().max().unwrap_or(0));
    let (fit_name, fit_of) = (basis.column(), move |r: &CellRow| basis.score(r));

    // (title, value of a row, colour-scale direction: true when low is good).
    type Value = Box<dyn Fn(&CellRow) -> Option<f64>>;
    let panels: [(String, Value, bool); 3] = [
        ("W [(output unit)²]".to_string(), Box::new(|r: &CellRow| r.fit.criterion), true),
        ("L1C [%]".to_string(), Box::new(|r: &CellRow| r.fit.l1c.map(|v| 100.0 * v)), true),
        (format!("{fit_name} [%]"), Box::new(move |r: &CellRow| fit_of(r)), false),
    ];
    let n_rows = nb_hi - nb_lo + 1;
    let height = (150 + 34 * n_rows).clamp(330, 900);
    let title_text = format!("Heat maps over (nB, nF) at k = {} (k index {k_index}){scope}", crate::text::k(k));
    let mut clipped_note = Vec::new();
    let svg = render((HEAT_WIDTH, height), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (body, foot) = body.split_vertically(body.dim_in_pixel().1 as i32 - 34);
        let columns = body.split_evenly((1, 3));
        for ((name, value, low_good), area) in panels.iter().zip(columns.iter()) {
            let values: Vec<f64> =
                cells.iter().filter(|r| r.ok()).filter_map(|r| value(r)).filter(|v| v.is_finite()).collect();
            // A few very bad cells (an unstable start, a tiny order) would wash out the scale;
            // the 10th/90th percentile bounds the colours on the bad side, the labels keep values.
            let (mut lo, mut hi) = (quantile(&values, 0.0).unwrap_or(0.0), quantile(&values, 1.0).unwrap_or(1.0));
            if *low_good {
                let q = quantile(&values, 0.9).unwrap_or(hi);
                if q > lo && q < hi {
                    clipped_note.push(format!("{name} above {} share the top colour", sig(q, 3)));
                    hi = q;
                }
            } else {
                let q = quantile(&values, 0.1).unwrap_or(lo);
                if q < hi && q > lo {
                    clipped_note.push(format!("{name} below {} share the bottom colour", sig(q, 3)));
                    lo = q;
                }
            }
            // The labels resolve a fifth of the panel's spread (before clipping).
            let spread = quantile(&values, 1.0).unwrap_or(0.0) - quantile(&values, 0.0).unwrap_or(0.0);
            // A fit of 99.93 % must not read "100".
            let min_decimals = if name.starts_with('W') { 0 } else { 1 };
            let constant = hi <= lo;
            if constant {
                hi = lo + lo.abs().max(1e-9) * 1e-3;
            }
            // Bright = good on every panel: low W, low L1C, high fit.
            let colour_of = |v: f64| {
                let t = (v - lo) / (hi - lo);
                viridis(if *low_good { 1.0 - t } else { t })
            };
            let (plot_area, bar_area) = area.split_horizontally(area.dim_in_pixel().0 as i32 - 66);
            let mut chart = ChartBuilder::on(&plot_area)
                .caption(name, text(15.0))
                .margin(4)
                .x_label_area_size(42)
                .y_label_area_size(40)
                .build_cartesian_2d(int_axis(nf_lo, nf_hi, 16), int_axis(nb_lo, nb_hi, 16))?;
            chart
                .configure_mesh()
                .disable_mesh()
                .x_desc("nF")
                .y_desc("nB")
                .label_style(text(13.0))
                .axis_desc_style(text(14.0))
                .draw()?;
            let (pw, ph) = chart.plotting_area().dim_in_pixel();
            let cell_w = pw as f64 / (nf_hi - nf_lo + 1) as f64;
            let cell_h = ph as f64 / n_rows as f64;
            // Labels only where the widest fits: sans-serif digits are about 0.64 em wide, the
            // point and the minus less, at 10 px.
            let widest = values
                .iter()
                .map(|v| {
                    cell_label(*v, spread, min_decimals)
                        .chars()
                        .map(|c| if c.is_ascii_digit() { 6.4 } else { 3.3 })
                        .sum::<f64>()
                })
                .fold(0.0, f64::max);
            let labels = cell_w >= widest + 2.0 && cell_h >= 14.0;
            for r in &cells {
                let (x, y) = (r.key.nf as f64, r.key.nb as f64);
                let corners = [(x - 0.5, y - 0.5), (x + 0.5, y + 0.5)];
                match value(r).filter(|v| r.ok() && v.is_finite()) {
                    Some(v) => {
                        let c = colour_of(v);
                        chart.draw_series(std::iter::once(Rectangle::new(corners, c.filled())))?;
                        if labels {
                            let s = cell_label(v, spread, min_decimals);
                            let ink = ink_on(c);
                            let style = text(10.0).color(&ink).pos(Pos::new(HPos::Center, VPos::Center));
                            chart.draw_series(std::iter::once(Text::new(s, (x, y), style)))?;
                        }
                    }
                    None => {
                        chart
                            .draw_series(std::iter::once(Rectangle::new(corners, RGBColor(215, 215, 215).filled())))?;
                        let style = text(12.0).pos(Pos::new(HPos::Center, VPos::Center));
                        chart.draw_series(std::iter::once(Text::new("×", (x, y), style)))?;
                    }
                }
            }
            for (i, p) in picks.iter().enumerate().filter(|(_, p)| p.model.k_index() == k_index) {
                // Nested outlines, so two picks of the same cell both show.
                let inset = 0.5 - 0.12 * i as f64;
                let (x, y) = (p.model.key.nf as f64, p.model.key.nb as f64);
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(x - inset, y - inset), (x + inset, y + inset)],
                    p.colour.stroke_width(3),
                )))?;
            }
            colour_bar(&bar_area, lo, hi, *low_good, constant)?;
        }
        let mut entries: Vec<(Mark, String)> = picks
            .iter()
            .map(|p| (Mark::Line { colour: p.colour, width: 3, dashed: false }, format!("outline: {}", p.label())))
            .collect();
        entries.push((Mark::Patch(RGBColor(215, 215, 215).to_rgba()), "× failed or missing cell".into()));
        entries.push((Mark::Patch(viridis(1.0).to_rgba()), "bright = low W, low L1C, high fit".into()));
        legend(&foot, 60, 2, HEAT_WIDTH as i32 - 80, &entries, 13.0)?;
        Ok(())
    })?;
    let caption = format!(
        "Every Huber cell at k = {}: the criterion W, the L1 contribution L1C and the model-choice fit \
         ({fit_name}), one square per (nB, nF), with its value printed when there is room. Colour scales are \
         per panel; bright is good on all three. {}",
        crate::text::k(k),
        if clipped_note.is_empty() { String::new() } else { format!("Scales clipped: {}.", clipped_note.join("; ")) }
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

/// Width of a heat-map figure: three panels whose cells hold readable labels for about ten nF
/// values, shown unscaled on the page (see the page's `max-width`).
const HEAT_WIDTH: u32 = 1270;

/// A heat-map cell's label: decimals enough to tell apart values a fifth of `spread` apart (at
/// least `min_decimals`, at most four), three significant digits when all values are equal.
fn cell_label(v: f64, spread: f64, min_decimals: usize) -> String {
    if v != 0.0 && v.abs() < 1e-3 || spread <= 0.0 {
        return sig(v, 3);
    }
    let decimals = (-(spread / 5.0).log10()).ceil().clamp(min_decimals as f64, 4.0) as usize;
    format!("{v:.decimals$}")
}

/// A vertical colour bar from `lo` (bottom) to `hi` (top) with ticks on its right.
fn colour_bar(area: &Area<'_>, lo: f64, hi: f64, low_good: bool, constant: bool) -> Drawn {
    // A constant panel gets one tick: a scale of made-up neighbouring values would mislead.
    let ticks = if constant { vec![lo] } else { nice_ticks(lo, hi, 6) };
    let mut chart = ChartBuilder::on(area)
        .margin_top(34)
        .margin_bottom(48)
        .margin_right(4)
        .right_y_label_area_size(52)
        .build_cartesian_2d(axis(0.0, 1.0, vec![]), axis(lo, hi, ticks))?;
    chart.configure_mesh().disable_mesh().label_style(text(12.0)).draw()?;
    let steps = 64;
    chart.draw_series((0..steps).map(|i| {
        let (a, b) = (i as f64 / steps as f64, (i + 1) as f64 / steps as f64);
        let c = viridis(if low_good { 1.0 - (a + b) / 2.0 } else { (a + b) / 2.0 });
        Rectangle::new([(0.0, lo + a * (hi - lo)), (1.0, lo + b * (hi - lo))], c.filled())
    }))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_map_labels_resolve_the_spread() {
        assert_eq!(cell_label(0.80199, 0.015, 0), "0.802");
        assert_eq!(cell_label(24.934, 0.5, 0), "24.9");
        assert_eq!(cell_label(99.934, 1.5, 1), "99.9");
        assert_eq!(cell_label(99.934, 12.0, 1), "99.9");
        assert_eq!(cell_label(99.934, 12.0, 0), "100");
        assert_eq!(cell_label(4.52, 0.0, 1), "4.52");
        assert_eq!(cell_label(1234.6, 800.0, 0), "1235");
        assert_eq!(cell_label(24.934, 0.07, 0), "24.93");
    }
}
