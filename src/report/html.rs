//! The page: `report.html`, one self-contained file with inline CSS that links the SVG figures
//! beside it by relative paths (so the folder can be moved, zipped or served as it is) and loads
//! nothing from the network.

use super::figures::Figure;
use super::plot::sig;
use crate::reduce::Candidate;
use crate::table::CellRow;
use std::fmt::Write;

/// A section of the page: a heading, an introduction, figures and notes (e.g. why a figure is
/// absent).
pub struct Section {
    pub id: &'static str,
    pub heading: String,
    /// Raw HTML (already escaped by the caller).
    pub intro_html: String,
    pub figures: Vec<Figure>,
    pub notes: Vec<String>,
}

/// Escape text for HTML content and attribute values.
pub fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite()).map(|v| sig(v, digits)).unwrap_or_else(|| "–".into())
}

fn pct(v: Option<f64>) -> String {
    v.filter(|v| v.is_finite()).map(|v| format!("{v:.2}")).unwrap_or_else(|| "–".into())
}

const CSS: &str = "
body { font-family: system-ui, -apple-system, 'Segoe UI', Roboto, 'DejaVu Sans', sans-serif; color: #222;
       max-width: 1320px; margin: 0 auto; padding: 1.2em 1.5em 4em; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 2.2em; border-bottom: 1px solid #ddd; padding-bottom: 0.2em; }
h3 { font-size: 1.05em; margin-top: 1.4em; }
.meta { color: #555; font-size: 0.92em; }
nav a { margin-right: 1em; }
table { border-collapse: collapse; font-size: 0.9em; margin: 0.6em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.55em; text-align: right; }
th { background: #f3f3f3; }
td.l, th.l { text-align: left; }
tr.m1 td:first-child { border-left: 5px solid #d62728; }
tr.m2 td:first-child { border-left: 5px solid #ff7f0e; }
tr.ls td:first-child { border-left: 5px solid #1f77b4; }
.params { display: flex; flex-wrap: wrap; gap: 2em; }
figure { margin: 1.4em 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #e3e3e3; }
figcaption { font-size: 0.9em; color: #444; margin-top: 0.3em; }
.rule { font-size: 0.9em; color: #333; background: #fafafa; border-left: 3px solid #bbb; padding: 0.3em 0.8em; }
.note { color: #8a5a00; }
code { font-size: 0.95em; }
";

/// What the page header says about the sweep.
pub struct Header {
    pub name: String,
    pub folder: String,
    pub version: Option<String>,
    /// Lines of "label: value" facts (raw HTML, escaped by the caller).
    pub facts: Vec<(String, String)>,
}

/// The full page.
pub fn page(header: &Header, sections: &[Section]) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>oesweep report: {}</title>\n<style>{CSS}</style>\n</head>\n<body>\n",
        esc(&header.name)
    );
    let _ = writeln!(h, "<h1>Review report: {}</h1>", esc(&header.name));
    let _ = writeln!(
        h,
        "<p class=\"meta\">Results folder <code>{}</code>{}. Written by <code>oesweep report</code>; every \
         figure is an SVG file beside this page (click one to open it at full size).</p>",
        esc(&header.folder),
        header.version.as_ref().map(|v| format!(", sweep run by oesweep {}", esc(v))).unwrap_or_default()
    );
    h.push_str("<table>\n");
    for (k, v) in &header.facts {
        let _ = writeln!(h, "<tr><th class=\"l\">{}</th><td class=\"l\">{v}</td></tr>", esc(k));
    }
    h.push_str("</table>\n<nav>");
    for s in sections {
        let _ = write!(h, "<a href=\"#{}\">{}</a>", s.id, esc(&s.heading));
    }
    h.push_str("</nav>\n");
    for s in sections {
        let _ = writeln!(h, "<section id=\"{}\">\n<h2>{}</h2>", s.id, esc(&s.heading));
        h.push_str(&s.intro_html);
        for n in &s.notes {
            let _ = writeln!(h, "<p class=\"note\">{}</p>", esc(n));
        }
        for f in &s.figures {
            let _ = writeln!(
                h,
                "<figure>\n<a href=\"{file}\"><img src=\"{file}\" alt=\"{alt}\"></a>\n<figcaption>{cap}</figcaption>\n</figure>",
                file = esc(&f.file),
                alt = esc(&f.alt),
                cap = esc(&f.caption)
            );
        }
        h.push_str("</section>\n");
    }
    h.push_str("</body>\n</html>\n");
    h
}

/// One line of the picks table.
pub struct PickRow<'a> {
    /// "M1", "M2" or "LS".
    pub name: &'static str,
    /// CSS class of the row.
    pub class: &'static str,
    pub row: &'a CellRow,
}

/// The picks table (Tables 2 and 3 of the paper give the parameters; this adds the numbers the
/// choice was made on).
pub fn picks_table(rows: &[PickRow<'_>], basis_column: &str) -> String {
    // Eleven columns, related numbers paired in one cell, so that the table fits a 1300-pixel
    // window (tests/report.rs checks it in Chromium); sigma is gamma / k.
    let mut h = String::from(
        "<table>\n<tr><th class=\"l\">model</th><th class=\"l\">orders</th><th>k</th><th>γ = kσ</th>\
         <th>W</th><th>L1C [%]</th><th>fit / val / band [%]</th><th>max |pole|</th><th class=\"l\">solver</th>\
         <th>max std/|θ|</th><th>white / indep. p</th><th class=\"l\">flags</th></tr>\n",
    );
    for p in rows {
        let r = p.row;
        let fits = format!("{} / {} / {}", pct(r.fit.fit), pct(r.fit.fit_val), pct(r.fit.fit_band));
        let solver = format!(
            "{} it., {}",
            r.fit.iterations.map(|v| v.to_string()).unwrap_or_else(|| "–".into()),
            esc(r.fit.termination.as_deref().unwrap_or("–"))
        );
        let tests = format!("{} / {}", opt(r.evidence.resid_white_p, 3), opt(r.evidence.resid_indep_p, 3));
        let _ = writeln!(
            h,
            "<tr class=\"{}\"><td class=\"l\">{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td><td>{fits}</td><td>{}</td><td class=\"l\">{solver}</td><td>{}</td><td>{tests}</td>\
             <td class=\"l\">{}</td></tr>",
            p.class,
            p.name,
            orders(&r.key),
            opt(r.k, 4),
            opt(r.fit.gamma, 4),
            opt(r.fit.criterion, 4),
            r.fit.l1c.map(|v| format!("{:.2}", 100.0 * v)).unwrap_or_else(|| "–".into()),
            opt(r.fit.max_pole_radius, 4),
            opt(r.evidence.max_rel_std, 3),
            esc(&flags(r).join("; ")),
        );
    }
    h.push_str("</table>\n");
    let _ = writeln!(
        h,
        "<p class=\"meta\">W is the Huber criterion for the picks and (1/N) Σ e²/2 for the least-squares (LS) \
         fits of the same orders. The picks are ranked by <code>{}</code>.</p>",
        esc(basis_column)
    );
    h
}

/// A row's orders as the tables show them: `OE(nB,nF), d = D` for one input, the structure's
/// label (`OE(2,1 d1; 1,1 d0)`) for several.
pub fn orders(key: &crate::table::RowKey) -> String {
    if key.m() == 1 { format!("OE({},{}), d = {}", key.nb, key.nf, key.delay) } else { key.label() }
}

/// Significance level of the residual tests' flags.
pub const TEST_LEVEL: f64 = 0.01;

/// What an engineer should look at before building on a model: a failed residual test, a
/// parameter whose standard deviation exceeds its value.
pub fn flags(r: &CellRow) -> Vec<&'static str> {
    let mut out = Vec::new();
    if r.evidence.resid_white_p.is_some_and(|p| p < TEST_LEVEL) {
        out.push("residuals not white");
    }
    if r.evidence.resid_indep_p.is_some_and(|p| p < TEST_LEVEL) {
        out.push("residuals depend on u");
    }
    if r.evidence.max_rel_std.is_some_and(|v| v > 1.0) {
        out.push("a parameter's std exceeds its value");
    }
    out
}

/// Parameter table of one model: B = b_1 + b_2 q^-1 + ..., F = 1 + f_1 q^-1 + ..., each with
/// its standard deviation when known (`b_std`, `f_std`; empty slices: not known).
pub fn parameter_table(title: &str, (b, b_std): (&[f64], &[f64]), (f, f_std): (&[f64], &[f64])) -> String {
    let mut h = format!("<div><h3>{}</h3>\n<table>\n<tr><th>i</th><th>b_i</th><th>f_i</th></tr>\n", esc(title));
    for i in 0..b.len().max(f.len()) {
        let cell = |v: Option<&f64>, s: Option<&f64>| match (v, s) {
            (Some(v), Some(s)) => format!("{v:.6e} ± {s:.1e}"),
            (Some(v), None) => format!("{v:.6e}"),
            _ => String::new(),
        };
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td></tr>",
            i + 1,
            cell(b.get(i), b_std.get(i)),
            cell(f.get(i), f_std.get(i))
        );
    }
    h.push_str("</table></div>\n");
    h
}

/// The best candidates of a pick, as a short table.
pub fn candidates_table(candidates: &[Candidate], basis_column: &str, limit: usize) -> String {
    let mut h = format!(
        "<table>\n<tr><th>#</th><th class=\"l\">orders</th><th>k</th><th>W</th><th>L1C [%]</th><th>{}</th></tr>\n",
        esc(basis_column)
    );
    for (i, c) in candidates.iter().take(limit).enumerate() {
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{:.2}</td><td>{:.3}</td></tr>",
            i + 1,
            c.key.short_label(),
            super::plot::short(c.k()),
            sig(c.criterion(), 4),
            100.0 * c.l1c(),
            c.score
        );
    }
    h.push_str("</table>\n");
    if candidates.len() > limit {
        let _ = writeln!(h, "<p class=\"meta\">… and {} more in selection.json.</p>", candidates.len() - limit);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping() {
        assert_eq!(esc("a<b & \"c\"'"), "a&lt;b &amp; &quot;c&quot;&#39;");
    }

    #[test]
    fn page_links_figures_relatively() {
        let fig = Figure { file: "report-x.svg".into(), alt: "x <1>".into(), caption: "c".into(), svg: String::new() };
        let s = Section { id: "a", heading: "A".into(), intro_html: String::new(), figures: vec![fig], notes: vec![] };
        let h = Header { name: "n".into(), folder: "/f".into(), version: None, facts: vec![] };
        let p = page(&h, &[s]);
        assert!(p.contains("<img src=\"report-x.svg\" alt=\"x &lt;1&gt;\">"), "{p}");
        assert!(!p.contains("http://") && !p.contains("https://"));
    }
}
