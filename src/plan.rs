//! The plan: a validated job expanded into structures ("pairs": nB, nF, delay) and cells
//! (a pair and a k).
//!
//! Order is fixed and independent of threads: pairs in (delay, nB, nF) order, k in the job's
//! order. The least-squares phase depends only on the pair (METHOD.md 5), so the pair is the
//! unit that owns it and the cells of a pair share its result.

use crate::job::{self, Job, StartStrategy, ValidJob};

/// A model structure: orders (nB, nF) and input delay.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pair {
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
}

/// All pairs of the given ranges, in plan order.
fn pairs(nb: &[usize], nf: &[usize], delays: &[usize]) -> Vec<Pair> {
    let mut out = Vec::with_capacity(nb.len() * nf.len() * delays.len());
    for &delay in delays {
        for &b in nb {
            for &f in nf {
                out.push(Pair { nb: b, nf: f, delay });
            }
        }
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
    pub pairs: Vec<Pair>,
    pub ks: Vec<f64>,
    pub start: StartStrategy,
}

impl Plan {
    pub fn from_job(job: &ValidJob) -> Plan {
        Plan { pairs: pairs(&job.nb, &job.nf, &job.delays), ks: job.ks.clone(), start: job.job.start }
    }

    /// The plan of a job that was validated before (the job file a run leaves in its
    /// checkpoint, read back by `oesweep merge`): the same plan as [`Plan::from_job`] gave then,
    /// without the checks and the file system access of validation.
    pub fn from_normalised(job: &Job) -> Plan {
        let ([b0, b1], [f0, f1]) = (job.grid.nb, job.grid.nf);
        let [d0, d1] = job.grid.delay.unwrap_or([job.delay.unwrap_or(job::DEFAULT_DELAY); 2]);
        let (nb, nf, delays): (Vec<usize>, Vec<usize>, Vec<usize>) =
            ((b0..=b1).collect(), (f0..=f1).collect(), (d0..=d1).collect());
        Plan { pairs: pairs(&nb, &nf, &delays), ks: job::k_values(&job.grid.k), start: job.start }
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
