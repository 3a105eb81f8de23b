//! Bode plots of the picks against the spectral estimate.

use super::super::plot::*;
use super::{Figure, Picked};
use crate::oe::freq_response;
use crate::spectral::SpectralEstimate;
use plotters::prelude::*;
use std::f64::consts::PI;

/// Wrap an angle in degrees into (-180, 180].
fn wrap180(d: f64) -> f64 {
    let w = d - 360.0 * (d / 360.0).round();
    if w <= -180.0 { w + 360.0 } else { w }
}

/// The filter a Bode figure draws: one input's `q^-delay B/F` of a pick, for a model of
/// several inputs the input's name, and the pick's band fit of that filter (one input:
/// `fit_band`; several: the input's entry of `fit_band_i`).
pub struct Response<'a> {
    pub b: &'a [f64],
    pub f: &'a [f64],
    pub delay: usize,
    pub input: Option<&'a str>,
    pub band_fit: Option<f64>,
}

/// Model points of a Bode figure without an estimate (its frequency grid otherwise).
const POINTS_WITHOUT_ESTIMATE: usize = 257;

/// Bode magnitude (dB) and phase (deg) of one pick against the Welch estimate, with the fit band
/// shaded and the coherence below (paper Figs. 11 and 13); without an estimate (`est` None: the
/// record's spectral estimate failed) the model's response alone. For one input of several
/// (`response.input`) the estimate is that input's `H_i = (P^-1 s)_i` and the coherence the
/// multiple coherence of all inputs ([`crate::spectral::estimate_inputs`], METHOD.md 19).
/// `gain_band`, when given, maps a normalised frequency w (rad/sample) to the model's |G| and
/// its standard deviation (the robust covariance through the gradient of G, METHOD.md 10): the
/// figure draws |G| +/- 2 std.
pub fn bode_figure(
    (est, ts): (Option<&SpectralEstimate>, f64),
    band: Option<[f64; 2]>,
    pick: Picked<'_>,
    response: Response<'_>,
    gain_band: Option<&dyn Fn(f64) -> (f64, f64)>,
    file: &str,
) -> std::result::Result<Figure, String> {
    let bins = est.map_or(POINTS_WITHOUT_ESTIMATE, |e| e.freq_hz.len());
    let nyquist = 0.5 / ts;
    // Four model points per Welch bin; index 4 k is bin k.
    const REFINE: usize = 4;
    let fine = (bins - 1) * REFINE + 1;
    let rad_per_fine = PI / (fine - 1) as f64;
    let mut mag = Vec::with_capacity(fine);
    let mut phase = Vec::with_capacity(fine);
    let mut prev = 0.0;
    for j in 0..fine {
        let (re, im) = freq_response(response.b, response.f, response.delay, rad_per_fine * j as f64);
        mag.push(20.0 * re.hypot(im).log10());
        let p = im.atan2(re).to_degrees();
        // Unwrap along frequency: the model's phase is smooth, so each step is well below 180.
        let p = if j == 0 { p } else { prev + wrap180(p - prev) };
        phase.push(p);
        prev = p;
    }
    let freq_fine = |j: usize| nyquist * j as f64 / (fine - 1) as f64;
    // A logarithmic frequency axis (x = log10 f) from the first point above 0 Hz to Nyquist.
    let (x_lo, x_hi) = (freq_fine(1).log10(), nyquist.log10());
    // The band's colour: the pick's, lightened towards white.
    let light = {
        let l = |c: u8| c + ((255 - c) as f64 * 0.55) as u8;
        RGBColor(l(pick.colour.0), l(pick.colour.1), l(pick.colour.2))
    };
    // |G| +/- 2 std in dB (the lower edge floored 100 dB below |G| where the band reaches 0).
    let confidence: Vec<(f64, f64, f64)> = gain_band
        .map(|gb| {
            (0..fine)
                .skip(1)
                .filter_map(|j| {
                    let (g, s) = gb(rad_per_fine * j as f64);
                    let db = |v: f64| 20.0 * v.max(g * 1e-5).log10();
                    (g > 0.0 && s.is_finite()).then(|| (freq_fine(j).log10(), db(g - 2.0 * s), db(g + 2.0 * s)))
                })
                .collect()
        })
        .unwrap_or_default();
    // The estimate's phase is drawn on the model's branch (within ±180° of it), so a 360° jump at
    // one noisy bin cannot offset the rest of the curve as a plain unwrap would.
    let mut welch: Vec<(f64, f64, f64, f64)> = Vec::new();
    if let Some(est) = est {
        for k in 0..bins {
            let (re, im) = (est.re[k], est.im[k]);
            if re.is_finite() && im.is_finite() && est.freq_hz[k] > 0.0 {
                let p = im.atan2(re).to_degrees();
                let reference = phase[k * REFINE];
                welch.push((
                    est.freq_hz[k].log10(),
                    20.0 * re.hypot(im).log10(),
                    reference + wrap180(p - reference),
                    est.coherence[k],
                ));
            }
        }
    }
    let mag_values = mag.iter().copied().chain(welch.iter().map(|w| w.1)).filter(|v| v.is_finite());
    let (mut mlo, mhi) = padded_range(mag_values, 0.05).unwrap_or((-60.0, 0.0));
    // Notches of the estimate between PRBS lines can reach -200 dB; keep 100 dB below the top.
    mlo = mlo.max(mhi - 100.0);
    let (plo, phi) =
        padded_range(phase.iter().copied().chain(welch.iter().map(|w| w.2)), 0.05).unwrap_or((-180.0, 180.0));
    let band_text = band.map(|[a, b]| format!("{} to {} Hz", short(a), short(b)));
    // The robust estimate is Welch's of the output with its spikes cleaned out (METHOD.md 11).
    let cleaned = match est {
        Some(e) if e.replaced > 0 => format!(", {} output spikes cleaned out first", e.replaced),
        _ => String::new(),
    };
    let from = response.input.map(|u| format!(" from input {u}")).unwrap_or_default();
    // Several inputs: the input's column of the H1 estimate, and the inputs' multiple coherence.
    let (estimate_name, coherence_name) = match response.input {
        Some(u) => (format!("Welch estimate H = P⁻¹ s, input {u}"), "multiple coherence"),
        None => ("Welch estimate S_yu/S_uu".to_string(), "coherence"),
    };
    let title_text = match est {
        Some(_) => {
            format!("Frequency response of {}{from} against the Welch estimate (cf. paper Figs. 11, 13)", pick.label())
        }
        None => format!("Frequency response of {}{from} (cf. paper Figs. 11, 13)", pick.label()),
    };
    // Without an estimate there is no coherence panel: the phase panel carries the axis.
    let last = if est.is_some() { 2 } else { 1 };
    let svg = render((1000, if est.is_some() { 900 } else { 700 }), |root| {
        let body = title(root, &title_text, 17.0)?;
        // Room for three legend rows (the model, the estimate, its band and the fit band).
        let (head, body) = body.split_vertically(80);
        let (mag_area, rest) = body.split_vertically(350);
        let (phase_area, coh_area) = if est.is_some() { rest.split_vertically(260) } else { (rest.clone(), rest) };
        let fx = || log_axis(x_lo, x_hi);
        let panels = [
            (&mag_area, mlo, mhi, "|G| [dB, output unit per input unit]", nice_ticks(mlo, mhi, 7), 20),
            (&phase_area, plo, phi, "phase [deg]", phase_ticks(plo, phi), if last == 1 { 46 } else { 20 }),
            (&coh_area, 0.0, 1.05, coherence_name, vec![0.0, 0.5, 1.0], 46),
        ];
        for (i, (area, lo, hi, desc, ticks, xl)) in panels.into_iter().enumerate().take(last + 1) {
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
            if i == last {
                mesh.x_desc("frequency [Hz]");
            } else {
                // Shared frequency axis: numbers only under the last panel.
                mesh.x_label_formatter(&|_| String::new());
            }
            mesh.draw()?;
            if let Some([a, b]) = band.filter(|[_, b]| b.log10() > x_lo) {
                let (a, b) = (a.log10().max(x_lo), b.log10());
                chart
                    .draw_series(std::iter::once(Rectangle::new([(a, lo), (b, hi)], BAND_COLOUR.mix(0.18).filled())))?;
            }
            match i {
                0 => {
                    // The model's +/- 2 std band, clipped to the panel.
                    for edge in [1usize, 2] {
                        chart.draw_series(LineSeries::new(
                            confidence.iter().map(|c| (c.0, if edge == 1 { c.1 } else { c.2 }.clamp(lo, hi))),
                            light.stroke_width(1),
                        ))?;
                    }
                    chart.draw_series(welch.iter().map(|w| Circle::new((w.0, w.1), 2, MEASURED.filled())))?;
                    chart.draw_series(LineSeries::new(
                        (1..fine).map(|j| (freq_fine(j).log10(), mag[j])).filter(|p| p.1.is_finite()),
                        pick.colour.stroke_width(2),
                    ))?;
                }
                1 => {
                    chart.draw_series(welch.iter().map(|w| Circle::new((w.0, w.2), 2, MEASURED.filled())))?;
                    chart.draw_series(LineSeries::new(
                        (1..fine).map(|j| (freq_fine(j).log10(), phase[j])),
                        pick.colour.stroke_width(2),
                    ))?;
                }
                _ => {
                    chart.draw_series(welch.iter().map(|w| Circle::new((w.0, w.3), 2, MEASURED.filled())))?;
                }
            }
        }
        let mut entries =
            vec![(Mark::Line { colour: pick.colour, width: 2, dashed: false }, format!("{}{from}", pick.label()))];
        if let Some(est) = est {
            entries.push((
                Mark::Dot(MEASURED),
                format!("{estimate_name} ({}-sample Hann segments){cleaned}", est.segment),
            ));
        }
        if !confidence.is_empty() {
            entries.push((
                Mark::Line { colour: light, width: 1, dashed: false },
                "|G| ± 2 std (robust covariance)".into(),
            ));
        }
        if let Some(t) = &band_text {
            entries.push((Mark::Patch(BAND_COLOUR.mix(0.35)), format!("fit band {t}")));
        }
        legend(&head, 90, 4, 900, &entries, 14.0)?;
        Ok(())
    })?;
    if est.is_none() {
        let caption = format!(
            "Magnitude and phase of {}{from}, that input's filter q^-d B/F alone; the thin light lines are |G| ± 2 \
             standard deviations (its block of the robust parameter covariance through the gradient of G, METHOD.md \
             10). No spectral estimate of the record could be made, so no measured response is drawn.",
            pick.label()
        );
        return Ok(Figure { file: file.into(), alt: title_text, caption, svg });
    }
    let several = match response.input {
        Some(u) => format!(
            "The record has several inputs: the dots are input {u}'s column of H = P⁻¹ s, P the inputs' cross-spectral \
             matrix and s their cross-spectra with the output, and the coherence is the multiple coherence, the share \
             of the output's power all inputs explain together (METHOD.md 19). "
        ),
        None => String::new(),
    };
    let caption = format!(
        "Magnitude and phase of {} (line) and the nonparametric Welch estimate of the estimation record \
         (dots; robust by default: samples that a robust prediction filter misses by more than 3 robust \
         standard deviations are replaced by its prediction first, METHOD.md 11); the thin light lines are |G| ± 2 \
         standard deviations of the model (its robust parameter covariance through the gradient of G, METHOD.md 10); \
         with the magnitude-squared coherence below: where it is low the estimate itself is \
         unreliable. {several}{}The estimate's phase is drawn within ±180° of the model's. {} = {}.",
        pick.label(),
        band_text.map(|t| format!("Shaded: the band {t} of fit_band. ")).unwrap_or_default(),
        if response.input.is_some() { "This input's band fit" } else { "fit_band" },
        response.band_fit.map(|v| format!("{v:.2} %")).unwrap_or("n/a (no band)".into()),
    );
    Ok(Figure { file: file.into(), alt: title_text, caption, svg })
}

/// Phase ticks: multiples of 90, 180, 360 ... degrees, about 6 of them.
fn phase_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let step =
        [45.0, 90.0, 180.0, 360.0, 720.0, 1440.0, 2880.0].into_iter().find(|s| (hi - lo) / s <= 7.0).unwrap_or(5760.0);
    ((lo / step).ceil() as i64..=(hi / step).floor() as i64).map(|i| i as f64 * step).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phase_helpers() {
        assert_eq!(wrap180(190.0), -170.0);
        assert_eq!(wrap180(-180.0), 180.0);
        assert_eq!(wrap180(540.0), 180.0);
        assert_eq!(phase_ticks(-700.0, 10.0), vec![-540.0, -360.0, -180.0, 0.0]);
    }
}
