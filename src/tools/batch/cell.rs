//! One cell of a plan: one ordinary render (or its continuation, or the merge of a reference's
//! parts), its state on disk, and the command line that brings it up to date.

use super::BatchError;
use crate::film::{Metadata, TraceWindow};
use crate::options::RenderOptions;
use crate::render::{iteration_fits, StopAfter};
use crate::tools::metadata;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// How much a cell renders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    Time(Duration),
    /// CPU time, all the render's threads together: equal work for cells that share a machine.
    CpuTime(Duration),
    Iterations(u64),
}

impl Budget {
    /// One of `parts` equal shares (a reference split by seed).
    pub fn split(self, parts: u64) -> Budget {
        match self {
            Budget::Time(t) => Budget::Time(t / parts.max(1) as u32),
            Budget::CpuTime(t) => Budget::CpuTime(t / parts.max(1) as u32),
            Budget::Iterations(n) => Budget::Iterations(n.div_ceil(parts.max(1))),
        }
    }

    /// What is left after the render `m` describes; `None` when it is spent, `Some(None)`
    /// when it cannot be told (a CPU budget and a file without its CPU time). A time budget is
    /// spent when the render loop would start no further iteration in what is left
    /// ([`iteration_fits`]), or when at most 1% of it (at least half a second) is left: a
    /// snapshot can land just short of the end.
    pub fn remaining(self, m: &Metadata) -> Option<Option<Budget>> {
        let left_of = |t: Duration, spent: f64, wrap: fn(Duration) -> Budget| {
            let left = t.as_secs_f64() - spent;
            let slack = (0.01 * t.as_secs_f64()).max(0.5);
            (left > slack && iteration_fits(left, spent, m.iterations))
                .then(|| wrap(Duration::from_secs_f64(left)))
        };
        match self {
            Budget::Iterations(n) => {
                (m.iterations < n).then(|| Some(Budget::Iterations(n - m.iterations)))
            }
            Budget::Time(t) => left_of(t, m.render_seconds, Budget::Time).map(Some),
            Budget::CpuTime(t) => match m.cpu_seconds {
                Some(cpu) => left_of(t, cpu, Budget::CpuTime).map(Some),
                None => Some(None),
            },
        }
    }

    /// The command-line flag: `-n N`, `--time Ts` or `--cpu-time Ts`.
    fn flags(self) -> [String; 2] {
        match self {
            Budget::Iterations(n) => ["-n".into(), n.to_string()],
            Budget::Time(t) => ["--time".into(), seconds(t)],
            Budget::CpuTime(t) => ["--cpu-time".into(), seconds(t)],
        }
    }

    /// `8 it`, `20m` or `20m CPU`, for status lines.
    pub fn describe(self) -> String {
        match self {
            Budget::Iterations(n) => format!("{n} it"),
            Budget::Time(t) => seconds(t),
            Budget::CpuTime(t) => format!("{} CPU", seconds(t)),
        }
    }

    /// The stop conditions of a run with this budget, after `earlier_iterations`.
    pub fn stop_after(self, earlier_iterations: u64) -> StopAfter {
        match self {
            Budget::Iterations(n) => StopAfter {
                iterations: Some(earlier_iterations + n),
                ..StopAfter::default()
            },
            Budget::Time(t) => StopAfter {
                time: Some(t),
                ..StopAfter::default()
            },
            Budget::CpuTime(t) => StopAfter {
                cpu_time: Some(t),
                ..StopAfter::default()
            },
        }
    }
}

fn seconds(t: Duration) -> String {
    format!("{}s", t.as_secs_f64())
}

#[derive(Clone, Debug, PartialEq)]
pub enum CellKind {
    /// A reference render (or one seed part of it), measured against nothing.
    Reference,
    /// The merge of a reference's parts (the plan's cell indices).
    Merge { parts: Vec<usize> },
    /// A technique at one set of options, measured against its reference.
    Render,
}

/// What a render cell is measured against.
#[derive(Clone, Debug, PartialEq)]
pub enum ReferenceSource {
    File(PathBuf),
    /// The cell of the plan at this index.
    Cell(usize),
}

#[derive(Clone, Debug)]
pub struct Cell {
    /// The file stem, from the parameters: `corners.front.vcm.r0_01`.
    pub name: String,
    pub output: PathBuf,
    pub kind: CellKind,
    pub scene: String,
    pub camera: String,
    pub scene_file: PathBuf,
    pub options: RenderOptions,
    pub budget: Budget,
    pub reference: Option<ReferenceSource>,
    pub traces: Vec<TraceWindow>,
    /// The technique with its options but the radius and seed (see [`super::variant_name`]).
    pub variant: String,
}

/// A cell's file, as found.
#[derive(Clone, Debug, PartialEq)]
pub enum State {
    Missing,
    /// Rendered in full.
    Done {
        metadata: Box<Metadata>,
    },
    /// Rendered in part (interrupted, or a snapshot); the rest of the budget is left.
    Partial {
        metadata: Box<Metadata>,
        left: Budget,
    },
    /// Made with other settings than the plan's (or unreadable): rendered again from scratch.
    Stale {
        reason: String,
    },
}

impl State {
    pub fn word(&self) -> &'static str {
        match self {
            State::Missing => "missing",
            State::Done { .. } => "done",
            State::Partial { .. } => "partial",
            State::Stale { .. } => "stale",
        }
    }

    pub fn metadata(&self) -> Option<&Metadata> {
        match self {
            State::Done { metadata } | State::Partial { metadata, .. } => Some(metadata),
            _ => None,
        }
    }
}

/// What bringing a cell up to date takes.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    Render,
    Continue(Budget),
    Merge(Vec<PathBuf>),
}

/// Same file, by canonical path where both exist, else by name.
fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

fn modified(path: &Path) -> Option<std::time::SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

impl Cell {
    /// The reference file this cell is measured against, if any.
    pub fn reference_file<'p>(&'p self, cells: &'p [Cell]) -> Option<&'p Path> {
        match self.reference.as_ref()? {
            ReferenceSource::File(f) => Some(f),
            ReferenceSource::Cell(i) => Some(&cells[*i].output),
        }
    }

    /// The cell's file compared with what the plan says it should be.
    pub fn state(&self, cells: &[Cell]) -> State {
        if !self.output.exists() {
            return State::Missing;
        }
        let m = match metadata(&self.output) {
            Ok(m) => m,
            Err(e) => {
                return State::Stale {
                    reason: e.to_string(),
                }
            }
        };
        let stale = |reason: String| State::Stale { reason };
        if m.options != self.options {
            return stale("rendered with other options".into());
        }
        if !same_file(Path::new(&m.scene), &self.scene_file) {
            return stale(format!("rendered from {}", m.scene));
        }
        let reference = self.reference_file(cells);
        match (reference, &m.reference) {
            (None, None) => {}
            (Some(want), Some(have)) if same_file(want, Path::new(have)) => {
                // A reference rendered again after this cell measured against it.
                if let (Some(r), Some(c)) = (modified(want), modified(&self.output)) {
                    if r > c {
                        return stale("its reference is newer".into());
                    }
                }
            }
            _ => return stale("measured against another reference".into()),
        }
        if m.traces != self.traces {
            return stale("other trace windows".into());
        }
        if let CellKind::Merge { parts } = &self.kind {
            let sum: u64 = parts
                .iter()
                .filter_map(|&p| cells[p].state(cells).metadata().map(|m| m.iterations))
                .sum();
            return if sum == m.iterations {
                State::Done {
                    metadata: Box::new(m),
                }
            } else {
                stale(format!(
                    "merged {} iterations, the parts hold {sum}",
                    m.iterations
                ))
            };
        }
        match self.budget.remaining(&m) {
            None => State::Done {
                metadata: Box::new(m),
            },
            Some(Some(left)) => State::Partial {
                metadata: Box::new(m),
                left,
            },
            Some(None) => stale("no CPU time recorded to measure its CPU budget by".into()),
        }
    }

    /// What the cell needs now, or `None` when it is done or waits for other cells (its
    /// reference, or a merge's parts). `done(i)` says whether cell `i` is done.
    pub fn action(
        &self,
        state: &State,
        cells: &[Cell],
        done: &dyn Fn(usize) -> bool,
    ) -> Option<Action> {
        if let CellKind::Merge { parts } = &self.kind {
            if matches!(state, State::Done { .. }) || !parts.iter().all(|&p| done(p)) {
                return None;
            }
            return Some(Action::Merge(
                parts.iter().map(|&p| cells[p].output.clone()).collect(),
            ));
        }
        match &self.reference {
            Some(ReferenceSource::Cell(i)) if !done(*i) => return None,
            Some(ReferenceSource::File(f)) if !f.exists() => return None,
            _ => {}
        }
        match state {
            State::Done { .. } => None,
            State::Partial { left, .. } => Some(Action::Continue(*left)),
            State::Missing | State::Stale { .. } => Some(Action::Render),
        }
    }

    /// The `vmerge` arguments of `action` (after the program's name).
    pub fn arguments(
        &self,
        action: &Action,
        cells: &[Cell],
        threads: Option<usize>,
        snapshot: Option<Duration>,
    ) -> Vec<String> {
        let path = |p: &Path| p.to_string_lossy().into_owned();
        let mut args = Vec::new();
        match action {
            Action::Merge(parts) => {
                args.push("merge".into());
                args.push(path(&self.output));
                args.extend(parts.iter().map(|p| path(p)));
                return args;
            }
            Action::Render => {
                args.extend(["render".into(), path(&self.scene_file)]);
                args.extend(self.options.to_args());
                args.extend(self.budget.flags());
                args.extend(["--output".into(), path(&self.output)]);
                if let Some(reference) = self.reference_file(cells) {
                    args.extend(["--reference".into(), path(reference)]);
                }
                for t in &self.traces {
                    args.extend(["--trace".into(), t.to_string()]);
                }
            }
            Action::Continue(left) => {
                args.extend(["continue".into(), path(&self.output)]);
                args.extend(left.flags());
            }
        }
        if let Some(every) = snapshot {
            args.extend(["--snapshot".into(), seconds(every)]);
        }
        if let Some(n) = threads {
            args.extend(["--threads".into(), n.to_string()]);
        }
        args
    }

    /// The final error sample of a rendered cell: `[mae, rmse]` and the trace windows'.
    pub fn final_errors(state: &State) -> Option<&crate::film::ErrorSample> {
        state.metadata()?.errors.last()
    }
}

/// Checks that the folder for the cells exists, creating it.
pub fn make_output(dir: &Path) -> Result<(), BatchError> {
    std::fs::create_dir_all(dir).map_err(|e| BatchError::Write {
        file: dir.into(),
        message: e.to_string(),
    })
}
