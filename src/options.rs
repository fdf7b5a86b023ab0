//! The options of a render, in one place: the techniques, [`RenderOptions`] with its defaults,
//! and [`RULES`], the one table of which technique takes which option and what values it
//! accepts. A leaf: everything above (the integrators, the render loop, the film's metadata,
//! the tools, the command line) takes its options from here.
//!
//! Options are named by [`OptionName`], data rather than text, so that a front end decides how
//! they are spelled in messages (the command line writes `--upg-packet`, the library
//! `` `upg_packet` ``).

use serde::{Deserialize, Serialize};
use std::fmt;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use thiserror::Error;

/// The rendering techniques.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Technique {
    Pt,
    Lt,
    Bpt,
    Ppm,
    Bpm,
    Vcm,
    Upg,
    UpgCamera,
}

impl Technique {
    pub const ALL: [Technique; 8] = [
        Technique::Pt,
        Technique::Lt,
        Technique::Bpt,
        Technique::Ppm,
        Technique::Bpm,
        Technique::Vcm,
        Technique::Upg,
        Technique::UpgCamera,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Technique::Pt => "pt",
            Technique::Lt => "lt",
            Technique::Bpt => "bpt",
            Technique::Ppm => "ppm",
            Technique::Bpm => "bpm",
            Technique::Vcm => "vcm",
            Technique::Upg => "upg",
            Technique::UpgCamera => "upg-camera",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            Technique::Pt => "path tracing with next-event estimation",
            Technique::Lt => "light tracing, splatting to the camera",
            Technique::Bpt => "bidirectional path tracing",
            Technique::Ppm => "progressive photon mapping",
            Technique::Bpm => "bidirectional photon mapping",
            Technique::Vcm => "vertex connection and merging",
            Technique::Upg => "unbiased photon gathering, merging from the light side",
            Technique::UpgCamera => "unbiased photon gathering, merging from the camera side",
        }
    }

    /// The technique called `name` (as [`Technique::name`] spells it).
    pub fn from_name(name: &str) -> Option<Technique> {
        Technique::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Merges by density estimation, whose radius shrinks (000 eq. 2.85).
    pub fn shrinks_radius(self) -> bool {
        matches!(self, Technique::Ppm | Technique::Bpm | Technique::Vcm)
    }

    /// Unbiased photon gathering: merges at a fixed radius (000 sec. 2.4.6).
    pub fn is_upg(self) -> bool {
        matches!(self, Technique::Upg | Technique::UpgCamera)
    }

    /// Merges light vertices at all.
    pub fn merges(self) -> bool {
        self.shrinks_radius() || self.is_upg()
    }

    /// Traces a set of light sub-paths per iteration that `light_paths` sizes: the techniques
    /// of the vertex-merging core (bpt traces one per pixel, its own way).
    pub fn traces_light_paths(self) -> bool {
        self == Technique::Lt || self.merges()
    }
}

impl fmt::Display for Technique {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Which numbers the sub-paths are built from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SamplerKind {
    /// Shuffled, Owen-scrambled 2D Sobol' points per dimension pair.
    Sobol,
    /// Independent uniform numbers (PCG32), as SmallVCM and the thesis draw them.
    Independent,
}

impl SamplerKind {
    pub const ALL: [SamplerKind; 2] = [SamplerKind::Sobol, SamplerKind::Independent];

    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Sobol => "sobol",
            SamplerKind::Independent => "independent",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            SamplerKind::Sobol => "randomised quasi-Monte Carlo: shuffled, Owen-scrambled Sobol'",
            SamplerKind::Independent => "independent uniform random numbers (PCG32)",
        }
    }
}

/// 002's MIS heuristics for density estimates: the merge at x_i counts n_VM / k_i light
/// sub-paths instead of n_VM, with k_i the expected number of light vertices in its radius.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum DensityMis {
    /// 002 eq. (6).
    #[serde(rename = "vcm+")]
    Plus,
    /// 002 eq. (7): normalised by the path's mean of 1 / k_j.
    #[serde(rename = "vcm*")]
    Star,
}

impl DensityMis {
    pub const ALL: [DensityMis; 2] = [DensityMis::Plus, DensityMis::Star];

    pub fn name(self) -> &'static str {
        match self {
            DensityMis::Plus => "vcm+",
            DensityMis::Star => "vcm*",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            DensityMis::Plus => "merges weighed by n_VM / k (002 eq. 6)",
            DensityMis::Star => "and normalised by the path's mean of 1 / k (002 eq. 7)",
        }
    }
}

/// Every option that changes the image. Serialized into the EXR so `continue` can resume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderOptions {
    pub technique: Technique,
    pub seed: u64,
    pub camera: Option<String>,
    pub resolution: Option<[u32; 2]>,
    /// MIS power (1 = balance heuristic, 2 = power heuristic).
    pub beta: f32,
    /// Merge radius in world units; `None` = the scene's default.
    pub radius: Option<f32>,
    /// Radius shrinking exponent (000 eq. 2.85); `None` = the technique's default.
    pub alpha: Option<f32>,
    /// Segments of a full path; `None` = the scene's default, 0 = unbounded.
    pub max_path_length: Option<u32>,
    /// Path length (in segments) from which Russian roulette may end paths.
    pub roulette: u32,
    pub no_vc: bool,
    pub no_vm: bool,
    /// `bpt` only: render the contribution of one (s, t) technique alone.
    #[serde(default)]
    pub strategy: Option<[u32; 2]>,
    /// `bpt` only: leave the MIS weights out (each technique at weight 1).
    #[serde(default)]
    pub unweighted: bool,
    /// `upg`, `upg-camera`: tentative rays traced 1 or 8 at a time.
    #[serde(default = "default_upg_packet")]
    pub upg_packet: u32,
    /// `upg`, `upg-camera`: Bernoulli trials after which a merge is dropped.
    #[serde(default = "default_upg_max_trials")]
    pub upg_max_trials: u32,
    /// `vcm`, `bpm`: 002's density-map heuristic instead of VCM's.
    #[serde(default)]
    pub density_mis: Option<DensityMis>,
    /// Iterations whose light vertices fill the density map; after them it is fixed (002
    /// sec. 5.1), so the weights are deterministic.
    #[serde(default = "default_density_map_iterations")]
    pub density_map_iterations: u32,
    /// Render every triangle flat, ignoring the meshes' vertex normals (applied when the scene
    /// is loaded).
    #[serde(default)]
    pub no_shading_normals: bool,
    /// Light sub-paths per iteration, n_VM (the thesis's `--num-photons`); `None` = one per
    /// pixel (001 sec. 2.3).
    #[serde(default)]
    pub light_paths: Option<u32>,
    /// Paths of fewer segments are left out of the image (0 and 1 keep every path; 3 drops
    /// direct light, as 000 Fig. 4.3 does).
    #[serde(default)]
    pub min_path_length: u32,
    /// The numbers sub-paths are built from. Renders written before the choice existed drew
    /// independent numbers, so that is what a file without it continues with.
    #[serde(default = "independent")]
    pub sampler: SamplerKind,
}

fn independent() -> SamplerKind {
    SamplerKind::Independent
}

fn default_density_map_iterations() -> u32 {
    RenderOptions::DEFAULT.density_map_iterations
}

fn default_upg_packet() -> u32 {
    RenderOptions::DEFAULT.upg_packet
}

fn default_upg_max_trials() -> u32 {
    RenderOptions::DEFAULT.upg_max_trials
}

impl RenderOptions {
    /// The defaults, the one place they are written.
    pub const DEFAULT: RenderOptions = RenderOptions {
        technique: Technique::Pt,
        seed: 0,
        camera: None,
        resolution: None,
        beta: 2.0,
        radius: None,
        alpha: None,
        max_path_length: None,
        roulette: 3,
        no_vc: false,
        no_vm: false,
        strategy: None,
        unweighted: false,
        upg_packet: 1,
        upg_max_trials: 10_000,
        density_mis: None,
        density_map_iterations: 50,
        no_shading_normals: false,
        light_paths: None,
        min_path_length: 0,
        sampler: SamplerKind::Sobol,
    };

    /// The radius-shrinking exponent a render uses: the given one, 0.75 for the techniques
    /// whose density estimate shrinks its radius (000 eq. 2.85), and 1 (a fixed radius) for
    /// the rest; UPG is unbiased at any radius (000 sec. 2.4.6).
    pub fn alpha(&self) -> f32 {
        if self.technique.shrinks_radius() {
            self.alpha.unwrap_or(0.75)
        } else {
            1.0
        }
    }

    /// Checks every option against [`RULES`]: an option the technique does not take must keep
    /// its default, and every value must lie in its range.
    pub fn validate(&self) -> Result<(), OptionError> {
        for rule in RULES {
            if !(rule.takes)(self.technique) && (rule.is_set)(self) {
                return Err(OptionError::NotTaken {
                    option: OptionName(rule.name),
                    technique: self.technique,
                    takes: Technique::ALL
                        .into_iter()
                        .filter(|&t| (rule.takes)(t))
                        .collect(),
                });
            }
            if let Some(value) = (rule.invalid)(self) {
                return Err(OptionError::OutOfRange {
                    option: OptionName(rule.name),
                    value,
                    expected: rule.expected,
                });
            }
        }
        Ok(())
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions::DEFAULT
    }
}

/// One row of the options table.
pub struct OptionRule {
    /// The field of [`RenderOptions`] (the command line spells it with dashes).
    pub name: &'static str,
    /// The techniques that take the option.
    pub takes: fn(Technique) -> bool,
    /// Whether the option differs from its default.
    pub is_set: fn(&RenderOptions) -> bool,
    /// The value, written out, when it lies outside the valid range.
    pub invalid: fn(&RenderOptions) -> Option<String>,
    /// The valid range, in words.
    pub expected: &'static str,
}

fn every(_: Technique) -> bool {
    true
}

fn never_invalid(_: &RenderOptions) -> Option<String> {
    None
}

/// The options table: which technique takes which option, and its valid values. Seed,
/// camera, resolution and the path-length options apply to every technique.
pub static RULES: &[OptionRule] = &[
    OptionRule {
        name: "resolution",
        takes: every,
        is_set: |o| o.resolution.is_some(),
        invalid: |o| match o.resolution {
            Some([w, h]) if w == 0 || h == 0 => Some(format!("{w}x{h}")),
            _ => None,
        },
        expected: "a width and a height of at least 1",
    },
    OptionRule {
        name: "beta",
        takes: every,
        is_set: |o| o.beta != RenderOptions::DEFAULT.beta,
        invalid: |o| (!(o.beta.is_finite() && o.beta >= 0.0)).then(|| o.beta.to_string()),
        expected: "a finite power >= 0 (1 = balance heuristic, 2 = power heuristic)",
    },
    OptionRule {
        name: "radius",
        takes: Technique::merges,
        is_set: |o| o.radius.is_some(),
        invalid: |o| match o.radius {
            Some(r) if !(r.is_finite() && r > 0.0) => Some(r.to_string()),
            _ => None,
        },
        expected: "a finite radius > 0 in world units",
    },
    OptionRule {
        name: "alpha",
        takes: Technique::shrinks_radius,
        is_set: |o| o.alpha.is_some(),
        invalid: |o| match o.alpha {
            Some(a) if !(a > 0.0 && a <= 1.0) => Some(a.to_string()),
            _ => None,
        },
        expected: "an exponent in (0, 1] (1 keeps the radius)",
    },
    OptionRule {
        name: "max_path_length",
        takes: every,
        is_set: |o| o.max_path_length.is_some(),
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "roulette",
        takes: every,
        is_set: |o| o.roulette != RenderOptions::DEFAULT.roulette,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "min_path_length",
        takes: every,
        is_set: |o| o.min_path_length != RenderOptions::DEFAULT.min_path_length,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "light_paths",
        takes: Technique::traces_light_paths,
        is_set: |o| o.light_paths.is_some(),
        invalid: |o| (o.light_paths == Some(0)).then(|| "0".to_string()),
        expected: "at least 1 light sub-path per iteration",
    },
    OptionRule {
        name: "no_vc",
        // Merge-only UPG is the "pristine" technique of 000 sec. 5.2.
        takes: |t| t == Technique::Vcm || t.is_upg(),
        is_set: |o| o.no_vc,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "no_vm",
        takes: |t| t == Technique::Vcm,
        is_set: |o| o.no_vm,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "strategy",
        takes: |t| t == Technique::Bpt,
        is_set: |o| o.strategy.is_some(),
        invalid: |o| match o.strategy {
            Some([s, t]) if t == 0 || s + t < 2 => Some(format!("{s},{t}")),
            _ => None,
        },
        expected: "an existing technique S,T: T counts the camera vertex, so T >= 1 and S + T >= 2",
    },
    OptionRule {
        name: "unweighted",
        takes: |t| t == Technique::Bpt,
        is_set: |o| o.unweighted,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "upg_packet",
        takes: Technique::is_upg,
        is_set: |o| o.upg_packet != RenderOptions::DEFAULT.upg_packet,
        invalid: |o| (o.upg_packet != 1 && o.upg_packet != 8).then(|| o.upg_packet.to_string()),
        expected: "1 or 8 tentative rays at a time",
    },
    OptionRule {
        name: "upg_max_trials",
        takes: Technique::is_upg,
        is_set: |o| o.upg_max_trials != RenderOptions::DEFAULT.upg_max_trials,
        invalid: |o| (o.upg_max_trials == 0).then(|| "0".to_string()),
        expected: "at least 1 trial",
    },
    OptionRule {
        name: "sampler",
        takes: every,
        is_set: |o| o.sampler != RenderOptions::DEFAULT.sampler,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "no_shading_normals",
        takes: every,
        is_set: |o| o.no_shading_normals,
        invalid: never_invalid,
        expected: "",
    },
    OptionRule {
        name: "density_mis",
        takes: |t| matches!(t, Technique::Vcm | Technique::Bpm),
        is_set: |o| o.density_mis.is_some(),
        invalid: |o| (o.density_mis.is_some() && o.no_vm).then(|| "with no merges".to_string()),
        expected: "merges to weigh (not with no_vm)",
    },
    OptionRule {
        name: "density_map_iterations",
        takes: |t| matches!(t, Technique::Vcm | Technique::Bpm),
        is_set: |o| o.density_map_iterations != RenderOptions::DEFAULT.density_map_iterations,
        invalid: |o| (o.density_map_iterations == 0).then(|| "0".to_string()),
        expected: "at least 1 iteration",
    },
];

/// The most iterations a render may reach: far beyond any real render, and low enough that the
/// count of a continued render cannot wrap.
pub const MAX_ITERATIONS: u64 = 1 << 48;

/// The longest `time` or `snapshot` interval: 100 years.
pub const MAX_DURATION: Duration = Duration::from_secs(100 * 365 * 24 * 3600);

/// The stop conditions and the snapshot interval: not part of the image (so not in
/// [`RenderOptions`]), checked like the table's options. `iterations` counts the iterations
/// the render ends with, a continued render's earlier ones included.
pub fn validate_run(
    iterations: Option<u64>,
    time: Option<Duration>,
    snapshot: Option<Duration>,
) -> Result<(), OptionError> {
    if let Some(n) = iterations {
        if n == 0 {
            return Err(OptionError::OutOfRange {
                option: OptionName("iterations"),
                value: "0".into(),
                expected: "at least 1 iteration",
            });
        }
        if n > MAX_ITERATIONS {
            return Err(OptionError::Above {
                option: OptionName("iterations"),
                value: n,
                limit: MAX_ITERATIONS,
                why: "iterations in total, a continued render's earlier ones included".into(),
            });
        }
    }
    for (name, value) in [("time", time), ("snapshot", snapshot)] {
        match value {
            Some(d) if d.is_zero() => {
                return Err(OptionError::OutOfRange {
                    option: OptionName(name),
                    value: "0s".into(),
                    expected: "a duration > 0 (e.g. 90s, 10m, 2h)",
                })
            }
            Some(d) if d > MAX_DURATION => {
                return Err(OptionError::Above {
                    option: OptionName(name),
                    value: d.as_secs(),
                    limit: MAX_DURATION.as_secs(),
                    why: "seconds, 100 years".into(),
                })
            }
            _ => {}
        }
    }
    Ok(())
}

/// The most worker threads a render may ask for: 4 per core of this machine. More only
/// multiplies per-thread buffers; the image does not depend on the count.
pub fn max_threads() -> usize {
    4 * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// A thread count of at least 1 and at most [`max_threads`].
pub fn validate_threads(threads: usize) -> Result<(), OptionError> {
    if threads == 0 {
        return Err(OptionError::OutOfRange {
            option: OptionName("threads"),
            value: "0".into(),
            expected: "at least 1 thread",
        });
    }
    let limit = max_threads();
    if threads > limit {
        return Err(OptionError::Above {
            option: OptionName("threads"),
            value: threads as u64,
            limit: limit as u64,
            why: format!("4 per core; this machine has {}", limit / 4),
        });
    }
    Ok(())
}

/// A duration like `90s`, `10m`, `2h`, `500ms` (a bare number is seconds), zero included:
/// whether a zero means anything is for the caller to say.
pub fn parse_duration(s: &str) -> Result<std::time::Duration, String> {
    let s = s.trim();
    let split = s.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(s.len());
    let (number, unit) = s.split_at(split);
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a duration like 90s, 10m, 2h"))?;
    let seconds = match unit {
        "ms" => value / 1000.0,
        "" | "s" => value,
        "m" | "min" => value * 60.0,
        "h" => value * 3600.0,
        _ => return Err(format!("'{s}': unknown unit '{unit}' (ms, s, m, h)")),
    };
    if !(seconds.is_finite() && seconds >= 0.0) {
        return Err(format!("'{s}' is not a non-negative duration"));
    }
    std::time::Duration::try_from_secs_f64(seconds)
        .map_err(|_| format!("'{s}' is too long a duration"))
}

/// Whether [`OptionName`]s are written as command-line flags; set once by the command line.
static SPELL_AS_FLAGS: AtomicBool = AtomicBool::new(false);

/// The name of an option (or of another setting a message refers to, such as a stopping
/// condition), as data: messages print it in the front end's spelling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OptionName(pub &'static str);

impl OptionName {
    /// From now on, messages write option names as command-line flags (`--upg-packet`).
    pub fn spell_as_flags() {
        SPELL_AS_FLAGS.store(true, Ordering::Relaxed);
    }
}

impl fmt::Display for OptionName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if SPELL_AS_FLAGS.load(Ordering::Relaxed) {
            write!(f, "--{}", self.0.replace('_', "-"))
        } else {
            write!(f, "`{}`", self.0)
        }
    }
}

/// Options that do not mean anything together.
#[derive(Debug, Error, PartialEq)]
pub enum OptionError {
    #[error("{option} does not apply to {technique} (only to {})", names(takes))]
    NotTaken {
        option: OptionName,
        technique: Technique,
        takes: Vec<Technique>,
    },
    #[error("{option} {value}: expected {expected}")]
    OutOfRange {
        option: OptionName,
        value: String,
        expected: &'static str,
    },
    #[error("{option} {value}: at most {limit} ({why})")]
    Above {
        option: OptionName,
        value: u64,
        limit: u64,
        why: String,
    },
    #[error("{option}: {message}")]
    Needs { option: OptionName, message: String },
}

fn names(techniques: &[Technique]) -> String {
    let names: Vec<&str> = techniques.iter().map(|t| t.name()).collect();
    names.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_validate_for_every_technique() {
        for technique in Technique::ALL {
            let options = RenderOptions {
                technique,
                ..RenderOptions::DEFAULT
            };
            assert_eq!(options.validate(), Ok(()));
        }
    }

    /// A render recorded before the sampler was an option drew independent numbers, and
    /// continues with them; a new one records its sampler.
    #[test]
    fn recorded_options_without_a_sampler_continue_with_independent_numbers() {
        let mut table = match toml::Value::try_from(RenderOptions::DEFAULT) {
            Ok(toml::Value::Table(t)) => t,
            other => panic!("{other:?}"),
        };
        assert_eq!(
            table.remove("sampler"),
            Some(toml::Value::String("sobol".into()))
        );
        let old: RenderOptions = toml::Value::Table(table).try_into().unwrap();
        assert_eq!(old.sampler, SamplerKind::Independent);
    }

    #[test]
    fn every_rule_names_a_field_once() {
        let mut names: Vec<&str> = RULES.iter().map(|r| r.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), RULES.len());
    }

    #[test]
    fn options_of_other_techniques_are_refused() {
        let upg_alpha = RenderOptions {
            technique: Technique::Upg,
            alpha: Some(0.5),
            ..RenderOptions::DEFAULT
        };
        assert!(matches!(
            upg_alpha.validate(),
            Err(OptionError::NotTaken {
                option: OptionName("alpha"),
                ..
            })
        ));
        let bad_packet = RenderOptions {
            technique: Technique::UpgCamera,
            upg_packet: 4,
            ..RenderOptions::DEFAULT
        };
        assert!(matches!(
            bad_packet.validate(),
            Err(OptionError::OutOfRange {
                option: OptionName("upg_packet"),
                ..
            })
        ));
    }

    #[test]
    fn stop_conditions_and_threads_have_ranges() {
        let second = Some(Duration::from_secs(1));
        assert_eq!(validate_run(Some(1), second, second), Ok(()));
        assert!(validate_run(Some(0), None, None).is_err());
        assert!(validate_run(Some(MAX_ITERATIONS + 1), None, None).is_err());
        assert!(validate_run(None, Some(Duration::ZERO), None).is_err());
        assert!(validate_run(None, second, Some(Duration::ZERO)).is_err());
        assert!(validate_run(None, Some(MAX_DURATION * 2), None).is_err());
        assert_eq!(validate_threads(1), Ok(()));
        assert!(validate_threads(0).is_err());
        assert!(validate_threads(max_threads() + 1).is_err());
    }

    #[test]
    fn names_round_trip() {
        for t in Technique::ALL {
            assert_eq!(Technique::from_name(t.name()), Some(t));
        }
    }
}
