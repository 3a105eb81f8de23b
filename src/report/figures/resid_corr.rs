//! Residual correlations of a pick, as MATLAB's `resid` shows them.

use super::super::plot::*;
use super::{Figure, Picked};
use crate::estimate::residual_tests::MAX_LAG;
use plotters::prelude::*;

/// The autocorrelation of the pick's robust residuals psi_g(e) (lags 1..25) and their
/// cross-correlation with the input (lags 0..25), with the 99 % bounds of the tests. `scope`
/// ends the title (several inputs: the input of the cross-correlation).
pub fn resid_corr_figure(
    acf: &[f64],
    ccf: &[f64],
    n: usize,
    (white_p, indep_p): (Option<f64>, Option<f64>),
    pick: Picked<'_>,
    scope: &str,
    file: &str,
) -> std::result::Result<Figure, String> {
    let bound = 2.58 / (n as f64).sqrt();
    let title_text = format!("Residual tests of {}: correlations of the robust residuals ψ_γ(e){scope}", pick.label());
    let p = |v: Option<f64>| v.map_or("–".to_string(), |v| sig(v, 3));
    let svg = render((1000, 640), |root| {
        let body = title(root, &title_text, 17.0)?;
        let (top, bottom) = body.split_vertically(body.dim_in_pixel().1 as i32 / 2);
        let panels = [
            (&top, acf, 1usize, format!("autocorrelation of ψ_γ(e) (whiteness p = {})", p(white_p)), "lag k [samples]"),
            (
                &bottom,
                ccf,
                0usize,
                format!("cross-correlation of ψ_γ(e)_t with u_(t-k) (independence p = {})", p(indep_p)),
                "lag k [samples]",
            ),
        ];
        for (area, values, first, name, xdesc) in panels {
            let shown: Vec<(usize, f64)> = values.iter().copied().enumerate().skip(first).collect();
            let reach = shown.iter().map(|(_, v)| v.abs()).fold(2.0 * bound, f64::max) * 1.15;
            let mut chart =
                ChartBuilder::on(area).margin(10).x_label_area_size(46).y_label_area_size(80).build_cartesian_2d(
                    axis(-0.5, MAX_LAG as f64 + 0.5, nice_ticks(0.0, MAX_LAG as f64, 10)),
                    axis(-reach, reach, nice_ticks(-reach, reach, 6)),
                )?;
            chart
                .configure_mesh()
                .x_desc(xdesc)
                .y_desc("correlation")
                .label_style(text(13.0))
                .axis_desc_style(text(14.0))
                .bold_line_style(GRID_COLOUR)
                .light_line_style(TRANSPARENT)
                .draw()?;
            chart.draw_series(
                shown
                    .iter()
                    .map(|&(k, v)| PathElement::new(vec![(k as f64, 0.0), (k as f64, v)], pick.colour.stroke_width(3))),
            )?;
            chart.draw_series(shown.iter().map(|&(k, v)| Circle::new((k as f64, v), 3, pick.colour.filled())))?;
            for b in [-bound, bound] {
                chart.draw_series(DashedLineSeries::new(
                    [(-0.5, b), (MAX_LAG as f64 + 0.5, b)],
                    6,
                    4,
                    BLACK.stroke_width(1),
                ))?;
            }
            let entries = vec![
                (Mark::Line { colour: pick.colour, width: 3, dashed: false }, name),
                (
                    Mark::Line { colour: BLACK, width: 1, dashed: true },
                    format!("99 % bounds ±2.58/√N = ±{}", sig(bound, 2)),
                ),
            ];
            legend(&area.margin(16, 0, 100, 0), 6, 2, 1, &entries, 13.0)?;
        }
        Ok(())
    })?;
    let caption = format!(
        "Top: autocorrelation of the robust residuals ψ_γ(e_t) = clamp(e_t, −γ, γ) of the pick on the estimation \
         record ({n} samples); bottom: their cross-correlation with the input k samples earlier. Within the dashed \
         99 % bounds the residuals look white and independent of past inputs: the model captured the dynamics. \
         The p-values are those of the portmanteau tests over all 25 lags (METHOD.md 10); below 0.01 the report \
         flags the pick."
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}
