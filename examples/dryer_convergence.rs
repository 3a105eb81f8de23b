//! The least-squares path of OE(2,2 d1) x 3 on the dryer's estimation half (rows 1-433 of
//! `jobs/data/dryer.csv`; METHOD.md 19, "Slow convergence"): from each initial guess, with the
//! default and a heavy initial damping, the criterion at iterations 0, 10, 30, ... 10 000, the
//! termination and the pole radii per input.
//!
//! Usage: `cargo run --release --example dryer_convergence -- [SCALES [offset|none [CAP]]]`,
//! SCALES the factors of the three input columns (`1,0.1,0.01`: fan in tenths, feed in
//! hundredths; default `1,1,1`), `offset` to take the inputs' means out and fit c, CAP the
//! iteration cap (default 20 000).
use oesweep::estimate::{Loss, Problem, SolverOptions, Workspace, initial_guess, solver};
use oesweep::oe::{Orders, Structure};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let scale: Vec<f64> =
        args.get(1).map(|s| s.split(',').map(|v| v.parse().unwrap()).collect()).unwrap_or(vec![1.0, 1.0, 1.0]);
    let offset = args.get(2).map(|s| s == "offset").unwrap_or(false);
    let cap: usize = args.get(3).map(|s| s.parse().unwrap()).unwrap_or(20000);
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/jobs/data/dryer.csv")).unwrap();
    let rows: Vec<Vec<f64>> =
        text.lines().skip(1).map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    let n = 433;
    let mut u = vec![0.0; 3 * n];
    let mut y = vec![0.0; n];
    for t in 0..n {
        for i in 0..3 {
            u[i * n + t] = rows[t][i] * scale[i];
        }
        y[t] = rows[t][3];
    }
    if offset {
        for i in 0..3 {
            let m = u[i * n..(i + 1) * n].iter().sum::<f64>() / n as f64;
            u[i * n..(i + 1) * n].iter_mut().for_each(|v| *v -= m);
        }
    }
    let o = Orders { nb: 2, nf: 2, delay: 1 };
    let prob =
        Problem { u: &u, y: &y, structure: Structure::new(&[o, o, o]).unwrap(), offset, seams: &[], missing: &[] };
    let mut ws = Workspace::new();
    ws.record_trace = true;
    for (g, guess) in initial_guess::initial_guesses(&prob).iter().enumerate() {
        for lambda0 in [1e-3, 1.0] {
            let opts = SolverOptions { max_iterations: cap, lambda0, ..SolverOptions::default() };
            ws.trace.clear();
            let sol = solver::minimise(&prob, Loss::LeastSquares, guess, &opts, &mut ws);
            let marks: Vec<String> = [0usize, 10, 30, 100, 300, 1000, 3000, 10000]
                .iter()
                .filter(|&&i| i < ws.trace.len())
                .map(|&i| format!("{i}:{:.5}", ws.trace[i]))
                .collect();
            let radii: Vec<String> = (0..3)
                .map(|i| format!("{:.5}", oesweep::oe::max_pole_radius(&sol.theta[prob.structure.f_range(i)])))
                .collect();
            println!(
                "guess {g} lambda0 {lambda0}: crit {:.6} it {} accepted {} {:?} refl {} lambda {:.1e} radii {} | {}",
                sol.criterion,
                sol.iterations,
                ws.trace.len() - 1,
                sol.termination,
                sol.reflections,
                sol.lambda,
                radii.join(","),
                marks.join(" ")
            );
            println!("   theta {:?}", sol.theta.iter().map(|v| format!("{v:.4e}")).collect::<Vec<_>>());
        }
    }
}
