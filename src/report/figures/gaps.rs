//! The residuals of a pick over the whole estimation record, with its gaps: the missing
//! outputs shaded and the cuts between segments (seams) marked (METHOD.md 21.3).

use super::super::plot::*;
use super::{Figure, Picked};
use crate::data::Record;
use plotters::prelude::*;

/// Points drawn at most: a longer record is drawn as the minimum and maximum of each of
/// `MAX_POINTS / 2` buckets (its envelope), a bucket with no observed output a gap.
const MAX_POINTS: usize = 5000;

/// `e_t = y_t - ŷ_t` of the pick over the record `rec` (`y_h` its simulated output), NaN at a
/// missing output, drawn without a line across a gap; gaps shaded, seams dashed.
pub fn gaps_figure(
    rec: &Record,
    ts: f64,
    (pick, y_h): (Picked<'_>, &[f64]),
    file: &str,
) -> std::result::Result<Figure, String> {
    let n = rec.len();
    let mut e: Vec<f64> = rec.y.iter().zip(y_h).map(|(y, yh)| y - yh).collect();
    for &t in &rec.missing {
        e[t] = f64::NAN;
    }
    let (scale, unit) = if n as f64 * ts < 2.0 { (1e3, "ms") } else { (1.0, "s") };
    let t = |i: f64| i * ts * scale;
    let t_end = t(n.saturating_sub(1) as f64).max(ts * scale);
    let abs: Vec<f64> = e.iter().map(|v| v.abs()).collect();
    let reach = 2.5 * quantile(&abs, 0.9).unwrap_or(1.0).max(1e-12);
    let points = envelope(&e);
    let spans = missing_spans(&rec.missing, n);
    let longest = spans.iter().map(|s| s.len()).max().unwrap_or(0);
    let stretches = crate::data::observed_ranges(n, &rec.seams, &rec.missing);
    let title_text = format!("Residuals of {} over the estimation record, with its gaps", pick.label());
    let svg = render((1000, 420), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (head, body) = body.split_vertically(40);
        let mut chart = ChartBuilder::on(&body)
            .margin_left(10)
            .margin_right(20)
            .x_label_area_size(46)
            .y_label_area_size(80)
            .build_cartesian_2d(
                axis(0.0, t_end, nice_ticks(0.0, t_end, 10)),
                axis(-reach, reach, nice_ticks(-reach, reach, 5)),
            )?;
        chart
            .configure_mesh()
            .x_desc(format!("time [{unit}]"))
            .y_desc("e = y - ŷ [data unit]")
            .label_style(text(13.0))
            .axis_desc_style(text(14.0))
            .bold_line_style(GRID_COLOUR)
            .light_line_style(TRANSPARENT)
            .draw()?;
        // A gap of one sample is as wide as a sample (at least a hairline at this scale).
        chart.draw_series(spans.iter().map(|s| {
            Rectangle::new(
                [(t(s.start as f64 - 0.5), -reach), (t(s.end as f64 - 0.5), reach)],
                GAP_COLOUR.mix(0.6).filled(),
            )
        }))?;
        for s in &rec.seams {
            let x = t(*s as f64 - 0.5);
            chart.draw_series(DashedLineSeries::new([(x, -reach), (x, reach)], 6, 4, SEAM_COLOUR.stroke_width(1)))?;
        }
        for run in finite_runs(points.iter().map(|&(i, v)| (t(i), v.clamp(-reach, reach)))) {
            chart.draw_series(LineSeries::new(run, pick.colour.stroke_width(1)))?;
        }
        let mut entries =
            vec![(Mark::Line { colour: pick.colour, width: 1, dashed: false }, format!("e_t of {}", pick.label()))];
        if !rec.missing.is_empty() {
            entries.push((Mark::Patch(GAP_COLOUR.mix(0.6)), format!("missing output ({} of {n})", rec.missing.len())));
        }
        if !rec.seams.is_empty() {
            entries.push((
                Mark::Line { colour: SEAM_COLOUR, width: 1, dashed: true },
                format!("start of a segment or experiment ({})", rec.seams.len()),
            ));
        }
        legend(&head, 90, 4, 900, &entries, 14.0)?;
        Ok(())
    })?;
    let caption = format!(
        "The residuals e_t = y_t - ŷ_t of the pick (simulated from rest in each experiment or segment) over all {n} \
         samples of the estimation record: {} outputs missing in {} gaps (the longest {longest} samples), shaded; \
         {} cuts where a segment or experiment begins, dashed; {} stretches of observed outputs. No line crosses \
         a gap: a missing output has no residual, and W, L1C, σ, the fits, the criteria and the residual tests \
         are over the observed samples only (METHOD.md 21). Values beyond ±{} (2.5 times the 90 % quantile of \
         |e|) are drawn at the edge.",
        rec.missing.len(),
        spans.len(),
        rec.seams.len(),
        stretches.len(),
        sig(reach, 3)
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

/// The points (sample index, value) to draw: all of them, or for a long record each bucket's
/// minimum and maximum in the order they occur (NaN for a bucket with no finite value).
fn envelope(e: &[f64]) -> Vec<(f64, f64)> {
    if e.len() <= MAX_POINTS {
        return e.iter().enumerate().map(|(i, &v)| (i as f64, v)).collect();
    }
    let size = e.len().div_ceil(MAX_POINTS / 2);
    let mut out = Vec::with_capacity(MAX_POINTS);
    for (b, chunk) in e.chunks(size).enumerate() {
        let finite = chunk.iter().enumerate().filter(|(_, v)| v.is_finite());
        let lo = finite.clone().min_by(|a, b| a.1.total_cmp(b.1));
        let hi = finite.max_by(|a, b| a.1.total_cmp(b.1));
        match (lo, hi) {
            (Some(lo), Some(hi)) => {
                let (first, second) = if lo.0 <= hi.0 { (lo, hi) } else { (hi, lo) };
                out.push(((b * size + first.0) as f64, *first.1));
                out.push(((b * size + second.0) as f64, *second.1));
            }
            _ => out.push(((b * size) as f64, f64::NAN)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::oe::Structure;
    use crate::reduce::Candidate;
    use crate::table::{CellRow, FitKind, RowKey};

    fn candidate(kind: FitKind, k: Option<f64>) -> Candidate {
        let mut row = CellRow::empty(RowKey::new(kind, &Structure::siso(2, 2, 1), k.map(|_| 0)));
        row.k = k;
        Candidate { row, score: f64::NAN }
    }

    /// A record with missing outputs and a cut: both figures draw no NaN (no line through a gap),
    /// shade each gap once and name the counts.
    #[test]
    fn the_residual_figures_draw_the_gaps_and_no_nan() {
        let n = 800;
        let mut y: Vec<f64> = (0..n).map(|t| ((t * 37 % 23) as f64 - 11.0) * 0.1).collect();
        let missing: Vec<usize> = (100..120).chain([300, 301, 450]).collect();
        for &t in &missing {
            y[t] = f64::NAN;
        }
        let rec = Record {
            path: "r.csv".into(),
            u: vec![0.0; n],
            y,
            u_names: vec!["u".into()],
            y_name: "y".into(),
            seams: vec![600],
            missing,
        };
        let (ls, huber) = (candidate(FitKind::Ls, None), candidate(FitKind::Huber, Some(0.5)));
        let pick = Picked { name: "M2", model: &huber, colour: M2_COLOUR };
        let yh = vec![0.1; n];
        let fig = gaps_figure(&rec, 0.01, (pick, &yh), "x.svg").expect("drawn");
        assert!(!fig.svg.contains("NaN"), "a NaN coordinate");
        assert!(fig.svg.contains("missing output (23 of 800)"), "legend");
        assert!(fig.caption.contains("23 outputs missing in 3 gaps (the longest 20 samples)"), "{}", fig.caption);
        let out = super::super::output_figure(&rec, 0.01, "estimation", (&ls.row, &yh), (pick, &yh), 500, "o.svg")
            .expect("drawn");
        assert!(!out.svg.contains("NaN"), "a NaN coordinate in the output figure");
        assert!(out.svg.contains("missing output (23 here)"), "legend of the window's gaps");
        let hist = super::super::residual_figure(&rec, (&ls.row, &yh), (pick, &yh), "h.svg").expect("drawn");
        assert!(hist.caption.contains("(777 samples)"), "{}", hist.caption);
    }

    #[test]
    fn the_envelope_keeps_the_extremes_and_the_gaps() {
        let mut e: Vec<f64> = (0..20_000).map(|i| ((i * 7919 % 101) as f64 - 50.0) / 50.0).collect();
        e[12_345] = 9.0;
        e[4000..4100].iter_mut().for_each(|v| *v = f64::NAN);
        let pts = envelope(&e);
        assert!(pts.len() <= MAX_POINTS);
        assert!(pts.iter().any(|&(i, v)| i == 12_345.0 && v == 9.0));
        // The 100 missing samples hold at least one whole bucket (of 8): a break in the line.
        assert!(pts.iter().any(|&(i, v)| v.is_nan() && (4000.0..4100.0).contains(&i)));
        assert!(finite_runs(pts).len() >= 2);
    }
}
