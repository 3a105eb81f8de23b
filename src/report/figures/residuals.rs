//! Residual histograms of the picks with ±gamma marked (paper Fig. 9).

use super::super::plot::*;
use super::{Figure, Picked};
use crate::data::Record;
use crate::table::CellRow;
use plotters::prelude::*;
use std::f64::consts::PI;

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
/// `y_ls` and `y_h` are the two models' outputs from zero initial conditions (the residuals
/// of the criterion); a missing output (`rec.missing`) has no residual and is left out.
pub fn residual_figure(
    rec: &Record,
    (ls, y_ls): (&CellRow, &[f64]),
    (pick, y_h): (Picked<'_>, &[f64]),
    file: &str,
) -> std::result::Result<Figure, String> {
    let m = pick.model;
    let observed = |t: usize| rec.missing.binary_search(&t).is_err();
    let resid = |s: &[f64]| -> Vec<f64> {
        rec.y.iter().zip(s).enumerate().filter(|&(t, _)| observed(t)).map(|(_, (a, s))| a - s).collect()
    };
    let e_ls = resid(y_ls);
    let e_h = resid(y_h);
    let gamma = m.gamma();
    let sigma = ls.fit.sigma.unwrap_or(f64::NAN);
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
            (&top, &e_ls, LS_COLOUR, format!("least-squares {}, σ = {}", ls.key.short_label(), sig(sigma, 3))),
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
         of {} (top, with the Gaussian of the same σ) and for the Huber pick (bottom); each panel has its \
         own scale. Dashed red: ±γ; residuals beyond it form the L1 part of Huber's criterion (the pick's L1C \
         is {:.1} %). Residuals beyond the axis (the spikes) are counted in the legends.{}",
        e_ls.len(),
        ls.key.short_label(),
        100.0 * m.l1c(),
        if rec.missing.is_empty() {
            String::new()
        } else {
            format!(" The {} missing outputs of the record have no residual and are not counted.", rec.missing.len())
        }
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}
