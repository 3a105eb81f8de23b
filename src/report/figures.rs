//! The report's figures: each function prepares the numbers of one figure and draws it as SVG.
//! What each figure shows, and why, is documented in the parent module.

use super::plot::*;
use crate::estimate::fit_percent;
use crate::oe::{freq_response, simulate_vec};
use crate::reduce::{self, Candidate, Curve, FitBasis, ReduceOptions, Selection, local_minima, select};
use crate::spectral::SpectralEstimate;
use crate::table::{CellRow, Method};
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::f64::consts::PI;

/// One rendered figure and the text the page shows with it.
pub struct Figure {
    /// File name beside report.html.
    pub file: String,
    /// Alternative text of the image.
    pub alt: String,
    /// Caption (plain text; the page escapes it).
    pub caption: String,
    pub svg: String,
}

/// A pick as the figures need it: the model, a short name and its colour.
#[derive(Clone, Copy)]
pub struct Picked<'a> {
    pub name: &'static str,
    pub model: &'a Candidate,
    pub colour: RGBColor,
}

impl Picked<'_> {
    /// "M1 OE(9,9), k = 0.05".
    pub fn label(&self) -> String {
        format!("{} OE({},{}), k = {}", self.name, self.model.nb, self.model.nf, short(self.model.k))
    }
}

/// The fit column a basis names, with its label.
pub fn basis_column(basis: FitBasis) -> (&'static str, fn(&CellRow) -> Option<f64>) {
    match basis {
        FitBasis::Validation => ("fit_val", |r| r.fit_val),
        FitBasis::Band => ("fit_band", |r| r.fit_band),
        FitBasis::Estimation => ("fit", |r| r.fit),
    }
}

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
/// the pick marked (paper Figs. 10 and 12).
pub fn curve_figure(
    rows: &[CellRow],
    curve: Curve,
    k_index: u32,
    k: f64,
    min_tolerance: f64,
    pick: Option<Picked<'_>>,
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
    let nfs: Vec<u32> = curves.values().flatten().map(|r| r.nf).collect();
    let (nf_lo, nf_hi) = (nfs.iter().copied().min().unwrap_or(0), nfs.iter().copied().max().unwrap_or(1));
    let (ylo, yhi) = padded_range(all.iter().map(|v| shown(*v)), 0.08).unwrap_or((0.0, 1.0));

    let (what, unit_desc, fig_no) = match curve {
        Curve::W => ("criterion W", "W = (1/N) Σ ρ_γ(e_t)  [(output unit)²]", "10"),
        Curve::L1c => ("L1 contribution L1C", "L1C = share of samples with |e_t| > γ  [%]", "12"),
    };
    let title_text = format!("{what} versus nF at k = {} (one line per nB; cf. paper Fig. {fig_no})", short(k));
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
            let pts: Vec<(f64, f64)> = c.iter().map(|r| (r.nf as f64, shown(raw(r)))).collect();
            chart.draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))?;
            let values: Vec<f64> = c.iter().map(|r| raw(r)).collect();
            let minima = local_minima(&values, curve.tolerance(min_tolerance));
            minima_count += minima.len();
            chart.draw_series(minima.iter().map(|&m| Circle::new(pts[m], 7, colour.stroke_width(2))))?;
            entries.push((Mark::Line { colour, width: 2, dashed: false }, format!("nB = {nb}")));
        }
        if let Some(p) = pick.filter(|p| p.model.k_index == k_index) {
            let at = (p.model.nf as f64, shown(raw_of(p.model, curve)));
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
        short(k),
        if curve == Curve::W { "relative" } else { "absolute on the share" },
        if curve == Curve::W { "M1" } else { "M2" },
        pick.map(|p| format!("; the thick black ring is the pick, {}", p.label())).unwrap_or_default(),
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

fn raw_of(c: &Candidate, curve: Curve) -> f64 {
    match curve {
        Curve::W => c.criterion,
        Curve::L1c => c.l1c,
    }
}

/// Heat maps over (nB, nF) at one k: W, L1C and the fit of the selection's basis, with the picks
/// outlined.
pub fn heat_figure(
    rows: &[CellRow],
    k_index: u32,
    k: f64,
    basis: FitBasis,
    picks: &[Picked<'_>],
    file: &str,
) -> std::result::Result<Figure, String> {
    let cells: Vec<&CellRow> =
        rows.iter().filter(|r| r.method == Method::Huber && r.k_index == Some(k_index)).collect();
    let nbs: Vec<u32> = cells.iter().map(|r| r.nb).collect();
    let nfs: Vec<u32> = cells.iter().map(|r| r.nf).collect();
    let (nb_lo, nb_hi) = (nbs.iter().copied().min().unwrap_or(1), nbs.iter().copied().max().unwrap_or(1));
    let (nf_lo, nf_hi) = (nfs.iter().copied().min().unwrap_or(0), nfs.iter().copied().max().unwrap_or(0));
    let (fit_name, fit_of) = basis_column(basis);

    // (title, value of a row, colour-scale direction: true when low is good).
    type Value = Box<dyn Fn(&CellRow) -> Option<f64>>;
    let panels: [(String, Value, bool); 3] = [
        ("W [(output unit)²]".to_string(), Box::new(|r: &CellRow| r.criterion), true),
        ("L1C [%]".to_string(), Box::new(|r: &CellRow| r.l1c.map(|v| 100.0 * v)), true),
        (format!("{fit_name} [%]"), Box::new(move |r: &CellRow| fit_of(r)), false),
    ];
    let n_rows = nb_hi - nb_lo + 1;
    let height = (150 + 34 * n_rows).clamp(330, 900);
    let title_text = format!("Heat maps over (nB, nF) at k = {} (k index {k_index})", short(k));
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
                let (x, y) = (r.nf as f64, r.nb as f64);
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
            for (i, p) in picks.iter().enumerate().filter(|(_, p)| p.model.k_index == k_index) {
                // Nested outlines, so two picks of the same cell both show.
                let inset = 0.5 - 0.12 * i as f64;
                let (x, y) = (p.model.nf as f64, p.model.nb as f64);
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
        short(k),
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

/// The picks of the rules applied to one k alone, at x = log10 k.
struct KPicks {
    x: f64,
    m1: Option<Candidate>,
    m2: Option<Candidate>,
    /// The best ranking fit of any usable cell at this k.
    best: Option<f64>,
}

/// The M1- and M2-style pick if the grid had only one k, for every k: the orders and the fit.
pub fn picks_by_k_figure(
    rows: &[CellRow],
    ks: &[f64],
    selection: &Selection,
    file: &str,
) -> std::result::Result<Figure, String> {
    let opts = ReduceOptions {
        basis: selection.basis,
        min_tolerance: selection.min_tolerance,
        fit_tolerance: selection.fit_tolerance,
    };
    let (fit_name, fit_of) = basis_column(selection.basis);
    // select() on the rows of one k applies exactly the reducer's rules to that k alone.
    let mut per_k: Vec<KPicks> = Vec::new();
    for (i, &k) in ks.iter().enumerate() {
        let subset: Vec<CellRow> = rows.iter().filter(|r| r.k_index == Some(i as u32)).cloned().collect();
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
        per_k.iter().flat_map(|p| p.m1.iter().chain(&p.m2).flat_map(|c| [c.nb as f64, c.nf as f64])).collect();
    let (olo, ohi) = padded_range(orders.iter().copied(), 0.1).unwrap_or((0.0, 10.0));
    let fits: Vec<f64> = per_k.iter().flat_map(|p| p.m1.iter().chain(&p.m2).map(|c| c.score).chain(p.best)).collect();
    let (flo, fhi) = padded_range(fits.iter().copied(), 0.1).unwrap_or((0.0, 100.0));
    let title_text = "How the best model moves with k (the pick rules applied to each k alone)".to_string();
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
                if which == 0 { p.m1.as_ref() } else { p.m2.as_ref() }.map(|c| (p.x, c.nb as f64, c.nf as f64))
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
                let x = p.model.k.log10();
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
    let caption = format!(
        "Top: orders nB (circles) and nF (squares) of the model the M1 rule (red) and the M2 rule (orange, \
         dashed) would pick if the grid had only that k. Bottom: that model's {fit_name}, and the best \
         {fit_name} of any cell at that k (grey); the thin dashed verticals mark the k of the overall picks. \
         A stable choice keeps its orders over a range of k."
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

/// Wrap an angle in degrees into (-180, 180].
fn wrap180(d: f64) -> f64 {
    let w = d - 360.0 * (d / 360.0).round();
    if w <= -180.0 { w + 360.0 } else { w }
}

/// Bode magnitude (dB) and phase (deg) of one pick against the Welch estimate, with the fit band
/// shaded and the coherence below (paper Figs. 11 and 13).
pub fn bode_figure(
    est: &SpectralEstimate,
    band: Option<[f64; 2]>,
    pick: Picked<'_>,
    file: &str,
) -> std::result::Result<Figure, String> {
    let m = &pick.model;
    let bins = est.freq_hz.len();
    let nyquist = 0.5 / est.ts;
    // Four model points per Welch bin; index 4 k is bin k.
    const REFINE: usize = 4;
    let fine = (bins - 1) * REFINE + 1;
    let rad_per_fine = PI / (fine - 1) as f64;
    let mut mag = Vec::with_capacity(fine);
    let mut phase = Vec::with_capacity(fine);
    let mut prev = 0.0;
    for j in 0..fine {
        let (re, im) = freq_response(&m.b, &m.f, m.delay as usize, rad_per_fine * j as f64);
        mag.push(20.0 * re.hypot(im).log10());
        let p = im.atan2(re).to_degrees();
        // Unwrap along frequency: the model's phase is smooth, so each step is well below 180.
        let p = if j == 0 { p } else { prev + wrap180(p - prev) };
        phase.push(p);
        prev = p;
    }
    let freq_fine = |j: usize| nyquist * j as f64 / (fine - 1) as f64;
    // The estimate's phase is drawn on the model's branch (within ±180° of it), so a 360° jump at
    // one noisy bin cannot offset the rest of the curve as a plain unwrap would.
    let mut welch: Vec<(f64, f64, f64, f64)> = Vec::new();
    for k in 0..bins {
        let (re, im) = (est.re[k], est.im[k]);
        if re.is_finite() && im.is_finite() {
            let p = im.atan2(re).to_degrees();
            let reference = phase[k * REFINE];
            welch.push((
                est.freq_hz[k],
                20.0 * re.hypot(im).log10(),
                reference + wrap180(p - reference),
                est.coherence[k],
            ));
        }
    }
    let mag_values = mag.iter().copied().chain(welch.iter().map(|w| w.1)).filter(|v| v.is_finite());
    let (mut mlo, mhi) = padded_range(mag_values, 0.05).unwrap_or((-60.0, 0.0));
    // Notches of the estimate between PRBS lines can reach -200 dB; keep 100 dB below the top.
    mlo = mlo.max(mhi - 100.0);
    let (plo, phi) =
        padded_range(phase.iter().copied().chain(welch.iter().map(|w| w.2)), 0.05).unwrap_or((-180.0, 180.0));
    let band_text = band.map(|[a, b]| format!("{} to {} Hz", short(a), short(b)));
    let title_text =
        format!("Frequency response of {} against the Welch estimate (cf. paper Figs. 11, 13)", pick.label());
    let svg = render((1000, 860), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (head, body) = body.split_vertically(40);
        let (mag_area, rest) = body.split_vertically(350);
        let (phase_area, coh_area) = rest.split_vertically(260);
        let fx = || axis(0.0, nyquist, nice_ticks(0.0, nyquist, 10));
        let panels = [
            (&mag_area, mlo, mhi, "|G| [dB, output unit per input unit]", nice_ticks(mlo, mhi, 7), 20),
            (&phase_area, plo, phi, "phase [deg]", phase_ticks(plo, phi), 20),
            (&coh_area, 0.0, 1.05, "coherence", vec![0.0, 0.5, 1.0], 46),
        ];
        for (i, (area, lo, hi, desc, ticks, xl)) in panels.into_iter().enumerate() {
            let mut chart = ChartBuilder::on(area)
                .margin_left(10)
                .margin_right(20)
                .margin_top(6)
                .x_label_area_size(xl)
                .y_label_area_size(84)
                .build_cartesian_2d(fx(), axis(lo, hi, ticks))?;
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(desc)
                .label_style(text(13.0))
                .axis_desc_style(text(14.0))
                .bold_line_style(GRID_COLOUR)
                .light_line_style(TRANSPARENT);
            if i == 2 {
                mesh.x_desc("frequency [Hz]");
            } else {
                // Shared frequency axis: numbers only under the last panel.
                mesh.x_label_formatter(&|_| String::new());
            }
            mesh.draw()?;
            if let Some([a, b]) = band {
                chart
                    .draw_series(std::iter::once(Rectangle::new([(a, lo), (b, hi)], BAND_COLOUR.mix(0.18).filled())))?;
            }
            match i {
                0 => {
                    chart.draw_series(welch.iter().map(|w| Circle::new((w.0, w.1), 2, MEASURED.filled())))?;
                    chart.draw_series(LineSeries::new(
                        (0..fine).map(|j| (freq_fine(j), mag[j])).filter(|p| p.1.is_finite()),
                        pick.colour.stroke_width(2),
                    ))?;
                }
                1 => {
                    chart.draw_series(welch.iter().map(|w| Circle::new((w.0, w.2), 2, MEASURED.filled())))?;
                    chart.draw_series(LineSeries::new(
                        (0..fine).map(|j| (freq_fine(j), phase[j])),
                        pick.colour.stroke_width(2),
                    ))?;
                }
                _ => {
                    chart.draw_series(welch.iter().map(|w| Circle::new((w.0, w.3), 2, MEASURED.filled())))?;
                }
            }
        }
        let mut entries = vec![
            (Mark::Line { colour: pick.colour, width: 2, dashed: false }, pick.label()),
            (Mark::Dot(MEASURED), format!("Welch estimate S_yu/S_uu ({}-sample Hann segments)", est.segment)),
        ];
        if let Some(t) = &band_text {
            entries.push((Mark::Patch(BAND_COLOUR.mix(0.35)), format!("fit band {t}")));
        }
        legend(&head, 90, 4, 900, &entries, 14.0)?;
        Ok(())
    })?;
    let caption = format!(
        "Magnitude and phase of {} (line) and the nonparametric Welch estimate of the estimation record \
         (dots), with the magnitude-squared coherence below: where it is low the estimate itself is \
         unreliable. {}The estimate's phase is drawn within ±180° of the model's. fit_band = {}.",
        pick.label(),
        band_text.map(|t| format!("Shaded: the band {t} of fit_band. ")).unwrap_or_default(),
        m.fit_band.map(|v| format!("{v:.2} %")).unwrap_or("n/a (no band)".into()),
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

/// Phase ticks: multiples of 90, 180, 360 ... degrees, about 6 of them.
fn phase_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let step =
        [45.0, 90.0, 180.0, 360.0, 720.0, 1440.0, 2880.0].into_iter().find(|s| (hi - lo) / s <= 7.0).unwrap_or(5760.0);
    ((lo / step).ceil() as i64..=(hi / step).floor() as i64).map(|i| i as f64 * step).collect()
}

/// Histogram of `e` over `[-reach, reach]` in `bins` bins; also the count outside.
fn histogram(e: &[f64], reach: f64, bins: usize) -> (Vec<usize>, usize) {
    let width = 2.0 * reach / bins as f64;
    let mut h = vec![0usize; bins];
    let mut outside = 0;
    for v in e {
        let i = ((v + reach) / width).floor();
        if i >= 0.0 && (i as usize) < bins {
            h[i as usize] += 1;
        } else {
            outside += 1;
        }
    }
    (h, outside)
}

/// Residuals of the least-squares fit and of a Huber pick (same orders) on the estimation
/// record, as histograms with ±gamma marked (paper Fig. 9).
pub fn residual_figure(
    u: &[f64],
    y: &[f64],
    ls: &CellRow,
    pick: Picked<'_>,
    file: &str,
) -> std::result::Result<Figure, String> {
    let m = pick.model;
    let delay = m.delay as usize;
    let resid =
        |b: &[f64], f: &[f64]| -> Vec<f64> { y.iter().zip(simulate_vec(b, f, delay, u)).map(|(a, s)| a - s).collect() };
    let e_ls = resid(&ls.b, &ls.f);
    let e_h = resid(&m.b, &m.f);
    let gamma = m.gamma;
    let sigma = ls.sigma.unwrap_or(f64::NAN);
    let share = |e: &[f64]| 100.0 * e.iter().filter(|v| v.abs() > gamma).count() as f64 / e.len() as f64;
    let n = e_ls.len() as f64;
    let mean_ls = e_ls.iter().sum::<f64>() / n;
    // Spikes would stretch the axis over bins of nothing, and the two fits differ in scale by a
    // factor k: each panel spans 2.5 times the 90 % quantile of its |e| (at least ±3 gamma) and
    // counts what falls outside.
    let reach_of = |e: &[f64]| {
        let abs: Vec<f64> = e.iter().map(|v| v.abs()).collect();
        (2.5 * quantile(&abs, 0.9).unwrap_or(1.0)).max(3.0 * gamma).max(1e-12)
    };
    const BINS: usize = 61;
    let title_text =
        format!("Residuals on the estimation record: least squares against {} (cf. paper Fig. 9)", pick.label());
    let svg = render((1000, 720), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (top, bottom) = body.split_vertically(body.dim_in_pixel().1 as i32 / 2);
        let panels = [
            (&top, &e_ls, LS_COLOUR, format!("least-squares OE({},{}), σ = {}", ls.nb, ls.nf, sig(sigma, 3))),
            (&bottom, &e_h, pick.colour, format!("Huber {}, γ = k σ = {}", pick.label(), sig(gamma, 3))),
        ];
        for (i, (area, e, colour, name)) in panels.into_iter().enumerate() {
            let reach = reach_of(e);
            let width = 2.0 * reach / BINS as f64;
            let (h, outside) = histogram(e, reach, BINS);
            let top_count = h.iter().copied().max().unwrap_or(1).max(1) as f64 * 1.12;
            let mut chart =
                ChartBuilder::on(area).margin(10).x_label_area_size(46).y_label_area_size(80).build_cartesian_2d(
                    axis(-reach, reach, nice_ticks(-reach, reach, 10)),
                    axis(0.0, top_count, nice_ticks(0.0, top_count, 5)),
                )?;
            chart
                .configure_mesh()
                .y_desc("samples per bin")
                .x_desc("residual e_t = y_t - ŷ_t [output unit]")
                .label_style(text(13.0))
                .axis_desc_style(text(14.0))
                .bold_line_style(GRID_COLOUR)
                .light_line_style(TRANSPARENT)
                .draw()?;
            chart.draw_series(h.iter().enumerate().filter(|(_, c)| **c > 0).map(|(j, &c)| {
                let x0 = -reach + j as f64 * width;
                Rectangle::new([(x0, 0.0), (x0 + width, c as f64)], colour.mix(0.55).filled())
            }))?;
            if i == 0 && sigma.is_finite() && sigma > 0.0 {
                // The Gaussian with the same mean and sigma, scaled to counts per bin: the
                // least-squares residuals are far from it (sharp peak, heavy tails).
                let pts = (0..=400).map(|j| {
                    let x = -reach + 2.0 * reach * j as f64 / 400.0;
                    let z = (x - mean_ls) / sigma;
                    (x, n * width * (-0.5 * z * z).exp() / (sigma * (2.0 * PI).sqrt()))
                });
                chart.draw_series(LineSeries::new(pts, BLACK.stroke_width(2)))?;
            }
            for g in [-gamma, gamma] {
                chart.draw_series(DashedLineSeries::new(
                    [(g, 0.0), (g, top_count)],
                    6,
                    4,
                    M1_COLOUR.stroke_width(2),
                ))?;
            }
            let mut entries = vec![
                (Mark::Patch(colour.mix(0.55)), name),
                (
                    Mark::Line { colour: M1_COLOUR, width: 2, dashed: true },
                    format!("±γ = ±{} ({:.1} % of |e| beyond)", sig(gamma, 3), share(e)),
                ),
            ];
            if i == 0 {
                entries
                    .push((Mark::Line { colour: BLACK, width: 2, dashed: false }, "Gaussian, same mean and σ".into()));
            }
            if outside > 0 {
                entries
                    .push((Mark::Patch(TRANSPARENT), format!("{outside} samples beyond ±{} not shown", sig(reach, 3))));
            }
            // Upper left, one entry per row: the histograms peak in the middle, so the legend
            // covers at most a thin tail.
            let legend_area = area.margin(16, 0, 100, 0);
            legend(&legend_area, 6, 2, 1, &entries, 13.0)?;
        }
        Ok(())
    })?;
    let caption = format!(
        "Histograms of e_t = y_t - ŷ_t over the whole estimation record ({} samples), for the least-squares fit \
         of OE({},{}) (top, with the Gaussian of the same σ) and for the Huber pick (bottom); each panel has its \
         own scale. Dashed red: ±γ; residuals beyond it form the L1 part of Huber's criterion (the pick's L1C \
         is {:.1} %). Residuals beyond the axis (the spikes) are counted in the legends.",
        e_ls.len(),
        ls.nb,
        ls.nf,
        100.0 * m.l1c
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

/// Measured output and the simulated outputs of the least-squares model and of a Huber pick over
/// the first samples of a record, and their errors below (paper Fig. 14).
#[allow(clippy::too_many_arguments)]
pub fn output_figure(
    u: &[f64],
    y: &[f64],
    ts: f64,
    record: &str,
    ls: &CellRow,
    pick: Picked<'_>,
    window: usize,
    file: &str,
) -> std::result::Result<Figure, String> {
    let m = pick.model;
    let delay = m.delay as usize;
    let y_ls = simulate_vec(&ls.b, &ls.f, delay, u);
    let y_h = simulate_vec(&m.b, &m.f, delay, u);
    let (fit_ls, fit_h) = (fit_percent(y, &y_ls), fit_percent(y, &y_h));
    let n = window.min(y.len());
    let (scale, unit) = if n as f64 * ts < 2.0 { (1e3, "ms") } else { (1.0, "s") };
    let t = |i: usize| i as f64 * ts * scale;
    let t_end = t(n.saturating_sub(1)).max(ts * scale);
    // Spikes in the measured output would flatten the models to a line: bound the axis by the
    // models and the central 98 % of the measured samples, and count the samples beyond.
    let yw = &y[..n];
    let (q_lo, q_hi) = (quantile(yw, 0.01).unwrap_or(-1.0), quantile(yw, 0.99).unwrap_or(1.0));
    let (ylo, yhi) =
        padded_range(y_ls[..n].iter().chain(&y_h[..n]).copied().chain([q_lo, q_hi]), 0.08).unwrap_or((-1.0, 1.0));
    let beyond = yw.iter().filter(|v| **v < ylo || **v > yhi).count();
    // The errors y - ŷ make the difference between the models visible where the outputs overlap.
    let err_ls: Vec<f64> = (0..n).map(|i| y[i] - y_ls[i]).collect();
    let err_h: Vec<f64> = (0..n).map(|i| y[i] - y_h[i]).collect();
    let both: Vec<f64> = err_ls.iter().chain(&err_h).copied().collect();
    let abs_err: Vec<f64> = both.iter().map(|v| v.abs()).collect();
    // Twice the 90 % quantile: the spikes (a few % of the samples) go off-scale instead of
    // flattening the errors of the models to a line.
    let e_reach = 2.0 * quantile(&abs_err, 0.9).unwrap_or(1.0).max(1e-12);
    let title_text = format!("Simulated and measured output, {record} record, first {n} samples (cf. paper Fig. 14)");
    let svg = render((1000, 640), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (head, body) = body.split_vertically(40);
        let (out_area, err_area) = body.split_vertically(360);
        let mut chart = ChartBuilder::on(&out_area)
            .margin_left(10)
            .margin_right(20)
            .x_label_area_size(20)
            .y_label_area_size(80)
            .build_cartesian_2d(
                axis(0.0, t_end, nice_ticks(0.0, t_end, 10)),
                axis(ylo, yhi, nice_ticks(ylo, yhi, 7)),
            )?;
        chart
            .configure_mesh()
            .y_desc("output [data unit]")
            .x_label_formatter(&|_| String::new())
            .label_style(text(13.0))
            .axis_desc_style(text(14.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;
        chart.draw_series(LineSeries::new((0..n).map(|i| (t(i), y[i])), MEASURED.stroke_width(1)))?;
        chart.draw_series(DashedLineSeries::new((0..n).map(|i| (t(i), y_ls[i])), 6, 3, LS_COLOUR.stroke_width(2)))?;
        chart.draw_series(LineSeries::new((0..n).map(|i| (t(i), y_h[i])), pick.colour.stroke_width(2)))?;

        let mut chart = ChartBuilder::on(&err_area)
            .margin_left(10)
            .margin_right(20)
            .margin_top(8)
            .x_label_area_size(46)
            .y_label_area_size(80)
            .build_cartesian_2d(
                axis(0.0, t_end, nice_ticks(0.0, t_end, 10)),
                axis(-e_reach, e_reach, nice_ticks(-e_reach, e_reach, 5)),
            )?;
        chart
            .configure_mesh()
            .x_desc(format!("time [{unit}]"))
            .y_desc("error y - ŷ [data unit]")
            .label_style(text(13.0))
            .axis_desc_style(text(14.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;
        chart.draw_series(LineSeries::new((0..n).map(|i| (t(i), err_ls[i])), LS_COLOUR.stroke_width(1)))?;
        chart.draw_series(LineSeries::new((0..n).map(|i| (t(i), err_h[i])), pick.colour.stroke_width(1)))?;

        let entries = [
            (Mark::Line { colour: MEASURED, width: 1, dashed: false }, "measured".to_string()),
            (
                Mark::Line { colour: LS_COLOUR, width: 2, dashed: true },
                format!("least squares OE({},{}), fit {:.2} %", ls.nb, ls.nf, fit_ls),
            ),
            (
                Mark::Line { colour: pick.colour, width: 2, dashed: false },
                format!("Huber {}, fit {:.2} %", pick.label(), fit_h),
            ),
        ];
        legend(&head, 90, 4, 900, &entries, 14.0)?;
        Ok(())
    })?;
    let caption = format!(
        "Top: the first {n} of {} samples of the {record} record ({}) and the outputs the least-squares and the \
         Huber model simulate from its input (zero initial conditions); bottom: their errors y - ŷ, on an axis of \
         twice the 90 % quantile of |y - ŷ| (spikes go beyond it). Fits are over the whole record.{}",
        y.len(),
        if record == "validation" { "never used for fitting" } else { "the data the models were fitted to" },
        if beyond > 0 {
            format!(" {beyond} measured samples in the window lie beyond the vertical axis (spikes).")
        } else {
            String::new()
        }
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
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

    #[test]
    fn phase_helpers() {
        assert_eq!(wrap180(190.0), -170.0);
        assert_eq!(wrap180(-180.0), 180.0);
        assert_eq!(wrap180(540.0), 180.0);
        assert_eq!(phase_ticks(-700.0, 10.0), vec![-540.0, -360.0, -180.0, 0.0]);
    }
}
