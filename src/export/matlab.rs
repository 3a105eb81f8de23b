//! `oesweep export --to matlab`: a MATLAB/Octave script that defines the model's coefficients
//! and builds its `tf` (Control System Toolbox, Octave's control package) and, where the System
//! Identification Toolbox is installed, its `idpoly` with the covariance. A several-input model
//! is MATLAB's MISO `idpoly`: `B` and `F` cell arrays (one entry per input, `B{i}` with input
//! i's `nk(i)` leading zeros) and a 1 x m `tf`.

use super::continuous::ContinuousModel;
use super::model::ModelOut;
use std::fmt::Write;

impl ModelOut {
    /// A MATLAB/Octave script that defines the coefficients and builds `G = tf(num, den, Ts)`,
    /// and `sys = idpoly(...)` with its covariance where the System Identification Toolbox is
    /// installed.
    pub fn to_matlab(&self) -> String {
        self.to_matlab_with(&[])
    }

    /// [`Self::to_matlab`] that also builds the continuous equivalent (one per input, as
    /// [`ModelOut::to_continuous`] gives them; none when empty) as `Gc` (a `tf`) and `Gz` (a `zpk`,
    /// well-conditioned), with its dead time as `InputDelay` in MATLAB (Octave's `tf` and `zpk`
    /// have none, so there `input_delay` stands beside them).
    pub fn to_matlab_with(&self, continuous: &[ContinuousModel]) -> String {
        if self.m() > 1 {
            return self.several_inputs_matlab(continuous);
        }
        let p = &self.inputs[0];
        let (num, den) = p.num_den();
        let row = |v: &[f64]| v.iter().map(|x| matlab_number(*x)).collect::<Vec<_>>().join(", ");
        let mut s = String::new();
        let _ = writeln!(s, "% {} from oesweep", self.name);
        let _ =
            writeln!(s, "% y(t) = q^-nk B(q)/F(q) (u(t) - u0) + offset, B = b1 + b2 q^-1 + ..., F = 1 + f1 q^-1 + ...");
        let _ = writeln!(s, "Ts = {};", matlab_number(self.ts));
        let _ = writeln!(s, "nk = {};", p.delay);
        let _ = writeln!(s, "b = [{}];", row(&p.b));
        let _ = writeln!(s, "F = [1, {}];", row(&p.f));
        let _ = writeln!(s, "u0 = {};", matlab_number(p.input_level));
        let _ = writeln!(s, "offset = {};", self.offset.map_or("0".to_string(), matlab_number));
        match self.covariance_rows() {
            Some(rows) => {
                let rows: Vec<String> = rows.iter().map(|r| row(r)).collect();
                let _ = writeln!(s, "% over [{}]", self.parameters.join(", "));
                let _ = writeln!(s, "covariance = [{}];", rows.join("; ...\n  "));
            }
            None => {
                let _ = writeln!(s, "covariance = []; % not known");
            }
        }
        let _ = writeln!(s, "num = [{}];", row(&num));
        let _ = writeln!(s, "den = [{}];", row(&den));
        let _ = writeln!(s, "B = [zeros(1, nk), b];");
        let _ = writeln!(s, "if exist('OCTAVE_VERSION', 'builtin')");
        let _ = writeln!(s, "  pkg load control");
        let _ = writeln!(s, "end");
        let _ = writeln!(s, "G = tf(num, den, Ts);");
        let _ = writeln!(s, "if exist('idpoly')");
        let _ = writeln!(
            s,
            "  sys = idpoly(1, B, 1, 1, F, {}, Ts);",
            self.noise_variance.map_or("1".to_string(), matlab_number)
        );
        let _ = writeln!(s, "  sys.Structure.B.Free(1:nk) = false;");
        let np = p.b.len() + p.f.len();
        let _ = writeln!(s, "  if ~isempty(covariance)");
        let _ = writeln!(s, "    sys = setcov(sys, covariance(1:{np}, 1:{np}));");
        let _ = writeln!(s, "  end");
        let _ = writeln!(s, "end");
        if let Some(c) = continuous.first() {
            let _ =
                writeln!(s, "% continuous-time equivalent ({}): Gc(s) = exp(-input_delay s) numc(s)/denc(s)", c.method);
            let _ = writeln!(s, "numc = [{}];", row(&c.num));
            let _ = writeln!(s, "denc = [{}];", row(&c.den));
            let _ =
                writeln!(s, "input_delay = {}; % seconds, {} samples", matlab_number(c.input_delay), c.delay_samples);
            let complex_row = |v: &[(f64, f64)]| v.iter().map(|&z| matlab_complex(z)).collect::<Vec<_>>().join(", ");
            let _ =
                writeln!(s, "% the same as zeros, poles (rad/s) and gain: well-conditioned where numc, denc are not");
            let _ = writeln!(s, "% (high orders, short sample times; docs/METHOD.md 18): prefer Gz");
            let _ = writeln!(s, "zc = [{}];", complex_row(&c.zeros));
            let _ = writeln!(s, "pc = [{}];", complex_row(&c.poles));
            let _ = writeln!(s, "kc = {};", matlab_number(c.gain));
            let _ = writeln!(s, "if exist('OCTAVE_VERSION', 'builtin')");
            let _ = writeln!(s, "  Gc = tf(numc, denc); % Octave's tf has no dead time");
            let _ = writeln!(s, "  Gz = zpk(zc, pc, kc);");
            let _ = writeln!(s, "else");
            let _ = writeln!(s, "  Gc = tf(numc, denc, 'InputDelay', input_delay);");
            let _ = writeln!(s, "  Gz = zpk(zc, pc, kc, 'InputDelay', input_delay);");
            let _ = writeln!(s, "end");
        }
        s
    }
}

impl ModelOut {
    /// The script of a model of several inputs: per-input coefficients in cell arrays (`b{i}`,
    /// `F{i}`, `num{i}`, `den{i}`; `nk`, `u0` rows), `G` the 1 x m `tf`, `sys` the MISO
    /// `idpoly` whose covariance is theta's reordered to MATLAB's parameter order (every B, then
    /// every F), and with `continuous` each input's equivalent in `Gc`, `Gz` (1 x m).
    fn several_inputs_matlab(&self, continuous: &[ContinuousModel]) -> String {
        let m = self.m();
        let row = |v: &[f64]| v.iter().map(|x| matlab_number(*x)).collect::<Vec<_>>().join(", ");
        let cells = |rows: Vec<String>| format!("{{{}}}", rows.join(", "));
        let each = |f: &dyn Fn(&super::model::InputModel) -> String| cells(self.inputs.iter().map(f).collect());
        let (num, den): (Vec<_>, Vec<_>) = self.num_den().into_iter().unzip();
        let mut s = String::new();
        let _ = writeln!(s, "% {} from oesweep", self.name);
        let _ = writeln!(
            s,
            "% y(t) = sum_i q^-nk(i) B_i(q)/F_i(q) (u_i(t) - u0(i)) + offset, B_i = b1 + b2 q^-1 + ..., \
             F_i = 1 + f1 q^-1 + ..."
        );
        let _ = writeln!(s, "% {m} inputs: the cell arrays and rows hold one entry per input");
        let _ = writeln!(s, "Ts = {};", matlab_number(self.ts));
        let _ =
            writeln!(s, "nk = [{}];", self.inputs.iter().map(|p| p.delay.to_string()).collect::<Vec<_>>().join(", "));
        let _ = writeln!(s, "b = {};", each(&|p| format!("[{}]", row(&p.b))));
        let _ = writeln!(
            s,
            "F = {};",
            each(&|p| if p.f.is_empty() { "[1]".into() } else { format!("[1, {}]", row(&p.f)) })
        );
        let _ = writeln!(s, "u0 = [{}];", row(&self.inputs.iter().map(|p| p.input_level).collect::<Vec<_>>()));
        let _ = writeln!(s, "offset = {};", self.offset.map_or("0".to_string(), matlab_number));
        match self.covariance_rows() {
            Some(rows) => {
                let rows: Vec<String> = rows.iter().map(|r| row(r)).collect();
                let _ = writeln!(s, "% over [{}]", self.parameters.join(", "));
                let _ = writeln!(s, "covariance = [{}];", rows.join("; ...\n  "));
            }
            None => {
                let _ = writeln!(s, "covariance = []; % not known");
            }
        }
        let _ = writeln!(s, "num = {};", cells(num.iter().map(|v| format!("[{}]", row(v))).collect()));
        let _ = writeln!(s, "den = {};", cells(den.iter().map(|v| format!("[{}]", row(v))).collect()));
        let _ = writeln!(s, "B = cell(1, {m});");
        let _ = writeln!(s, "for i = 1:{m}");
        let _ = writeln!(s, "  B{{i}} = [zeros(1, nk(i)), b{{i}}];");
        let _ = writeln!(s, "end");
        let _ = writeln!(s, "if exist('OCTAVE_VERSION', 'builtin')");
        let _ = writeln!(s, "  pkg load control");
        let _ = writeln!(s, "end");
        let _ = writeln!(s, "G = tf(num, den, Ts); % 1 x {m}: one column per input");
        let _ = writeln!(s, "if exist('idpoly')");
        let _ = writeln!(
            s,
            "  sys = idpoly(1, B, 1, 1, F, {}, Ts);",
            self.noise_variance.map_or("1".to_string(), matlab_number)
        );
        let _ = writeln!(s, "  for i = 1:{m}");
        let _ = writeln!(s, "    sys.Structure.B(i).Free(1:nk(i)) = false;");
        let _ = writeln!(s, "  end");
        let _ = writeln!(s, "  if ~isempty(covariance)");
        let _ = writeln!(
            s,
            "    % theta is [b_1, f_1, ..., b_m, f_m]; an idpoly's parameters are [B_1, ..., B_m, F_1, ..., F_m]"
        );
        let order: Vec<String> = idpoly_order(self).iter().map(|i| (i + 1).to_string()).collect();
        let _ = writeln!(s, "    order = [{}];", order.join(", "));
        let _ = writeln!(s, "    sys = setcov(sys, covariance(order, order));");
        let _ = writeln!(s, "  end");
        let _ = writeln!(s, "end");
        if let Some(first) = continuous.first() {
            let complex_row = |v: &[(f64, f64)]| v.iter().map(|&z| matlab_complex(z)).collect::<Vec<_>>().join(", ");
            let list = |f: &dyn Fn(&ContinuousModel) -> String| cells(continuous.iter().map(f).collect());
            let _ = writeln!(
                s,
                "% continuous-time equivalents ({}), one per input: Gc_i(s) = exp(-input_delay(i) s) numc{{i}}(s)/denc{{i}}(s)",
                first.method
            );
            let _ = writeln!(s, "numc = {};", list(&|c| format!("[{}]", row(&c.num))));
            let _ = writeln!(s, "denc = {};", list(&|c| format!("[{}]", row(&c.den))));
            let delays: Vec<f64> = continuous.iter().map(|c| c.input_delay).collect();
            let samples: Vec<String> = continuous.iter().map(|c| c.delay_samples.to_string()).collect();
            let _ = writeln!(s, "input_delay = [{}]; % seconds, [{}] samples", row(&delays), samples.join(", "));
            let _ =
                writeln!(s, "% the same as zeros, poles (rad/s) and gains: well-conditioned where numc, denc are not");
            let _ = writeln!(s, "% (high orders, short sample times; docs/METHOD.md 18): prefer Gz");
            let _ = writeln!(s, "zc = {};", list(&|c| format!("[{}]", complex_row(&c.zeros))));
            let _ = writeln!(s, "pc = {};", list(&|c| format!("[{}]", complex_row(&c.poles))));
            let _ = writeln!(s, "kc = [{}];", row(&continuous.iter().map(|c| c.gain).collect::<Vec<_>>()));
            let _ = writeln!(s, "if exist('OCTAVE_VERSION', 'builtin')");
            let _ = writeln!(s, "  Gc = tf(numc, denc); % Octave's tf has no dead time");
            let _ = writeln!(s, "  Gz = zpk(zc, pc, kc);");
            let _ = writeln!(s, "else");
            let _ = writeln!(s, "  Gc = tf(numc, denc, 'InputDelay', input_delay);");
            let _ = writeln!(s, "  Gz = zpk(zc, pc, kc, 'InputDelay', input_delay);");
            let _ = writeln!(s, "end");
        }
        s
    }
}

/// Theta's indices (0-based) in the order of an `idpoly`'s parameters: every input's b, then
/// every input's f (theta is `[b_1, f_1, ..., b_m, f_m]`), then the offset when estimated.
fn idpoly_order(m: &ModelOut) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut at = 0;
    for p in &m.inputs {
        starts.push(at);
        at += p.b.len() + p.f.len();
    }
    let mut order: Vec<usize> = Vec::with_capacity(at);
    for (p, s) in m.inputs.iter().zip(&starts) {
        order.extend(*s..s + p.b.len());
    }
    for (p, s) in m.inputs.iter().zip(&starts) {
        order.extend(s + p.b.len()..s + p.b.len() + p.f.len());
    }
    order
}

/// `re+imi` as MATLAB reads a complex number inside brackets (no spaces), `re` when `im` is zero.
fn matlab_complex((re, im): (f64, f64)) -> String {
    if im == 0.0 {
        matlab_number(re)
    } else {
        format!("{}{}{}i", matlab_number(re), if im < 0.0 { "-" } else { "+" }, matlab_number(im.abs()))
    }
}

/// Shortest text that reads back as exactly `x` in MATLAB (NaN and Inf by their names).
fn matlab_number(x: f64) -> String {
    if x.is_nan() {
        "NaN".into()
    } else if x.is_infinite() {
        if x > 0.0 { "Inf".into() } else { "-Inf".into() }
    } else {
        format!("{x:e}").replace("e0", "")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::export::model::tests::{model, two_inputs};

    #[test]
    fn numbers_round_trip_through_the_script() {
        for x in [0.1, 1.0 / 3.0, -2.5e-17, 123456.789, 1e300] {
            assert_eq!(matlab_number(x).parse::<f64>().unwrap(), x, "{}", matlab_number(x));
        }
        let s = model().to_matlab();
        assert!(s.contains("G = tf(num, den, Ts);") && s.contains("nk = 2;"), "{s}");
        assert!(s.contains("covariance = [4, 1, 5e-1, 1e-1; ...\n  1, 3,"), "{s}");
        let j = model().to_json();
        assert_eq!(j["covariance"][1][1], 3.0);
        assert_eq!(j["dt"], 1e-3);
    }

    /// A several-input script: cell arrays of one entry per input, the MISO idpoly, and the
    /// covariance reordered from theta's order to the idpoly's.
    #[test]
    fn a_several_input_script_is_a_miso_idpoly() {
        let mut m = two_inputs();
        m.covariance = Some((0..36).map(|i| i as f64).collect());
        let s = m.to_matlab();
        for want in [
            "nk = [2, 0];",
            "b = {[5e-1, -2.5e-1], [1.5]};",
            "F = {[1, -8e-1], [1, -1.2, 5e-1]};",
            "u0 = [2.5e-1, -1];",
            "num = {[0, 0, 5e-1, -2.5e-1], [1.5, 0, 0]};",
            "G = tf(num, den, Ts); % 1 x 2",
            "sys = idpoly(1, B, 1, 1, F, 1e-2, Ts);",
            "sys.Structure.B(i).Free(1:nk(i)) = false;",
            "order = [1, 2, 4, 3, 5, 6];",
        ] {
            assert!(s.contains(want), "{want} in:\n{s}");
        }
        assert_eq!(idpoly_order(&m), vec![0, 1, 3, 2, 4, 5]);
    }
}
