//! A dependency-driven list scheduler: the sweep's tasks (least-squares phases, Huber walks)
//! run on the pool's threads as soon as the tasks they read from are done, the ready task of
//! highest priority first (docs/ARCHITECTURE.md, "The schedule").
//!
//! Which thread runs a task and when is not deterministic, but a task reads nothing but the
//! results of the tasks it is declared to come after, and those are final before it starts, so
//! the results are the same whatever the thread count and order. `benches/replay.py` replays
//! the same rule on a run's `--profile` to bound the speed-up on more cores.

use std::collections::BinaryHeap;
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::{Condvar, Mutex};

/// The tasks' dependencies: `after[i]` lists the tasks whose results task `i` reads (each
/// lower or higher than `i`, but acyclic).
pub struct Graph {
    pub after: Vec<Vec<usize>>,
    /// Larger runs first among the ready tasks; ties: the lower index.
    pub priority: Vec<u64>,
}

impl Graph {
    /// Bottom levels: per task, its `cost` plus the largest bottom level of the tasks that come
    /// after it (the longest estimated path from its start to the end of the run). Ordering
    /// ready tasks by it starts the critical path first and the long tasks before the short
    /// ones (Adam, Chandy and Dickson 1974, "HLFET").
    pub fn with_bottom_levels(after: Vec<Vec<usize>>, cost: &[u64]) -> Graph {
        let n = after.len();
        let mut before: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, a) in after.iter().enumerate() {
            for &j in a {
                before[j].push(i);
            }
        }
        let order = topological(&after);
        let mut level = vec![0u64; n];
        for &i in order.iter().rev() {
            level[i] = cost[i] + before[i].iter().map(|&j| level[j]).max().unwrap_or(0);
        }
        Graph { after, priority: level }
    }

    pub fn len(&self) -> usize {
        self.after.len()
    }

    pub fn is_empty(&self) -> bool {
        self.after.is_empty()
    }

    /// Task indices in the order a single worker runs them.
    pub fn serial_order(&self) -> Vec<usize> {
        let mut out = Vec::with_capacity(self.len());
        let mut state = State::new(self);
        while let Some(i) = state.ready.pop().map(|(_, std::cmp::Reverse(i))| i) {
            out.push(i);
            state.finish(self, i);
        }
        out
    }
}

/// Tasks in an order where every task comes after those it depends on.
fn topological(after: &[Vec<usize>]) -> Vec<usize> {
    let n = after.len();
    let mut before: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut waiting: Vec<usize> = after.iter().map(Vec::len).collect();
    for (i, a) in after.iter().enumerate() {
        for &j in a {
            before[j].push(i);
        }
    }
    let mut out: Vec<usize> = (0..n).filter(|&i| waiting[i] == 0).collect();
    let mut next = 0;
    while next < out.len() {
        let i = out[next];
        next += 1;
        for &j in &before[i] {
            waiting[j] -= 1;
            if waiting[j] == 0 {
                out.push(j);
            }
        }
    }
    assert_eq!(out.len(), n, "the sweep's task graph has a cycle");
    out
}

struct State {
    /// Per task, how many of the tasks it comes after are not done.
    waiting: Vec<usize>,
    before: Vec<Vec<usize>>,
    ready: BinaryHeap<(u64, std::cmp::Reverse<usize>)>,
    /// Tasks not yet done (ready, running or waiting).
    left: usize,
    panic: Option<Box<dyn std::any::Any + Send>>,
}

impl State {
    fn new(g: &Graph) -> State {
        let n = g.len();
        let mut before: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, a) in g.after.iter().enumerate() {
            for &j in a {
                before[j].push(i);
            }
        }
        let waiting: Vec<usize> = g.after.iter().map(Vec::len).collect();
        let ready = (0..n).filter(|&i| waiting[i] == 0).map(|i| (g.priority[i], std::cmp::Reverse(i))).collect();
        State { waiting, before, ready, left: n, panic: None }
    }

    fn finish(&mut self, g: &Graph, i: usize) {
        self.left -= 1;
        for k in 0..self.before[i].len() {
            let j = self.before[i][k];
            self.waiting[j] -= 1;
            if self.waiting[j] == 0 {
                self.ready.push((g.priority[j], std::cmp::Reverse(j)));
            }
        }
    }
}

/// Runs every task of `g` (`task(i)`) on `workers` threads of the current rayon pool (at most
/// its size; the others stay idle), each as soon as the tasks it comes after are done. A panic
/// escaping a task is raised again once the others have run.
pub fn run(g: &Graph, workers: usize, task: &(dyn Fn(usize) + Sync)) {
    if g.is_empty() {
        return;
    }
    let state = Mutex::new(State::new(g));
    let wake = Condvar::new();
    let lock = || state.lock().unwrap_or_else(|e| e.into_inner());
    let worker = || {
        let mut s = lock();
        loop {
            if let Some((_, std::cmp::Reverse(i))) = s.ready.pop() {
                drop(s);
                let outcome = catch_unwind(AssertUnwindSafe(|| task(i)));
                s = lock();
                if let Err(e) = outcome {
                    s.panic.get_or_insert(e);
                }
                s.finish(g, i);
                wake.notify_all();
            } else if s.left == 0 {
                return;
            } else {
                s = wake.wait(s).unwrap_or_else(|e| e.into_inner());
            }
        }
    };
    let workers = workers.clamp(1, rayon::current_num_threads());
    rayon::broadcast(|ctx| {
        if ctx.index() < workers {
            worker();
        }
    });
    if let Some(e) = lock().panic.take() {
        resume_unwind(e);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// A diamond and a tail: 0 -> {1, 2} -> 3, and 4 on its own.
    fn diamond() -> Graph {
        Graph::with_bottom_levels(vec![vec![], vec![0], vec![0], vec![1, 2], vec![]], &[1, 5, 2, 1, 3])
    }

    #[test]
    fn bottom_levels_put_the_critical_path_first() {
        let g = diamond();
        assert_eq!(g.priority, vec![7, 6, 3, 1, 3]);
        // 0 (level 7) first; then 1 (6), then 2 and 4 tie at 3 and go by index.
        assert_eq!(g.serial_order(), vec![0, 1, 2, 4, 3]);
    }

    #[test]
    fn every_task_runs_once_after_its_dependencies() {
        let g = diamond();
        for threads in [1, 2, 4] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let done: Vec<AtomicUsize> = (0..g.len()).map(|_| AtomicUsize::new(0)).collect();
            let clock = AtomicUsize::new(1);
            pool.install(|| {
                run(&g, threads, &|i| {
                    for &j in &g.after[i] {
                        assert!(done[j].load(Ordering::SeqCst) > 0, "{i} ran before {j}");
                    }
                    let t = clock.fetch_add(1, Ordering::SeqCst);
                    assert_eq!(done[i].swap(t, Ordering::SeqCst), 0, "{i} ran twice");
                })
            });
            assert!(done.iter().all(|d| d.load(Ordering::SeqCst) > 0));
        }
    }

    #[test]
    fn a_panicking_task_is_raised_after_the_others_ran() {
        let g = diamond();
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let ran = AtomicUsize::new(0);
        let out = catch_unwind(AssertUnwindSafe(|| {
            pool.install(|| {
                run(&g, 2, &|i| {
                    ran.fetch_add(1, Ordering::SeqCst);
                    assert_ne!(i, 1, "task 1 fails");
                })
            })
        }));
        assert!(out.is_err());
        assert_eq!(ran.load(Ordering::SeqCst), 5);
    }
}
