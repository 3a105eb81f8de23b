//! The whole estimation of one model at one k, as `oesweep fit` runs it and as every bootstrap
//! replicate reruns it (METHOD.md 5.2, 5.5 `ls`, 17): the least-squares phase, the Huber fit
//! from theta_LS and its extra starts, and, when that fit ends on the stability boundary
//! (largest pole radius >= [`BOUNDARY`]), more starts, so that a boundary fit is never returned
//! when an interior fit with a criterion as low or lower was within reach.
//!
//! Why: on the boundary a pole at radius ~1 gives 1/F an almost infinite memory, the fit creeps
//! and stops there, and the starts of the least-squares phase may all lead to it. In a Monte
//! Carlo of a lightly damped OE(12,12) with spikes (`examples/uncertainty_mc.rs`, issue 37),
//! fits stopped on the boundary with W above W at the true parameters. The further starts are
//! the boundary fit with its poles pulled inside ([`super::least_squares::CONTRACTED`]), the initial guesses (ARX, IV)
//! as Huber starts, and a walk down in k from theta_LS pulled inside (the largest k lies
//! nearest the least-squares fit, as the sweep's backward pass uses it, METHOD.md 5.5).

use super::chains::fit_huber_multi;
use super::fit::{HuberFit, Judge, LsFit, fit_huber};
use super::least_squares::{BOUNDARY, contracted, fit_ls};
use super::options::SolverOptions;
use super::problem::Problem;
use super::workspace::Workspace;
use crate::oe;

/// One model's estimation: the least-squares fit, the Huber fit returned, and where it came
/// from.
#[derive(Clone, Debug)]
pub struct OneFit {
    pub ls: LsFit,
    pub huber: HuberFit,
    /// The start of the fit returned: `ls` (theta_LS), `ls_alt` (an extra start of the
    /// least-squares phase), or one of the boundary's further starts: `contracted`, `guess`,
    /// `walk`.
    pub start: &'static str,
    /// Huber fits run in all.
    pub fits: usize,
}

/// The tuning constants of the walk down to k: from [`WALK_TOP`] k down by factors of
/// [`WALK_FACTOR`]. Near k sigma = 2 sigma nearly every residual is in the L2 set and the Huber
/// minimum lies next to theta_LS; smaller k moves it step by step.
pub const WALK_TOP: f64 = 2.0;
pub const WALK_FACTOR: f64 = 2.0;

/// Estimate one model (`prob`'s orders) at tuning constant `k` (METHOD.md 17.1).
pub fn fit_one(prob: &Problem, k: f64, judge: &Judge, opts: &SolverOptions, ws: &mut Workspace) -> OneFit {
    let ls = fit_ls(prob, judge, opts, ws);
    let (huber, start) = fit_huber_multi(prob, &ls, k, judge, opts, ws);
    let fits = 1 + ls.alternatives.len();
    let start = if start == 0 { "ls" } else { "ls_alt" };
    off_the_boundary(prob, OneFit { ls, huber, start, fits }, judge, opts, ws)
}

/// `fit` as it is when its Huber fit is inside the stability region; on the boundary, the
/// fit of [`choose`] among it and the fits from the further starts (module doc).
pub fn off_the_boundary(
    prob: &Problem,
    fit: OneFit,
    judge: &Judge,
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> OneFit {
    if !on_boundary(&fit.huber) || !fit.ls.ok() {
        return fit;
    }
    let OneFit { ls, huber, start, fits } = fit;
    let k = huber.k;
    let mut candidates = vec![(huber, start)];
    for (theta, name) in super::boundary::boundary_starts(prob, &candidates[0].0.theta()) {
        let fit = fit_huber(prob, ls.sigma, k, &theta, judge, opts, ws);
        candidates.push((fit, name));
    }
    // The walk down in k from theta_LS pulled inside.
    let mut point = contracted(prob, &ls.theta());
    let mut kk = (WALK_TOP * k).max(WALK_TOP);
    let mut walked = false;
    while kk > k * (1.0 + 1e-12) {
        point = fit_huber(prob, ls.sigma, kk, &point, judge, opts, ws).theta();
        kk /= WALK_FACTOR;
        walked = true;
    }
    if walked {
        candidates.push((fit_huber(prob, ls.sigma, k, &point, judge, opts, ws), "walk"));
    }
    let fits = fits + candidates.len() - 1;
    let best = choose(&candidates.iter().map(|(h, _)| h).collect::<Vec<_>>());
    let (huber, start) = candidates.swap_remove(best);
    OneFit { ls, huber, start, fits }
}

/// True when the fit's largest pole radius is on the stability boundary ([`BOUNDARY`]).
pub fn on_boundary(h: &HuberFit) -> bool {
    oe::max_pole_radius(&h.f) >= BOUNDARY
}

/// The fit to return among `fits`: the lowest usable criterion (ties: the earlier), except that
/// a fit on the stability boundary gives way to an interior fit whose criterion is no higher
/// than its own plus [`super::Chains::MERGE`] relative (the same minimum to the solver's
/// precision, reached from inside: its covariance means something, the boundary fit's does not).
pub fn choose(fits: &[&HuberFit]) -> usize {
    let usable = |h: &HuberFit| h.criterion.is_finite();
    let lowest = |pred: &dyn Fn(&HuberFit) -> bool| {
        let mut best: Option<usize> = None;
        for (i, h) in fits.iter().enumerate() {
            if usable(h) && pred(h) && best.is_none_or(|b| h.criterion < fits[b].criterion) {
                best = Some(i);
            }
        }
        best
    };
    let Some(best) = lowest(&|_| true) else { return 0 };
    if !on_boundary(fits[best]) {
        return best;
    }
    let tol = super::Chains::MERGE * fits[best].criterion.abs();
    match lowest(&|h| !on_boundary(h)) {
        Some(i) if fits[i].criterion <= fits[best].criterion + tol => i,
        _ => best,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimate::criteria::Robust;
    use crate::estimate::evidence::Evidence;
    use crate::estimate::fit::Assessment;
    use crate::estimate::options::Termination;

    /// A fit of criterion `w` whose one pole is at `radius`.
    fn fit(w: f64, radius: f64) -> HuberFit {
        HuberFit {
            k: 0.5,
            gamma: 0.5,
            criterion: w,
            l1c: 0.1,
            assessment: Assessment {
                fit: 90.0,
                fit_val: None,
                fit_band: None,
                fit_band_inputs: None,
                fit_exp: None,
                fit_val_exp: None,
                max_pole_radius: radius,
                evidence: Evidence::default(),
            },
            iterations: 10,
            termination: Termination::CriterionTolerance,
            reflections: 0,
            b: vec![1.0],
            f: vec![-radius],
            offset: None,
            criteria: Robust { raic: 0.0, rbic: 0.0 },
            structure: crate::oe::Structure::siso(1, 1, 1),
        }
    }

    #[test]
    fn a_boundary_fit_gives_way_to_an_interior_fit_as_low_or_lower() {
        // The boundary fit is higher: the interior one wins whatever the order.
        let (edge, inside) = (fit(1.0, 0.9999), fit(0.9, 0.95));
        assert_eq!(choose(&[&edge, &inside]), 1);
        assert_eq!(choose(&[&inside, &edge]), 0);
        // Equal to the solver's precision: the interior fit, though a hair higher.
        let level = fit(1.0 + 1e-7, 0.95);
        assert_eq!(choose(&[&edge, &level]), 1);
        // A boundary fit clearly lower is kept (the doubt of METHOD.md 17.2 then speaks).
        let higher = fit(1.01, 0.95);
        assert_eq!(choose(&[&higher, &edge]), 1);
        // Among interior fits the lowest, ties to the earlier; unusable fits never win.
        let (a, b, nan) = (fit(2.0, 0.5), fit(2.0, 0.6), fit(f64::NAN, 0.5));
        assert_eq!(choose(&[&nan, &a, &b]), 1);
        assert_eq!(choose(&[&nan]), 0);
    }
}
