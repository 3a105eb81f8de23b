//! How the commands print their outcomes (stdout: results; stderr: notes and warnings).

use crate::engine::{FitReport, Prepared};
use crate::error::Result;
use crate::plan::Plan;
use crate::{reduce, shard};
use std::path::PathBuf;

pub(super) fn opt_pct(v: Option<f64>) -> String {
    v.map_or_else(|| "-".to_string(), |x| format!("{x:.2} %"))
}

/// What was missing in the records and what became of it (selection.json's `gaps`, METHOD.md
/// 21.1): a line per record that missed anything, none for complete records.
pub(super) fn print_gaps(gaps: Option<&crate::data::RecordGaps>) {
    for (name, g) in gaps.into_iter().flat_map(|g| [("data", &g.data), ("validation", &g.validation)]) {
        if let Some(g) = g {
            outln!("gaps       {name}: {}", g.describe());
        }
    }
}

pub(super) fn print_fit_summary(r: &FitReport) {
    let h = &r.huber;
    let l = &r.ls;
    match r.structure.single() {
        Some(_) => outln!("OE(nB={}, nF={}) delay {} on {} ({} samples)", r.nb, r.nf, r.delay, r.data.display(), r.n),
        None => outln!("{} on {} ({} samples)", r.structure.label(), r.data.display(), r.n),
    }
    if let (Some(p), Some(c)) = (&r.validation, &r.validation_column) {
        outln!("validation: {} (column '{c}')", p.display());
    }
    outln!();
    outln!("{:<22}{:>18}{:>18}", "", "least squares", format!("Huber k={}", crate::text::k(h.k)));
    outln!("{:<22}{:>18.6e}{:>18.6e}", "criterion", l.criterion, h.criterion);
    outln!("{:<22}{:>18}{:>18.6e}", "gamma", "-", h.gamma);
    outln!("{:<22}{:>18.6e}{:>18}", "sigma", l.sigma, "");
    outln!("{:<22}{:>18}{:>18}", "L1C", "-", format!("{:.2} %", 100.0 * h.l1c));
    outln!("{:<22}{:>18}{:>18}", "fit (estimation)", opt_pct(Some(l.assessment.fit)), opt_pct(Some(h.assessment.fit)));
    outln!("{:<22}{:>18}{:>18}", "fit (validation)", opt_pct(l.assessment.fit_val), opt_pct(h.assessment.fit_val));
    outln!("{:<22}{:>18}{:>18}", "fit (band)", opt_pct(l.assessment.fit_band), opt_pct(h.assessment.fit_band));
    // Several inputs: each input's band fit (the line above is their mean).
    let input_band = |a: &crate::estimate::Assessment, i: usize| a.fit_band_inputs.as_ref().map(|v| v[i]);
    for i in 0..h.assessment.fit_band_inputs.as_ref().map_or(0, Vec::len) {
        let label = format!("fit (band, input {})", i + 1);
        outln!(
            "{:<22}{:>18}{:>18}",
            label,
            opt_pct(input_band(&l.assessment, i)),
            opt_pct(input_band(&h.assessment, i))
        );
    }
    outln!("{:<22}{:>18}{:>18}", "iterations", l.iterations, h.iterations);
    outln!("{:<22}{:>18} {:>17}", "termination", l.termination.as_str(), h.termination.as_str());
    outln!("{:<22}{:>18.6}{:>18.6}", "max pole radius", l.assessment.max_pole_radius, h.assessment.max_pole_radius);
    let (le, he) = (&l.assessment.evidence, &h.assessment.evidence);
    // Not computed prints as NaN, as the table's null reads in numpy.
    let v = |x: Option<f64>| x.unwrap_or(f64::NAN);
    outln!("{:<22}{:>18.3e}{:>18.3e}", "max std/|value|", v(le.max_rel_std), v(he.max_rel_std));
    outln!("{:<22}{:>18.4}{:>18.4}", "residuals white p", v(le.resid_white_p), v(he.resid_white_p));
    outln!("{:<22}{:>18.4}{:>18.4}", "resid. indep. of u p", v(le.resid_indep_p), v(he.resid_indep_p));
    outln!();
    let with_std = |v: &[f64], s: &[f64]| {
        v.iter().zip(s).map(|(v, s)| format!("{v:.6e} +/- {s:.1e}")).collect::<Vec<_>>().join(", ")
    };
    let s = &r.structure;
    let (bs, bstd, fs, fstd) = (s.split_b(&h.b), s.split_b(&he.b_std), s.split_f(&h.f), s.split_f(&he.f_std));
    for i in 0..s.m() {
        // One input keeps its unnumbered lines; several are numbered after their inputs.
        let input = if s.m() == 1 { String::new() } else { format!(" (u{})", i + 1) };
        outln!("Huber b{input} = [{}]", with_std(&bs[i], &bstd[i]));
        outln!("Huber f{input} = [{}]", with_std(&fs[i], &fstd[i]));
    }
    match h.offset {
        Some(c) => outln!(
            "offset = {c}{} ({}; input level u0 = {} taken out)",
            he.offset_std.map_or(String::new(), |s| format!(" +/- {s:.1e}")),
            r.offset_mode.as_str(),
            levels(&r.input_level)
        ),
        None => outln!("offset: none (the paper's model)"),
    }
    outln!("initial state of the judged fits: {}", r.initial_state.as_str());
    outln!("Huber fit from start '{}'", r.start);
    if let Some(b) = &r.bootstrap {
        print_bootstrap(r, b);
    }
    outln!("({:.3} s)", r.seconds);
}

/// Input levels as the summary prints them: one number for one input, a list for several.
fn levels(u0: &[f64]) -> String {
    match u0 {
        [one] => one.to_string(),
        all => format!("[{}]", all.iter().map(f64::to_string).collect::<Vec<_>>().join(", ")),
    }
}

/// The bootstrap's intervals beside the sandwich std (METHOD.md 17.3).
fn print_bootstrap(r: &FitReport, b: &crate::estimate::bootstrap::Bootstrap) {
    let he = &r.huber.assessment.evidence;
    let stds: Vec<f64> = he.b_std.iter().chain(&he.f_std).copied().chain(he.offset_std).collect();
    outln!();
    print_intervals(&r.parameters, &r.huber.theta(), &stds, b, r.ts);
}

/// A pick's bootstrap (the job's `uncertainty`), one block per model.
pub(super) fn print_pick_bootstraps(selection: &reduce::Selection) {
    for p in &selection.bootstrap {
        let rules = p.rules.iter().map(|r| r.as_str()).collect::<Vec<_>>().join(", ");
        let k = p.k.map_or("least squares".to_string(), |k| format!("k = {}", crate::text::k(k)));
        outln!();
        outln!("{} {k} (picked by {rules})", p.label());
        let stds: Vec<f64> = p.sandwich_std.iter().map(|s| s.unwrap_or(f64::NAN)).collect();
        print_intervals(&p.parameters, &p.values, &stds, &p.intervals, Some(p.ts));
    }
}

/// The bootstrap's parameter intervals beside the values and sandwich std, and its intervals
/// of the frequency response (in Hz when the sampling period is known).
fn print_intervals(
    names: &[String],
    values: &[f64],
    stds: &[f64],
    b: &crate::estimate::bootstrap::Bootstrap,
    ts: Option<f64>,
) {
    let pct = 100.0 * b.level;
    outln!(
        "bootstrap: {} replicates ({} failed, {} on the stability boundary), residual blocks of {}, seed {}",
        b.replicates,
        b.failed,
        b.boundary,
        b.block,
        b.seed
    );
    outln!(
        "{:<10}{:>15}{:>12}{:>12}{:>29}",
        "parameter",
        "value",
        "std",
        "boot std",
        format!("{pct} % percentile interval")
    );
    for (i, (name, iv)) in names.iter().zip(&b.parameters).enumerate() {
        let (v, s) = (values.get(i).copied().unwrap_or(f64::NAN), stds.get(i).copied().unwrap_or(f64::NAN));
        outln!("{name:<10}{v:>15.6e}{s:>12.2e}{:>12.2e}    [{:.6e}, {:.6e}]", iv.std, iv.lower, iv.upper);
    }
    let hz =
        |w: f64| ts.map_or(format!("{:.4} rad/sample", w), |ts| format!("{:.4} Hz", w / (std::f64::consts::TAU * ts)));
    // One table per input (one input: G's, as before).
    let several = b.magnitude.len() > 1;
    for (i, (mags, phases)) in b.magnitude.iter().zip(&b.phase_deg).enumerate() {
        let g = if several { format!("|G_{}| interval", i + 1) } else { "|G| interval".to_string() };
        let phase = if several { format!("phase of G_{} (deg)", i + 1) } else { "phase interval (deg)".to_string() };
        outln!("{:<22}{:>36}{:>36}", "frequency", g, phase);
        for ((w, m), p) in b.frequencies.iter().zip(mags).zip(phases) {
            outln!(
                "{:<22}{:>36}{:>36}",
                hz(*w),
                format!("[{:.5e}, {:.5e}]", m.lower, m.upper),
                format!("[{:.2}, {:.2}]", p.lower, p.upper)
            );
        }
    }
}

pub(super) fn describe_grid(p: &Prepared) -> String {
    let (job, ks) = (&p.job, &p.job.ks);
    let (kmin, kmax) = ks.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &k| (a.min(k), b.max(k)));
    if job.m > 1 {
        // Several inputs: each input's ranges, then the product the sweep runs.
        let span = |v: &[usize]| {
            if v[0] == v[v.len() - 1] { v[0].to_string() } else { format!("{}..{}", v[0], v[v.len() - 1]) }
        };
        let inputs: Vec<String> = job
            .grids
            .iter()
            .enumerate()
            .map(|(i, g)| format!("u{}: nB {} x nF {} x delay {}", i + 1, span(&g.nb), span(&g.nf), span(&g.delays)))
            .collect();
        return format!(
            "{}; their product: {} structures x {} values of k in [{kmin}, {kmax}]; offset {}, initial state {}",
            inputs.join("; "),
            p.plan.pairs.len(),
            ks.len(),
            job.job.offset.as_str(),
            job.job.initial_state.as_str(),
        );
    }
    let (d0, d1) = (job.delays[0], job.delays[job.delays.len() - 1]);
    let delays = if d0 == d1 { format!("delay {d0}") } else { format!("delay {d0}..{d1}") };
    format!(
        "nB {}..{} x nF {}..{} x {delays} x {} values of k in [{kmin}, {kmax}]; offset {}, initial state {}",
        job.nb[0],
        job.nb[job.nb.len() - 1],
        job.nf[0],
        job.nf[job.nf.len() - 1],
        ks.len(),
        job.job.offset.as_str(),
        job.job.initial_state.as_str(),
    )
}

/// The shard layout of `oesweep plan --shards N`: per shard its pairs, cells and estimated cost.
pub(super) fn print_layout(plan: &Plan, n: usize) {
    let layout = shard::layout(plan, n);
    let total: f64 = (0..plan.pairs.len()).map(|p| shard::pair_cost(plan, p)).sum();
    outln!("shards     {n} (run each with `oesweep run JOB --shard I/{n}`, then `oesweep merge OUTPUT`)");
    outln!("{:>7} {:>6} {:>7} {:>11} {:>7}  order pairs (nB,nF)", "shard", "pairs", "cells", "est. cost", "share");
    for (i, pairs) in layout.iter().enumerate() {
        let cost: f64 = pairs.iter().map(|&p| shard::pair_cost(plan, p)).sum();
        let list: Vec<String> =
            pairs.iter().map(|&p| format!("({},{})", plan.pairs[p].one().nb, plan.pairs[p].one().nf)).collect();
        outln!(
            "{:>7} {:>6} {:>7} {:>11} {:>6.1}%  {}",
            format!("{i}/{n}"),
            pairs.len(),
            pairs.len() * plan.ks.len(),
            cost,
            100.0 * cost / total.max(1.0),
            list.join(" ")
        );
    }
}

/// M1, M2 and the lead rule's pick, each with its score under the name of the fit column that
/// ranked it (`fit_val`, `fit_band` or `fit`): the estimation fit `fit` is another number.
/// A picked model's name: `OE(nB, nF)` (with `delay d`) for one input, every input's orders
/// for several.
fn model_name(key: &crate::table::RowKey, with_delay: bool) -> String {
    match key.m() {
        1 if with_delay => format!("OE({}, {}) delay {}", key.nb, key.nf, key.delay),
        1 => format!("OE({}, {})", key.nb, key.nf),
        _ => key.structure().label(),
    }
}

pub(super) fn print_picks(selection: &reduce::Selection) {
    let basis = selection.basis.column();
    for (label, pick) in [("M1 (W minima)  ", &selection.m1), ("M2 (L1C minima)", &selection.m2)] {
        match pick {
            Some(m) => outln!(
                "{label} {} k = {} gamma = {:.4e}  W = {:.4e}  L1C = {:.2} %  {basis} = {}",
                model_name(&m.model.key, false),
                crate::text::k(m.model.k()),
                m.model.gamma(),
                m.model.criterion(),
                100.0 * m.model.l1c(),
                opt_pct(Some(m.model.score))
            ),
            None => outln!("{label} none (no usable cell)"),
        }
    }
    let rule = selection.rule;
    match selection.picks.get(&rule).and_then(|p| p.model.as_ref()) {
        Some(m) => outln!(
            "pick ({}) {}{}  {} = {}",
            rule.as_str(),
            model_name(&m.key, true),
            m.row.k.map_or(" (least squares)".to_string(), |k| format!(" k = {}", crate::text::k(k))),
            basis,
            opt_pct(Some(m.score).filter(|v| v.is_finite()))
        ),
        None => outln!("pick ({}) none", rule.as_str()),
    }
}

/// Every pick rule's model, the lead rule first marked with `*` (selection.json's `picks`).
pub(super) fn print_rules(selection: &reduce::Selection) {
    if selection.picks.is_empty() {
        return;
    }
    let basis = selection.basis.column();
    outln!("{:<12}{:<22}{:>8}{:>24}{:>12}{:>10}{:>8}", "rule", "model", "k", "value", basis, "indep p", "cancel");
    for (rule, pick) in &selection.picks {
        let lead = if *rule == selection.rule { "*" } else { " " };
        let Some(m) = &pick.model else {
            outln!("{lead}{:<11}none: {}", rule.as_str(), pick.why);
            continue;
        };
        let k = m.row.k.map_or("-".to_string(), crate::text::k);
        let value = pick.value.map_or("-".to_string(), |v| format!("{} {v:.6}", pick.measure));
        let score = Some(m.score).filter(|v| v.is_finite());
        outln!(
            "{lead}{:<11}{:<22}{:>8}{:>24}{:>12}{:>10}{:>8}",
            rule.as_str(),
            if m.key.m() == 1 {
                format!("OE({},{}) delay {}", m.key.nb, m.key.nf, m.key.delay)
            } else {
                m.key.structure().label()
            },
            k,
            value,
            opt_pct(score),
            m.evidence.resid_indep_p.map_or("-".to_string(), |p| format!("{p:.3}")),
            m.evidence.cancellations.map_or("-".to_string(), |c| c.to_string()),
        );
    }
    let why = if selection.rule_why.is_empty() { selection.rule.as_str() } else { selection.rule_why.as_str() };
    outln!("(* the rule the summary leads with, {why}; every rule's reason is in selection.json's picks)");
}

/// The page of a report, or its error after the summary was printed.
pub(super) fn print_report(report: Option<Result<PathBuf>>) -> Result<()> {
    if let Some(page) = report {
        outln!("report in {}", page?.display());
    }
    Ok(())
}

/// `oesweep spectrum`'s table: per usable bin, |G| in dB with its band, phase, coherence
/// (several inputs: one table per input, the multiple coherence in each).
pub(super) fn print_spectrum(r: &crate::engine::SpectrumReport) {
    outln!(
        "{} ({} samples): {} estimate, {} segments of {}{}",
        r.data.display(),
        r.n,
        r.method.as_str(),
        r.segments,
        r.segment,
        if r.replaced > 0 { format!(", {} output samples cleaned", r.replaced) } else { String::new() }
    );
    let db = |v: f64| if v > 0.0 { 20.0 * v.log10() } else { f64::NEG_INFINITY };
    for i in 0..r.re.len() {
        if r.re.len() > 1 {
            outln!("input {} ({}):", i + 1, r.u.get(i).map_or("", String::as_str));
        }
        outln!(
            "{:>14} {:>12} {:>12} {:>12} {:>10} {:>10}",
            "freq_hz",
            "|G| dB",
            "lower dB",
            "upper dB",
            "phase deg",
            "coherence"
        );
        let (re, im) = (&r.re[i], &r.im[i]);
        for k in 0..r.freq_hz.len() {
            outln!(
                "{:>14.6} {:>12.3} {:>12.3} {:>12.3} {:>10.2} {:>10.4}",
                r.freq_hz[k],
                db(re[k].hypot(im[k])),
                db(r.mag_lower[i][k]),
                db(r.mag_upper[i][k]),
                im[k].atan2(re[k]).to_degrees(),
                r.coherence[k]
            );
        }
    }
}
