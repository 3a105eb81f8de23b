//! Where a run's work goes (`oesweep run --profile FILE`): solver iterations and fits by the
//! role they play, and worker time by phase (docs/PERFORMANCE.md, "Where the time goes").
//!
//! The table's `iterations` column holds the winning fit's iterations of each cell only; the
//! losing chains, the backward pass, the least-squares starts and the polishing of a long
//! record are counted here. Counters are atomics shared by the workers of one run (one
//! [`Profile`] per run, reached through each worker's [`crate::estimate::Workspace`]), so
//! concurrent runs in one process do not mix. Times are worker seconds (summed over the
//! threads); with T busy threads a phase's wall share is about its worker seconds / T. A run
//! without `--profile` carries no profile and pays nothing.
//!
//! The profile also lists the tasks the worker pool ran ([`Schedule`]): per task its kind, its
//! pair, the tasks it waited for and its worker seconds, and the run's serial parts in wall
//! seconds, so that `benches/replay.py` can replay the run on other worker counts.

use serde::Serialize;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// The role of a minimisation (who asked for it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Role {
    /// The least-squares phase of a pair: its starts, the robust detour, the final fits.
    LeastSquares,
    /// A chain's fit in the up walk along k (winning or losing); under the `ls` and `best`
    /// strategies, a cell's fits from the pair's least-squares starts.
    Chain,
    /// A losing chain's fit on the creeping budget.
    Creep,
    /// The backward pass walking down from a jump.
    Back,
    /// The top cell's fits from theta_LS (cold and warm).
    Top,
    /// A long record's cell polished on the whole record from its head's solution.
    Polish,
    /// The boundary probe of a pair whose walk ended on the stability boundary, and the walk
    /// from a probe that won (METHOD.md 5.5).
    Probe,
    /// Anything else: single fits, the warm fits of the `neighbour` and `best` strategies.
    #[default]
    Other,
}

impl Role {
    pub const ALL: [Role; 8] =
        [Role::LeastSquares, Role::Chain, Role::Creep, Role::Back, Role::Top, Role::Polish, Role::Probe, Role::Other];

    pub fn as_str(self) -> &'static str {
        match self {
            Role::LeastSquares => "least_squares",
            Role::Chain => "chain",
            Role::Creep => "creep",
            Role::Back => "back",
            Role::Top => "top",
            Role::Polish => "polish",
            Role::Probe => "probe",
            Role::Other => "other",
        }
    }
}

/// Phases of worker time. The solver's time is split by [`Role`]; `Evidence` and `Judge` are
/// inside the least-squares and Huber phases but outside the solver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Reading and checking the job and its records (wall).
    Read,
    /// The spectral estimate of the estimation record (workers: a task of the sweep,
    /// [`crate::spectral::Deferred`]).
    Spectrum,
    /// The least-squares phase of every pair: initial guesses, solver, assessment (workers).
    LeastSquares,
    /// The Huber phase of every pair: chains, backward pass, assessment (workers).
    Huber,
    /// Covariance, residual tests and robust criteria of every reported fit (workers).
    Evidence,
    /// Fit %, the validation simulation and the band fit of every reported fit (workers).
    Judge,
    /// The sweep from its first to its last cell (wall).
    Sweep,
    /// Reducing to the picks and writing the result files (wall).
    Write,
}

impl Phase {
    pub const ALL: [Phase; 8] = [
        Phase::Read,
        Phase::Spectrum,
        Phase::LeastSquares,
        Phase::Huber,
        Phase::Evidence,
        Phase::Judge,
        Phase::Sweep,
        Phase::Write,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Read => "read",
            Phase::Spectrum => "spectrum",
            Phase::LeastSquares => "least_squares_phase",
            Phase::Huber => "huber_phase",
            Phase::Evidence => "evidence",
            Phase::Judge => "judge",
            Phase::Sweep => "sweep",
            Phase::Write => "write",
        }
    }
}

const ROLES: usize = Role::ALL.len();
const PHASES: usize = Phase::ALL.len();

/// The counters of one run.
#[derive(Debug, Default)]
pub struct Profile {
    fits: [AtomicU64; ROLES],
    iterations: [AtomicU64; ROLES],
    solver_nanos: [AtomicU64; ROLES],
    phase_nanos: [AtomicU64; PHASES],
    schedule: Mutex<Schedule>,
}

fn nanos(since: Instant) -> u64 {
    since.elapsed().as_nanos().min(u64::MAX as u128) as u64
}

impl Profile {
    /// One minimisation of `role` that took `iterations` and started at `since`.
    pub fn fit(&self, role: Role, iterations: usize, since: Instant) {
        let i = role as usize;
        self.fits[i].fetch_add(1, Ordering::Relaxed);
        self.iterations[i].fetch_add(iterations as u64, Ordering::Relaxed);
        self.solver_nanos[i].fetch_add(nanos(since), Ordering::Relaxed);
    }

    /// `seconds` more of `phase`.
    pub fn add_seconds(&self, phase: Phase, seconds: f64) {
        self.phase_nanos[phase as usize].fetch_add((seconds * 1e9) as u64, Ordering::Relaxed);
    }

    /// Time of `phase` from `since` to now.
    pub fn add(&self, phase: Phase, since: Instant) {
        self.phase_nanos[phase as usize].fetch_add(nanos(since), Ordering::Relaxed);
    }

    /// The sweep's tasks before they run (their `seconds` 0), and how many may run at once.
    pub fn plan_tasks(&self, tasks: Vec<TaskTime>, workers: Workers) {
        let mut s = self.schedule.lock().unwrap_or_else(|e| e.into_inner());
        s.tasks = tasks;
        s.workers = Some(workers);
    }

    /// Task `id` of [`Profile::plan_tasks`] took the time from `since` to now.
    pub fn task(&self, id: usize, since: Instant) {
        let seconds = since.elapsed().as_secs_f64();
        let mut s = self.schedule.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(t) = s.tasks.get_mut(id) {
            t.seconds += seconds;
        }
    }

    /// `seconds` of wall time that no worker shared, in run order.
    pub fn serial(&self, part: &'static str, seconds: f64) {
        let mut s = self.schedule.lock().unwrap_or_else(|e| e.into_inner());
        match s.serial.iter_mut().find(|p| p.part == part) {
            Some(p) => p.seconds += seconds,
            None => s.serial.push(PartTime { part, seconds }),
        }
    }

    /// The wall time of the pool's tasks, from the first task's start to the last one's end.
    pub fn tasks_wall(&self, seconds: f64) {
        self.schedule.lock().unwrap_or_else(|e| e.into_inner()).wall_seconds += seconds;
    }

    /// The counters as they are now.
    pub fn report(&self) -> ProfileReport {
        let get = |a: &AtomicU64| a.load(Ordering::Relaxed);
        let roles = Role::ALL
            .iter()
            .map(|&r| {
                let i = r as usize;
                RoleCount {
                    role: r.as_str(),
                    fits: get(&self.fits[i]),
                    iterations: get(&self.iterations[i]),
                    solver_seconds: get(&self.solver_nanos[i]) as f64 * 1e-9,
                }
            })
            .collect();
        let phases = Phase::ALL
            .iter()
            .map(|&p| PhaseTime { phase: p.as_str(), seconds: get(&self.phase_nanos[p as usize]) as f64 * 1e-9 })
            .collect();
        let schedule = self.schedule.lock().unwrap_or_else(|e| e.into_inner()).clone();
        ProfileReport { roles, phases, schedule }
    }
}

/// Adds the time from its creation to its drop to a phase of an optional profile.
pub struct Span<'a> {
    profile: Option<&'a Profile>,
    phase: Phase,
    since: Instant,
}

impl<'a> Span<'a> {
    pub fn start(profile: Option<&'a Profile>, phase: Phase) -> Self {
        Span { profile, phase, since: Instant::now() }
    }
}

impl Drop for Span<'_> {
    fn drop(&mut self) {
        if let Some(p) = self.profile {
            p.add(self.phase, self.since);
        }
    }
}

/// Solver work of one role.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct RoleCount {
    pub role: &'static str,
    /// Minimisations run.
    pub fits: u64,
    /// Their iterations (normal equations built).
    pub iterations: u64,
    /// Worker seconds inside the solver.
    pub solver_seconds: f64,
}

/// Time of one phase (worker seconds, or wall seconds for the phases marked so in [`Phase`]).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PhaseTime {
    pub phase: &'static str,
    pub seconds: f64,
}

/// One task of the worker pool: a unit of work one worker runs from start to end.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct TaskTime {
    /// Its index in [`Schedule::tasks`].
    pub id: usize,
    /// `least_squares_own` (a pair's own least-squares minima), `least_squares` (a pair's
    /// least-squares phase finished), `chains` (a pair's Huber cells under the `chains`
    /// strategy: the walk, the backward pass, the whole-record refits, the evidence),
    /// `neighbour` (a pair's Huber cells under `neighbour`/`best`), `cell` (one Huber cell under
    /// `ls`), `nested` (one Huber cell's nested check, METHOD.md 5.6) or `spectrum` (the
    /// spectral estimate of the band fits, before every `least_squares`; its pair's orders 0).
    pub kind: &'static str,
    pub nb: usize,
    pub nf: usize,
    pub delay: usize,
    /// The cell's k index (kinds `cell` and `nested` only).
    pub k_index: Option<usize>,
    /// The ids of the tasks whose results it reads: it starts once they are done.
    pub after: Vec<usize>,
    /// The sweep's priority among ready tasks (larger first; ties: the lower id): the
    /// estimated cost of the longest path from the task to the end of the sweep.
    pub priority: u64,
    /// Worker seconds (0 when it did not run: stopped, or taken from a checkpoint).
    pub seconds: f64,
}

/// How many workspaces, so tasks, may run at once ([`crate::sweep::live_workspaces`]).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct Workers {
    /// The pool's threads (`--threads`, or the cores).
    pub threads: usize,
    /// Tasks that ran at once at most: min(threads, cap).
    pub live: usize,
    /// Samples of the longest record a workspace holds buffers of.
    pub record_rows: usize,
    /// The bytes a workspace is budgeted for on that record.
    pub workspace_bytes: usize,
    /// The workspaces' budget, and the count allowed whatever it says: cap =
    /// max(min_live, budget_bytes / workspace_bytes).
    pub budget_bytes: usize,
    pub min_live: usize,
}

/// Wall seconds of a serial part of the run.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PartTime {
    pub part: &'static str,
    pub seconds: f64,
}

/// The sweep's tasks and the run's serial parts, for a replay on other worker counts.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Schedule {
    pub workers: Option<Workers>,
    pub tasks: Vec<TaskTime>,
    /// In run order: `read` (reading and checking the job and records; the spectral estimate
    /// is a task, kind `spectrum`), `setup` (checkpoint, plan, pool), `sweep_serial` (the sweep's wall outside
    /// its tasks: collecting and sorting the rows), `nested` (the waves of `sweep::nested_pass`,
    /// their wall time, when a profiled run runs them: a whole run checks its cells as tasks)
    /// and `write` (reducing and writing).
    pub serial: Vec<PartTime>,
    /// Wall seconds from the first task's start to the last task's end.
    pub wall_seconds: f64,
}

/// What `--profile` writes (JSON) and prints.
#[derive(Clone, Debug, Serialize)]
pub struct ProfileReport {
    pub roles: Vec<RoleCount>,
    pub phases: Vec<PhaseTime>,
    pub schedule: Schedule,
}

impl ProfileReport {
    pub fn iterations(&self) -> u64 {
        self.roles.iter().map(|r| r.iterations).sum()
    }

    pub fn fits(&self) -> u64 {
        self.roles.iter().map(|r| r.fits).sum()
    }

    pub fn seconds(&self, phase: Phase) -> f64 {
        self.phases.iter().find(|p| p.phase == phase.as_str()).map_or(0.0, |p| p.seconds)
    }

    /// The report as a text table.
    pub fn table(&self) -> String {
        use std::fmt::Write;
        let mut s = String::from("solver work by role:\n  role             fits  iterations  per fit  solver s\n");
        for r in self.roles.iter().filter(|r| r.fits > 0) {
            let per = r.iterations as f64 / r.fits as f64;
            let _ = writeln!(
                s,
                "  {:<14} {:>6} {:>11} {:>8.1} {:>9.2}",
                r.role, r.fits, r.iterations, per, r.solver_seconds
            );
        }
        let (f, i) = (self.fits(), self.iterations());
        let solver: f64 = self.roles.iter().map(|r| r.solver_seconds).sum();
        let _ = writeln!(s, "  {:<14} {:>6} {:>11} {:>8.1} {:>9.2}", "all", f, i, i as f64 / f.max(1) as f64, solver);
        s.push_str("time by phase (s; workers' summed for the phases inside the sweep):\n");
        for p in &self.phases {
            let _ = writeln!(s, "  {:<20} {:>9.3}", p.phase, p.seconds);
        }
        let tasks = &self.schedule.tasks;
        if !tasks.is_empty() {
            let worker: f64 = tasks.iter().map(|t| t.seconds).sum();
            let longest = tasks.iter().map(|t| t.seconds).fold(0.0, f64::max);
            let serial: f64 = self.schedule.serial.iter().map(|p| p.seconds).sum();
            let _ = writeln!(
                s,
                "tasks: {} ({:.3} worker s, the longest {:.3} s) in {:.3} wall s; serial parts {:.3} s",
                tasks.len(),
                worker,
                longest,
                self.schedule.wall_seconds,
                serial
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_add_up_by_role_and_phase() {
        let p = Profile::default();
        let t = Instant::now();
        p.fit(Role::Chain, 4, t);
        p.fit(Role::Chain, 6, t);
        p.fit(Role::Top, 3, t);
        {
            let _s = Span::start(Some(&p), Phase::Evidence);
        }
        let r = p.report();
        assert_eq!(r.iterations(), 13);
        assert_eq!(r.fits(), 3);
        let chain = r.roles.iter().find(|c| c.role == "chain").unwrap();
        assert_eq!((chain.fits, chain.iterations), (2, 10));
        assert!(r.seconds(Phase::Evidence) >= 0.0);
        assert!(r.table().contains("chain"));
    }
}
