//! The plan: a validated job expanded into structures ("pairs": every input's nB, nF, delay)
//! and cells (a pair and a k).
//!
//! Order is fixed and independent of threads: for one input pairs in (delay, nB, nF) order;
//! for several the product of the inputs' order lists with input 1 slowest and the last
//! input fastest ([`Plan::product`]); k in the job's order. A pair's sub-models drop one order
//! of one input ([`sub_structures`]). The least-squares phase depends on the pair and, through its nested starts, on its
//! sub-models' fits (METHOD.md 5.2), so a pair's is finished after theirs
//! ([`Plan::ls_sub_models`]); the pair is the unit that owns its least-squares fit and the
//! cells of a pair share it.

use crate::job::{StartStrategy, ValidJob};
use std::collections::HashMap;

pub use crate::oe::{Orders, Structure};

/// All pairs of one input's ranges, in plan order: (delay, nB, nF).
fn pairs(nb: &[usize], nf: &[usize], delays: &[usize]) -> Vec<Structure> {
    let orders = one_input_orders(nb, nf, delays);
    product(&[orders])
}

/// One input's orders of the given ranges in (delay, nB, nF) order.
pub fn one_input_orders(nb: &[usize], nf: &[usize], delays: &[usize]) -> Vec<Orders> {
    let mut out = Vec::with_capacity(nb.len() * nf.len() * delays.len());
    for &delay in delays {
        for &b in nb {
            for &f in nf {
                out.push(Orders { nb: b, nf: f, delay });
            }
        }
    }
    out
}

/// The product of the inputs' order lists: input 1 slowest, the last input fastest, each
/// input's orders in the order given (for one input the list itself).
fn product(per_input: &[Vec<Orders>]) -> Vec<Structure> {
    let mut out: Vec<Vec<Orders>> = vec![Vec::new()];
    for orders in per_input {
        out = out.iter().flat_map(|head| orders.iter().map(move |o| [&head[..], &[*o]].concat())).collect();
    }
    out.iter().filter_map(|s| Structure::new(s)).collect()
}

/// Position of each pair in `pairs`.
fn pair_index(pairs: &[Structure]) -> HashMap<Structure, usize> {
    pairs.iter().enumerate().map(|(i, p)| (*p, i)).collect()
}

/// The sub-models of a structure (METHOD.md 5.2, 5.6): every structure that drops one order
/// of one input (nB_i - 1 or nF_i - 1, the same delays), input by input, nB before nF.
pub fn sub_structures(s: &Structure) -> Vec<Structure> {
    let mut out = Vec::new();
    for (i, o) in s.inputs().iter().enumerate() {
        if o.nb > 0 {
            out.push(s.with(i, Orders { nb: o.nb - 1, ..*o }));
        }
        if o.nf > 0 {
            out.push(s.with(i, Orders { nf: o.nf - 1, ..*o }));
        }
    }
    out
}

/// Indices of pair `i`'s sub-models ([`sub_structures`]) in `pairs`, those it has.
fn sub_models(pairs: &[Structure], index: &HashMap<Structure, usize>, i: usize) -> Vec<usize> {
    sub_structures(&pairs[i]).iter().filter_map(|s| index.get(s).copied()).collect()
}

/// A sub-model's `theta` (`[b_1, f_1, ..., b_m, f_m]` and the offset c when `offset`) placed
/// into the theta of the larger structure `big` input by input, by [`Structure::b_range`] and
/// [`Structure::f_range`], its missing trailing coefficients zero: the same model as a point
/// of the larger one (for one input what `estimate::embed` does). Panics when `sub` is no
/// sub-model of `big` (inputs, delays, orders) or `theta` does not fit `sub`.
pub fn embed(theta: &[f64], sub: &Structure, big: &Structure, offset: bool) -> Vec<f64> {
    assert_eq!(sub.m(), big.m(), "{} is no sub-model of {}", sub.label(), big.label());
    assert_eq!(theta.len(), sub.dim() + usize::from(offset), "parameters of {}", sub.label());
    let mut out = vec![0.0; big.dim() + usize::from(offset)];
    for (i, (s, b)) in sub.inputs().iter().zip(big.inputs()).enumerate() {
        assert!(
            s.nb <= b.nb && s.nf <= b.nf && s.delay == b.delay,
            "{} is no sub-model of {}",
            sub.label(),
            big.label()
        );
        let (sb, bb) = (sub.b_range(i), big.b_range(i));
        out[bb.start..bb.start + s.nb].copy_from_slice(&theta[sb]);
        let (sf, bf) = (sub.f_range(i), big.f_range(i));
        out[bf.start..bf.start + s.nf].copy_from_slice(&theta[sf]);
    }
    if offset {
        out[big.dim()] = theta[sub.dim()];
    }
    out
}

/// One Huber cell: an order pair and an index into the k grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cell {
    pub pair: usize,
    pub k_index: usize,
}

#[derive(Clone, Debug)]
pub struct Plan {
    pub pairs: Vec<Structure>,
    pub ks: Vec<f64>,
    pub start: StartStrategy,
    /// Pairs outside `pairs` whose least-squares phase the plan needs for the nested starts of
    /// its own (METHOD.md 5.2, step 2): their sub-models down the grid. Empty for a whole grid;
    /// a shard's plan ([`Plan::with_pairs`]) lists the sub-models another shard owns. They
    /// give no rows.
    pub ls_support: Vec<Structure>,
}

impl Plan {
    pub fn from_job(job: &ValidJob) -> Plan {
        if job.m > 1 {
            let per_input: Vec<Vec<Orders>> =
                job.grids.iter().map(|g| one_input_orders(&g.nb, &g.nf, &g.delays)).collect();
            return Plan::product(&per_input, job.ks.clone(), job.job.start);
        }
        Plan {
            pairs: pairs(&job.nb, &job.nf, &job.delays),
            ks: job.ks.clone(),
            start: job.job.start,
            ls_support: Vec::new(),
        }
    }

    /// The full product of the inputs' order lists (`per_input[i]`: input i's (nB, nF, delay)
    /// in the order to sweep them; input 1 slowest), every structure at every k of `ks`. For
    /// one input and its orders in (delay, nB, nF) order ([`one_input_orders`]), the plan of
    /// [`Plan::from_job`].
    pub fn product(per_input: &[Vec<Orders>], ks: Vec<f64>, start: StartStrategy) -> Plan {
        Plan { pairs: product(per_input), ks, start, ls_support: Vec::new() }
    }

    /// Number of inputs of the plan's structures (1 for an empty plan).
    pub fn m(&self) -> usize {
        self.pairs.first().map_or(1, Structure::m)
    }

    /// This plan restricted to some of its pairs (indices into `pairs`, in the order given):
    /// a shard's plan ([`crate::shard`]). A pair's cells are computed exactly as in the full
    /// plan: a cell depends on no other pair but through the least-squares phase's nested
    /// starts, and the sub-models those come from are kept as `ls_support`.
    pub fn with_pairs(&self, pairs: &[usize]) -> Plan {
        let own: Vec<Structure> = pairs.iter().map(|&p| self.pairs[p]).collect();
        let all = self.ls_pairs();
        let index = pair_index(&all);
        // `pairs` index `self.pairs`, the head of `all`.
        let mut is_own = vec![false; all.len()];
        for &p in pairs {
            is_own[p] = true;
        }
        let mut needed = vec![false; all.len()];
        let mut stack: Vec<usize> = pairs.to_vec();
        while let Some(i) = stack.pop() {
            for j in sub_models(&all, &index, i) {
                if !needed[j] {
                    needed[j] = true;
                    stack.push(j);
                }
            }
        }
        let ls_support = (0..all.len()).filter(|&j| needed[j] && !is_own[j]).map(|j| all[j]).collect();
        Plan { pairs: own, ls_support, ..self.clone() }
    }

    /// The pairs whose least-squares phase the plan runs: `pairs`, then `ls_support`.
    pub fn ls_pairs(&self) -> Vec<Structure> {
        self.pairs.iter().chain(&self.ls_support).copied().collect()
    }

    /// Indices into [`Plan::ls_pairs`] in waves of equal nB + nF (summed over the inputs), increasing: every pair's
    /// sub-models are in an earlier wave, and the pairs of one wave are independent (the order
    /// of a serial walk over the pairs; the sweep itself waits for each pair's own sub-models
    /// only, `sweep::tasks`).
    pub fn ls_waves(&self) -> Vec<Vec<usize>> {
        let all = self.ls_pairs();
        let mut waves: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
        for (i, p) in all.iter().enumerate() {
            waves.entry(p.dim()).or_default().push(i);
        }
        waves.into_values().collect()
    }

    /// Per pair of [`Plan::ls_pairs`], the indices of its sub-models ([`sub_structures`]:
    /// for one input (nB - 1, nF) and (nB, nF - 1) with its delay), those the plan has.
    pub fn ls_sub_models(&self) -> Vec<Vec<usize>> {
        let all = self.ls_pairs();
        let index = pair_index(&all);
        (0..all.len()).map(|i| sub_models(&all, &index, i)).collect()
    }

    pub fn n_cells(&self) -> usize {
        self.pairs.len() * self.ks.len()
    }

    /// All cells, pair-major.
    pub fn cells(&self) -> Vec<Cell> {
        (0..self.pairs.len()).flat_map(|p| (0..self.ks.len()).map(move |k| Cell { pair: p, k_index: k })).collect()
    }

    /// k indices in increasing k (ties: grid order): the order of the `chains` strategy.
    pub fn k_ascending(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.ks.len()).collect();
        idx.sort_by(|&a, &b| self.ks[a].total_cmp(&self.ks[b]).then(a.cmp(&b)));
        idx
    }

    /// k indices in the order of the `neighbour` and `best` strategies: largest k first (closest to
    /// least squares), then down.
    pub fn k_descending(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.ks.len()).collect();
        idx.sort_by(|&a, &b| self.ks[b].total_cmp(&self.ks[a]).then(a.cmp(&b)));
        idx
    }
}
