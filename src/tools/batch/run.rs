//! What a plan needs now, and running it: `status`, `--dry-run`, the in-process runner with its
//! progress bar and `--jobs` command lines (Slurm's array jobs are in `slurm.rs`).

use super::cell::{make_output, Action, Cell, CellKind, ReferenceSource, State};
use super::{BatchError, Plan};
use crate::accel::AccelKind;
use crate::render::{self, NewRender, RenderError, RunEvent, RunWarning, StopFlag};
use crate::scene::{Scene, Warning};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Duration;

pub(super) fn states(plan: &Plan) -> Vec<State> {
    plan.cells.iter().map(|c| c.state(&plan.cells)).collect()
}

fn is_done(state: &State) -> bool {
    matches!(state, State::Done { .. })
}

/// The actions that bring the plan up to date, in the order they can run: each cell's once
/// the cells it waits for have theirs. With `now_only`, just those that can run now.
pub(super) fn planned(plan: &Plan, states: &[State], now_only: bool) -> Vec<(usize, Action)> {
    let mut done: Vec<bool> = states.iter().map(is_done).collect();
    let mut out: Vec<(usize, Action)> = Vec::new();
    loop {
        let before = out.len();
        let snapshot = done.clone();
        for (i, cell) in plan.cells.iter().enumerate() {
            if done[i] || out.iter().any(|(j, _)| *j == i) {
                continue;
            }
            if let Some(action) = cell.action(&states[i], &plan.cells, &|j| snapshot[j]) {
                out.push((i, action));
                done[i] = true;
            }
        }
        if now_only || out.len() == before {
            return out;
        }
    }
}

/// One line per cell (state, name, what it holds or waits for), then a summary.
pub fn status(plan: &Plan) -> String {
    let states = states(plan);
    let now = planned(plan, &states, true);
    let mut text = String::new();
    let mut counts = [0usize; 4];
    for (i, (cell, state)) in plan.cells.iter().zip(&states).enumerate() {
        counts[match state {
            State::Done { .. } => 0,
            State::Partial { .. } => 1,
            State::Missing => 2,
            State::Stale { .. } => 3,
        }] += 1;
        let detail = match state {
            State::Done { metadata } | State::Partial { metadata, .. } => {
                let cpu = metadata
                    .cpu_seconds
                    .map_or(String::new(), |c| format!(", {c:.1} CPU s"));
                let mut d = format!(
                    "{} it, {:.1} s{cpu} of {}",
                    metadata.iterations,
                    metadata.render_seconds,
                    cell.budget.describe()
                );
                if let Some(e) = metadata.errors.last() {
                    let _ = write!(d, ", mae {:.4e}, rmse {:.4e}", e.mae, e.rmse);
                }
                d
            }
            State::Stale { reason } => reason.clone(),
            State::Missing => String::new(),
        };
        let runnable = now.iter().any(|(j, _)| *j == i);
        let waits = if is_done(state) || runnable {
            ""
        } else {
            " (waits for its reference or parts)"
        };
        let _ = writeln!(
            text,
            "{:<8} {}{}{detail}{waits}",
            state.word(),
            cell.name,
            if detail.is_empty() { "" } else { "  " },
        );
    }
    let _ = writeln!(
        text,
        "{} cells: {} done, {} partial, {} missing, {} stale; {} can run now",
        plan.cells.len(),
        counts[0],
        counts[1],
        counts[2],
        counts[3],
        now.len()
    );
    text
}

/// `render`, `continue (3 it left)` or `merge 2 parts`.
pub fn describe(action: &Action) -> String {
    match action {
        Action::Render => "render".into(),
        Action::Continue(left) => format!("continue ({} left)", left.describe()),
        Action::Merge(parts) => format!("merge {} parts", parts.len()),
    }
}

/// What running the plan would do, in order, without doing it.
pub fn dry_run(plan: &Plan) -> String {
    let states = states(plan);
    let all = planned(plan, &states, false);
    let mut text = String::new();
    for (i, action) in &all {
        let _ = writeln!(text, "{:<28} {}", describe(action), plan.cells[*i].name);
    }
    let blocked: Vec<&Cell> = plan
        .cells
        .iter()
        .zip(&states)
        .enumerate()
        .filter(|(i, (_, s))| !is_done(s) && !all.iter().any(|(j, _)| j == i))
        .map(|(_, (c, _))| c)
        .collect();
    for cell in &blocked {
        if let Some(ReferenceSource::File(f)) = &cell.reference {
            let _ = writeln!(
                text,
                "cannot run {}: no reference {}",
                cell.name,
                f.display()
            );
        }
    }
    let _ = writeln!(
        text,
        "{} of {} cells would run",
        all.len(),
        plan.cells.len()
    );
    text
}

/// A shell word: quoted unless it is made of safe characters alone.
pub(super) fn quote(word: &str) -> String {
    let safe = |c: char| c.is_ascii_alphanumeric() || "_./=,:+-@%".contains(c);
    if !word.is_empty() && word.chars().all(safe) {
        word.to_string()
    } else {
        format!("'{}'", word.replace('\'', "'\\''"))
    }
}

pub(super) fn command_line(program: &Path, args: &[String]) -> String {
    let mut words = vec![quote(&program.to_string_lossy())];
    words.extend(args.iter().map(|a| quote(a)));
    words.join(" ")
}

/// The command lines of the cells that can run now, references first, and how many cells wait
/// for them. `program` is the `vmerge` to call. Run them with `parallel -j N`, `xargs -P N` or
/// anything else, then ask again until nothing is left.
pub fn jobs(plan: &Plan, program: &Path) -> Result<(Vec<String>, usize), BatchError> {
    make_output(&plan.output)?;
    let states = states(plan);
    let now = planned(plan, &states, true);
    let later = planned(plan, &states, false).len() - now.len();
    let lines = now
        .iter()
        .map(|(i, action)| {
            let args = plan.cells[*i].arguments(action, &plan.cells, plan.threads, plan.snapshot);
            command_line(program, &args)
        })
        .collect();
    Ok((lines, later))
}

/// Slurm's `D-HH:MM:SS`.
pub(super) fn slurm_time(t: Duration) -> String {
    let s = t.as_secs();
    format!(
        "{}-{:02}:{:02}:{:02}",
        s / 86400,
        s / 3600 % 24,
        s / 60 % 60,
        s % 60
    )
}

/// What the in-process runner reports.
#[derive(Clone, Debug)]
pub enum Event<'a> {
    /// The run begins with this many cells to bring up to date.
    Plan { cells: usize },
    /// A cell begins.
    Cell { name: &'a str, action: &'a Action },
    /// An iteration of the current cell finished.
    Iteration { iterations: u64, elapsed: Duration },
    /// The current cell is up to date.
    Finished,
    /// Loading the current cell's scene went on past a problem.
    Warning(&'a Warning),
    /// Rendering the current cell went on past a problem.
    RunWarning(&'a RunWarning),
}

/// An `indicatif` bar over a plan's cells, with the current cell and its iterations.
pub struct ProgressBar {
    bar: indicatif::ProgressBar,
    cell: String,
}

impl Default for ProgressBar {
    fn default() -> Self {
        let bar = indicatif::ProgressBar::new(0);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} cells, ETA {eta} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        ProgressBar {
            bar,
            cell: String::new(),
        }
    }
}

impl ProgressBar {
    pub fn show(&mut self, event: &Event) {
        match event {
            Event::Plan { cells } => self.bar.set_length(*cells as u64),
            Event::Cell { name, action } => {
                self.cell = format!("{} {name}", describe(action));
                self.bar.set_message(self.cell.clone());
            }
            Event::Iteration {
                iterations,
                elapsed,
            } => self.bar.set_message(format!(
                "{}: {iterations} it, {:.1} s",
                self.cell,
                elapsed.as_secs_f64()
            )),
            Event::Finished => self.bar.inc(1),
            // The caller shows warnings (see `suspend`).
            Event::Warning(_) | Event::RunWarning(_) => {}
        }
    }

    pub fn finish(&self) {
        self.bar.finish();
    }

    /// Runs `f` (which may write to the terminal) with the bar hidden.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }
}

fn render_error(cell: &Cell) -> impl Fn(RenderError) -> BatchError + '_ {
    |source| BatchError::Render {
        cell: cell.name.clone(),
        source,
    }
}

/// Runs every cell that needs it, references first, in this process (on rayon's global pool,
/// which the caller sizes to the plan's threads): a cell's action, then the cells that waited
/// for it. Stops after the current iteration when `stop` is raised (the
/// cell is written and continues next time). Returns the number of cells run.
pub fn run(
    plan: &Plan,
    accel: AccelKind,
    stop: &StopFlag,
    on: &mut dyn FnMut(&Event),
) -> Result<usize, BatchError> {
    plan.check_references()?;
    make_output(&plan.output)?;
    let mut states = states(plan);
    let work = planned(plan, &states, false).len();
    on(&Event::Plan { cells: work });
    let mut scene: Option<(PathBuf, Scene)> = None;
    let mut ran = 0;
    let mut tried = vec![false; plan.cells.len()];
    while !stop.load(Ordering::Relaxed) {
        let next = planned(plan, &states, true)
            .into_iter()
            .find(|(i, _)| !tried[*i]);
        let Some((i, action)) = next else {
            break;
        };
        tried[i] = true;
        let cell = &plan.cells[i];
        on(&Event::Cell {
            name: &cell.name,
            action: &action,
        });
        run_cell(plan, cell, &action, accel, stop, &mut scene, on)?;
        ran += 1;
        on(&Event::Finished);
        // This cell and those measured against it or merged from it.
        for (j, other) in plan.cells.iter().enumerate() {
            let depends = j == i
                || other.reference == Some(ReferenceSource::Cell(i))
                || matches!(&other.kind, CellKind::Merge { parts } if parts.contains(&i));
            if depends {
                states[j] = other.state(&plan.cells);
            }
        }
    }
    Ok(ran)
}

/// A render's progress as [`Event::Iteration`]s, its warnings as [`Event::Warning`]s.
fn iterations<'a>(on: &'a mut dyn FnMut(&Event)) -> impl FnMut(RunEvent) + 'a {
    |event| match event {
        RunEvent::Iteration(p) => on(&Event::Iteration {
            iterations: p.iterations,
            elapsed: p.elapsed,
        }),
        RunEvent::Warning(w) => on(&Event::RunWarning(w)),
    }
}

pub(super) fn run_cell(
    plan: &Plan,
    cell: &Cell,
    action: &Action,
    accel: AccelKind,
    stop: &StopFlag,
    cached: &mut Option<(PathBuf, Scene)>,
    on: &mut dyn FnMut(&Event),
) -> Result<(), BatchError> {
    let err = render_error(cell);
    match action {
        Action::Merge(parts) => Ok(crate::tools::merge(&cell.output, parts)?),
        Action::Render => {
            let setup = NewRender {
                scene: cell.scene_file.clone(),
                options: cell.options.clone(),
                accel,
                lenient: false,
                output: cell.output.clone(),
                png: true,
                snapshot_every: plan.snapshot,
                reference: cell.reference_file(&plan.cells).map(PathBuf::from),
                traces: cell.traces.clone(),
                memory_limit: None,
            };
            // Cells of one scene follow each other: the last scene is kept.
            if cached.as_ref().is_none_or(|(p, _)| *p != cell.scene_file) {
                *cached = None;
                let loaded = setup.load_scene().map_err(|e| err(RenderError::Scene(e)))?;
                for w in &loaded.warnings {
                    on(&Event::Warning(w));
                }
                *cached = Some((cell.scene_file.clone(), loaded));
            }
            let Some((_, scene)) = cached.as_ref() else {
                return Ok(());
            };
            let mut job = setup.job(scene).map_err(&err)?;
            job.run(cell.budget.stop_after(0), stop, &mut iterations(on))
                .map_err(&err)
        }
        Action::Continue(left) => {
            let (film, metadata) = crate::film::exr::read_render(&cell.output)?;
            let scene = render::load_for_continue(&metadata, accel, false).map_err(&err)?;
            for w in &scene.warnings {
                on(&Event::Warning(w));
            }
            let earlier = film.iterations;
            let mut job = render::continued_job(
                &scene,
                film,
                metadata,
                cell.output.clone(),
                true,
                plan.snapshot,
                None,
            )
            .map_err(&err)?;
            job.run(left.stop_after(earlier), stop, &mut iterations(on))
                .map_err(&err)
        }
    }
}
