//! Levenberg-Marquardt prediction-error minimisation of an OE criterion (METHOD.md 3, 5).
//!
//! At `theta` with residuals `e_t`, row weights `w_t` and influence `r_t = psi_g(e_t)`:
//!
//! ```text
//! H = (1/N) sum_t w_t psi_t psi_t^T        g = (1/N) sum_t psi_t r_t   (= -grad criterion)
//! (H + lambda D) delta = g,   D = diag(H) (Marquardt scaling, floored)
//! ```
//!
//! Least squares: `w = 1`, `r = e`. Huber: `r = clamp(e, -g, g)` and either the exact
//! Gauss-Newton weights (1 on the L2 set, 0 on the L1 set; METHOD.md 3) or IRLS weights
//! `min(1, g/|e|)`. The exact weights make `H` near singular at small k; the damping
//! `lambda D` is what keeps the step defined, and the gain ratio drives lambda (Nielsen's rule).
//!
//! Invariants: a trial step is accepted only when the criterion strictly decreases, and only
//! with a stable F. An unstable trial F is first reflected into the unit circle (as the scipy
//! peer does) and accepted if that point lowers the criterion; otherwise the step is
//! rejected and lambda raised, i.e. the step shortened (METHOD.md 8).
//!
//! All buffers live in [`Workspace`]; after the first call of a given size the iteration loop
//! allocates nothing, pole reflections included (stack buffers up to nF = 64; tested in
//! `tests/no_allocation.rs`).

use super::huber::Loss;
use super::linalg::{cholesky, cholesky_solve};
use super::options::{HuberHessian, SolverMethod, SolverOptions, Termination};
use super::problem::{Problem, Solution, add_offset, output_filtered};
use super::separable;
use super::workspace::Workspace;

/// The damping after a failed step. From lambda = 0 (allowed as `lambda0`: a pure
/// Gauss-Newton first step) it starts at a level that can grow.
fn raised(lambda: f64, nu: f64) -> f64 {
    (lambda * nu).max(MIN_RAISED_LAMBDA)
}

/// Smallest damping after a failed step (relative to the Marquardt scaling diag(H)): from
/// lambda = 0 (a pure Gauss-Newton `lambda0`) a rejected step must raise lambda to a level
/// that multiplying can grow; at 1e-12 the first raised step is still Gauss-Newton to
/// rounding, so nothing is damped that did not need it.
const MIN_RAISED_LAMBDA: f64 = 1e-12;

fn norm2(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Minimise `loss` over theta = [b, f] (or [b, f, c], see [`Problem::offset`]) from `theta0`.
/// The returned F is stable. Counted in the workspace's profile under its current role.
pub fn minimise(prob: &Problem, loss: Loss, theta0: &[f64], opts: &SolverOptions, ws: &mut Workspace) -> Solution {
    let since = std::time::Instant::now();
    let sol = minimise_unprofiled(prob, loss, theta0, opts, ws);
    if let Some(p) = ws.profile() {
        p.fit(ws.role, sol.iterations, since);
    }
    sol
}

fn minimise_unprofiled(
    prob: &Problem,
    loss: Loss,
    theta0: &[f64],
    opts: &SolverOptions,
    ws: &mut Workspace,
) -> Solution {
    let n = prob.n();
    let d = prob.dim();
    assert_eq!(theta0.len(), d);
    assert_eq!(prob.y.len(), n);
    ws.prepare(n, prob.m(), d);
    ws.theta.copy_from_slice(theta0);
    let mut reflections = 0;
    let mut lambda = opts.lambda0;
    if prob.reflect_unstable(&mut ws.theta) {
        reflections += 1;
    }
    let lay = prob.layout();
    let y_scale = prob.mean_square_output();
    // Residuals at this level are rounding noise of the simulation.
    let exact_level = 1e-26 * y_scale.max(f64::MIN_POSITIVE);

    // yhat = q^-d B (1/F) u = B applied to xu = (1/F) u (LTI operators commute, zero initial
    // conditions): one pass gives the simulation and both Jacobian signals (xu and
    // xy = (1/F) yhat), so an accepted trial point needs no further filtering.
    // Variable projection is written for one input so far: several inputs take the full
    // Levenberg-Marquardt step (the same minimum, more iterations).
    // A record with missing outputs too: the projection's inner least squares is written for a
    // complete record (METHOD.md 21.2).
    let separable = opts.method == SolverMethod::Separable && prob.m() == 1 && prob.missing.is_empty();
    let mut crit = if separable {
        let ws = &mut *ws;
        let c = separable::project(
            prob,
            loss,
            &mut ws.theta,
            &mut ws.xu,
            &mut ws.yhat,
            &mut ws.r,
            &mut ws.w,
            &mut ws.inner,
        );
        output_filtered(prob, &ws.theta, &ws.yhat, &mut ws.xy);
        c
    } else {
        prob.simulate_filtered(&ws.theta, &mut ws.xu, &mut ws.yhat, &mut ws.xy);
        add_offset(&mut ws.yhat, prob.offset_of(&ws.theta));
        prob.criterion(loss, &ws.yhat)
    };
    let finish = |ws: &mut Workspace, crit, iterations, termination, reflections, lambda| Solution {
        theta: ws.theta.clone(),
        criterion: crit,
        iterations,
        termination,
        reflections,
        lambda,
    };
    if !crit.is_finite() {
        return finish(ws, crit, 0, Termination::NonFinite, reflections, lambda);
    }
    if ws.record_trace {
        ws.trace.push(crit);
    }
    let mut nu = 2.0;
    // Missing outputs enter the normal equations with weight 0 (least squares too).
    let use_weights = !matches!(loss, Loss::LeastSquares) || !prob.missing.is_empty();

    for it in 0..opts.max_iterations {
        if crit <= exact_level {
            return finish(ws, crit, it, Termination::ExactFit, reflections, lambda);
        }
        // Residual influence and row weights at the current point.
        let irls = opts.huber_hessian == HuberHessian::Irls;
        crate::kernels::influence(prob.y, &ws.yhat, loss.gamma(), irls, &mut ws.r, &mut ws.w);
        if !prob.missing.is_empty() {
            if loss == Loss::LeastSquares {
                ws.w[..n].fill(1.0);
            }
            for &t in prob.missing {
                ws.r[t] = 0.0;
                ws.w[t] = 0.0;
            }
        }
        let w = if use_weights { Some(&ws.w[..]) } else { None };
        ws.ne.build_all(&lay, prob.offset, prob.seams, &ws.xu, &ws.xy, w, &ws.r, &mut ws.h, &mut ws.g);
        if !prob.missing.is_empty() {
            // The normal equations average over all N rows; the criterion over the observed.
            let scale = n as f64 / prob.n_obs() as f64;
            ws.h[..d * d].iter_mut().chain(ws.g[..d].iter_mut()).for_each(|v| *v *= scale);
        }
        if ws.h.iter().any(|v| !v.is_finite()) || ws.g.iter().any(|v| !v.is_finite()) {
            return finish(ws, crit, it, Termination::NonFinite, reflections, lambda);
        }
        let hmax = (0..d).map(|i| ws.h[i * d + i]).fold(0.0, f64::max);
        let floor = 1e-12 * hmax.max(f64::MIN_POSITIVE);
        let scaled_grad = (0..d).map(|i| ws.g[i].abs() / ws.h[i * d + i].max(floor).sqrt()).fold(0.0, f64::max);
        if scaled_grad <= opts.gtol * (2.0 * crit).sqrt() {
            return finish(ws, crit, it, Termination::GradientTolerance, reflections, lambda);
        }

        // Inner loop: raise damping until a step decreases the criterion.
        loop {
            ws.a.copy_from_slice(&ws.h);
            for i in 0..d {
                // Variable projection damps F only: b and c are solved for, not stepped.
                let damped = !separable || prob.structure.f_range(0).contains(&i);
                ws.a[i * d + i] += if damped { lambda * ws.h[i * d + i].max(floor) } else { floor };
            }
            if !cholesky(&mut ws.a, d) {
                lambda = raised(lambda, nu);
                nu *= 2.0;
                if lambda > 1e20 {
                    return finish(ws, crit, it + 1, Termination::Stalled, reflections, lambda);
                }
                continue;
            }
            ws.delta.copy_from_slice(&ws.g);
            cholesky_solve(&ws.a, d, &mut ws.delta);
            // Predicted decrease of the quadratic model: g.delta - delta^T H delta / 2.
            let mut quad = 0.0;
            for (row, &di) in ws.h[..d * d].chunks_exact(d).zip(&ws.delta[..d]) {
                let mut hi = 0.0;
                for (&hij, &dj) in row.iter().zip(&ws.delta[..d]) {
                    hi += hij * dj;
                }
                quad += di * hi;
            }
            let pred = ws.g.iter().zip(&ws.delta).map(|(a, b)| a * b).sum::<f64>() - 0.5 * quad;
            for i in 0..d {
                ws.trial[i] = ws.theta[i] + ws.delta[i];
            }
            let mut reflected = false;
            if ws.trial.iter().any(|v| !v.is_finite()) {
                // A degenerate system (e.g. gamma ~ 0 on noise-free data): more damping.
                lambda = raised(lambda, nu);
                nu *= 2.0;
                if lambda > 1e20 {
                    return finish(ws, crit, it + 1, Termination::Stalled, reflections, lambda);
                }
                continue;
            }
            if !prob.is_stable(&ws.trial) {
                prob.reflect_unstable(&mut ws.trial);
                reflected = true;
            }
            let new_crit = if separable {
                // r and w were used up by this iteration's normal equations: scratch now.
                let ws = &mut *ws;
                separable::project(
                    prob,
                    loss,
                    &mut ws.trial,
                    &mut ws.trial_xu,
                    &mut ws.trial_yhat,
                    &mut ws.r,
                    &mut ws.w,
                    &mut ws.inner,
                )
            } else {
                prob.simulate_filtered(&ws.trial, &mut ws.trial_xu, &mut ws.trial_yhat, &mut ws.trial_xy);
                add_offset(&mut ws.trial_yhat, prob.offset_of(&ws.trial));
                prob.criterion(loss, &ws.trial_yhat)
            };
            if new_crit.is_finite() && new_crit < crit {
                let rho = if pred > 0.0 { (crit - new_crit) / pred } else { 0.0 };
                lambda *= f64::max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0).powi(3));
                nu = 2.0;
                // The separable step moved b and c to their inner optimum, not by delta.
                let step = if separable {
                    ws.trial.iter().zip(&ws.theta).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt()
                } else {
                    norm2(&ws.delta)
                };
                let rel_actual = (crit - new_crit) / crit;
                let rel_pred = pred.abs() / crit;
                let small_step = step <= opts.xtol * (norm2(&ws.theta) + opts.xtol);
                if separable {
                    output_filtered(prob, &ws.trial, &ws.trial_yhat, &mut ws.trial_xy);
                }
                std::mem::swap(&mut ws.theta, &mut ws.trial);
                std::mem::swap(&mut ws.yhat, &mut ws.trial_yhat);
                std::mem::swap(&mut ws.xu, &mut ws.trial_xu);
                std::mem::swap(&mut ws.xy, &mut ws.trial_xy);
                crit = new_crit;
                if reflected {
                    reflections += 1;
                }
                if ws.record_trace {
                    ws.trace.push(crit);
                }
                if !reflected && rel_actual <= opts.ftol && rel_pred <= opts.ftol {
                    return finish(ws, crit, it + 1, Termination::CriterionTolerance, reflections, lambda);
                }
                if !reflected && small_step {
                    return finish(ws, crit, it + 1, Termination::StepTolerance, reflections, lambda);
                }
                break;
            }
            // Rejected. A predicted decrease below rounding of the criterion means the point is
            // a minimum to machine precision: more damping cannot help.
            if !reflected && pred.abs() <= 1e-15 * crit {
                return finish(ws, crit, it + 1, Termination::CriterionTolerance, reflections, lambda);
            }
            lambda = raised(lambda, nu);
            nu *= 2.0;
            if lambda > 1e20 {
                return finish(ws, crit, it + 1, Termination::Stalled, reflections, lambda);
            }
        }
    }
    finish(ws, crit, opts.max_iterations, Termination::MaxIterations, reflections, lambda)
}
