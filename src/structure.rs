//! A model structure: the orders (nB_i, nF_i, d_i) of each of the m inputs of
//! `y = sum_i q^-d_i B_i/F_i u_i (+ c) + e` (METHOD.md 2; one input: the paper's OE(nB, nF)).
//! The parameter vector theta is `[b_1, f_1, ..., b_m, f_m]` (+ an offset c).

/// Inputs a model may have (a fixed array keeps [`Structure`] `Copy` and allocation-free).
pub const MAX_INPUTS: usize = 8;

/// One input's orders: nB, nF and its delay d.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Orders {
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
}

/// A model structure: the orders of every input, `y = sum_i q^-d_i B_i/F_i u_i` (the plan
/// calls its structures "pairs", after the order pairs of the paper's grid). A single-input
/// model is the case m = 1; theta is `[b_1, f_1, ..., b_m, f_m]` (+ an offset c).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Structure {
    m: u8,
    orders: [Orders; MAX_INPUTS],
}

impl Structure {
    /// One input: OE(nB, nF) with delay d.
    pub const fn siso(nb: usize, nf: usize, delay: usize) -> Self {
        let mut orders = [Orders { nb: 0, nf: 0, delay: 0 }; MAX_INPUTS];
        orders[0] = Orders { nb, nf, delay };
        Structure { m: 1, orders }
    }

    /// Every input's orders; `None` without inputs or with more than [`MAX_INPUTS`].
    pub fn new(inputs: &[Orders]) -> Option<Self> {
        if inputs.is_empty() || inputs.len() > MAX_INPUTS {
            return None;
        }
        let mut orders = [Orders::default(); MAX_INPUTS];
        orders[..inputs.len()].copy_from_slice(inputs);
        Some(Structure { m: inputs.len() as u8, orders })
    }

    /// The orders of each input, in the job's order of the inputs.
    pub fn inputs(&self) -> &[Orders] {
        &self.orders[..self.m as usize]
    }

    /// Number of inputs m.
    pub fn m(&self) -> usize {
        self.m as usize
    }

    /// The one input's orders of a single-input structure (`None` for several inputs).
    pub fn single(&self) -> Option<Orders> {
        (self.m == 1).then_some(self.orders[0])
    }

    /// The orders of a single-input structure. Whatever counts a structure's orders as one
    /// (nB, nF, d) triple calls this: the plan, shards, graph and table for one input.
    pub fn one(&self) -> Orders {
        debug_assert_eq!(self.m, 1, "a several-input structure where one input is expected");
        self.orders[0]
    }

    /// Parameters of the dynamics: sum over the inputs of nB_i + nF_i.
    pub fn dim(&self) -> usize {
        self.inputs().iter().map(|o| o.nb + o.nf).sum()
    }

    /// Where input i's b_i and f_i sit in theta.
    pub fn b_range(&self, i: usize) -> std::ops::Range<usize> {
        let start = self.orders[..i].iter().map(|o| o.nb + o.nf).sum::<usize>();
        start..start + self.orders[i].nb
    }
    pub fn f_range(&self, i: usize) -> std::ops::Range<usize> {
        let b = self.b_range(i);
        b.end..b.end + self.orders[i].nf
    }

    /// The same structure with input i's orders replaced.
    pub fn with(&self, i: usize, o: Orders) -> Self {
        let mut s = *self;
        s.orders[i] = o;
        s
    }

    /// `OE(nB,nF) delay d` for one input, `OE(nB_1,nF_1 d_1; nB_2,nF_2 d_2; ...)` for several.
    pub fn label(&self) -> String {
        match self.single() {
            Some(o) => format!("OE({},{}) delay {}", o.nb, o.nf, o.delay),
            None => {
                let parts: Vec<String> =
                    self.inputs().iter().map(|o| format!("{},{} d{}", o.nb, o.nf, o.delay)).collect();
                format!("OE({})", parts.join("; "))
            }
        }
    }

    /// Flat B coefficients (every input's b one after the other, as fits store them) split
    /// per input; the same for flat F coefficients with [`Structure::split_f`].
    pub fn split_b<T: Clone>(&self, flat: &[T]) -> Vec<Vec<T>> {
        split(flat, self.inputs().iter().map(|o| o.nb))
    }
    pub fn split_f<T: Clone>(&self, flat: &[T]) -> Vec<Vec<T>> {
        split(flat, self.inputs().iter().map(|o| o.nf))
    }
}

/// `flat` cut into consecutive pieces of the given lengths (what is left over is dropped).
fn split<T: Clone>(flat: &[T], lengths: impl Iterator<Item = usize>) -> Vec<Vec<T>> {
    let mut at = 0;
    lengths
        .map(|n| {
            let end = (at + n).min(flat.len());
            let piece = flat[at.min(end)..end].to_vec();
            at = end;
            piece
        })
        .collect()
}
