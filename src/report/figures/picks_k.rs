//! The picks' W, L1C and fit as functions of k.

use super::super::plot::*;
use super::Figure;
use crate::reduce::{self, Candidate, ReduceOptions, Selection, select};
use crate::table::CellRow;
use plotters::prelude::*;

/// The picks of the rules applied to one k alone, at x = log10 k.
struct KPicks {
    x: f64,
    m1: Option<Candidate>,
    m2: Option<Candidate>,
    /// The best ranking fit of any usable cell at this k.
    best: Option<f64>,
}

/// The M1- and M2-style pick if the grid had only one k, for every k: the orders and the fit.
/// A model of several inputs has one such figure per input (`input`: its index and name): the
/// rules applied to every row of each k as for one input, the orders drawn those of that input.
pub fn picks_by_k_figure(
    rows: &[CellRow],
    ks: &[f64],
    selection: &Selection,
    input: Option<(usize, &str)>,
    file: &str,
) -> std::result::Result<Figure, String> {
    // The orders drawn: the model's (one input) or input i's (several).
    let orders_of = |c: &Candidate| match input {
        None => (c.key.nb as f64, c.key.nf as f64),
        Some((i, _)) => {
            let o = c.key.structure().inputs()[i];
            (o.nb as f64, o.nf as f64)
        }
    };
    let settings = reduce::SelectionSettings {
        min_tolerance: selection.min_tolerance,
        fit_tolerance: selection.fit_tolerance,
        rule: Some(selection.rule),
    };
    let opts = ReduceOptions { basis: selection.basis, settings };
    let (fit_name, fit_of) = (selection.basis.column(), move |r: &CellRow| selection.basis.score(r));
    // select() on the rows of one k applies exactly the reducer's rules to that k alone.
    let mut per_k: Vec<KPicks> = Vec::new();
    for (i, &k) in ks.iter().enumerate() {
        let subset: Vec<CellRow> = rows.iter().filter(|r| r.key.k_index == Some(i as u32)).cloned().collect();
        let sel = select(&subset, &opts);
        let best = subset
            .iter()
            .filter(|r| reduce::takes_part(r))
            .filter_map(fit_of)
            .filter(|v| v.is_finite())
            .reduce(f64::max);
        per_k.push(KPicks { x: k.log10(), m1: sel.m1.map(|p| p.model), m2: sel.m2.map(|p| p.model), best });
    }
    let (mut klo, mut khi) = padded_range(per_k.iter().map(|p| p.x), 0.05).unwrap_or((-1.0, 0.0));
    if khi - klo < 0.6 {
        // One k (or a narrow range): show at least 0.6 decades so the axis has labelled ticks.
        let mid = 0.5 * (klo + khi);
        (klo, khi) = (mid - 0.3, mid + 0.3);
    }
    let orders: Vec<f64> =
        per_k.iter().flat_map(|p| p.m1.iter().chain(&p.m2).flat_map(|c| <[f64; 2]>::from(orders_of(c)))).collect();
    let (olo, ohi) = padded_range(orders.iter().copied(), 0.1).unwrap_or((0.0, 10.0));
    let fits: Vec<f64> = per_k.iter().flat_map(|p| p.m1.iter().chain(&p.m2).map(|c| c.score).chain(p.best)).collect();
    let (flo, fhi) = padded_range(fits.iter().copied(), 0.1).unwrap_or((0.0, 100.0));
    let of_input = input.map(|(_, name)| format!(", input {name}'s orders")).unwrap_or_default();
    let title_text = format!("How the best model moves with k (the pick rules applied to each k alone){of_input}");
    let svg = render((1000, 640), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (top, rest) = body.split_vertically(300);
        let (bottom, foot) = rest.split_vertically(rest.dim_in_pixel().1 as i32 - 40);
        let kx = || log_axis(klo, khi);
        let mut chart = ChartBuilder::on(&top)
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(80)
            .build_cartesian_2d(kx(), axis(olo.floor(), ohi.ceil(), nice_ticks(olo, ohi, 8)))?;
        chart
            .configure_mesh()
            .x_desc("k (log scale)")
            .y_desc("model order")
            .y_label_formatter(&|v| int_label(*v))
            .label_style(text(13.0))
            .axis_desc_style(text(14.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;
        for (which, colour, width, dashed) in [(0, M1_COLOUR, 3, false), (1, M2_COLOUR, 2, true)] {
            let of = |p: &KPicks| {
                if which == 0 { p.m1.as_ref() } else { p.m2.as_ref() }.map(|c| {
                    let (nb, nf) = orders_of(c);
                    (p.x, nb, nf)
                })
            };
            let nb: Vec<(f64, f64)> = per_k.iter().filter_map(of).map(|(x, nb, _)| (x, nb)).collect();
            let nf: Vec<(f64, f64)> = per_k.iter().filter_map(of).map(|(x, _, nf)| (x, nf)).collect();
            for (pts, square) in [(nb, false), (nf, true)] {
                let style = colour.stroke_width(width);
                if dashed {
                    chart.draw_series(DashedLineSeries::new(pts.iter().copied(), 7, 5, style))?;
                } else {
                    chart.draw_series(LineSeries::new(pts.iter().copied(), style))?;
                }
                // M1 markers large and hollow, M2 small and filled: both visible on the same order.
                let r = if which == 0 { 7 } else { 4 };
                let marker = if which == 0 { colour.stroke_width(2) } else { colour.filled() };
                if square {
                    chart.draw_series(
                        pts.iter().map(|&p| EmptyElement::at(p) + Rectangle::new([(-r, -r), (r, r)], marker)),
                    )?;
                } else {
                    chart.draw_series(pts.iter().map(|&p| Circle::new(p, r as u32, marker)))?;
                }
            }
        }
        let mut chart = ChartBuilder::on(&bottom)
            .margin(10)
            .x_label_area_size(46)
            .y_label_area_size(80)
            .build_cartesian_2d(kx(), axis(flo, fhi, nice_ticks(flo, fhi, 6)))?;
        chart
            .configure_mesh()
            .x_desc("k (log scale), γ = k σ")
            .y_desc(format!("{fit_name} [%]"))
            .label_style(text(13.0))
            .axis_desc_style(text(14.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;
        let best: Vec<(f64, f64)> = per_k.iter().filter_map(|p| p.best.map(|b| (p.x, b))).collect();
        chart.draw_series(DashedLineSeries::new(best.iter().copied(), 3, 4, MEASURED.stroke_width(2)))?;
        for (which, colour) in [(0, M1_COLOUR), (1, M2_COLOUR)] {
            let pts: Vec<(f64, f64)> = per_k
                .iter()
                .filter_map(|p| if which == 0 { p.m1.as_ref() } else { p.m2.as_ref() }.map(|c| (p.x, c.score)))
                .collect();
            chart.draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 4, colour.filled())))?;
        }
        for (pick, colour) in [(&selection.m1, M1_COLOUR), (&selection.m2, M2_COLOUR)] {
            if let Some(p) = pick {
                let x = p.model.k().log10();
                chart.draw_series(DashedLineSeries::new([(x, flo), (x, fhi)], 2, 4, colour.stroke_width(1)))?;
            }
        }
        let entries = [
            (Mark::Line { colour: M1_COLOUR, width: 3, dashed: false }, "M1 rule (W minima)".to_string()),
            (Mark::Line { colour: M2_COLOUR, width: 2, dashed: true }, "M2 rule (L1C minima)".to_string()),
            (Mark::Ring(BLACK), "nB".to_string()),
            (Mark::Square(BLACK), "nF".to_string()),
            (Mark::Line { colour: MEASURED, width: 2, dashed: true }, format!("best {fit_name} of any cell")),
        ];
        legend(&foot, 80, 4, 900, &entries, 13.0)?;
        Ok(())
    })?;
    let whose = match input {
        Some((_, name)) => {
            format!("input {name}'s orders nB and nF (circles, squares; the other inputs' in their own figures)")
        }
        None => "orders nB (circles) and nF (squares)".to_string(),
    };
    let caption = format!(
        "Top: {whose} of the model the M1 rule (red) and the M2 rule (orange, \
         dashed) would pick if the grid had only that k. Bottom: that model's {fit_name}, and the best \
         {fit_name} of any cell at that k (grey); the thin dashed verticals mark the k of the overall picks. \
         A stable choice keeps its orders over a range of k."
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}
