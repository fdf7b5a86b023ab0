//! Batch generation of results (000 ch. 4): a plan of renders (scenes x cameras x techniques x
//! radii x betas x seeds, each with a budget, measured against a reference per scene and
//! camera), run resumably in-process or handed to GNU parallel or Slurm as ordinary `vmerge`
//! command lines, and a report of whatever cells exist.
//!
//! - `plan.rs`: the plan file and its expansion into cells;
//! - `cell.rs`: one cell, its state on disk (done, partial, missing, stale) and its command;
//! - `run.rs`: status, dry runs, the in-process runner and `--jobs` lines;
//! - `slurm.rs`: the plan as Slurm array jobs chained by dependencies, submitted and followed;
//! - `cost.rs`: each cell's cost (iterations, wall and CPU seconds, efficiency), the spread
//!   over seeds, and the warning when comparable cells got unequal shares of the machine;
//! - `report.rs`: the static HTML report with thumbnails, tables and charts.
//!
//! A cell is idempotent: its file holds its options, reference and trace windows, so a cell
//! already rendered in full is skipped, one rendered in part continues, and one made with other
//! settings than the plan now says is rendered again. References come first: a cell whose
//! reference is not there yet waits, and `--jobs` lists only what can run now.

mod cell;
mod cost;
mod plan;
mod report;
mod run;
mod slurm;

pub use cell::{Action, Budget, Cell, CellKind, ReferenceSource, State};
pub use cost::{
    efficiency, error_columns, CellCost, ShareWarning, Spread, CPU_SHARE_SPREAD, ITERATION_SPREAD,
};
pub use plan::{parse_duration, variant_name, Plan};
pub use report::{report, report_warnings};
pub use run::{describe as describe_action, dry_run, jobs, run, status, Event, ProgressBar};
pub use slurm::{
    class as slurm_class, run_one, slurm, slurm_states, slurm_status, stages, submit, submitted,
    Asked, SlurmSettings, Submission, Task, RECORD,
};

use crate::film::FilmError;
use crate::render::RenderError;
use std::path::PathBuf;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum BatchError {
    /// The plan file is missing, unreadable or wrong; the message names the entry.
    #[error("{file}: {message}")]
    Plan { file: PathBuf, message: String },
    #[error("{file}: cannot write: {message}")]
    Write { file: PathBuf, message: String },
    #[error("cell {cell}: {source}")]
    Render {
        cell: String,
        #[source]
        source: RenderError,
    },
    #[error(transparent)]
    Film(#[from] FilmError),
    /// A cell asked for by name whose reference or parts are not done.
    #[error("cell {cell} waits for its reference or parts, which are not done")]
    Waits { cell: String },
    /// Cells still queued or running from an earlier submission.
    #[error("still queued or running from an earlier submission: {cells}; wait for them or scancel them first")]
    Busy { cells: String },
    #[error("{command}: {message}")]
    Slurm { command: String, message: String },
    /// A command-line flag's value that cannot be used, refused before any work.
    #[error("{flag} {message}")]
    Flag { flag: &'static str, message: String },
}

impl BatchError {
    /// Whether the error is the user's input (the plan, a scene, a reference) rather than the
    /// system.
    pub fn is_input(&self) -> bool {
        match self {
            BatchError::Plan { .. } | BatchError::Flag { .. } => true,
            BatchError::Write { .. } => false,
            BatchError::Render { source, .. } => {
                !matches!(source, RenderError::Film(FilmError::Write { .. }))
            }
            BatchError::Film(f) => !matches!(f, FilmError::Write { .. }),
            BatchError::Waits { .. } | BatchError::Busy { .. } | BatchError::Slurm { .. } => false,
        }
    }
}
