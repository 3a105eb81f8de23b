use super::*;
use std::os::unix::fs::PermissionsExt;

/// `merge.sbatch` run by bash with a stand-in oesweep that logs its arguments, exits
/// `merge_status` from `merge` and 5 from anything else: the log and the script's exit code.
fn run_merge_script(merge_status: u8) -> (Vec<String>, Option<i32>) {
    let dir = tempfile::tempdir().unwrap();
    let (script, fake, log) = (dir.path().join("merge.sbatch"), dir.path().join("oesweep"), dir.path().join("log"));
    std::fs::write(&script, MERGE_SBATCH).unwrap();
    let text = format!(
        "#!/bin/sh\necho \"$*\" >> {}\ncase \"$1\" in merge) exit {merge_status} ;; *) exit 5 ;; esac\n",
        log.display()
    );
    std::fs::write(&fake, text).unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let o = std::process::Command::new("bash")
        .arg(&script)
        .args(["/results/out", "--report"])
        .env("OESWEEP", &fake)
        .output()
        .unwrap();
    let calls = std::fs::read_to_string(&log).unwrap_or_default().lines().map(str::to_string).collect();
    (calls, o.status.code())
}

#[test]
fn the_merge_script_submits_the_next_round_when_merge_exits_3_and_only_then() {
    for status in [0, 1, 2] {
        let (calls, code) = run_merge_script(status);
        assert_eq!(calls, ["merge /results/out --report"], "merge exits {status}");
        assert_eq!(code, Some(i32::from(status)), "the job ends as its merge");
    }
    let (calls, code) = run_merge_script(NEXT_ROUND);
    assert_eq!(calls, ["merge /results/out --report", "slurm --next-round /results/out"]);
    assert_eq!(code, Some(5), "the job ends as `oesweep slurm --next-round`");
}

#[test]
fn the_templates_written_are_the_files_of_jobs_slurm() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("jobs/slurm");
    assert_eq!(std::fs::read_to_string(dir.join("merge.sbatch")).unwrap(), MERGE_SBATCH);
    assert_eq!(std::fs::read_to_string(dir.join("sweep.sbatch")).unwrap(), SWEEP_SBATCH);
    // A user's merge script is checked for the same call (layout).
    assert!(MERGE_SBATCH.contains("slurm --next-round"));
}

fn request() -> SlurmRequest {
    SlurmRequest {
        job: "/jobs/three inputs.json".into(),
        shards: 4,
        sbatch: None,
        cpus_per_task: Some(2),
        sbatch_args: vec!["--partition=long".into()],
        report: true,
        max_rounds: None,
    }
}

fn state(rounds: &[Option<usize>]) -> Loop {
    let arrays = rounds
        .iter()
        .enumerate()
        .map(|(i, &round)| Array {
            round,
            sweep_job: Some(format!("{}", 100 + 2 * i)),
            merge_job: Some(format!("{}", 101 + 2 * i)),
        })
        .collect();
    Loop { request: request(), max_rounds: 5, arrays }
}

#[test]
fn the_loop_submits_each_next_round_until_the_search_is_finished() {
    assert_eq!(state(&[Some(1)]).decide(Found::NextRound(2)), Decision::Submit(2));
    assert_eq!(state(&[Some(1), Some(2), Some(3)]).decide(Found::NextRound(5)), Decision::Submit(5));
    // The first array on an earlier run's rows: its round is known from the merge after it.
    assert_eq!(state(&[None]).decide(Found::NextRound(4)), Decision::Submit(4));
    assert_eq!(state(&[Some(1), Some(2)]).decide(Found::Finished), Decision::Finished);
    assert_eq!(state(&[Some(1); 5]).decide(Found::Finished), Decision::Finished, "finished at the bound");
}

#[test]
fn the_loop_stops_without_progress_at_its_bound_and_on_missing_cells() {
    let stop = |s: Loop, found: Found| match s.decide(found) {
        Decision::Stop(why) => why,
        d => panic!("{found:?} after {:?}: {d:?}", s.arrays),
    };
    // The array of round 2 left round 2 waiting: its shards wrote none of its rows.
    let why = stop(state(&[Some(1), Some(2)]), Found::NextRound(2));
    assert!(why.contains("round 2 still waits after the array submitted for round 2 (Slurm job 102)"), "{why}");
    assert!(why.contains("`oesweep slurm '/jobs/three inputs.json' --shards 4 --cpus-per-task 2"), "{why}");
    assert!(why.contains("--sbatch-arg=--partition=long --report`"), "{why}");
    assert!(stop(state(&[Some(3)]), Found::NextRound(1)).contains("round 1 still waits"));
    // Five arrays are the most: the sixth round is not submitted, and the way on doubles it.
    let why = stop(state(&[Some(1), Some(2), Some(3), Some(4), Some(5)]), Found::NextRound(6));
    assert!(why.contains("round 6 waits after 5 arrays, the most --max-rounds allows"), "{why}");
    assert!(why.ends_with("--sbatch-arg=--partition=long --report --max-rounds 10`"), "{why}");
    let why = stop(state(&[Some(1)]), Found::Missing);
    assert!(why.contains("cells of its round are missing"), "{why}");
    assert!(why.contains("`oesweep slurm --next-round OUTPUT` goes on"), "{why}");
}

#[test]
fn the_state_is_read_back_as_written() {
    let dir = tempfile::tempdir().unwrap();
    let err = Loop::read(dir.path()).unwrap_err();
    assert!(err.is_bad_input() && err.to_string().contains("oesweep slurm JOB"), "{err}");
    std::fs::create_dir(dir.path().join("slurm")).unwrap();
    let s = state(&[Some(1), None]);
    s.write(dir.path()).unwrap();
    assert_eq!(Loop::read(dir.path()).unwrap(), s);
    std::fs::write(dir.path().join("slurm").join(STATE_FILE), "{}").unwrap();
    assert!(Loop::read(dir.path()).unwrap_err().to_string().contains("not the state of a Slurm search"));
}

#[test]
fn a_job_environment_is_not_passed_on_but_sbatch_settings_are() {
    for name in ["SLURM_JOB_ID", "SLURM_CPUS_PER_TASK", "SLURM_ARRAY_TASK_ID", "SLURM_MEM_PER_CPU"] {
        assert!(from_the_job(name), "{name}");
    }
    for name in ["SLURM_CONF", "SLURM_CLUSTERS", "SBATCH_PARTITION", "PATH", "OESWEEP"] {
        assert!(!from_the_job(name), "{name}");
    }
}
