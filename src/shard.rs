//! Shards: one sweep split over several processes (a Slurm array job, GNU parallel, plain
//! background processes), each writing its own checkpoint folder, merged afterwards.
//!
//! **The unit is the order pair.** The least-squares phase of a pair (and its extra Huber
//! starts, [`crate::estimate::LsFit::alternatives`]) is shared by all its k values, and a
//! continuation chain (`start: chains | neighbour | best`) runs through all of them in order. Splitting a
//! pair would either compute its least-squares phase twice or make one shard wait for
//! another; giving every pair to exactly one shard does neither, and each shard is then simply
//! the sweep of a smaller plan, computed by the same code with the same bits. The one link
//! between pairs is the least-squares phase's nested starts (`solver.nested_starts`, METHOD.md
//! 5.2 step 2): a pair starts from its sub-models' fits, so a shard's plan also lists those
//! sub-models that other shards own (`Plan::ls_support`) and fits them again, without rows.
//! That repeats least-squares work (a shard owning the largest pair refits every smaller one);
//! `solver.nested_starts: false` makes the pairs independent again.
//!
//! **Deterministic layout.** Every shard process computes the whole layout from the job alone
//! and takes its own part, so no coordinator and no shared state are needed: same job and
//! same N give the same partition on every node and every rerun.
//!
//! **Balanced by an estimated cost.** Shards should finish together, since the merge waits for
//! the last one. The cost of a pair is estimated as `(nB + nF) (number of k + 1)`: the
//! parameter count stands for the cost of an iteration, the `+ 1` for the least-squares phase.
//! Measured times also depend on iteration counts, which are not known in advance, so this is
//! only a proxy; it is enough to keep the big pairs apart. The pairs are dealt out greedily,
//! largest first, each to the least loaded shard (longest processing time first, within 4/3
//! of the best possible makespan of the estimate); ties go to the earlier pair and the lower
//! shard, so the result depends on nothing but the plan.
//!
//! **Folders.** Shard I of N keeps its checkpoint in `<output>/parts/shard-I-of-N/`, with its
//! own manifest and job file, so concurrent shards never write the same file.

use crate::error::{Error, Result};
use crate::plan::Plan;
use std::fmt;
use std::str::FromStr;

/// Shard `index` (0-based) of `count`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl FromStr for Shard {
    type Err = String;
    /// `I/N` with 0 <= I < N.
    fn from_str(s: &str) -> std::result::Result<Shard, String> {
        let (i, n) = s.split_once('/').ok_or_else(|| format!("expected I/N (e.g. 0/4), got '{s}'"))?;
        let num = |x: &str| x.trim().parse::<usize>().map_err(|_| format!("'{x}' in '{s}' is not a whole number"));
        let (index, count) = (num(i)?, num(n)?);
        if count == 0 || index >= count {
            return Err(format!("shard {index} of {count}: need N >= 1 and 0 <= I < N"));
        }
        Ok(Shard { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// Name of the shard's checkpoint folder inside `parts/`.
    pub fn folder_name(&self) -> String {
        format!("shard-{}-of-{}", self.index, self.count)
    }

    /// The shard a checkpoint folder name belongs to (`shard-2-of-4` -> 2/4).
    pub fn from_folder_name(name: &str) -> Option<Shard> {
        let (i, n) = name.strip_prefix("shard-")?.split_once("-of-")?;
        let digits = |x: &str| !x.is_empty() && x.bytes().all(|b| b.is_ascii_digit());
        if !(digits(i) && digits(n)) {
            return None;
        }
        format!("{i}/{n}").parse().ok()
    }
}

/// Estimated cost of the order pair `pair` of `plan`, in arbitrary units (see the module
/// documentation).
pub fn pair_cost(plan: &Plan, pair: usize) -> f64 {
    let p = plan.pairs[pair];
    (p.dim() * (plan.ks.len() + 1)) as f64
}

/// The pairs (indices into `plan.pairs`, ascending) of each of `count` shards.
pub fn layout(plan: &Plan, count: usize) -> Vec<Vec<usize>> {
    assert!(count >= 1, "at least one shard");
    let mut order: Vec<usize> = (0..plan.pairs.len()).collect();
    // Largest first; equal costs in plan order (the sort is stable).
    order.sort_by(|&a, &b| pair_cost(plan, b).total_cmp(&pair_cost(plan, a)));
    let mut load = vec![0.0f64; count];
    let mut shards = vec![Vec::new(); count];
    for p in order {
        // The least loaded shard; `min_by` keeps the first of equal loads.
        let s = (0..count).min_by(|&a, &b| load[a].total_cmp(&load[b])).expect("count >= 1");
        load[s] += pair_cost(plan, p);
        shards[s].push(p);
    }
    for s in &mut shards {
        s.sort_unstable();
    }
    shards
}

/// A number of shards for `plan`: at least 1, and at most one per Huber cell of the plan (a
/// typo such as `--shards 1000000000000` must be an error, not a layout that allocates a list
/// per shard and aborts). Returns what is wrong; the caller names the flag or folder.
pub fn check_count(count: usize, plan: &Plan) -> std::result::Result<(), String> {
    let cells = plan.n_cells().max(1);
    if count == 0 {
        Err("the number of shards must be at least 1".into())
    } else if count > cells {
        Err(format!("{count} shards for a job of {cells} cells: at most one shard per cell"))
    } else {
        Ok(())
    }
}

/// The plan of one shard: the full plan restricted to the shard's pairs (k grid, delay and
/// start unchanged), and the shard's pair indices into the full plan.
pub fn plan_of(plan: &Plan, shard: Shard) -> (Plan, Vec<usize>) {
    let pairs = layout(plan, shard.count).swap_remove(shard.index);
    (plan.with_pairs(&pairs), pairs)
}

/// The shard of `count` that owns the pair (nb, nf) of a one-input `plan` (its first delay).
pub fn owner(plan: &Plan, count: usize, nb: usize, nf: usize) -> Result<usize> {
    let p = plan
        .pairs
        .iter()
        .position(|q| q.single().is_some_and(|o| o.nb == nb && o.nf == nf))
        .ok_or_else(|| Error::Invalid(format!("OE({nb}, {nf}) is not an order pair of the plan")))?;
    owner_of(plan, count, p)
}

/// The shard of `count` that owns pair `p` (an index into `plan.pairs`), for any number of
/// inputs.
pub fn owner_of(plan: &Plan, count: usize, p: usize) -> Result<usize> {
    layout(plan, count)
        .iter()
        .position(|s| s.contains(&p))
        .ok_or_else(|| Error::Invalid(format!("pair {p} is not an order pair of the plan")))
}

/// Cells of a plan that a table lacks, by order pair.
#[derive(Debug, Default)]
pub struct Missing {
    /// (pair index into the plan, whether its `ls` row is missing, missing k indices).
    pub pairs: Vec<(usize, bool, Vec<usize>)>,
    pub cells: usize,
    pub ls: usize,
}

impl Missing {
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// One line per incomplete pair (at most `limit`, then a count of the rest), e.g.
    /// `OE(3, 4): ls, k_index 0-5, 9`.
    pub fn lines(&self, plan: &Plan, limit: usize) -> Vec<String> {
        let mut out: Vec<String> = self
            .pairs
            .iter()
            .take(limit)
            .map(|(p, ls, ks)| {
                let pair = plan.pairs[*p];
                let mut what = Vec::new();
                if *ls {
                    what.push("ls".to_string());
                }
                if ks.len() == plan.ks.len() {
                    what.push(format!("all {} k", ks.len()));
                } else if !ks.is_empty() {
                    what.push(format!("k_index {}", ranges(ks)));
                }
                match pair.single() {
                    Some(o) => format!("OE({}, {}): {}", o.nb, o.nf, what.join(", ")),
                    None => format!("{}: {}", pair.label(), what.join(", ")),
                }
            })
            .collect();
        if self.pairs.len() > limit {
            out.push(format!("... and {} more order pairs", self.pairs.len() - limit));
        }
        out
    }
}

/// `[0, 1, 2, 5, 7, 8]` -> `0-2, 5, 7-8`.
pub fn ranges(v: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < v.len() {
        let mut j = i;
        while j + 1 < v.len() && v[j + 1] == v[j] + 1 {
            j += 1;
        }
        parts.push(if j == i { v[i].to_string() } else { format!("{}-{}", v[i], v[j]) });
        i = j + 1;
    }
    parts.join(", ")
}

/// What of `plan` is not in `rows` (rows of other plans are ignored).
pub fn missing(plan: &Plan, rows: &[crate::table::CellRow]) -> Missing {
    use crate::table::RowKey;
    use std::collections::HashSet;
    let have: HashSet<RowKey> = rows.iter().map(|r| r.key).collect();
    let mut m = Missing::default();
    for (p, pair) in plan.pairs.iter().enumerate() {
        let ls = !have.contains(&RowKey::ls(pair));
        let ks: Vec<usize> = (0..plan.ks.len()).filter(|&k| !have.contains(&RowKey::huber(pair, k))).collect();
        if ls || !ks.is_empty() {
            m.cells += ks.len();
            m.ls += ls as usize;
            m.pairs.push((p, ls, ks));
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::job::StartStrategy;
    use crate::plan::Structure;

    fn plan(nb: std::ops::RangeInclusive<usize>, nf: std::ops::RangeInclusive<usize>, n_k: usize) -> Plan {
        let pairs = nb.flat_map(|b| nf.clone().map(move |f| Structure::siso(b, f, 1))).collect();
        Plan {
            pairs,
            ks: (1..=n_k).map(|i| i as f64 / 10.0).collect(),
            start: StartStrategy::Ls,
            ls_support: Vec::new(),
        }
    }

    #[test]
    fn shard_spec_parses_and_names_its_folder() {
        let s: Shard = "2/4".parse().unwrap();
        assert_eq!(s, Shard { index: 2, count: 4 });
        assert_eq!(s.to_string(), "2/4");
        assert_eq!(s.folder_name(), "shard-2-of-4");
        assert_eq!(Shard::from_folder_name("shard-2-of-4"), Some(s));
        for bad in ["4/4", "0/0", "1", "a/3", "-1/3", "1/3/4", ""] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        for bad in ["shard-4-of-4", "shard-1-of-4.deleted-12", "shard--of-4", "part-000001.parquet"] {
            assert_eq!(Shard::from_folder_name(bad), None, "{bad}");
        }
    }

    #[test]
    fn shard_layout_is_a_balanced_partition() {
        let p = plan(7..=14, 4..=15, 40);
        for n in [1, 2, 3, 4, 7, 96, 100] {
            let shards = layout(&p, n);
            assert_eq!(shards.len(), n);
            let mut all: Vec<usize> = shards.iter().flatten().copied().collect();
            all.sort_unstable();
            assert_eq!(all, (0..p.pairs.len()).collect::<Vec<_>>(), "n = {n}: every pair exactly once");
            assert_eq!(shards, layout(&p, n), "deterministic");
            let loads: Vec<f64> = shards.iter().map(|s| s.iter().map(|&q| pair_cost(&p, q)).sum()).collect();
            let (lo, hi) = loads.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &l| (a.min(l), b.max(l)));
            let biggest = (0..p.pairs.len()).map(|q| pair_cost(&p, q)).fold(0.0, f64::max);
            // Greedy LPT: no shard exceeds the lightest by more than one pair.
            assert!(hi - lo <= biggest, "n = {n}: loads {loads:?}");
        }
        let (sub, idx) = plan_of(&p, Shard { index: 1, count: 3 });
        assert_eq!(sub.pairs, idx.iter().map(|&i| p.pairs[i]).collect::<Vec<_>>());
        assert_eq!(sub.ks, p.ks);
        let q = p.pairs[idx[0]];
        assert_eq!(owner(&p, 3, q.one().nb, q.one().nf).unwrap(), 1);
    }

    #[test]
    fn shard_missing_cells_are_listed_compactly() {
        use crate::table::{CellRow, RowKey};
        let p = plan(1..=2, 1..=1, 10);
        let mut rows = vec![CellRow::failed(RowKey::ls(&p.pairs[0]), None, "x".into())];
        for k in [0, 1, 2, 5, 7, 8] {
            rows.push(CellRow::failed(RowKey::huber(&p.pairs[0], k), Some(p.ks[k]), "x".into()));
        }
        let m = missing(&p, &rows);
        assert_eq!((m.cells, m.ls), (4 + 10, 1));
        assert_eq!(m.lines(&p, 10), vec!["OE(1, 1): k_index 3-4, 6, 9", "OE(2, 1): ls, all 10 k"]);
        assert_eq!(m.lines(&p, 1)[1], "... and 1 more order pairs");
    }
}
