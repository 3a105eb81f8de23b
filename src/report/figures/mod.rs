//! The report's figures: each function prepares the numbers of one figure and draws it as SVG.
//! What each figure shows, and why, is documented in the parent module; one file per figure.

use crate::reduce::Candidate;
use plotters::prelude::*;

mod bode;
mod criteria;
mod curve;
mod gaps;
mod heat;
mod output;
mod picks_k;
mod resid_corr;
mod residuals;

pub use bode::{Response, bode_figure};
pub use criteria::criteria_figure;
pub use curve::curve_figure;
pub use gaps::gaps_figure;
pub use heat::heat_figure;
pub use output::output_figure;
pub use picks_k::picks_by_k_figure;
pub use resid_corr::resid_corr_figure;
pub use residuals::residual_figure;

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
    /// "M1 OE(9,9), k = 0.05" (several inputs: "M1 OE(2,2 d1; 1,1 d0), k = 0.05").
    pub fn label(&self) -> String {
        format!("{} {}, k = {}", self.name, self.model.key.short_label(), crate::text::k(self.model.k()))
    }
}
