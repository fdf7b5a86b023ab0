//! The memory a render will need, estimated before it starts and held against a limit (the
//! machine's available memory unless told otherwise), so that a resolution too large for the
//! machine is refused with a message rather than aborting in an allocation.
//!
//! The merging techniques' light vertices dominate, and how much they take depends on the
//! layout (`memory`, [`MemoryLayout`]): two-stage keeps every light vertex whole, with what
//! its BSDF needs, one-stage only what a merge reads (001 sec. 6.2). The estimate is made for
//! the layout asked for, and a refusal of two-stage says whether one-stage would fit.

use crate::integrator::subpath::MergeVertex;
use crate::integrator::vcm::{LightVertex, ONE_STAGE_VERTEX_BYTES};
use crate::options::{MemoryLayout, OptionName, Technique};
use glam::Vec3;
use std::fmt;
use thiserror::Error;

/// Bytes per pixel of everything image-sized: the f64 sums (24), one iteration's frame (12),
/// the mean written out (12), the EXR's channels while encoding (3 x (4 + 8)), the preview (16).
const FILM_BYTES_PER_PIXEL: u64 = 24 + 12 + 12 + 36 + 16;

/// Light vertices a light sub-path stores on average, beyond the roulette's start: paths go on
/// with probability about the albedo, 1 / (1 - 0.8) = 5 more for albedo 0.8.
const VERTICES_AFTER_ROULETTE: u64 = 5;

/// Per worker thread: its stack and its tile buffers.
const BYTES_PER_THREAD: u64 = 4 << 20;

/// Bytes of the hash grid per light vertex: its points in cell order (16) and its table
/// (16-byte slots, at most three per point).
const GRID_BYTES: u64 = 16 + 48;

/// Bytes per light vertex of the two-stage layout: stored twice (the light pass's chunks and
/// their concatenation, both kept from one iteration to the next), once more as the merges'
/// compact copy, their positions, the hash grid and its two sort buffers (24 bytes per point
/// each: key, index and position; 32 where cell keys take more than 32 bits).
fn two_stage_vertex_bytes() -> u64 {
    2 * std::mem::size_of::<LightVertex>() as u64
        + std::mem::size_of::<MergeVertex>() as u64
        + 12
        + GRID_BYTES
        + 2 * 24
}

/// Bytes per light vertex of the in-place grid build's sort: a (key, index) pair, 16 bytes
/// where cell keys take more than 32 bits, 8 otherwise.
const IN_PLACE_SORT_BYTES: u64 = 16;

/// Bytes per distinct cell while the grid is built (its key and the end of its range), at most
/// one cell a point.
const CELL_BYTES: u64 = 16;

/// Bytes per light vertex of the one-stage layout at its peak, the most of its phases: in the
/// eye pass, the previous iteration's packed vertices (a stored vertex without its position,
/// which the grid keeps) with their grid, and this iteration's as they are stored; at the
/// iteration's end, the previous ones freed, this iteration's with the grid being built over
/// them (its sort in place and its cells), then their copy in the grid's order.
fn one_stage_vertex_bytes() -> u64 {
    let stored = ONE_STAGE_VERTEX_BYTES as u64;
    let merge = stored - std::mem::size_of::<Vec3>() as u64;
    let eye_pass = merge + GRID_BYTES + stored;
    let build = stored + IN_PLACE_SORT_BYTES + GRID_BYTES + CELL_BYTES;
    let reorder = 2 * merge + GRID_BYTES;
    eye_pass.max(build).max(reorder)
}

/// The parts of a render's memory, in bytes, and the light vertices' layout where it has any.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryNeed {
    pub parts: Vec<(&'static str, u64)>,
    pub layout: Option<MemoryLayout>,
    /// For a two-stage render, what the same render would need one-stage.
    pub one_stage_total: Option<u64>,
}

impl MemoryNeed {
    pub fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0u64, |total, (_, bytes)| total.saturating_add(*bytes))
    }
}

impl fmt::Display for MemoryNeed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .parts
            .iter()
            .filter(|(_, bytes)| *bytes > 0)
            .map(|(what, bytes)| format!("{what} {}", Bytes(*bytes)))
            .collect();
        write!(f, "{} ({}", Bytes(self.total()), parts.join(", "))?;
        match self.layout {
            Some(layout) => write!(f, "; {} layout)", layout.name()),
            None => write!(f, ")"),
        }
    }
}

/// A byte count in binary units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bytes(pub u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let units = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
        let mut value = self.0 as f64;
        let mut unit = 0;
        while value >= 1024.0 && unit + 1 < units.len() {
            value /= 1024.0;
            unit += 1;
        }
        if unit == 0 {
            write!(f, "{} B", self.0)
        } else {
            write!(f, "{value:.1} {}", units[unit])
        }
    }
}

/// The estimate for a render of `pixels` pixels with `technique`, light vertices kept as
/// `layout` says, paths of at most `max_path_length` segments (`u32::MAX` unbounded),
/// roulette from `roulette`, on `threads` worker threads.
pub fn estimate(
    technique: Technique,
    layout: MemoryLayout,
    pixels: u64,
    max_path_length: u32,
    roulette: u32,
    threads: usize,
) -> MemoryNeed {
    let film = pixels.saturating_mul(FILM_BYTES_PER_PIXEL);
    // The merging techniques keep one light sub-path per pixel; one-stage, the techniques that
    // take it (density-estimate merges), the two iterations' compact vertices at once.
    let one_stage = layout == MemoryLayout::OneStage && technique.shrinks_radius();
    let vertices = |per_vertex: u64| {
        let per_path = (max_path_length as u64).min(roulette as u64 + VERTICES_AFTER_ROULETTE);
        pixels.saturating_mul(per_path).saturating_mul(per_vertex)
    };
    let (light_vertices, layout, one_stage_total) = if !technique.merges() {
        (0, None, None)
    } else if one_stage {
        (vertices(one_stage_vertex_bytes()), Some(layout), None)
    } else {
        let other = technique.shrinks_radius().then(|| {
            film.saturating_add(vertices(one_stage_vertex_bytes()))
                .saturating_add((threads as u64).saturating_mul(BYTES_PER_THREAD))
        });
        (
            vertices(two_stage_vertex_bytes()),
            Some(MemoryLayout::TwoStage),
            other,
        )
    };
    MemoryNeed {
        parts: vec![
            ("film", film),
            ("light vertices", light_vertices),
            ("threads", (threads as u64).saturating_mul(BYTES_PER_THREAD)),
        ],
        layout,
        one_stage_total,
    }
}

/// The memory the system could give this process now (Linux's `MemAvailable`), if known.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// A render that would need more memory than it may use.
#[derive(Debug, Error, PartialEq)]
#[error("the render needs about {need}, more than the {limit} {source_of_limit}; lower the resolution{hint} or raise {}", OptionName("memory_limit"))]
pub struct MemoryError {
    pub need: MemoryNeed,
    pub limit: Bytes,
    pub source_of_limit: &'static str,
    pub hint: &'static str,
}

/// Holds `need` against `limit`, or against the available memory when `limit` is `None`
/// (and nothing when that is unknown).
pub fn check(need: &MemoryNeed, limit: Option<u64>) -> Result<(), MemoryError> {
    let (limit, source_of_limit) = match limit {
        Some(l) => (l, "given"),
        None => match available() {
            Some(a) => (a, "available on this machine"),
            None => return Ok(()),
        },
    };
    if need.total() <= limit {
        return Ok(());
    }
    let merges = need
        .parts
        .iter()
        .any(|(what, bytes)| *what == "light vertices" && *bytes > 0);
    let hint = match need.one_stage_total {
        Some(total) if total <= limit => ", set `memory` one-stage (it would fit)",
        _ if merges => " or the path length",
        _ => "",
    };
    Err(MemoryError {
        need: need.clone(),
        limit: Bytes(limit),
        source_of_limit,
        hint,
    })
}

/// Parses a size such as `512M`, `8G`, `1.5T` or a plain byte count.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a size like 512M or 8G"))?;
    let scale = match unit
        .to_ascii_uppercase()
        .trim_end_matches("IB")
        .trim_end_matches('B')
    {
        "" => 1.0,
        "K" => 1024.0,
        "M" => 1024.0 * 1024.0,
        "G" => 1024.0 * 1024.0 * 1024.0,
        "T" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => return Err(format!("'{s}': unknown unit '{unit}' (K, M, G, T)")),
    };
    let bytes = value * scale;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("'{s}' is not a size of at least one byte"));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_films_are_refused_without_overflow() {
        let huge = u64::from(u32::MAX).pow(2);
        let need = estimate(Technique::Vcm, MemoryLayout::TwoStage, huge, 10, 3, 8);
        assert_eq!(need.total(), u64::MAX);
        let err = check(&need, Some(1 << 30)).unwrap_err().to_string();
        assert!(err.contains("path length"), "{err}");
        let small = estimate(Technique::Pt, MemoryLayout::TwoStage, 64 * 64, 10, 3, 2);
        assert_eq!(small.parts[1].1, 0);
        assert_eq!(check(&small, Some(1 << 30)), Ok(()));
    }

    /// A 4K vcm render: one-stage needs less than half of two-stage, a refusal of two-stage
    /// names one-stage where that fits, and the message names the layout.
    #[test]
    fn one_stage_needs_less_and_is_suggested() {
        let pixels = 3840 * 2160;
        let two = estimate(Technique::Vcm, MemoryLayout::TwoStage, pixels, 10, 3, 2);
        let one = estimate(Technique::Vcm, MemoryLayout::OneStage, pixels, 10, 3, 2);
        assert!(2 * one.total() < two.total(), "{one} against {two}");
        assert_eq!(two.one_stage_total, Some(one.total()));
        let err = check(&two, Some(one.total())).unwrap_err().to_string();
        assert!(err.contains("one-stage (it would fit)"), "{err}");
        assert!(err.contains("two-stage layout"), "{err}");
        let err = check(&two, Some(one.total() - 1)).unwrap_err().to_string();
        assert!(err.contains("path length"), "{err}");
        let upg = estimate(Technique::Upg, MemoryLayout::OneStage, pixels, 10, 3, 2);
        assert_eq!(upg.layout, Some(MemoryLayout::TwoStage));
    }

    /// One-stage's estimate per light vertex holds what its eye pass holds at least (two
    /// iterations' records, one with its position, and the grid's 16 bytes a point), and
    /// stays below half of two-stage's.
    #[test]
    fn one_stage_counts_both_iterations() {
        let stored = ONE_STAGE_VERTEX_BYTES as u64;
        let held = 2 * stored - std::mem::size_of::<Vec3>() as u64 + 16;
        assert!(
            one_stage_vertex_bytes() >= held,
            "{}",
            one_stage_vertex_bytes()
        );
        assert!(2 * one_stage_vertex_bytes() < two_stage_vertex_bytes());
    }

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("512M"), Ok(512 << 20));
        assert_eq!(parse_size("8GiB"), Ok(8 << 30));
        assert_eq!(parse_size("1000"), Ok(1000));
        for bad in ["", "0", "-1G", "nanG", "5Q", "infT"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
