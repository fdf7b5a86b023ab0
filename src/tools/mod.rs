//! Tools that work on rendered files (000 sec. 3.4 and Appendix A), one library call per
//! `vmerge` subcommand:
//! - compare: [`average`], [`errors`] (every error measure), [`diff`];
//! - merge: [`merge`] renders of one scene made with different seeds;
//! - convert: [`bake`] to a plain EXR, [`strip`] the error series;
//! - inspect: [`time`], [`metadata`], [`measurements`], [`traces`];
//! - plot: convergence charts, [`plot`];
//! - batch: plans of renders, their command lines for GNU parallel or Slurm, their report.
//!
//! Every function reads its inputs, writes its output atomically and returns a [`FilmError`]
//! naming the offending file.
//!
//! [`FilmError`]: crate::film::FilmError

pub mod batch;
mod compare;
mod convert;
mod inspect;
mod merge;
mod plot;

pub use compare::{average, diff, errors};
pub use convert::{bake, strip};
pub use inspect::{measurements, metadata, time, traces};
pub use merge::{merge, MERGED_SEEDS};
pub use plot::{draw_charts, plot, Chart, ChartSeries, Metric};
