//! Estimation of one model ("cell") and the quantities it is judged by (METHOD.md 5-6).
//!
//! ```text
//! 1. theta_0  = initial_guess (ARX + IV, F stable)                       [initial_guess]
//! 2. theta_LS = argmin (1/N) sum e^2/2 from theta_0, sigma = std(e_LS)   [fit_ls]
//! 3. theta_H  = argmin W_{N, k sigma} from theta_LS                      [fit_huber]
//! ```
//! Steps 1-2 depend only on (nB, nF, delay), so a sweep runs them once per order pair and
//! shares the [`LsFit`] across all k.
//!
//! The modules, and what each uses (no module uses one that uses it back):
//!
//! ```text
//! options        settings, Termination                         (none)
//! criteria       AIC, AICc, BIC, FPE; robust AIC, BIC           huber
//! cancellation   pole-zero pairs within their confidence       oe
//! linalg         Cholesky of the normal equations              (none)
//! huber          rho, psi, L1C                                  (none)
//! layout         the Jacobian's columns: sequence, sign, lag   (none)
//! normal         normal equations from lagged correlations     kernels, layout
//! problem        record + structure, Solution, theta's parts   options, layout, oe
//! initial_state  free response, model output                   linalg
//! initial_guess  ARX + IV starts                                problem
//! integrating    the record's integrating-plant test (IV pole)  problem, initial_guess, initial_state, least_squares
//! separable      variable projection inner problem             problem, linalg, normal, huber
//! residual_tests whiteness and independence of the residuals    kernels
//! jacobian_r     the scaled Jacobian's R: shifted CholeskyQR3  problem
//! evidence       covariance, residual tests                    problem, normal, huber, cancellation, residual_tests,
//!                                                              jacobian_r
//! workspace      per-worker buffers                            problem, normal, separable, evidence
//! solver         Levenberg-Marquardt                           all of the above
//! fit            LsFit, HuberFit, assessment                   solver, evidence, initial_state
//! least_squares  steps 1-2: theta_LS and sigma                 fit, initial_guess, solver
//! chains         step 3 over k: continuation chains            fit, least_squares, solver
//! single         one model at one k, boundary starts           chains, fit, least_squares, initial_guess
//! quadratic      is W quadratic over the confidence region?    evidence, huber, least_squares, problem
//! bootstrap      percentile intervals of the whole estimation  single
//! ```

pub mod bootstrap;
pub mod boundary;
pub mod cancellation;
pub mod chains;
pub mod criteria;
pub mod evidence;
pub mod fit;
pub mod fit_percent;
pub mod huber;
pub mod initial_guess;
pub mod initial_state;
pub mod integrating;
pub mod jacobian_r;
pub mod layout;
pub mod least_squares;
pub mod linalg;
pub mod normal;
pub mod options;
pub mod problem;
pub mod quadratic;
pub mod residual_tests;
pub mod separable;
pub mod single;
pub mod solver;
pub mod workspace;

pub use chains::{ChainWalk, Chains, fit_huber_multi, fit_huber_starts};
pub(crate) use fit::judged;
pub use fit::{Assessment, HuberFit, Judge, LsFit, PairProblem, StartKind, embed, fit_huber, fit_ls_from, theta_of};
pub use fit_percent::fit_percent;
pub use huber::Loss;
pub use initial_state::InitialState;
pub use least_squares::{OwnMinima, exploration_head, finish_ls, fit_ls, fit_ls_nested, own_minima};
pub use options::{HuberHessian, SolverMethod, SolverOptions, Termination};
pub use problem::{Problem, Solution};
pub use problem::{flat_parts, theta_in};
pub use single::{OneFit, fit_one};
pub use workspace::Workspace;
