//! Drawing primitives shared by the report's figures: SVG rendering, axes with hand-made ticks,
//! colours, legends, the colour map, and number formatting.
//!
//! Every chart uses `WithKeyPoints<RangedCoordf64>` axes whose ticks are computed here (1-2-5
//! steps, or decades for logarithmic data plotted as log10 values), so one code path serves
//! linear and logarithmic axes alike and the tick labels are round numbers.
//!
//! Text sizes: plotters' SVG backend writes `font-size = size / 1.24`, so the sizes passed to
//! plotters are [`px`] of the wanted CSS pixel size. Text is written as SVG `<text>` elements
//! with the generic `sans-serif` family: the browser picks the font, no font file is needed.

use plotters::coord::Shift;
use plotters::coord::ranged1d::{KeyPointHint, NoDefaultFormatting, Ranged, ValueFormatter};
use plotters::prelude::*;
pub use plotters::style::text_anchor::{HPos, Pos, VPos};

/// The drawing area of one SVG figure (pixel coordinates).
pub type Area<'a> = DrawingArea<SVGBackend<'a>, Shift>;
/// Result of a drawing step; plotters' errors are boxed and turned into a message by [`render`].
pub type Drawn<T = ()> = std::result::Result<T, Box<dyn std::error::Error>>;

/// Generic font family: resolved by the browser, so the SVG needs no font file.
pub const FONT: &str = "sans-serif";

/// plotters size for a CSS pixel size (see the module docs).
pub fn px(css: f64) -> f64 {
    css * 1.24
}

/// A text style of `css` pixels.
pub fn text(css: f64) -> TextStyle<'static> {
    (FONT, px(css)).into_font().color(&BLACK)
}

/// A bold text style of `css` pixels.
pub fn bold(css: f64) -> TextStyle<'static> {
    (FONT, px(css), FontStyle::Bold).into_font().color(&BLACK)
}

/// Render a figure of `size` pixels into an SVG document.
pub fn render(size: (u32, u32), draw: impl FnOnce(&Area<'_>) -> Drawn) -> std::result::Result<String, String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        draw(&root).map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(svg)
}

/// A linear f64 axis with explicit tick positions and tick labels that match them. (plotters'
/// own f64 axis picks its ticks itself, and its key-point combinator loses the label format.)
#[derive(Clone, Debug)]
pub struct Axis {
    lo: f64,
    hi: f64,
    ticks: Vec<f64>,
    labels: Labels,
}

/// How an [`Axis`] writes its tick labels.
#[derive(Clone, Copy, Debug)]
enum Labels {
    /// As many decimals as the tick step needs, so neighbouring labels always differ.
    Step(f64),
    /// The axis holds log10 of the values: label 10^v.
    Pow10,
    /// Integers only (orders).
    Int,
}

impl Ranged for Axis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, v: &f64, limit: (i32, i32)) -> i32 {
        let length = limit.1 - limit.0;
        if self.hi == self.lo || length == 0 {
            return limit.0 + length / 2;
        }
        let t = (v - self.lo) / (self.hi - self.lo);
        if !t.is_finite() {
            // Off-scale values land just outside the plot, where they are clipped.
            return if t > 0.0 { limit.1 + length.signum() } else { limit.0 - length.signum() };
        }
        // Clamp far off-scale values (a -200 dB notch, a spike) to a few plot sizes outside.
        let t = t.clamp(-4.0, 5.0);
        limit.0 + (length as f64 * t).round() as i32
    }

    fn key_points<H: KeyPointHint>(&self, hint: H) -> Vec<f64> {
        // Bold points only: the charts draw no minor grid.
        if hint.weight().allow_light_points() { Vec::new() } else { self.ticks.clone() }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.lo..self.hi
    }
}

impl ValueFormatter<f64> for Axis {
    fn format_ext(&self, v: &f64) -> String {
        match self.labels {
            Labels::Step(step) => step_label(*v, step),
            Labels::Pow10 => sig_pow10(*v),
            Labels::Int => int_label(*v),
        }
    }
}

/// `v` with the decimals a tick step of `step` needs (exponent form for tiny or huge values).
pub fn step_label(v: f64, step: f64) -> String {
    if !(step.is_finite() && step > 0.0) {
        return short(v);
    }
    let top = v.abs().max(step);
    if !(1e-3..1e6).contains(&top) {
        let digits = (top.log10().floor() - step.log10().floor()).max(0.0) as usize;
        return format!("{v:.digits$e}");
    }
    let decimals = (-step.log10() - 1e-9).ceil().max(0.0) as usize;
    let s = format!("{v:.decimals$}");
    // "-0.0" would read as a sign error on an axis.
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') { "0".into() } else { s }
}

/// Axis from `lo` to `hi` with ticks at `ticks` (those outside the range are dropped), labelled
/// with the decimals their spacing needs.
pub fn axis(lo: f64, hi: f64, ticks: Vec<f64>) -> Axis {
    let slack = 1e-9 * (hi - lo).abs();
    let ticks: Vec<f64> = ticks.into_iter().filter(|t| *t >= lo - slack && *t <= hi + slack).collect();
    let step = ticks.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min);
    let step = if step.is_finite() { step } else { (hi - lo).abs() / 4.0 };
    Axis { lo, hi, ticks, labels: Labels::Step(step) }
}

/// Axis of log10 values from `lo` to `hi`, labelled with the values themselves.
pub fn log_axis(lo: f64, hi: f64) -> Axis {
    Axis { labels: Labels::Pow10, ..axis(lo, hi, log_ticks(lo, hi)) }
}

/// Axis of integers `first..=last` with half a unit of room at both ends.
pub fn int_axis(first: u32, last: u32, max_ticks: usize) -> Axis {
    Axis { labels: Labels::Int, ..axis(first as f64 - 0.5, last as f64 + 0.5, int_ticks(first, last, max_ticks)) }
}

/// Round tick positions (steps of 1, 2 or 5 times a power of ten), at most about `max` of them.
pub fn nice_ticks(lo: f64, hi: f64, max: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo];
    }
    let raw = (hi - lo) / max.max(1) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0].iter().map(|m| m * mag).find(|s| *s >= raw).unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    // Multiplying the index (not accumulating steps) keeps 0.1 * 3 from drifting to 0.30000000000000004
    // in a way that shows in labels; [`sig`] formats the rest.
    (first..=last).map(|i| i as f64 * step).collect()
}

/// Integer ticks from `lo` to `hi` (inclusive), thinned to at most about `max`.
pub fn int_ticks(lo: u32, hi: u32, max: usize) -> Vec<f64> {
    let n = (hi - lo + 1) as usize;
    let step = n.div_ceil(max.max(1)).max(1);
    (lo..=hi).step_by(step).map(f64::from).collect()
}

/// Ticks for log10-transformed data spanning `lo..hi` (both log10 values): 1, 2, 5 per decade,
/// or only the decades when the span is wide.
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let mantissas: &[f64] = if hi - lo > 3.0 { &[1.0] } else { &[1.0, 2.0, 5.0] };
    let mut out = Vec::new();
    for e in (lo.floor() as i32)..=(hi.ceil() as i32) {
        for m in mantissas {
            let v = (m * 10f64.powi(e)).log10();
            if v >= lo - 1e-9 && v <= hi + 1e-9 {
                out.push(v);
            }
        }
    }
    if out.len() < 2 {
        // Less than one 1-2-5 step inside: label the ends instead.
        out = vec![lo, hi];
    }
    out
}

/// `[lo, hi]` of the finite values, widened by `pad` of the span on both sides (and made
/// non-empty when all values are equal).
pub fn padded_range(values: impl IntoIterator<Item = f64>, pad: f64) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return None;
    }
    let span = if hi > lo { hi - lo } else { lo.abs().max(1e-12) };
    Some((lo - pad * span, hi + pad * span))
}

/// The points split where a value is not finite (a missing output's NaN): one line per run,
/// so that no line is drawn through a gap.
pub fn finite_runs(points: impl IntoIterator<Item = (f64, f64)>) -> Vec<Vec<(f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for (x, y) in points {
        if y.is_finite() {
            runs.last_mut().expect("never empty").push((x, y));
        } else if !runs.last().expect("never empty").is_empty() {
            runs.push(Vec::new());
        }
    }
    runs.retain(|r| !r.is_empty());
    runs
}

/// The runs of consecutive samples of `missing` (sorted) below `end`, as `start..end` ranges:
/// the bands a figure shades where the output is missing.
pub fn missing_spans(missing: &[usize], end: usize) -> Vec<std::ops::Range<usize>> {
    let mut spans: Vec<std::ops::Range<usize>> = Vec::new();
    for &t in missing.iter().take_while(|&&t| t < end) {
        match spans.last_mut() {
            Some(s) if s.end == t => s.end = t + 1,
            _ => spans.push(t..t + 1),
        }
    }
    spans
}

/// Shading for missing outputs, and the colour of a cut between segments (a seam).
pub const GAP_COLOUR: RGBColor = RGBColor(200, 160, 220);
pub const SEAM_COLOUR: RGBColor = RGBColor(90, 90, 90);

/// The `q`-quantile (0..=1) of the finite values (linear interpolation), None when there are none.
pub fn quantile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (i, frac) = (pos.floor() as usize, pos.fract());
    Some(if i + 1 < v.len() { v[i] + frac * (v[i + 1] - v[i]) } else { v[i] })
}

pub use crate::text::{sig, trimmed};

/// Tick label: three significant digits without trailing zeros ("0.6", "1", "2.5e-5").
pub fn short(v: f64) -> String {
    trimmed(v, 3)
}

/// Tick label of a log10-transformed axis: the value itself.
pub fn sig_pow10(v: f64) -> String {
    short(10f64.powf(v))
}

/// Label of an integer tick (empty between integers).
pub fn int_label(v: f64) -> String {
    if (v - v.round()).abs() < 1e-6 { format!("{}", v.round() as i64) } else { String::new() }
}

/// Ten distinguishable colours (Tableau 10), cycled for more series.
pub fn palette(i: usize) -> RGBColor {
    const P: [(u8, u8, u8); 10] = [
        (31, 119, 180),
        (255, 127, 14),
        (44, 160, 44),
        (214, 39, 40),
        (148, 103, 189),
        (140, 86, 75),
        (227, 119, 194),
        (127, 127, 127),
        (188, 189, 34),
        (23, 190, 207),
    ];
    let (r, g, b) = P[i % P.len()];
    RGBColor(r, g, b)
}

/// Colours that mean the same thing in every figure.
pub const MEASURED: RGBColor = RGBColor(120, 120, 120);
pub const LS_COLOUR: RGBColor = RGBColor(31, 119, 180);
pub const M1_COLOUR: RGBColor = RGBColor(214, 39, 40);
pub const M2_COLOUR: RGBColor = RGBColor(255, 127, 14);
/// The lead rule's pick where it is neither M1 nor M2 (several inputs' grid figures).
pub const LEAD_COLOUR: RGBColor = RGBColor(44, 160, 44);
pub const BAND_COLOUR: RGBColor = RGBColor(120, 170, 230);
pub const GRID_COLOUR: RGBColor = RGBColor(225, 225, 225);

/// Viridis colour map at `t` in [0, 1] (piecewise linear between nine samples of the map):
/// perceptually uniform and readable in grey scale and by colour-blind readers.
pub fn viridis(t: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 9] = [
        (68.0, 1.0, 84.0),
        (71.0, 44.0, 122.0),
        (59.0, 81.0, 139.0),
        (44.0, 113.0, 142.0),
        (33.0, 144.0, 141.0),
        (39.0, 173.0, 129.0),
        (92.0, 200.0, 99.0),
        (170.0, 220.0, 50.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.0 };
    let pos = t * (STOPS.len() - 1) as f64;
    let i = (pos.floor() as usize).min(STOPS.len() - 2);
    let f = pos - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |x: f64, y: f64| (x + f * (y - x)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// Black or white, whichever reads better on `c`.
pub fn ink_on(c: RGBColor) -> RGBColor {
    let lum = 0.299 * c.0 as f64 + 0.587 * c.1 as f64 + 0.114 * c.2 as f64;
    if lum > 140.0 { BLACK } else { WHITE }
}

/// How a legend entry is drawn.
#[derive(Clone, Copy)]
pub enum Mark {
    /// A line segment, dashed or not, of the given width.
    Line { colour: RGBColor, width: u32, dashed: bool },
    /// A filled circle.
    Dot(RGBColor),
    /// A hollow circle.
    Ring(RGBColor),
    /// A hollow square.
    Square(RGBColor),
    /// A filled square (areas, shading).
    Patch(RGBAColor),
}

/// Draw legend entries in rows from (x, y), wrapping at `width` pixels (1: one entry per row),
/// on a translucent white box so a legend over data stays readable; returns the height used.
pub fn legend(area: &Area<'_>, x: i32, y: i32, width: i32, entries: &[(Mark, String)], size: f64) -> Drawn<i32> {
    let row = (size * 1.6).round() as i32;
    // Layout first (positions and the box), then drawing.
    let (mut cx, mut cy, mut right) = (x, y, x);
    let mut placed = Vec::with_capacity(entries.len());
    for (_, label) in entries {
        // A generous estimate of the width of sans-serif text, so entries never overlap.
        let w = 32 + (label.chars().count() as f64 * size * 0.55).round() as i32 + 18;
        if cx > x && cx + w > x + width {
            cx = x;
            cy += row;
        }
        placed.push((cx, cy + row / 2));
        right = right.max(cx + w - 14);
        cx += w;
    }
    area.draw(&Rectangle::new([(x - 6, y - 2), (right + 4, cy + row + 2)], WHITE.mix(0.85).filled()))?;
    for ((mark, label), &(cx, mid)) in entries.iter().zip(&placed) {
        draw_mark(area, *mark, (cx, mid), (cx + 26, mid))?;
        area.draw(&Text::new(label.clone(), (cx + 32, mid), text(size).pos(Pos::new(HPos::Left, VPos::Center))))?;
    }
    Ok(cy + row - y)
}

/// Draw one legend mark between the two pixel points.
fn draw_mark(area: &Area<'_>, mark: Mark, a: (i32, i32), b: (i32, i32)) -> Drawn {
    let mid = ((a.0 + b.0) / 2, a.1);
    match mark {
        Mark::Line { colour, width, dashed: false } => {
            area.draw(&PathElement::new(vec![a, b], colour.stroke_width(width)))?;
        }
        Mark::Line { colour, width, dashed: true } => {
            for s in (a.0..b.0).step_by(9) {
                area.draw(&PathElement::new(vec![(s, a.1), ((s + 5).min(b.0), a.1)], colour.stroke_width(width)))?;
            }
        }
        Mark::Dot(c) => {
            area.draw(&Circle::new(mid, 5, c.filled()))?;
        }
        Mark::Ring(c) => {
            area.draw(&Circle::new(mid, 6, c.stroke_width(2)))?;
        }
        Mark::Square(c) => {
            area.draw(&Rectangle::new([(mid.0 - 6, mid.1 - 6), (mid.0 + 6, mid.1 + 6)], c.stroke_width(2)))?;
        }
        Mark::Patch(c) => {
            area.draw(&Rectangle::new([(a.0 + 4, a.1 - 6), (b.0 - 4, a.1 + 6)], c.filled()))?;
        }
    }
    Ok(())
}

/// A title line centred at the top of `area`; returns the rest of the area.
pub fn title<'a>(area: &Area<'a>, title: &str, size: f64) -> Drawn<Area<'a>> {
    Ok(area.titled(title, bold(size))?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round() {
        assert_eq!(nice_ticks(0.0, 1.0, 5), vec![0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]);
        assert_eq!(nice_ticks(-3.0, 7.0, 5), vec![-2.0, 0.0, 2.0, 4.0, 6.0]);
        assert_eq!(int_ticks(6, 14, 20), (6..=14).map(f64::from).collect::<Vec<_>>());
        assert_eq!(int_ticks(1, 60, 10).len(), 10);
        let t = log_ticks(0.05f64.log10(), 2f64.log10());
        let v: Vec<String> = t.iter().map(|x| sig_pow10(*x)).collect();
        assert_eq!(v, ["0.05", "0.1", "0.2", "0.5", "1", "2"]);
        assert_eq!(short(0.6000000000000001), "0.6");
        assert_eq!(short(2.5e-5), "2.5e-5");
        assert_eq!(short(1500.0), "1500");
        assert_eq!(step_label(24.93, 0.02), "24.93");
        assert_eq!(step_label(25.0, 0.05), "25.00");
        assert_eq!(step_label(0.6000000000000001, 0.2), "0.6");
        assert_eq!(step_label(1500.0, 500.0), "1500");
        assert_eq!(step_label(-0.0001, 0.5), "0");
        assert_eq!(step_label(2.5e-5, 5e-6), "2.5e-5");
    }

    #[test]
    fn formatting_and_quantiles() {
        assert_eq!(sig(0.0123456, 3), "0.0123");
        assert_eq!(sig(99.9068, 4), "99.91");
        assert_eq!(sig(12345.0, 3), "12345");
        assert_eq!(sig(1.5e-7, 3), "1.50e-7");
        assert_eq!(sig(-0.00001, 2), "-1.0e-5");
        assert_eq!(int_label(3.0), "3");
        assert_eq!(int_label(3.5), "");
        assert_eq!(quantile(&[3.0, 1.0, 2.0, f64::NAN], 0.5), Some(2.0));
        assert_eq!(quantile(&[], 0.5), None);
        assert_eq!(padded_range([1.0, 3.0], 0.5), Some((0.0, 4.0)));
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
    }
}
