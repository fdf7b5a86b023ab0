//! A plan on a Slurm cluster: its cells as array jobs, one per stage (reference parts, their
//! merges, the cells measured against them), each stage started by `--dependency=afterok:` on
//! the one before; the record of what was submitted; and the cells' states as Slurm sees them.
//!
//! An array task runs `vmerge batch PLAN --cell NAME`, which decides when it starts whether
//! its cell renders, continues from its snapshot or is already done: so a task that Slurm
//! requeues (preemption, a node failure, `scontrol requeue`) continues where its last snapshot
//! left it instead of starting over.

use super::cell::{make_output, Budget, Cell, CellKind, ReferenceSource, State};
use super::run::{command_line, planned, quote, run_cell, slurm_time, states, Event};
use super::{BatchError, Plan};
use crate::accel::AccelKind;
use crate::film::atomic_write;
use crate::render::StopFlag;
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

/// The plan's `[slurm]` table.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SlurmSettings {
    pub partition: Option<String>,
    pub account: Option<String>,
    /// Every task's time limit, over the one derived from the budgets.
    pub time_limit: Option<Duration>,
    /// Every task's memory in bytes, over vmerge's own estimate.
    pub mem: Option<u64>,
    /// Further `#SBATCH` options, as written (`--qos=low`).
    pub sbatch: Vec<String>,
}

/// The file in the plan's output folder that records what `--submit` submitted.
pub const RECORD: &str = "slurm-jobs.toml";

/// Memory a task needs beyond vmerge's estimate of the render: the program, the scene and its
/// acceleration structure, which the estimate leaves out.
const MEMORY_ALLOWANCE: u64 = 512 << 20;

/// The cells to bring up to date, by stage: a cell's stage is one more than the latest of the
/// stages of the cells it waits for (its reference, or a merge's parts), so every stage can
/// start once the one before it has ended well. Also the number of cells that cannot run at
/// all (a reference file that is not there).
pub fn stages(plan: &Plan) -> (Vec<Vec<usize>>, usize) {
    let states = states(plan);
    let all = planned(plan, &states, false);
    let pending: Vec<usize> = all.iter().map(|(i, _)| *i).collect();
    let mut stage_of = vec![0usize; plan.cells.len()];
    let mut stages: Vec<Vec<usize>> = Vec::new();
    // `planned` lists each cell after those it waits for.
    for &i in &pending {
        let waits_for: Vec<usize> = match (&plan.cells[i].kind, &plan.cells[i].reference) {
            (CellKind::Merge { parts }, _) => parts.clone(),
            (_, Some(ReferenceSource::Cell(j))) => vec![*j],
            _ => Vec::new(),
        };
        let stage = waits_for
            .iter()
            .filter(|j| pending.contains(j))
            .map(|&j| stage_of[j] + 1)
            .max()
            .unwrap_or(0);
        stage_of[i] = stage;
        if stages.len() <= stage {
            stages.resize(stage + 1, Vec::new());
        }
        stages[stage].push(i);
    }
    let blocked = states
        .iter()
        .filter(|s| !matches!(s, State::Done { .. }))
        .count()
        - pending.len();
    (stages, blocked)
}

/// The time limit of a stage's tasks: the plan's `time_limit`, else the longest time or CPU
/// budget with a fifth more and ten minutes for loading the scene and writing the image. Iteration
/// budgets say nothing about time: a stage with one gets the partition's default limit.
fn time_limit(plan: &Plan, cells: &[usize]) -> Option<Duration> {
    if let Some(t) = plan.slurm.time_limit {
        return Some(t);
    }
    let times: Option<Vec<Duration>> = cells
        .iter()
        .map(|&i| match (&plan.cells[i].kind, plan.cells[i].budget) {
            (CellKind::Merge { .. }, _) => Some(Duration::ZERO),
            (_, Budget::Time(t)) => Some(t),
            // Slurm gives a task its cores alone, so its wall time is at most its CPU time.
            (_, Budget::CpuTime(t)) => Some(t),
            (_, Budget::Iterations(_)) => None,
        })
        .collect();
    let longest = times?.into_iter().max()?;
    Some(longest.mul_f64(1.2) + Duration::from_secs(600))
}

/// A stage's memory in MiB: the plan's `mem`, else vmerge's estimate for its largest cell (the
/// one `--memory-limit` is held against) and [`MEMORY_ALLOWANCE`]. Unknown when a cell takes
/// its resolution from its scene.
fn memory_mib(plan: &Plan, cells: &[usize]) -> Option<u64> {
    let bytes = match plan.slurm.mem {
        Some(m) => m,
        None => {
            let threads = plan.threads.unwrap_or_else(|| {
                std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
            });
            let needs: Option<Vec<u64>> = cells
                .iter()
                .map(|&i| {
                    let o = &plan.cells[i].options;
                    let [w, h] = o.resolution?;
                    // Without the scene's own limit, the longest paths the roulette allows.
                    let max_path_length = match o.max_path_length {
                        Some(0) | None => u32::MAX,
                        Some(n) => n,
                    };
                    let need = crate::memory::estimate(
                        o.technique,
                        o.memory,
                        w as u64 * h as u64,
                        max_path_length,
                        o.roulette,
                        threads,
                    );
                    Some(need.total())
                })
                .collect();
            needs?.into_iter().max()?.saturating_add(MEMORY_ALLOWANCE)
        }
    };
    Some(bytes.div_ceil(1 << 20))
}

/// An absolute path, so that tasks find it from any working directory.
fn absolute(path: &Path) -> Result<PathBuf, BatchError> {
    std::path::absolute(path).map_err(|e| BatchError::Write {
        file: path.into(),
        message: e.to_string(),
    })
}

/// The sbatch script of one stage: an array job, task i bringing `cells[i]` up to date.
fn stage_script(
    plan: &Plan,
    program: &Path,
    stage: usize,
    count: usize,
    cells: &[usize],
) -> Result<String, BatchError> {
    let plan_file = absolute(&plan.file)?;
    let output = absolute(&plan.output)?;
    let stem = plan_file
        .file_stem()
        .map_or("plan".into(), |s| s.to_string_lossy().into_owned());
    let mut s = String::from("#!/usr/bin/env bash\n");
    let _ = writeln!(
        s,
        "# vmerge batch {}: stage {} of {count}, {} cells, one array task each.",
        plan_file.display(),
        stage + 1,
        cells.len()
    );
    let mut option = |text: String| {
        let _ = writeln!(s, "#SBATCH {text}");
    };
    option(format!(
        "--job-name={}",
        quote(&format!("vmerge-{stem}-{stage}"))
    ));
    option(format!("--array=0-{}", cells.len().saturating_sub(1)));
    // Requeued tasks (preemption, node failure) continue from their cell's snapshot, and
    // their log goes on in the same file.
    option("--requeue".into());
    option("--open-mode=append".into());
    // A later stage whose cells can never start (a task of this one failed) leaves the queue.
    option("--kill-on-invalid-dep=yes".into());
    if let Some(n) = plan.threads {
        option(format!("--cpus-per-task={n}"));
    }
    if let Some(t) = time_limit(plan, cells) {
        option(format!("--time={}", slurm_time(t)));
    }
    if let Some(mib) = memory_mib(plan, cells) {
        option(format!("--mem={mib}M"));
    }
    if let Some(p) = &plan.slurm.partition {
        option(format!("--partition={p}"));
    }
    if let Some(a) = &plan.slurm.account {
        option(format!("--account={a}"));
    }
    for line in &plan.slurm.sbatch {
        option(line.clone());
    }
    let log = output.join("slurm-%A_%a.log");
    option(format!("--output={}", quote(&log.to_string_lossy())));
    s.push_str("set -euo pipefail\n");
    s.push_str("case \"${SLURM_ARRAY_TASK_ID:?set by sbatch --array}\" in\n");
    let plan_arg = plan_file.to_string_lossy().into_owned();
    for (task, &i) in cells.iter().enumerate() {
        let args = [
            "batch".to_string(),
            plan_arg.clone(),
            "--cell".into(),
            plan.cells[i].name.clone(),
        ];
        let _ = writeln!(s, "    {task}) exec {} ;;", command_line(program, &args));
    }
    s.push_str(
        "    *) echo \"no array task $SLURM_ARRAY_TASK_ID in this script\" >&2; exit 2 ;;\n",
    );
    s.push_str("esac\n");
    Ok(s)
}

/// One stage's sbatch script and the cells of its array tasks.
struct StageScript {
    text: String,
    cells: Vec<usize>,
}

/// The stages' scripts, and the cells that cannot run.
fn scripts(plan: &Plan, program: &Path) -> Result<(Vec<StageScript>, usize), BatchError> {
    make_output(&plan.output)?;
    let (stages, blocked) = stages(plan);
    let scripts = stages
        .iter()
        .enumerate()
        .map(|(k, cells)| {
            Ok(StageScript {
                text: stage_script(plan, program, k, stages.len(), cells)?,
                cells: cells.clone(),
            })
        })
        .collect::<Result<_, BatchError>>()?;
    Ok((scripts, blocked))
}

/// The heredoc delimiter around each stage's script in the driver.
const DELIMITER: &str = "VMERGE_STAGE";

/// Writes to `file` a driver that submits every stage with `sbatch`, each but the first with
/// `--dependency=afterok:` on the one before, and prints the job ids: one file that holds all
/// the `#SBATCH` lines to edit before `bash FILE`. Returns the number of array tasks per stage
/// and the number of cells that cannot run.
pub fn slurm(plan: &Plan, program: &Path, file: &Path) -> Result<(Vec<usize>, usize), BatchError> {
    plan.check_script(file)?;
    let (scripts, blocked) = scripts(plan, program)?;
    let mut s = String::from("#!/usr/bin/env bash\n");
    let _ = writeln!(
        s,
        "# Submits vmerge batch {} to Slurm: {} stages, each an array job that starts once the\n\
         # one before it has ended well. Edit the #SBATCH lines, then run: bash {}",
        plan.file.display(),
        scripts.len(),
        quote(&file.to_string_lossy())
    );
    s.push_str("set -euo pipefail\n");
    for (k, stage) in scripts.iter().enumerate() {
        let (script, cells) = (&stage.text, &stage.cells);
        let dependency = if k == 0 {
            String::new()
        } else {
            format!(" --dependency=afterok:\"$job{}\"", k - 1)
        };
        let _ = write!(
            s,
            "job{k}=$(sbatch --parsable{dependency} <<'{DELIMITER}'\n{script}{DELIMITER}\n)\n\
             job{k}=${{job{k}%%;*}}\n\
             echo \"stage {}: job $job{k} ({} cells)\"\n",
            k + 1,
            cells.len()
        );
    }
    atomic_write(file, |f| f.write_all(s.as_bytes())).map_err(|e| BatchError::Write {
        file: file.into(),
        message: e.to_string(),
    })?;
    Ok((scripts.iter().map(|s| s.cells.len()).collect(), blocked))
}

/// One array task of a submission.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Task {
    pub cell: String,
    /// The array job's id.
    pub job: String,
    /// The task's index in its array.
    pub task: usize,
    pub stage: usize,
}

impl Task {
    /// `12_3`, as Slurm names an array task.
    pub fn id(&self) -> String {
        format!("{}_{}", self.job, self.task)
    }
}

#[derive(Debug, Default, Serialize, Deserialize)]
struct Record {
    task: Vec<Task>,
}

fn record_path(plan: &Plan) -> PathBuf {
    plan.output.join(RECORD)
}

/// The tasks submitted for the plan's cells, the latest for each cell; none when nothing was.
pub fn submitted(plan: &Plan) -> Result<Vec<Task>, BatchError> {
    let file = record_path(plan);
    let text = match std::fs::read_to_string(&file) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => {
            return Err(BatchError::Plan {
                file,
                message: e.to_string(),
            })
        }
    };
    let record: Record = toml::from_str(&text).map_err(|e| BatchError::Plan {
        file,
        message: e.to_string(),
    })?;
    Ok(record.task)
}

fn write_record(plan: &Plan, tasks: &[Task]) -> Result<(), BatchError> {
    let file = record_path(plan);
    let text = toml::to_string(&Record {
        task: tasks.to_vec(),
    })
    .map_err(|e| BatchError::Write {
        file: file.clone(),
        message: e.to_string(),
    })?;
    atomic_write(&file, |f| f.write_all(text.as_bytes())).map_err(|e| BatchError::Write {
        file,
        message: e.to_string(),
    })
}

/// Runs a Slurm command, returning its standard output.
fn slurm_command(
    program: &str,
    args: &[String],
    input: Option<&str>,
) -> Result<String, BatchError> {
    let failed = |message: String| BatchError::Slurm {
        command: format!("{program} {}", args.join(" ")),
        message,
    };
    let mut child = Command::new(program)
        .args(args)
        .stdin(if input.is_some() {
            Stdio::piped()
        } else {
            Stdio::null()
        })
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| failed(e.to_string()))?;
    if let (Some(text), Some(mut stdin)) = (input, child.stdin.take()) {
        stdin
            .write_all(text.as_bytes())
            .map_err(|e| failed(e.to_string()))?;
    }
    let out = child
        .wait_with_output()
        .map_err(|e| failed(e.to_string()))?;
    if !out.status.success() {
        return Err(failed(format!(
            "{} ({})",
            String::from_utf8_lossy(&out.stderr).trim(),
            out.status
        )));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// What `--submit` did.
#[derive(Clone, Debug)]
pub struct Submission {
    /// Each stage's job id and number of tasks.
    pub jobs: Vec<(String, usize)>,
    /// Cells that cannot run (a reference file that is not there).
    pub blocked: usize,
}

/// Submits every stage of the plan with `sbatch`, each but the first with
/// `--dependency=afterok:` on the one before, and records the tasks in the output folder
/// ([`RECORD`], written after each stage so that a failed `sbatch` leaves the earlier ones
/// known). Refuses while a cell of the plan is still queued or running from an earlier
/// submission, since two tasks would then write one cell.
pub fn submit(plan: &Plan, program: &Path) -> Result<Submission, BatchError> {
    let earlier = submitted(plan)?;
    let asked = slurm_states(&earlier);
    let busy: Vec<String> = earlier
        .iter()
        .filter(|t| {
            asked
                .states
                .get(&t.id())
                .is_some_and(|s| matches!(class(s), "queued" | "running"))
        })
        .map(|t| format!("{} ({})", t.cell, t.id()))
        .collect();
    if !busy.is_empty() {
        // A sweep has hundreds of cells: the first few name the jobs.
        let mut cells = busy[..busy.len().min(4)].join(", ");
        if busy.len() > 4 {
            let _ = write!(cells, " and {} more", busy.len() - 4);
        }
        return Err(BatchError::Busy { cells });
    }
    let (scripts, blocked) = scripts(plan, program)?;
    let mut record = earlier;
    let mut jobs = Vec::new();
    for (k, stage) in scripts.iter().enumerate() {
        let (script, cells) = (&stage.text, &stage.cells);
        let mut args = vec!["--parsable".to_string()];
        if let Some((previous, _)) = jobs.last() {
            args.push(format!("--dependency=afterok:{previous}"));
        }
        let out = slurm_command("sbatch", &args, Some(script))?;
        // `ID` or `ID;CLUSTER`.
        let id = out.trim().split(';').next().unwrap_or("").to_string();
        if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
            return Err(BatchError::Slurm {
                command: format!("sbatch {}", args.join(" ")),
                message: format!("expected a job id, got '{}'", out.trim()),
            });
        }
        let names: Vec<&str> = cells.iter().map(|&i| plan.cells[i].name.as_str()).collect();
        record.retain(|t| !names.contains(&t.cell.as_str()));
        record.extend(names.iter().enumerate().map(|(task, cell)| Task {
            cell: cell.to_string(),
            job: id.clone(),
            task,
            stage: k,
        }));
        write_record(plan, &record)?;
        jobs.push((id, cells.len()));
    }
    Ok(Submission { jobs, blocked })
}

/// Array tasks' states (`RUNNING`, `COMPLETED`, ...) by task id (`12_3`), and where they came
/// from.
#[derive(Debug, Default)]
pub struct Asked {
    pub states: HashMap<String, String>,
    pub sources: Vec<&'static str>,
}

/// Asks `squeue` for every state the controller still holds (finished jobs stay for
/// `MinJobAge`), then `sacct` for the tasks it no longer does (where accounting storage is
/// set up); either may be missing, and then the files alone tell.
pub fn slurm_states(tasks: &[Task]) -> Asked {
    let mut asked = Asked::default();
    let mut jobs: Vec<&str> = tasks.iter().map(|t| t.job.as_str()).collect();
    jobs.sort();
    jobs.dedup();
    if jobs.is_empty() {
        return asked;
    }
    let list = jobs.join(",");
    let squeue = [
        "--noheader",
        "--array",
        "--states=all",
        "--format=%i|%T",
        &format!("--jobs={list}"),
    ]
    .map(String::from);
    if let Ok(out) = slurm_command("squeue", &squeue, None) {
        asked.sources.push("squeue");
        read_states(&out, &mut asked.states);
    }
    if tasks.iter().any(|t| !asked.states.contains_key(&t.id())) {
        let sacct = [
            "--noheader",
            "--parsable2",
            "--allocations",
            "--format=JobID,State",
            &format!("--jobs={list}"),
        ]
        .map(String::from);
        if let Ok(out) = slurm_command("sacct", &sacct, None) {
            let mut found = HashMap::new();
            read_states(&out, &mut found);
            if !found.is_empty() {
                asked.sources.push("sacct");
            }
            for (id, state) in found {
                asked.states.entry(id).or_insert(state);
            }
        }
    }
    asked
}

/// `ID|STATE` lines; sacct writes `CANCELLED by 0`, squeue `CANCELLED`.
fn read_states(text: &str, into: &mut HashMap<String, String>) {
    for line in text.lines() {
        if let Some((id, state)) = line.trim().split_once('|') {
            let state = state.split_whitespace().next().unwrap_or("");
            if !id.is_empty() && !state.is_empty() {
                into.insert(id.to_string(), state.to_string());
            }
        }
    }
}

/// A Slurm job state in four words: queued, running, done or failed.
pub fn class(state: &str) -> &'static str {
    match state {
        "PENDING" | "REQUEUED" | "REQUEUE_HOLD" | "REQUEUE_FED" | "RESV_DEL_HOLD" => "queued",
        "RUNNING" | "CONFIGURING" | "COMPLETING" | "SUSPENDED" | "STAGE_OUT" | "SIGNALING"
        | "RESIZING" => "running",
        "COMPLETED" => "done",
        _ => "failed",
    }
}

/// The submitted tasks as Slurm sees them, one line each (`running 12_3 RUNNING CELL`), and a
/// summary; `None` when the plan was never submitted.
pub fn slurm_status(plan: &Plan) -> Result<Option<String>, BatchError> {
    let tasks = submitted(plan)?;
    if tasks.is_empty() {
        return Ok(None);
    }
    let asked = slurm_states(&tasks);
    let mut text = String::new();
    let mut counts: Vec<(&str, usize)> = ["queued", "running", "done", "failed", "unknown"]
        .into_iter()
        .map(|c| (c, 0))
        .collect();
    for task in &tasks {
        let (word, state) = match asked.states.get(&task.id()) {
            Some(s) => (class(s), s.as_str()),
            None => ("unknown", "-"),
        };
        if let Some(c) = counts.iter_mut().find(|(w, _)| *w == word) {
            c.1 += 1;
        }
        let _ = writeln!(
            text,
            "{word:<8} {:<10} {state:<12} {}",
            task.id(),
            task.cell
        );
    }
    let mut jobs: Vec<&str> = tasks.iter().map(|t| t.job.as_str()).collect();
    jobs.dedup();
    let source = if asked.sources.is_empty() {
        "neither squeue nor sacct answered: the cells' files above tell".to_string()
    } else {
        format!("from {}", asked.sources.join(" and "))
    };
    let summary: Vec<String> = counts
        .iter()
        .filter(|(w, n)| *n > 0 || *w != "unknown")
        .map(|(w, n)| format!("{n} {w}"))
        .collect();
    let _ = writeln!(
        text,
        "Slurm jobs {} ({source}): {}",
        jobs.join(", "),
        summary.join(", ")
    );
    Ok(Some(text))
}

/// Brings the cell named `name` up to date in this process: what an array task runs. Returns
/// whether the cell is done (it is not when `stop` was raised first); a cell already done
/// is left as it is, so that a requeued task that had finished does nothing.
pub fn run_one(
    plan: &Plan,
    name: &str,
    accel: AccelKind,
    stop: &StopFlag,
    on: &mut dyn FnMut(&Event),
) -> Result<bool, BatchError> {
    let Some(i) = plan.cells.iter().position(|c| c.name == name) else {
        return Err(BatchError::Plan {
            file: plan.file.clone(),
            message: format!("no cell named '{name}'"),
        });
    };
    make_output(&plan.output)?;
    let states = states(plan);
    let done = |j: usize| matches!(states[j], State::Done { .. });
    if done(i) {
        return Ok(true);
    }
    let cell: &Cell = &plan.cells[i];
    let Some(action) = cell.action(&states[i], &plan.cells, &done) else {
        return Err(BatchError::Waits { cell: name.into() });
    };
    on(&Event::Cell {
        name,
        action: &action,
    });
    run_cell(plan, cell, &action, accel, stop, &mut None, on)?;
    on(&Event::Finished);
    Ok(matches!(cell.state(&plan.cells), State::Done { .. }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::options::{MemoryLayout, Technique};

    #[test]
    fn squeue_and_sacct_states_read_alike() {
        let mut states = HashMap::new();
        read_states(
            "12_0|CANCELLED by 0\n12_1|COMPLETED\n\nnoise\n",
            &mut states,
        );
        assert_eq!(states.len(), 2);
        assert_eq!(states["12_0"], "CANCELLED");
        assert_eq!(states["12_1"], "COMPLETED");
        for (state, word) in [
            ("PENDING", "queued"),
            ("REQUEUED", "queued"),
            ("RUNNING", "running"),
            ("COMPLETING", "running"),
            ("COMPLETED", "done"),
            ("FAILED", "failed"),
            ("TIMEOUT", "failed"),
            ("CANCELLED", "failed"),
            ("NODE_FAIL", "failed"),
        ] {
            assert_eq!(class(state), word, "{state}");
        }
    }

    fn plan(dir: &Path, slurm: &str) -> Plan {
        let file = dir.join("plan.toml");
        std::fs::write(
            &file,
            format!(
                "output = \"out\"\nresolution = [1000, 500]\nbudget = \"20m\"\nthreads = 4\n\
                 {slurm}[[scene]]\nfile = \"{}/scenes/cornell-box/scene.toml\"\n\
                 reference = {{ budget = \"1h\", parts = 2 }}\n\
                 [[group]]\ntechniques = [\"vcm\"]\nradius = 0.01\n",
                env!("CARGO_MANIFEST_DIR")
            ),
        )
        .unwrap();
        Plan::load(&file).unwrap()
    }

    #[test]
    fn stages_time_limits_and_memory_follow_the_plan() {
        let dir = tempfile::tempdir().unwrap();
        let p = plan(dir.path(), "");
        let (stages, blocked) = stages(&p);
        // The reference's two parts, their merge, the cell.
        assert_eq!(stages, [vec![0, 1], vec![2], vec![3]]);
        assert_eq!(blocked, 0);
        // The longest budget (a part's 30 minutes), a fifth more, ten minutes; a merge ten.
        assert_eq!(
            time_limit(&p, &stages[0]),
            Some(Duration::from_secs(46 * 60))
        );
        assert_eq!(
            time_limit(&p, &stages[1]),
            Some(Duration::from_secs(10 * 60))
        );
        assert_eq!(
            time_limit(&p, &stages[2]),
            Some(Duration::from_secs(34 * 60))
        );
        let need = crate::memory::estimate(
            Technique::Vcm,
            MemoryLayout::TwoStage,
            500_000,
            u32::MAX,
            3,
            4,
        )
        .total();
        assert_eq!(
            memory_mib(&p, &stages[2]),
            Some((need + MEMORY_ALLOWANCE).div_ceil(1 << 20))
        );
        let p = plan(dir.path(), "[slurm]\ntime_limit = \"1h\"\nmem = \"2G\"\n");
        assert_eq!(time_limit(&p, &[0]), Some(Duration::from_secs(3600)));
        assert_eq!(memory_mib(&p, &[3]), Some(2048));
    }
}
