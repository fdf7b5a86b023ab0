//! Merging renders of one scene made with different seeds (on several machines, or in several
//! runs), weighted by their iterations.

use crate::film::{exr, Film, FilmError, Metadata};
use crate::options::RenderOptions;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// The statistic listing the seeds of a merged render's inputs, space separated.
pub const MERGED_SEEDS: &str = "merged_seeds";

/// Merges vmerge renders of the same scene (hash), resolution, technique and options, made
/// with different seeds, into `out`.
///
/// The sums and the iterations add up, so the result is the iteration-weighted mean of the
/// inputs, exact in f64 (a merge of renders of n1 and n2 iterations equals, up to the order of
/// the additions, a render of n1 + n2 iterations' worth of independent samples). Its metadata
/// is the first input's with the iterations, render seconds and dropped samples summed, the
/// seed of the first input, the statistic `merged_seeds` listing every input's seed (an input
/// that is itself a merge contributes its own list), and no error series (one input's series
/// does not describe the merge).
///
/// For the shrinking-radius techniques (ppm, bpm, vcm with alpha < 1) the result is the average
/// of independent progressive renders, each with its own radius sequence r_1 .. r_n (000 eq.
/// 2.85), not one longer progressive render whose radius would have shrunk further.
///
/// Refuses, naming both files: renders of different scenes, resolutions, techniques or options,
/// two inputs with the same seed (their samples would be the same ones counted twice), files
/// that are not vmerge renders, an empty input list, and an output another process is writing
/// (locked until the merge is written).
pub fn merge(out: &Path, inputs: &[PathBuf]) -> Result<(), FilmError> {
    let Some((first_path, rest)) = inputs.split_first() else {
        return Err(FilmError::Invalid {
            file: out.into(),
            message: "merge needs at least one input".into(),
        });
    };
    let refused = |e: crate::files::FileError| FilmError::Invalid {
        file: e.file,
        message: e.message,
    };
    crate::files::check_output(out, inputs).map_err(refused)?;
    // Held until the merge is written: another process writing `out` refuses meanwhile.
    let _lock = crate::files::lock_output(out).map_err(refused)?;
    let (mut film, mut metadata) = exr::read_render(first_path)?;
    let mut seeds: Vec<(u64, &Path)> = seeds_of(&metadata, first_path)?;
    for path in rest {
        let (other, m) = exr::read_render(path)?;
        check_compatible((&film, &metadata, first_path), (&other, &m, path))?;
        for (seed, from) in seeds_of(&m, path)? {
            if let Some((_, earlier)) = seeds.iter().find(|(s, _)| *s == seed) {
                return Err(FilmError::Invalid {
                    file: path.clone(),
                    message: format!(
                        "has seed {seed}, as {} has: the same samples would count twice",
                        earlier.display()
                    ),
                });
            }
            seeds.push((seed, from));
        }
        if film.iterations + other.iterations > crate::options::MAX_ITERATIONS {
            return Err(FilmError::Invalid {
                file: path.clone(),
                message: format!(
                    "the merge would have more than {} iterations",
                    crate::options::MAX_ITERATIONS
                ),
            });
        }
        film.accumulate(&other);
        if film.sum.iter().flatten().any(|s| !s.is_finite()) {
            return Err(FilmError::Invalid {
                file: path.clone(),
                message: "its sums and the earlier inputs' overflow f64 together".into(),
            });
        }
        metadata.render_seconds += m.render_seconds;
        metadata.cpu_seconds = metadata.cpu_seconds.zip(m.cpu_seconds).map(|(a, b)| a + b);
        metadata.dropped_samples += m.dropped_samples;
    }
    metadata.iterations = film.iterations;
    metadata.errors.clear();
    let list = seeds
        .iter()
        .map(|(s, _)| s.to_string())
        .collect::<Vec<_>>()
        .join(" ");
    metadata.statistics.retain(|(name, _)| name != MERGED_SEEDS);
    metadata.statistics.push((MERGED_SEEDS.into(), list));
    exr::write_render(out, &film, &metadata)
}

/// The seeds whose samples a render holds: its own, or the list a merge recorded.
fn seeds_of<'a>(metadata: &Metadata, path: &'a Path) -> Result<Vec<(u64, &'a Path)>, FilmError> {
    match metadata.statistic(MERGED_SEEDS) {
        None => Ok(vec![(metadata.options.seed, path)]),
        Some(list) => list
            .split_whitespace()
            .map(|s| {
                s.parse()
                    .map(|seed| (seed, path))
                    .map_err(|_| FilmError::Invalid {
                        file: path.into(),
                        message: format!("the statistic {MERGED_SEEDS} has a non-seed '{s}'"),
                    })
            })
            .collect(),
    }
}

fn check_compatible(
    (film, m, path): (&Film, &Metadata, &Path),
    (other_film, other, other_path): (&Film, &Metadata, &Path),
) -> Result<(), FilmError> {
    let mismatch = |what: String| {
        Err(FilmError::Invalid {
            file: other_path.into(),
            message: format!("cannot be merged with {}: {what}", path.display()),
        })
    };
    if other.scene_hash != m.scene_hash {
        return mismatch(format!(
            "a different scene (hash {} of {}, not {} of {})",
            other.scene_hash, other.scene, m.scene_hash, m.scene
        ));
    }
    if (other_film.width, other_film.height) != (film.width, film.height) {
        return mismatch(format!(
            "a different resolution ({}x{}, not {}x{})",
            other_film.width, other_film.height, film.width, film.height
        ));
    }
    if other.options.technique != m.options.technique {
        return mismatch(format!(
            "a different technique ({}, not {})",
            other.options.technique.name(),
            m.options.technique.name()
        ));
    }
    let differences = option_differences(&m.options, &other.options);
    if !differences.is_empty() {
        return mismatch(format!("different options ({})", differences.join(", ")));
    }
    Ok(())
}

/// The options other than the seed that differ, as `name: theirs vs ours`.
fn option_differences(ours: &RenderOptions, theirs: &RenderOptions) -> Vec<String> {
    let ours = RenderOptions {
        seed: theirs.seed,
        ..ours.clone()
    };
    if ours == *theirs {
        return Vec::new();
    }
    // Seeds aside (TOML's integers are i64, seeds u64).
    let table = |o: &RenderOptions| match toml::Value::try_from(RenderOptions {
        seed: 0,
        ..o.clone()
    }) {
        Ok(toml::Value::Table(t)) => t,
        _ => toml::Table::new(),
    };
    let (a, b) = (table(theirs), table(&ours));
    let names: BTreeSet<&String> = a.keys().chain(b.keys()).collect();
    let show = |v: Option<&toml::Value>| v.map_or("default".to_string(), |v| v.to_string());
    let differences: Vec<String> = names
        .into_iter()
        .filter(|n| a.get(*n) != b.get(*n))
        .map(|n| format!("{n}: {} vs {}", show(a.get(n)), show(b.get(n))))
        .collect();
    if differences.is_empty() {
        // Equal as TOML yet unequal as values: a NaN option compares so.
        vec!["options that compare unequal".into()]
    } else {
        differences
    }
}
