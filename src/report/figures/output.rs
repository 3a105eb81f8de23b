//! Measured and simulated outputs of the picks.

use super::super::plot::*;
use super::{Figure, Picked};
use crate::data::Record;
use crate::estimate::fit_percent;
use crate::table::CellRow;
use plotters::prelude::*;

/// Measured output and the simulated outputs of the least-squares model and of a Huber pick over
/// the first samples of a record, and their errors below (paper Fig. 14).
#[allow(clippy::too_many_arguments)]
/// `y_ls` and `y_h` are the two models' outputs on the record ([`crate::estimate::initial_state::model_output`]).
/// Missing outputs (NaN in `rec.y`) are shaded and no line crosses them; the starts of the
/// record's segments or experiments are dashed.
pub fn output_figure(
    rec: &Record,
    ts: f64,
    record: &str,
    (ls, y_ls): (&CellRow, &[f64]),
    (pick, y_h): (Picked<'_>, &[f64]),
    window: usize,
    file: &str,
) -> std::result::Result<Figure, String> {
    let y = &rec.y[..];
    let (fit_ls, fit_h) = (fit_percent(y, y_ls), fit_percent(y, y_h));
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
    let spans = missing_spans(&rec.missing, n);
    let seams: Vec<usize> = rec.seams.iter().copied().filter(|&s| s < n).collect();
    // The gaps and cuts of the window, on a chart of vertical extent lo..hi.
    let gaps_on = |lo: f64, hi: f64| {
        let bands = spans.iter().map(move |s| {
            Rectangle::new(
                [(t(s.start) - 0.5 * ts * scale, lo), (t(s.end) - 0.5 * ts * scale, hi)],
                GAP_COLOUR.mix(0.6).filled(),
            )
        });
        let cuts = seams.iter().map(move |&s| {
            PathElement::new(
                vec![(t(s) - 0.5 * ts * scale, lo), (t(s) - 0.5 * ts * scale, hi)],
                SEAM_COLOUR.stroke_width(1),
            )
        });
        (bands, cuts)
    };
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
        let (bands, cuts) = gaps_on(ylo, yhi);
        chart.draw_series(bands)?;
        chart.draw_series(cuts)?;
        for run in finite_runs((0..n).map(|i| (t(i), y[i]))) {
            chart.draw_series(LineSeries::new(run, MEASURED.stroke_width(1)))?;
        }
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
        let (bands, cuts) = gaps_on(-e_reach, e_reach);
        chart.draw_series(bands)?;
        chart.draw_series(cuts)?;
        for run in finite_runs((0..n).map(|i| (t(i), err_ls[i]))) {
            chart.draw_series(LineSeries::new(run, LS_COLOUR.stroke_width(1)))?;
        }
        for run in finite_runs((0..n).map(|i| (t(i), err_h[i]))) {
            chart.draw_series(LineSeries::new(run, pick.colour.stroke_width(1)))?;
        }

        let mut entries = vec![
            (Mark::Line { colour: MEASURED, width: 1, dashed: false }, "measured".to_string()),
            (
                Mark::Line { colour: LS_COLOUR, width: 2, dashed: true },
                format!("least squares {}, fit {:.2} %", ls.key.short_label(), fit_ls),
            ),
            (
                Mark::Line { colour: pick.colour, width: 2, dashed: false },
                format!("Huber {}, fit {:.2} %", pick.label(), fit_h),
            ),
        ];
        if !spans.is_empty() {
            let count = rec.missing.iter().take_while(|&&t| t < n).count();
            entries.push((Mark::Patch(GAP_COLOUR.mix(0.6)), format!("missing output ({count} here)")));
        }
        legend(&head, 90, 4, 900, &entries, 14.0)?;
        Ok(())
    })?;
    let caption = format!(
        "Top: the first {n} of {} samples of the {record} record ({}) and the outputs the least-squares and the \
         Huber model simulate from its input (offset included; initial state fitted to this record unless the job says initial_state \"zero\"); bottom: their errors y - ŷ, on an axis of \
         twice the 90 % quantile of |y - ŷ| (spikes go beyond it). Fits are over the whole record.{}{}",
        y.len(),
        if record == "validation" { "never used for fitting" } else { "the data the models were fitted to" },
        if beyond > 0 {
            format!(" {beyond} measured samples in the window lie beyond the vertical axis (spikes).")
        } else {
            String::new()
        },
        if rec.missing.is_empty() && rec.seams.is_empty() {
            String::new()
        } else {
            format!(
                " The record misses {} of its {} outputs (shaded where in the window; fits are over the observed                  ones) and has {} cuts where a segment or experiment starts from its own state (dashed).",
                rec.missing.len(),
                y.len(),
                rec.seams.len()
            )
        }
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}
