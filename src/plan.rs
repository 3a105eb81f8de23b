//! The plan: a validated job expanded into order pairs and cells (nB, nF, k).
//!
//! Order is fixed and independent of threads: pairs in (nB, nF) order, k in the job's order.
//! The least-squares phase depends only on the pair (METHOD.md 5), so the pair is the unit
//! that owns it and the cells of a pair share its result.

use crate::job::{self, Job, StartStrategy, ValidJob};

/// An order pair (nB, nF).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pair {
    pub nb: usize,
    pub nf: usize,
}

/// One Huber cell: an order pair and an index into the k grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cell {
    pub pair: usize,
    pub k_index: usize,
}

#[derive(Clone, Debug)]
pub struct Plan {
    pub delay: usize,
    pub pairs: Vec<Pair>,
    pub ks: Vec<f64>,
    pub start: StartStrategy,
}

impl Plan {
    pub fn from_job(job: &ValidJob) -> Plan {
        let pairs = job.nb.iter().flat_map(|&nb| job.nf.iter().map(move |&nf| Pair { nb, nf })).collect();
        Plan { delay: job.job.delay, pairs, ks: job.ks.clone(), start: job.job.start }
    }

    /// The plan of a job that was validated before (the job file a run leaves in its
    /// checkpoint, read back by `oesweep merge`): the same plan as [`Plan::from_job`] gave then,
    /// without the checks and the file system access of validation.
    pub fn from_normalised(job: &Job) -> Plan {
        let ([b0, b1], [f0, f1]) = (job.grid.nb, job.grid.nf);
        let pairs = (b0..=b1).flat_map(|nb| (f0..=f1).map(move |nf| Pair { nb, nf })).collect();
        Plan { delay: job.delay, pairs, ks: job::k_values(&job.grid.k), start: job.start }
    }

    /// This plan restricted to some of its pairs (indices into `pairs`, in the order given):
    /// a shard's plan ([`crate::shard`]). A pair's cells are computed exactly as in the full
    /// plan, since nothing in a cell depends on the other pairs.
    pub fn with_pairs(&self, pairs: &[usize]) -> Plan {
        Plan { pairs: pairs.iter().map(|&p| self.pairs[p]).collect(), ..self.clone() }
    }

    pub fn n_cells(&self) -> usize {
        self.pairs.len() * self.ks.len()
    }

    /// All cells, pair-major.
    pub fn cells(&self) -> Vec<Cell> {
        (0..self.pairs.len()).flat_map(|p| (0..self.ks.len()).map(move |k| Cell { pair: p, k_index: k })).collect()
    }

    /// Pair indices by decreasing estimated cost (nB + nF; ties: plan order), the order the
    /// sweep hands pairs to its workers.
    pub fn pairs_by_cost(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.pairs.len()).collect();
        idx.sort_by_key(|&p| (std::cmp::Reverse(self.pairs[p].nb + self.pairs[p].nf), p));
        idx
    }

    /// k indices in increasing k (ties: grid order): the order of the `chains` strategy.
    pub fn k_ascending(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.ks.len()).collect();
        idx.sort_by(|&a, &b| self.ks[a].total_cmp(&self.ks[b]).then(a.cmp(&b)));
        idx
    }

    /// k indices in continuation order: largest k first (closest to least squares), then down.
    pub fn k_chain(&self) -> Vec<usize> {
        let mut idx: Vec<usize> = (0..self.ks.len()).collect();
        idx.sort_by(|&a, &b| self.ks[b].total_cmp(&self.ks[a]).then(a.cmp(&b)));
        idx
    }
}
