//! What a render's metadata says: render time, error series, trace windows.

use crate::film::{exr, ErrorSample, FilmError, Metadata, TraceWindow};
use crate::metrics::Measure;
use std::fmt::Write;
use std::path::Path;

/// The metadata of a vmerge render.
pub fn metadata(path: &Path) -> Result<Metadata, FilmError> {
    Ok(exr::read_render(path)?.1)
}

/// Render time in seconds, earlier runs of a continued render and all inputs of a merge
/// included.
pub fn time(path: &Path) -> Result<f64, FilmError> {
    Ok(metadata(path)?.render_seconds)
}

/// The error series as CSV: a header line, then one line per sample with `seconds`,
/// `iterations`, `mae`, `rmse`, then `traceI_mae`, `traceI_rmse` of each trace window I (in the
/// order [`traces`] lists them), then, where the series has them, one column per other measure
/// ([`ErrorSample::OTHERS`], empty where a sample lacks it). Numbers are written so that they
/// parse back exactly.
pub fn measurements(path: &Path) -> Result<String, FilmError> {
    let m = metadata(path)?;
    let others: Vec<Measure> = ErrorSample::OTHERS
        .into_iter()
        .filter(|&o| m.errors.iter().any(|e| e.get(o).is_some()))
        .collect();
    let mut csv = String::from("seconds,iterations,mae,rmse");
    // Writing to a String cannot fail.
    for i in 0..m.traces.len() {
        let _ = write!(csv, ",trace{i}_mae,trace{i}_rmse");
    }
    for o in &others {
        let _ = write!(csv, ",{o}");
    }
    csv.push('\n');
    for e in &m.errors {
        let _ = write!(csv, "{},{},{},{}", e.seconds, e.iterations, e.mae, e.rmse);
        for [mae, rmse] in &e.traces {
            let _ = write!(csv, ",{mae},{rmse}");
        }
        for &o in &others {
            csv.push(',');
            if let Some(v) = e.get(o) {
                let _ = write!(csv, "{v}");
            }
        }
        csv.push('\n');
    }
    Ok(csv)
}

/// The trace windows the errors were measured in (000 Appendix A's `--trace`).
pub fn traces(path: &Path) -> Result<Vec<TraceWindow>, FilmError> {
    Ok(metadata(path)?.traces)
}
