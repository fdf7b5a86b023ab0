//! What each rendered cell cost and how its error spreads: the per-cell columns of the report
//! (iterations, wall and CPU seconds, errors, efficiency), the spread of the error over seeds,
//! and the check that cells meant to be compared got comparable shares of the machine.

use super::cell::{Budget, Cell};
use crate::film::{ErrorSample, Metadata};
use crate::tools::Metric;
use thiserror::Error;

/// How far the CPU seconds per wall-clock second of comparable cells may differ (as a ratio)
/// before the report warns: beyond it their wall-clock times tell the machine's load as much
/// as the techniques' cost.
pub const CPU_SHARE_SPREAD: f64 = 1.25;

/// How far the iteration counts of cells that should cost the same under one CPU budget (one
/// variant and radius, several seeds) may differ before the report warns.
pub const ITERATION_SPREAD: f64 = 1.10;

/// The error columns of a cell: each measure's name and value for its last error sample
/// (`None` where not measured: renders made before a measure existed). The one place that
/// lists the measures the report's per-cell and per-seed tables show.
pub fn error_columns(sample: &ErrorSample) -> Vec<(&'static str, Option<f64>)> {
    Metric::ALL
        .into_iter()
        .map(|m| (m.name(), sample.get(m)))
        .collect()
}

/// Efficiency as rendering papers count it, 1 / (error^2 x seconds): the inverse of the time
/// an estimator needs for a given error, so higher is better. `None` for a zero error or time.
pub fn efficiency(error: f64, seconds: f64) -> Option<f64> {
    let e = 1.0 / (error * error * seconds);
    e.is_finite().then_some(e)
}

/// A rendered cell with its cost and errors: a row of the per-cell table.
pub struct CellCost<'a> {
    pub cell: &'a Cell,
    pub iterations: u64,
    /// Wall-clock seconds of rendering.
    pub wall: f64,
    /// CPU seconds of rendering, all threads together; `None` when not recorded.
    pub cpu: Option<f64>,
    /// [`error_columns`] of its last error sample.
    pub errors: Vec<(&'static str, Option<f64>)>,
    /// Rendered in part: its budget is not spent.
    pub partial: bool,
}

impl<'a> CellCost<'a> {
    /// The cost of `cell` as its metadata records it; `None` without an error sample.
    pub fn new(cell: &'a Cell, metadata: &Metadata, partial: bool) -> Option<CellCost<'a>> {
        Some(CellCost {
            cell,
            iterations: metadata.iterations,
            wall: metadata.render_seconds,
            cpu: metadata.cpu_seconds,
            errors: error_columns(metadata.errors.last()?),
            partial,
        })
    }

    /// The error by `metric`.
    pub fn error(&self, metric: Metric) -> Option<f64> {
        self.errors
            .iter()
            .find(|(name, _)| *name == metric.name())
            .and_then(|(_, v)| *v)
    }

    /// CPU seconds per wall-clock second: the threads' share of the machine.
    pub fn cpu_share(&self) -> Option<f64> {
        let share = self.cpu? / self.wall;
        share.is_finite().then_some(share)
    }
}

/// The error of one variant at one radius over its seeds.
pub struct Spread {
    pub variant: String,
    pub radius: Option<f32>,
    pub seeds: usize,
    /// Per error column: its name, mean and sample standard deviation over the seeds that have
    /// it (`None` where none has it; the deviation `None` for one seed).
    pub errors: Vec<(&'static str, Option<f64>, Option<f64>)>,
    pub iterations: f64,
    pub wall: f64,
    /// The mean CPU seconds, where every seed's is recorded.
    pub cpu: Option<f64>,
}

/// Mean and sample standard deviation (`None` for fewer than two values).
fn mean_sd(values: &[f64]) -> (f64, Option<f64>) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let sd = (values.len() > 1).then(|| {
        let sum: f64 = values.iter().map(|v| (v - mean) * (v - mean)).sum();
        (sum / (n - 1.0)).sqrt()
    });
    (mean, sd)
}

/// The variants and radii of `costs`, each once, in the order they come.
fn variants_and_radii<'c>(
    costs: impl Iterator<Item = &'c CellCost<'c>>,
) -> Vec<(&'c str, Option<f32>)> {
    let mut keys = Vec::new();
    for c in costs {
        let key = (c.cell.variant.as_str(), c.cell.options.radius);
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    keys
}

/// The spread over seeds of every variant and radius, in the order the cells come.
pub fn spreads(costs: &[CellCost]) -> Vec<Spread> {
    variants_and_radii(costs.iter())
        .into_iter()
        .map(|(variant, radius)| {
            let here: Vec<&CellCost> = costs
                .iter()
                .filter(|c| c.cell.variant == variant && c.cell.options.radius == radius)
                .collect();
            let column =
                |i: usize| -> Vec<f64> { here.iter().filter_map(|c| c.errors[i].1).collect() };
            let errors = here[0]
                .errors
                .iter()
                .enumerate()
                .map(|(i, (name, _))| {
                    let values = column(i);
                    if values.is_empty() {
                        return (*name, None, None);
                    }
                    let (mean, sd) = mean_sd(&values);
                    (*name, Some(mean), sd)
                })
                .collect();
            let n = here.len() as f64;
            let cpu: Option<Vec<f64>> = here.iter().map(|c| c.cpu).collect();
            Spread {
                variant: variant.to_string(),
                radius,
                seeds: here.len(),
                errors,
                iterations: here.iter().map(|c| c.iterations as f64).sum::<f64>() / n,
                wall: here.iter().map(|c| c.wall).sum::<f64>() / n,
                cpu: cpu.map(|v| v.iter().sum::<f64>() / n),
            }
        })
        .collect()
}

/// Cells meant to be compared that got very different shares of the machine.
#[derive(Debug, Error, PartialEq)]
pub enum ShareWarning {
    /// Under a wall-clock or iteration budget: their times measure the load too.
    #[error(
        "{view}, budget {budget}: {low} got {low_share:.2} CPU s per wall s, {high} \
         {high_share:.2} (more than {CPU_SHARE_SPREAD}x apart): their times and efficiencies \
         tell the machine's load as much as the techniques; a CPU-time budget (cpu_time) \
         evens it out"
    )]
    CpuShare {
        view: String,
        budget: String,
        low: String,
        low_share: f64,
        high: String,
        high_share: f64,
    },
    /// Under a CPU budget, seeds of one variant and radius: their cost should be equal.
    #[error(
        "{view}, budget {budget}: {low} reached {low_iterations} iterations, {high} \
         {high_iterations} (more than {ITERATION_SPREAD}x apart) with the same CPU time"
    )]
    Iterations {
        view: String,
        budget: String,
        low: String,
        low_iterations: u64,
        high: String,
        high_iterations: u64,
    },
}

/// The lowest and the highest of `costs` by `value`, when they are more than `spread` apart.
fn extremes<'c, 'a>(
    costs: &[&'c CellCost<'a>],
    value: impl Fn(&CellCost<'a>) -> Option<f64>,
    spread: f64,
) -> Option<(&'c CellCost<'a>, f64, &'c CellCost<'a>, f64)> {
    let valued: Vec<(&CellCost, f64)> =
        costs.iter().filter_map(|c| Some((*c, value(c)?))).collect();
    let low = valued.iter().min_by(|a, b| a.1.total_cmp(&b.1))?;
    let high = valued.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    (low.1 > 0.0 && high.1 > spread * low.1).then_some((low.0, low.1, high.0, high.1))
}

/// The warnings of one view's cells: under one wall-clock or iteration budget, CPU shares
/// more than [`CPU_SHARE_SPREAD`] apart; under one CPU budget, iteration counts of one variant
/// and radius more than [`ITERATION_SPREAD`] apart.
pub fn share_warnings(view: &str, costs: &[CellCost]) -> Vec<ShareWarning> {
    let mut budgets: Vec<Budget> = Vec::new();
    for c in costs {
        if !budgets.contains(&c.cell.budget) {
            budgets.push(c.cell.budget);
        }
    }
    let mut warnings = Vec::new();
    for budget in budgets {
        let under: Vec<&CellCost> = costs.iter().filter(|c| c.cell.budget == budget).collect();
        let name = |c: &CellCost| c.cell.name.clone();
        if !matches!(budget, Budget::CpuTime(_)) {
            if let Some((low, low_share, high, high_share)) =
                extremes(&under, CellCost::cpu_share, CPU_SHARE_SPREAD)
            {
                warnings.push(ShareWarning::CpuShare {
                    view: view.into(),
                    budget: budget.describe(),
                    low: name(low),
                    low_share,
                    high: name(high),
                    high_share,
                });
            }
            continue;
        }
        for (variant, radius) in variants_and_radii(under.iter().copied()) {
            let seeds: Vec<&CellCost> = under
                .iter()
                .copied()
                .filter(|c| c.cell.variant == variant && c.cell.options.radius == radius)
                .collect();
            if let Some((low, _, high, _)) =
                extremes(&seeds, |c| Some(c.iterations as f64), ITERATION_SPREAD)
            {
                warnings.push(ShareWarning::Iterations {
                    view: view.into(),
                    budget: budget.describe(),
                    low: name(low),
                    low_iterations: low.iterations,
                    high: name(high),
                    high_iterations: high.iterations,
                });
            }
        }
    }
    warnings
}
