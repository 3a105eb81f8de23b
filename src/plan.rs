//! The plan: a validated job expanded into structures ("pairs": nB, nF, delay) and cells
//! (a pair and a k).
//!
//! Order is fixed and independent of threads: pairs in (delay, nB, nF) order, k in the job's
//! order. The least-squares phase depends on the pair and, through its nested starts, on its
//! sub-models' fits (METHOD.md 5.2), so a pair's is finished after theirs
//! ([`Plan::ls_sub_models`]); the pair is the unit that owns its least-squares fit and the
//! cells of a pair share it.

use crate::job::{StartStrategy, ValidJob};

pub use crate::oe::Structure;

/// All pairs of the given ranges, in plan order.
fn pairs(nb: &[usize], nf: &[usize], delays: &[usize]) -> Vec<Structure> {
    let mut out = Vec::with_capacity(nb.len() * nf.len() * delays.len());
    for &delay in delays {
        for &b in nb {
            for &f in nf {
                out.push(Structure::siso(b, f, delay));
            }
        }
    }
    out
}

/// Position of each pair in `pairs`.
fn pair_index(pairs: &[Structure]) -> std::collections::HashMap<(usize, usize, usize), usize> {
    pairs.iter().enumerate().map(|(i, p)| ((p.one().nb, p.one().nf, p.one().delay), i)).collect()
}

/// Indices of pair `i`'s sub-models (nB - 1, nF) and (nB, nF - 1), same delay, in `pairs`.
fn sub_models(
    pairs: &[Structure],
    index: &std::collections::HashMap<(usize, usize, usize), usize>,
    i: usize,
) -> Vec<usize> {
    let p = pairs[i];
    let mut out = Vec::new();
    if p.one().nb > 0 {
        out.extend(index.get(&(p.one().nb - 1, p.one().nf, p.one().delay)));
    }
    if p.one().nf > 0 {
        out.extend(index.get(&(p.one().nb, p.one().nf - 1, p.one().delay)));
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
        Plan {
            pairs: pairs(&job.nb, &job.nf, &job.delays),
            ks: job.ks.clone(),
            start: job.job.start,
            ls_support: Vec::new(),
        }
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

    /// Indices into [`Plan::ls_pairs`] in waves of equal nB + nF, increasing: every pair's
    /// sub-models are in an earlier wave, and the pairs of one wave are independent (the order
    /// of a serial walk over the pairs; the sweep itself waits for each pair's own sub-models
    /// only, `sweep::tasks`).
    pub fn ls_waves(&self) -> Vec<Vec<usize>> {
        let all = self.ls_pairs();
        let mut waves: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
        for (i, p) in all.iter().enumerate() {
            waves.entry(p.one().nb + p.one().nf).or_default().push(i);
        }
        waves.into_values().collect()
    }

    /// Per pair of [`Plan::ls_pairs`], the indices of its sub-models (nB - 1, nF) and
    /// (nB, nF - 1) with its delay, those the plan has.
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
