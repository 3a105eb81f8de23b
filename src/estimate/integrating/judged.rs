//! The integrating-plant test judged against fitted models (METHOD.md 7.3): their residuals'
//! drift and pole radii, and the warnings that name the record and, for several inputs, the
//! input.

use super::{BOUNDARY, HUBER_K, MAX_ROWS, PoleTest, Z95, long_run_sum, robust_scale};
use crate::estimate::fit::Judge;
use crate::estimate::initial_state::{InitialState, Scratch};
use crate::estimate::problem::Problem;
use crate::oe;
use crate::oe::Structure;

/// A model fitted to the record, against which the test is judged: its name in the warning
/// (e.g. "OE(2,2) delay 1 (picked by rbic)"), its largest pole radius, and its residuals'
/// [`drift_statistic`] (None when the radius alone decides: a pole on the stability boundary).
#[derive(Clone, Debug, PartialEq)]
pub struct Judged {
    pub name: String,
    pub radius: f64,
    pub drift: Option<f64>,
}

/// The 5 % point of the KPSS level statistic (Kwiatkowski, Phillips, Schmidt and Shin 1992,
/// table 1): above it the residuals drift.
pub const DRIFT_LEVEL: f64 = 0.463;

/// Whether a model with this pole radius is judged by its residuals (inside the stability
/// boundary) or agrees with the test by its radius alone.
pub fn judged_by_residuals(radius: f64) -> bool {
    radius < BOUNDARY
}

/// The KPSS statistic of the model `theta`'s residuals on the record `prob` as tested (its
/// head of [`MAX_ROWS`]), the initial state of each experiment fitted (the transient of a slow
/// model started from rest is no drift): see [`drift_statistic`]. With missing outputs, of the
/// observed residuals one after the other within each experiment (METHOD.md 21.3).
pub fn residual_drift(prob: &Problem, theta: &[f64]) -> f64 {
    let rows = prob.n().min(MAX_ROWS);
    // Several inputs' heads are copied (their columns are not contiguous in a head).
    let heads: Vec<f64>;
    let prob = if prob.m() == 1 || rows == prob.n() {
        prob.head(rows)
    } else {
        heads = (0..prob.m()).flat_map(|i| prob.input(i)[..rows].iter().copied()).collect();
        let seams = &prob.seams[..prob.seams.partition_point(|&s| s < rows)];
        let missing = &prob.missing[..prob.missing.partition_point(|&t| t < rows)];
        Problem { u: &heads, y: &prob.y[..rows], seams, missing, ..*prob }
    };
    let mut r = prob.simulate_vec(theta);
    let judge = Judge { initial_state: InitialState::Estimate, ..Judge::default() };
    judge.judge_output(&prob, theta, prob.y, &mut r, &mut Scratch::default());
    r.iter_mut().zip(prob.y).for_each(|(r, y)| *r = y - *r);
    if prob.missing.is_empty() {
        return drift_statistic(&r, prob.seams);
    }
    let (mut observed, mut seams, mut experiment) = (Vec::with_capacity(prob.n_obs()), Vec::new(), None);
    for x in crate::data::observed_ranges(prob.n(), prob.seams, prob.missing) {
        let start = prob.experiment_start(x.start);
        if experiment.is_some_and(|e| e != start) {
            seams.push(observed.len());
        }
        experiment = Some(start);
        observed.extend_from_slice(&r[x]);
    }
    drift_statistic(&observed, &seams)
}

/// The KPSS statistic of `r` about a level in each experiment (METHOD.md 7.3):
/// `eta = sum_t S_t^2 / (sum_k N_k^2 s^2)`, `S_t` the partial sums of `psi(r)` less its mean
/// within each experiment, `s^2` their Newey-West long-run variance with Bartlett weights up
/// to lag `floor(12 (N/100)^(1/4))` (KPSS's own), `psi` Huber's at `k = 2` robust scales
/// about the median (a spike moves S by at most that). About 1/6 for residuals that wander
/// about a level, growing with N when they drift; 0 for constant residuals.
pub fn drift_statistic(r: &[f64], seams: &[usize]) -> f64 {
    let n = r.len();
    if n < 2 {
        return 0.0;
    }
    let mut sorted = r.to_vec();
    let mid = n / 2;
    let centre = *sorted.select_nth_unstable_by(mid, f64::total_cmp).1;
    let scale = robust_scale(&r.iter().map(|v| v - centre).collect::<Vec<_>>(), |_| true);
    let cut = HUBER_K * scale;
    let mut psi: Vec<f64> = r.iter().map(|v| (v - centre).clamp(-cut, cut)).collect();
    let experiments = crate::data::experiment_ranges(n, seams);
    let (mut sums, mut lengths) = (0.0, 0.0);
    for x in &experiments {
        let e = &mut psi[x.clone()];
        let mean = e.iter().sum::<f64>() / e.len().max(1) as f64;
        let mut s = 0.0;
        for v in e.iter_mut() {
            *v -= mean;
            s += *v;
            sums += s * s;
        }
        lengths += (e.len() as f64).powi(2);
    }
    let lag = (12.0 * (n as f64 / 100.0).powf(0.25)).floor() as usize;
    let variance = long_run_sum(experiments.iter().map(|x| &psi[x.clone()]), lag) / n as f64;
    if variance > 0.0 { sums / lengths / variance } else { 0.0 }
}

/// The warning of the test judged against the models fitted to the record (METHOD.md 7.3):
/// none when the test does not fire; when it does, the integrating plant's when no model was
/// fitted or one has a pole on the stability boundary (the fit agrees), otherwise the drift
/// of the residuals of those stable models whose residuals drift, and none when no residuals
/// drift (the stable models explain the record the test's pole came from). `record` names
/// the record in the warning.
pub fn doubt(test: &PoleTest, record: &str, judged: &[Judged]) -> Option<String> {
    worded(test, record, judged, None)
}

/// [`doubt`] of the test of one input of several ([`pole_tests`]), `input` naming it ("input 2
/// (fan)"): each [`Judged`] model's `radius` is then the largest pole radius of that input's
/// F_i, and the warning names the input whose path looks integrating.
pub fn input_doubt(test: &PoleTest, input: &str, record: &str, judged: &[Judged]) -> Option<String> {
    worded(test, record, judged, Some(input))
}

/// The warnings of every input's test ([`pole_tests`]) judged against the models fitted to the
/// record: one input's [`doubt`]; with several, [`input_doubt`] of each input whose test fired,
/// named by its column in `names`. `judged(i)` gives the models judged for input i (each
/// `radius` that of its F_i; asked only for a test that fired).
pub fn doubts(
    tests: &[Option<PoleTest>],
    names: &[String],
    record: &str,
    mut judged: impl FnMut(usize) -> Vec<Judged>,
) -> Vec<String> {
    let fired = |i: usize| tests[i].as_ref().filter(|t| t.integrating);
    match tests {
        [_] => fired(0).and_then(|t| doubt(t, record, &judged(0))).into_iter().collect(),
        _ => (0..tests.len())
            .filter_map(|i| {
                let test = fired(i)?;
                let name = input_name(i, names.get(i).map_or("", String::as_str));
                input_doubt(test, &name, record, &judged(i))
            })
            .collect(),
    }
}

/// The largest pole radius of input i's F_i in `theta` (of structure `s`).
pub fn input_radius(s: &Structure, theta: &[f64], i: usize) -> f64 {
    oe::max_pole_radius(&theta[s.f_range(i)])
}

/// The input's words in the several-input warnings: "input 2 (fan)".
pub fn input_name(i: usize, name: &str) -> String {
    format!("input {} ({name})", i + 1)
}

fn worded(test: &PoleTest, record: &str, judged: &[Judged], input: Option<&str>) -> Option<String> {
    if !test.integrating {
        return None;
    }
    let what = pole_words(test);
    if judged.is_empty() || judged.iter().any(|j| !judged_by_residuals(j.radius)) {
        return Some(match input {
            None => format!(
                "a low-order IV fit of {record} has {what}: the plant looks integrating (or unstable), and an \
                 output-error model forces a stable model onto it (identify from the differenced output, or in \
                 closed loop)"
            ),
            Some(input) => format!(
                "{input} looks integrating: a low-order IV fit of {record} from that input, the other inputs' \
                 outputs taken out, has {what}; its path may integrate (or be unstable), and an output-error model \
                 forces a stable model onto it (identify from the differenced output with the other inputs \
                 differenced, or in closed loop)"
            ),
        });
    }
    let drifting: Vec<(&Judged, f64)> =
        judged.iter().filter_map(|j| j.drift.filter(|&d| d > DRIFT_LEVEL).map(|d| (j, d))).collect();
    let ((first, stat), rest) = drifting.split_first()?;
    let mut models = format!("{} (KPSS statistic {stat:.2}, slowest pole at radius {:.4})", first.name, first.radius);
    for (j, stat) in rest {
        models.push_str(&format!(" and of {} ({stat:.2}, {:.4})", j.name, j.radius));
    }
    let their = if rest.is_empty() { "its" } else { "their" };
    if let Some(input) = input {
        return Some(format!(
            "the residuals of {models} drift (above {DRIFT_LEVEL}, the 5 % point for residuals about a level), \
             though {their} poles are stable: a slow disturbance that the model does not explain, or {input} \
             integrates (a low-order IV fit of {record} from that input, the other inputs' outputs taken out, has \
             {what}); take the drift out of the record (detrend it, or high-pass every signal), or identify from \
             the differenced output with the other inputs differenced if that input's path integrates"
        ));
    }
    Some(format!(
        "the residuals of {models} drift (above {DRIFT_LEVEL}, the 5 % point for residuals about a level), \
         though {their} poles are stable: a slow disturbance that the model does not explain, or an integrating \
         plant (a low-order IV fit of {record} has {what}); take the drift out of the record (detrend it, or \
         high-pass both signals), or identify from the differenced output if the plant integrates"
    ))
}

/// The test's pole and its 95 % interval in words (enough decimals that the ends differ), or
/// the slowest complex pair and A(1)'s interval.
fn pole_words(test: &PoleTest) -> String {
    let decimals = |w: f64| (-w.log10()).ceil().clamp(3.0, 8.0) as usize + 1;
    let (p, a, sd) = (test.pole, test.a_at_1, test.a_at_1_std);
    match test.interval {
        Some((lo, hi)) => {
            let dp = decimals(hi - lo);
            let place = if lo > 1.0 { ", above 1" } else { " that may be 1" };
            format!("a pole at {:.dp$} (95 % interval {lo:.dp$}..{hi:.dp$}){place}", p.0)
        }
        None => format!(
            "its slowest poles at {:.4} +- {:.4}i and A(1) = {a:.3e} (95 % interval {:.3e}..{:.3e}), 0 for a pole at 1",
            p.0,
            p.1.abs(),
            a - Z95 * sd,
            a + Z95 * sd
        ),
    }
}
