//! The review report of a finished sweep: `report.html` and SVG figures beside it.
//!
//! Engineers choose a model by looking at the curves the paper looks at (Corbier et al. 2012,
//! METHOD.md 7), not only at the two picks in `selection.json`. [`write_report`] reads a results
//! folder (`cells.parquet`, `selection.json`, `job.json`), re-reads the data files `job.json`
//! names, and writes one page with these figures:
//!
//! 1. **W versus nF, one line per nB, at the M1 pick's k** (paper Fig. 10). The M1-style pick is
//!    the best-fitting local minimum over nF of these curves; the rings show every local minimum
//!    (the reducer's rule and tolerance), so one sees whether the pick is a clear minimum or one of
//!    many on a flat curve. W is drawn on a log axis when it spans more than a factor 20.
//! 2. **L1C versus nF at the M2 pick's k** (paper Fig. 12), the same for the M2-style pick. On data
//!    with a fixed share of spikes L1C is flat at small k (METHOD.md 8): the figure shows when
//!    L1C cannot rank the orders.
//! 3. **Heat maps over (nB, nF) of W, L1C and the ranking fit** (the `basis` of `selection.json`:
//!    `fit_val`, `fit_band` or `fit`), for every k when there are at most six, else six spread
//!    over the grid plus the picks' k. They show the whole grid at once: where the good orders
//!    lie, and which cells failed (grey crosses). The picks are outlined. Colour scales are per
//!    panel, bright meaning good on all three (low W, low L1C, high fit), bounded at the 90th (W)
//!    or 10th (fit) percentile so that a few bad cells do not wash out the rest; the values are
//!    printed in the cells when they fit.
//! 4. **How the picks move with k**: the M1 and M2 rules applied to each k alone (via
//!    [`crate::reduce::select`] on that k's rows), their orders and fit against k. A model whose
//!    orders hold over a range of k is a robust choice; one that jumps is sensitive to gamma.
//! 5. **Bode magnitude and phase of each pick against the Welch estimate** of the estimation
//!    record (the estimate `fit_band` is computed against, [`crate::spectral::WelchOptions`]
//!    default), the fit band shaded, the coherence below (paper Figs. 11 and 13). The question is
//!    whether the model follows the data in the band; the coherence says where the estimate
//!    itself can be trusted. The estimate's phase is drawn within ±180° of the model's.
//! 6. **Residual histograms** of the least-squares fit of the M2 pick's orders and of the M2 pick
//!    (paper Fig. 9), with ±gamma marked and the Gaussian of the least-squares sigma: the
//!    least-squares residuals are far from Gaussian, which is the paper's case for Huber's
//!    criterion; samples beyond ±gamma are the L1 part.
//! 7. **Simulated output of the least-squares model and of the M2 pick against the measured
//!    output**, first 500 samples of the estimation record and of the validation record when there
//!    is one (paper Fig. 14), with the errors y - ŷ below: the outputs overlap at this scale, the
//!    errors show how much the spikes pulled the least-squares model and not the Huber model.
//!
//! 8. **Every pick rule and the information criteria against nB + nF** (`rules.rs`).
//!
//! A model of several inputs (`inputs.rs`) has figures 1-3 per input, on the input's slice of
//! the grid through the lead pick (the other inputs at its orders); figure 4 per input (the
//! rules on every row of each k, that input's orders drawn); figure 5 one per pick and input,
//! against that input's column of the record's estimate `H = P^-1 s` with the multiple
//! coherence below ([`crate::spectral::estimate_inputs`], METHOD.md 19); the residuals'
//! cross-correlation is one per input.
//!
//! and tables: the picks with gamma, sigma, W, L1C, fits, pole radius and convergence, the
//! least-squares fits of the same orders, b and f (paper Tables 2, 3), the reducer's rule
//! sentence and best candidates, every rule's pick, and links to the result files.
//!
//! The figures are SVG files named `report-*.svg` beside `report.html`; the page links them by
//! relative paths and loads nothing from the network, so the folder can be opened offline,
//! moved or archived. Each file is written atomically, the page last, and `report-*.svg` files
//! of an earlier report that this one does not write are removed.
//!
//! A missing or partial folder (no `cells.parquet`, `selection.json` or `job.json`) or a data file
//! that is gone is an [`Error::Input`] naming the missing file.

mod bootstrap;
mod figures;
mod html;
mod inputs;
pub(crate) mod plot;
mod response;
mod rules;

use crate::data::Record;
use crate::error::{Error, Result};
use crate::estimate::InitialState;
use crate::estimate::initial_state::model_output;
use crate::export::write_atomically;
use crate::job::DataSpec;
use crate::job::ValidJob;
use crate::reduce::Curve;
use crate::reduce::{Candidate, Selection};
use crate::table::{CellRow, FitKind};
use figures::{Figure, Picked};
use html::{Section, esc};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// Files a finished sweep leaves in its folder.
/// Prefix of the figure files, so a new report can remove the figures of an old one.
const FIGURE_PREFIX: &str = "report-";
/// Samples shown in the simulated-output figures: a readable window of the record.
const OUTPUT_WINDOW: usize = 500;
/// Largest number of k values with a heat-map figure (besides the picks' own k).
const MAX_HEAT_MAPS: usize = 6;

/// Everything the report is drawn from: what the run wrote, and the records for the plots.
struct Review {
    folder: PathBuf,
    rows: Vec<CellRow>,
    selection: Selection,
    /// The job as run (`job.json`) and the program version that ran it.
    job: ValidJob,
    version: Option<String>,
    est: Record,
    val: Option<Record>,
    /// The input level the run took out of the records (`selection.json`'s `input_level`;
    /// files of versions before it ran without levels).
    u0: f64,
    /// Every input's level (one input: `[u0]`; several: `selection.json`'s `input_levels`).
    u0s: Vec<f64>,
}

impl Review {
    /// A table row's model output on a record, in the data's units.
    fn output_of_row(&self, r: &CellRow, rec: &Record, is: InitialState) -> Vec<f64> {
        if r.key.m() > 1 {
            return inputs::output_of_row(r, rec, &self.u0s, is);
        }
        // Each experiment of a list from its own initial state (METHOD.md 16).
        let mut out = Vec::with_capacity(rec.len());
        for e in rec.experiments() {
            let (u, y) = (&rec.u[e.clone()], &rec.y[e]);
            out.extend(model_output(&r.fit.b, &r.fit.f, r.key.delay as usize, r.fit.offset, self.u0, u, y, is));
        }
        out
    }

    fn load(folder: &Path) -> Result<Review> {
        let crate::results::Results { folder, rows, selection, job, version } = crate::results::read_results(folder)?;
        let job_path = folder.join(crate::export::JOB_FILE);
        let gone = |spec: &DataSpec, what: &str| -> Result<()> {
            if spec.path.is_file() {
                Ok(())
            } else {
                Err(Error::input(
                    &spec.path,
                    format!(
                        "missing: the {what} record named in {} is gone; the report re-reads it for the \
                         residuals, the simulated outputs and the spectral estimate",
                        job_path.display()
                    ),
                ))
            }
        };
        for spec in &job.job.data.specs {
            gone(spec, "estimation")?;
        }
        for spec in job.job.validation.iter().flat_map(|v| &v.specs) {
            gone(spec, "validation")?;
        }
        // Shaped as the run shaped them (segments shorter than the grid's largest model left
        // out), so the figures show the samples the models were fitted to.
        let (est, val, _) =
            crate::job::read_records_for(&job.job.data, job.job.validation.as_ref(), &job.largest_structure())?;
        let u0 = selection.input_level.unwrap_or(0.0);
        let u0s = selection.input_levels.clone().unwrap_or_else(|| vec![u0; job.m]);
        Ok(Review { folder, rows, selection, job, version, est, val, u0, u0s })
    }

    /// Input i's name (its column in the record).
    fn input_name(&self, i: usize) -> String {
        self.est.u_names.get(i).cloned().unwrap_or_else(|| format!("u{}", i + 1))
    }

    fn ts(&self) -> f64 {
        self.job.ts()
    }

    /// k of a k index: from the job's grid, else from a row (a grid edited after the run).
    fn k_of(&self, k_index: u32) -> f64 {
        self.job.ks.get(k_index as usize).copied().unwrap_or_else(|| {
            self.rows.iter().find(|r| r.key.k_index == Some(k_index)).and_then(|r| r.k).unwrap_or(f64::NAN)
        })
    }

    /// The Huber row of a candidate (for sigma, iterations, termination, pole radius).
    fn huber_row(&self, c: &Candidate) -> Option<&CellRow> {
        self.rows.iter().find(|r| {
            r.key.kind == FitKind::Huber
                && (r.key.nb, r.key.nf, r.key.delay) == (c.key.nb, c.key.nf, c.key.delay)
                && r.key.more == c.key.more
                && r.key.k_index == Some(c.k_index())
                && r.ok()
        })
    }

    /// The least-squares row of a candidate's order pair.
    fn ls_row(&self, c: &Candidate) -> Option<&CellRow> {
        self.rows.iter().find(|r| {
            r.key.kind == FitKind::Ls
                && (r.key.nb, r.key.nf, r.key.delay) == (c.key.nb, c.key.nf, c.key.delay)
                && r.key.more == c.key.more
                && r.ok()
        })
    }
}

/// Write `report.html` and its figures into `folder`; returns the page's path.
pub fn write_report(folder: &Path) -> Result<PathBuf> {
    let sweep = Review::load(folder)?;
    let sections = build_sections(&sweep)?;

    let mut written = BTreeSet::new();
    for fig in sections.iter().flat_map(|s| &s.figures) {
        let path = folder.join(&fig.file);
        write_atomically(&path, |f| std::io::Write::write_all(f, fig.svg.as_bytes()).map_err(|e| e.to_string()))?;
        written.insert(fig.file.clone());
    }
    remove_stale_figures(folder, &written);

    let page = html::page(&header(&sweep), &sections);
    let path = folder.join(crate::export::REPORT_FILE);
    write_atomically(&path, |f| std::io::Write::write_all(f, page.as_bytes()).map_err(|e| e.to_string()))?;
    Ok(path)
}

/// Remove the report of an earlier table (`report.html` and every `report-*.svg`), when new
/// results replace that table. Best effort, like [`remove_stale_figures`].
pub fn remove_report(folder: &Path) {
    let _ = std::fs::remove_file(folder.join(crate::export::REPORT_FILE));
    remove_stale_figures(folder, &BTreeSet::new());
}

/// Remove `report-*.svg` files of an earlier report (e.g. heat maps of other k). Best effort: a
/// stale figure is harmless, the page does not link it.
fn remove_stale_figures(folder: &Path, keep: &BTreeSet<String>) {
    let Ok(dir) = std::fs::read_dir(folder) else { return };
    for entry in dir.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with(FIGURE_PREFIX) && name.ends_with(".svg") && !keep.contains(&name) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// A drawn figure, or the error naming the file it was meant for.
fn figure(folder: &Path, file: &str, drawn: std::result::Result<Figure, String>) -> Result<Figure> {
    drawn.map_err(|msg| Error::output(folder.join(file), format!("cannot draw the figure: {msg}")))
}

/// Up to [`MAX_HEAT_MAPS`] k indices spread over the grid (all when there are few), plus the
/// picks' k indices.
fn heat_map_indices(n: usize, picks: &[u32]) -> Vec<u32> {
    let mut v: BTreeSet<u32> = if n <= MAX_HEAT_MAPS {
        (0..n as u32).collect()
    } else {
        (0..MAX_HEAT_MAPS).map(|i| ((i * (n - 1)) as f64 / (MAX_HEAT_MAPS - 1) as f64).round() as u32).collect()
    };
    v.extend(picks.iter().copied().filter(|&k| (k as usize) < n.max(1)));
    v.into_iter().collect()
}

/// The page's sections, in order: one function each.
fn build_sections(s: &Review) -> Result<Vec<Section>> {
    let sel = &s.selection;
    let m1 = sel.m1.as_ref().map(|p| Picked { name: "M1", model: &p.model, colour: plot::M1_COLOUR });
    let m2 = sel.m2.as_ref().map(|p| Picked { name: "M2", model: &p.model, colour: plot::M2_COLOUR });
    let grid = GridView::of(s, m2.or(m1));
    let mut sections = vec![picks_section(s, m1, m2), rules::rules_section(s)?];
    if !sel.bootstrap.is_empty() {
        sections.push(bootstrap::bootstrap_section(sel));
    }
    if s.job.m == 1 {
        sections.push(curves_section(s, &grid, m1, m2)?);
        sections.push(maps_section(s, &grid, m1, m2)?);
    } else {
        sections.push(inputs::grid_section(s, lead_pick(s, m1, m2), m1, m2)?);
    }
    sections.push(response::bode_section(s, m1, m2)?);
    sections.extend(response::residual_sections(s, m2.or(m1))?);
    sections.push(files_section());
    Ok(sections)
}

/// The lead rule's pick (`selection.json`'s `rule`), named as M1 or M2 when it is one of them
/// (else "lead"), or M2, M1 when the lead rule picked nothing.
fn lead_pick<'a>(s: &'a Review, m1: Option<Picked<'a>>, m2: Option<Picked<'a>>) -> Option<Picked<'a>> {
    let lead = s.selection.picks.get(&s.selection.rule).and_then(|p| p.model.as_ref());
    match lead {
        Some(c) => {
            let same = |p: &Option<Picked<'a>>| p.filter(|p| p.model.key == c.key);
            Some(same(&m2).or(same(&m1)).unwrap_or(Picked { name: "lead", model: c, colour: plot::LEAD_COLOUR }))
        }
        None => m2.or(m1),
    }
}

/// The rows the grid figures draw: with a delay grid, one delay (the picks', else the first).
struct GridView {
    rows: Vec<CellRow>,
    note: Option<String>,
}

impl GridView {
    fn of(s: &Review, pick: Option<Picked>) -> GridView {
        let delays: BTreeSet<u32> = s.rows.iter().map(|r| r.key.delay).collect();
        let shown_delay = pick.map(|p| p.model.key.delay).or_else(|| delays.first().copied());
        let rows = s.rows.iter().filter(|r| Some(r.key.delay) == shown_delay).cloned().collect();
        let note = (delays.len() > 1).then(|| {
            format!(
                "The table holds delays {}; the grid figures show delay {} (the picks').",
                delays.iter().map(|d| d.to_string()).collect::<Vec<_>>().join(", "),
                shown_delay.unwrap_or(0)
            )
        });
        GridView { rows, note }
    }
}

/// The picks with their least-squares twins, their rules, parameters and best candidates.
fn picks_section(s: &Review, m1: Option<Picked>, m2: Option<Picked>) -> Section {
    let sel = &s.selection;
    let basis_name = sel.basis.column();
    let mut intro = String::new();
    let mut table_rows = Vec::new();
    for (p, class, pick) in [(m1, "m1", &sel.m1), (m2, "m2", &sel.m2)] {
        if let (Some(p), Some(_)) = (p, pick) {
            if let Some(r) = s.huber_row(p.model) {
                table_rows.push(html::PickRow { name: p.name, class, row: r });
            }
            if let Some(r) = s.ls_row(p.model) {
                table_rows.push(html::PickRow { name: "LS", class: "ls", row: r });
            }
        }
    }
    if table_rows.is_empty() {
        intro.push_str("<p class=\"note\">No model was picked: no Huber cell had a usable fit.</p>\n");
    } else {
        intro.push_str(&html::picks_table(&table_rows, basis_name));
    }
    for (name, pick) in [("M1", &sel.m1), ("M2", &sel.m2)] {
        if let Some(p) = pick {
            intro.push_str(&format!("<p class=\"rule\"><b>{name}.</b> {}</p>\n", esc(&p.rule)));
        }
    }
    intro.push_str("<div class=\"params\">\n");
    for (name, pick) in [("M1", &sel.m1), ("M2", &sel.m2)] {
        if let Some(p) = pick {
            let m = &p.model;
            let title = format!(
                "{name}: {}, k = {}, γ = {}",
                m.key.short_label(),
                crate::text::k(m.k()),
                plot::sig(m.gamma(), 4)
            );
            let mut title = title;
            if let Some(c) = m.fit.offset {
                title.push_str(&format!(
                    ", offset {}{}",
                    plot::sig(c, 6),
                    m.evidence.offset_std.map_or(String::new(), |s| format!(" ± {}", plot::sig(s, 2)))
                ));
            }
            if m.key.m() > 1 {
                intro.push_str(&inputs::parameter_tables(s, &title, m));
                continue;
            }
            intro.push_str(&html::parameter_table(
                &title,
                (&m.fit.b, &m.evidence.b_std),
                (&m.fit.f, &m.evidence.f_std),
            ));
        }
    }
    intro.push_str(
        "</div>\n<p class=\"meta\">B(q⁻¹) = b₁ + b₂ q⁻¹ + …, F(q⁻¹) = 1 + f₁ q⁻¹ + …, \
                    y_t = q⁻ᵈ B/F (u_t − u₀) + offset + e_t (cf. paper Tables 2 and 3); ± one standard deviation \
                    (robust covariance, METHOD.md 10). Flags: a residual test failed at the 1 % level (white p: \
                    whiteness of the robust residuals; indep. p: their independence from u), or some parameter's \
                    std exceeds its value.</p>\n",
    );
    for (name, pick) in [("M1", &sel.m1), ("M2", &sel.m2)] {
        if let Some(p) = pick {
            intro.push_str(&format!("<h3>Best {name} candidates</h3>\n"));
            intro.push_str(&html::candidates_table(&p.candidates, basis_name, 10));
        }
    }
    Section { id: "picks", heading: "Picked models".into(), intro_html: intro, figures: vec![], notes: vec![] }
}

/// W and L1C over nF at the picks' k (paper Figs. 10 and 12).
fn curves_section(s: &Review, grid: &GridView, m1: Option<Picked>, m2: Option<Picked>) -> Result<Section> {
    let (folder, sel) = (&s.folder, &s.selection);
    let grid_rows = &grid.rows;
    let mut figs = Vec::new();
    let mut notes: Vec<String> = grid.note.iter().cloned().collect();
    let first_k = grid_rows.iter().filter_map(|r| r.key.k_index).min();
    for (curve, pick, file) in [(Curve::W, m1, "report-w-nf.svg"), (Curve::L1c, m2, "report-l1c-nf.svg")] {
        match pick.map(|p| p.model.k_index()).or(first_k) {
            Some(ki) => figs.push(figure(
                folder,
                file,
                figures::curve_figure(grid_rows, curve, (ki, s.k_of(ki)), sel.min_tolerance, pick, "", file),
            )?),
            None => notes.push(format!("{file}: the table has no Huber cell to draw.")),
        }
    }
    Ok(Section {
        id: "curves",
        heading: "Order choice: W and L1C over nF".into(),
        intro_html: "<p>The picks are local minima over nF of these curves (one curve per nB and k), chosen \
                     by their fit. The figures show the curves at the k of each pick.</p>\n"
            .into(),
        figures: figs,
        notes,
    })
}

/// Heat maps over (nB, nF) and the picks against k.
fn maps_section(s: &Review, grid: &GridView, m1: Option<Picked>, m2: Option<Picked>) -> Result<Section> {
    let (folder, sel) = (&s.folder, &s.selection);
    let grid_rows = &grid.rows;
    let picks: Vec<Picked> = m1.into_iter().chain(m2).collect();
    let pick_ks: Vec<u32> = picks.iter().map(|p| p.model.k_index()).collect();
    let mut figs = Vec::new();
    let n_k = s.job.ks.len().max(s.rows.iter().filter_map(|r| r.key.k_index).max().map_or(0, |m| m as usize + 1));
    for ki in heat_map_indices(n_k, &pick_ks) {
        let file = format!("{FIGURE_PREFIX}heat-k{ki:02}.svg");
        figs.push(figure(
            folder,
            &file,
            figures::heat_figure(grid_rows, ki, s.k_of(ki), sel.basis, &picks, "", &file),
        )?);
    }
    let file = "report-picks-k.svg";
    figs.push(figure(folder, file, figures::picks_by_k_figure(grid_rows, &s.job.ks, sel, None, file))?);
    let shown = if n_k <= MAX_HEAT_MAPS { "every k of the grid" } else { "k spread over the grid and the picks' k" };
    Ok(Section {
        id: "maps",
        heading: "The whole grid: heat maps and the picks against k".into(),
        intro_html: format!("<p>Heat maps for {shown} ({} of {n_k}).</p>\n", figs.len() - 1),
        figures: figs,
        notes: vec![],
    })
}

/// Links to the result files.
fn files_section() -> Section {
    Section {
        id: "files",
        heading: "Result files".into(),
        intro_html: format!(
            "<ul>\n<li><a href=\"{cells}\">{cells}</a>: one row per Huber cell and per least-squares fit \
             (columns in the README)</li>\n<li><a href=\"{selection}\">{selection}</a>: the picks, their rules and \
             candidate lists</li>\n<li><a href=\"{job}\">{job}</a>: the job as run</li>\n</ul>\n",
            cells = crate::export::CELLS_FILE,
            selection = crate::export::SELECTION_FILE,
            job = crate::export::JOB_FILE,
        ),
        figures: vec![],
        notes: vec![],
    }
}

/// Facts about the sweep shown at the top of the page.
fn header(s: &Review) -> html::Header {
    let j = &s.job.job;
    let huber = s.rows.iter().filter(|r| r.key.kind == FitKind::Huber).count();
    let ls = s.rows.iter().filter(|r| r.key.kind == FitKind::Ls).count();
    let record = |r: &Record| {
        format!(
            "<code>{}</code>: {} samples, u = {}, y = {}",
            esc(&r.path.display().to_string()),
            r.len(),
            esc(&r.u_names.join(", ")),
            esc(&r.y_name)
        )
    };
    let (kmin, kmax) = s.job.ks.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), k| (a.min(*k), b.max(*k)));
    let mut facts = vec![
        ("estimation record".to_string(), record(&s.est)),
        (
            "sampling period".to_string(),
            format!("{} s (Nyquist {} Hz)", plot::short(s.ts()), plot::short(0.5 / s.ts())),
        ),
    ];
    if let Some(v) = &s.val {
        facts.push(("validation record".into(), record(v)));
    }
    let range = |v: &[usize]| format!("{}..{}", v[0], v[v.len() - 1]);
    let orders = if s.job.m == 1 {
        format!("nB {}, nF {}", range(&s.job.nb), range(&s.job.nf))
    } else {
        let per_input: Vec<String> = (0..s.job.m)
            .map(|i| {
                let g = &s.job.grids[i];
                let delays: Vec<String> = g.delays.iter().map(usize::to_string).collect();
                let name = esc(&s.input_name(i));
                format!("{name}: nB {}, nF {}, delay {}", range(&g.nb), range(&g.nf), delays.join(", "))
            })
            .collect();
        per_input.join("; ")
    };
    facts.push((
        "grid".into(),
        format!(
            "{orders}, {} values of k from {} to {}, Huber fits start from <code>{}</code>",
            s.job.ks.len(),
            plot::short(kmin),
            plot::short(kmax),
            j.start.as_str()
        ),
    ));
    facts.push((
        "cells".into(),
        format!("{huber} Huber cells ({} failed), {ls} least-squares fits", s.selection.failed),
    ));
    facts.push((
        "signal levels".into(),
        format!(
            "offset <code>{}</code>, input level u0 = {} taken out; fits judged with initial state <code>{}</code>",
            j.offset.as_str(),
            if s.job.m == 1 {
                plot::short(s.u0)
            } else {
                format!("[{}]", s.u0s.iter().map(|v| plot::short(*v)).collect::<Vec<_>>().join(", "))
            },
            j.initial_state.as_str()
        ),
    ));
    for w in &s.selection.warnings {
        facts.push(("warning".into(), esc(w)));
    }
    facts.push((
        "fit band".into(),
        j.band_hz.map(|[a, b]| format!("{} to {} Hz", plot::short(a), plot::short(b))).unwrap_or_else(|| "none".into()),
    ));
    facts.push((
        "model choice".into(),
        format!(
            "ranked by <code>{}</code>; local-minimum tolerance {}, ties within {} points",
            s.selection.basis.column(),
            s.selection.min_tolerance,
            s.selection.fit_tolerance
        ),
    ));
    html::Header { name: j.name.clone(), folder: s.folder.display().to_string(), version: s.version.clone(), facts }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_maps_cover_the_grid_and_the_picks() {
        assert_eq!(heat_map_indices(3, &[1]), vec![0, 1, 2]);
        assert_eq!(heat_map_indices(12, &[]), vec![0, 2, 4, 7, 9, 11]);
        assert_eq!(heat_map_indices(40, &[3, 3]), vec![0, 3, 8, 16, 23, 31, 39]);
    }
}
