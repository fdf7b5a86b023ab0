//! The options of a render, in one place: the techniques, [`RenderOptions`] with its defaults,
//! and [`OPTIONS`], the one table that says of each option its flag, help, default, which
//! techniques take it, its valid values, and how it is written as a command-line argument and
//! read back. A leaf: everything above (the integrators, the render loop, the film's metadata,
//! the tools, the command line) takes its options from here.
//!
//! Options are named by [`OptionName`], data rather than text: the library writes
//! `` `upg_packet` ``, and a front end respells its messages ([`respell`]; the command line
//! writes `--upg-packet`).

use serde::{Deserialize, Serialize};
use std::fmt;
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
    VcmUpg,
    // Last, so the others keep their discriminants (tests seed renders by them).
    UpgHybrid,
}

impl Technique {
    pub const ALL: [Technique; 10] = [
        Technique::Pt,
        Technique::Lt,
        Technique::Bpt,
        Technique::Ppm,
        Technique::Bpm,
        Technique::Vcm,
        Technique::Upg,
        Technique::UpgCamera,
        Technique::UpgHybrid,
        Technique::VcmUpg,
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
            Technique::UpgHybrid => "upg-hybrid",
            Technique::VcmUpg => "vcm-upg",
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
            Technique::UpgHybrid => {
                "unbiased photon gathering, each merge from the side its glossiness picks"
            }
            Technique::VcmUpg => {
                "vcm, its merges near corners and edges made by unbiased photon gathering"
            }
        }
    }

    /// The technique called `name` (as [`Technique::name`] spells it).
    pub fn from_name(name: &str) -> Option<Technique> {
        Technique::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Merges by density estimation alone, whose radius shrinks (000 eq. 2.85): the
    /// techniques one-stage storage and per-pixel radii serve.
    pub fn shrinks_radius(self) -> bool {
        matches!(self, Technique::Ppm | Technique::Bpm | Technique::Vcm)
    }

    /// Biased, and consistent by shrinking its radius (000 eq. 2.85): the density estimators,
    /// and `vcm-upg`, whose merges are density estimates wherever the radius is small against
    /// the tentative ray.
    pub fn is_consistent(self) -> bool {
        self.shrinks_radius() || self == Technique::VcmUpg
    }

    /// Takes a radius per pixel (001 sec. 6.1): every merging technique but `vcm-upg`, whose
    /// merges read the light vertices' weights as they were traced, at one radius for all.
    pub fn takes_pixel_radius(self) -> bool {
        self.merges() && self != Technique::VcmUpg
    }

    /// Estimates acceptance probabilities with tentative rays (000 eq. 2.65).
    pub fn traces_tentative_rays(self) -> bool {
        self.is_upg() || self == Technique::VcmUpg
    }

    /// Unbiased photon gathering: merges at a fixed radius (000 sec. 2.4.6).
    pub fn is_upg(self) -> bool {
        matches!(
            self,
            Technique::Upg | Technique::UpgCamera | Technique::UpgHybrid
        )
    }

    /// Merges light vertices at all.
    pub fn merges(self) -> bool {
        self.is_consistent() || self.is_upg()
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

/// How the vertex-merging techniques keep their light vertices from one pass to the next.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MemoryLayout {
    /// All light sub-paths of an iteration first, stored whole (with what their BSDFs need),
    /// then the eye sub-paths connect and merge with them (001 sec. 2.3).
    TwoStage,
    /// Each pixel's light and eye sub-paths together; only what a merge reads is stored, and
    /// the eye sub-paths merge with the previous iteration's vertices (001 sec. 6.2).
    OneStage,
}

impl MemoryLayout {
    pub const ALL: [MemoryLayout; 2] = [MemoryLayout::TwoStage, MemoryLayout::OneStage];

    pub fn name(self) -> &'static str {
        match self {
            MemoryLayout::TwoStage => "two-stage",
            MemoryLayout::OneStage => "one-stage",
        }
    }

    pub fn description(self) -> &'static str {
        match self {
            MemoryLayout::TwoStage => "light pass, then eye pass: merges this iteration's vertices",
            MemoryLayout::OneStage => {
                "light and eye sub-path per pixel: merges the previous iteration's compact vertices"
            }
        }
    }
}

/// 002's MIS heuristics for merges (density estimates and UPG's): the merge at x_i counts
/// n_VM / k_i light sub-paths instead of n_VM, with k_i the expected number of light vertices
/// in its radius.
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

/// Every option that changes the image. Serialized into the EXR so `continue` can resume; a
/// field a recording lacks (it was written before the option existed) reads as
/// [`RenderOptions::RECORDED`] has it. [`OPTIONS`] says everything else about each field.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default = "RenderOptions::recorded")]
pub struct RenderOptions {
    pub technique: Technique,
    pub seed: u64,
    pub camera: Option<String>,
    pub resolution: Option<[u32; 2]>,
    /// MIS power (1 = balance heuristic, 2 = power heuristic).
    pub beta: f32,
    /// Merge radius in world units; `None` = the scene's default.
    pub radius: Option<f32>,
    /// Merge radius per eye sub-path from its pixel footprint (001 sec. 6.1): this many pixel
    /// widths at the distance of its first non-specular vertex; `None` = one global radius.
    pub radius_pixels: Option<f32>,
    /// Radius shrinking exponent (000 eq. 2.85); `None` = the technique's default.
    pub alpha: Option<f32>,
    /// Segments of a full path; `None` = the scene's default, 0 = unbounded.
    pub max_path_length: Option<u32>,
    /// Path length (in segments) from which Russian roulette may end paths.
    pub roulette: u32,
    pub no_vc: bool,
    pub no_vm: bool,
    /// `bpt` only: render the contribution of one (s, t) technique alone.
    pub strategy: Option<[u32; 2]>,
    /// `bpt` only: leave the MIS weights out (each technique at weight 1).
    pub unweighted: bool,
    /// `upg`, `upg-camera`, `vcm-upg`: tentative rays traced 1 or 8 at a time.
    pub upg_packet: u32,
    /// `upg`, `upg-camera`, `vcm-upg`: Bernoulli trials after which a merge is dropped.
    pub upg_max_trials: u32,
    /// `vcm-upg`: the length of a merge's tentative ray, in radii, up to which UPG makes every
    /// merge, and from which VCM's density estimate makes every one; smooth between.
    pub blend_near: f32,
    pub blend_far: f32,
    /// `upg-hybrid`: the roughness (an alpha: 0 smooth, 1 diffuse) from which a merge vertex's
    /// neighbour towards the light sends the tentative rays (`upg`'s gather); merges whose
    /// neighbour is smoother are gathered from the camera side (`upg-camera`'s).
    pub hybrid_roughness: f32,
    /// `vcm`, `bpm`, `upg`, `upg-camera`: 002's density-map heuristic instead of VCM's.
    pub density_mis: Option<DensityMis>,
    /// Iterations whose light vertices fill the density map; after them it is fixed (002
    /// sec. 5.1), so the weights are deterministic.
    pub density_map_iterations: u32,
    /// Render every triangle flat, ignoring the meshes' vertex normals (applied when the scene
    /// is loaded).
    pub no_shading_normals: bool,
    /// Light sub-paths per iteration, n_VM (the thesis's `--num-photons`); `None` = one per
    /// pixel (001 sec. 2.3).
    pub light_paths: Option<u32>,
    /// `vcm`, `bpm`, `ppm`: how light vertices are kept (001 sec. 6.2).
    pub memory: MemoryLayout,
    /// Paths of fewer segments are left out of the image (0 and 1 keep every path; 3 drops
    /// direct light, as 000 Fig. 4.3 does).
    pub min_path_length: u32,
    /// The numbers sub-paths are built from.
    pub sampler: SamplerKind,
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
        radius_pixels: None,
        alpha: None,
        max_path_length: None,
        roulette: 3,
        no_vc: false,
        no_vm: false,
        strategy: None,
        unweighted: false,
        upg_packet: 1,
        upg_max_trials: 10_000,
        blend_near: 4.0,
        blend_far: 12.0,
        hybrid_roughness: 0.2,
        density_mis: None,
        density_map_iterations: 50,
        no_shading_normals: false,
        light_paths: None,
        memory: MemoryLayout::TwoStage,
        min_path_length: 0,
        sampler: SamplerKind::Sobol,
    };

    /// What a recorded field that is absent means: its default, but for the sampler. Renders
    /// written before the sampler was a choice drew independent numbers, so that is what a
    /// file without it continues with.
    pub const RECORDED: RenderOptions = RenderOptions {
        sampler: SamplerKind::Independent,
        ..RenderOptions::DEFAULT
    };

    fn recorded() -> RenderOptions {
        RenderOptions::RECORDED
    }

    /// The radius-shrinking exponent a render uses: the given one, 0.75 for the techniques
    /// whose density estimate shrinks its radius (000 eq. 2.85), and 1 (a fixed radius) for
    /// the rest; UPG is unbiased at any radius (000 sec. 2.4.6).
    pub fn alpha(&self) -> f32 {
        if self.technique.is_consistent() {
            self.alpha.unwrap_or(0.75)
        } else {
            1.0
        }
    }

    /// Whether the render connects vertices (001's vertex connection: light sampling,
    /// light-to-camera and sub-path connections): not the light tracer nor the photon
    /// mappers, and the rest unless `no_vc`.
    pub fn connects(&self) -> bool {
        match self.technique {
            Technique::Lt | Technique::Ppm | Technique::Bpm => false,
            _ => !self.no_vc,
        }
    }

    /// Whether the render merges vertices: the techniques that merge, vcm unless `no_vm`
    /// (the one technique that takes it).
    pub fn merges(&self) -> bool {
        match self.technique {
            Technique::Vcm => !self.no_vm,
            t => t.merges(),
        }
    }

    /// Checks every option against [`OPTIONS`]: an option the technique does not take must
    /// keep its default, and every value must lie in its range.
    pub fn validate(&self) -> Result<(), OptionError> {
        for spec in OPTIONS {
            if !(spec.takes)(self.technique) && spec.is_set(self) {
                return Err(OptionError::NotTaken {
                    option: OptionName(spec.name),
                    technique: self.technique,
                    takes: Technique::ALL
                        .into_iter()
                        .filter(|&t| (spec.takes)(t))
                        .collect(),
                });
            }
            if let Some(value) = (spec.invalid)(self) {
                return Err(OptionError::OutOfRange {
                    option: OptionName(spec.name),
                    value,
                    expected: spec.expected,
                });
            }
        }
        Ok(())
    }

    /// The command-line arguments that give these options: every option that differs from
    /// its default, the technique always, in [`OPTIONS`]' order. [`RenderOptions::from_args`]
    /// reads them back.
    pub fn to_args(&self) -> Vec<String> {
        let mut args = Vec::new();
        for spec in OPTIONS {
            if spec.name != "technique" && !spec.is_set(self) {
                continue;
            }
            args.push(spec.flag());
            if let (Form::Value { .. }, Some(value)) = (spec.form, (spec.write)(self)) {
                args.push(value);
            }
        }
        args
    }

    /// Options from command-line arguments as [`RenderOptions::to_args`] writes them (and the
    /// command line takes them: `--flag VALUE`, a switch alone), each read by its
    /// [`OptionSpec::read`]; what is not given keeps its default. Not validated.
    pub fn from_args<S: AsRef<str>>(args: &[S]) -> Result<RenderOptions, OptionError> {
        let mut options = RenderOptions::DEFAULT;
        let mut args = args.iter().map(AsRef::as_ref);
        while let Some(arg) = args.next() {
            let spec = OPTIONS
                .iter()
                .find(|s| s.flag() == arg || s.short.is_some_and(|c| arg == format!("-{c}")))
                .ok_or_else(|| OptionError::Unknown {
                    argument: arg.to_string(),
                })?;
            let value = match spec.form {
                Form::Switch => SWITCH_ON,
                Form::Value { .. } => args.next().ok_or(OptionError::Needs {
                    option: OptionName(spec.name),
                    message: "needs a value".into(),
                })?,
            };
            spec.read(&mut options, value)?;
        }
        Ok(options)
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions::DEFAULT
    }
}

/// How an option is given on the command line.
#[derive(Clone, Copy, Debug)]
pub enum Form {
    /// A flag alone, which turns the option on.
    Switch,
    /// A flag and a value, shown as `value_name` in help; `choices`, when given, lists the
    /// values it accepts with their meaning.
    Value {
        value_name: &'static str,
        choices: Option<fn() -> Vec<Choice>>,
    },
}

/// One value of an option that takes a few named ones: its name and what it means.
pub type Choice = (&'static str, &'static str);

/// The value [`OptionSpec::read`] takes for a switch that is given.
pub const SWITCH_ON: &str = "true";

/// One row of the options table: a field of [`RenderOptions`] and everything said about it.
pub struct OptionSpec {
    /// The field of [`RenderOptions`]; the command line spells it with dashes (`--upg-packet`).
    pub name: &'static str,
    /// A one-letter flag beside the long one.
    pub short: Option<char>,
    pub form: Form,
    /// What the option does, in one line; [`OptionSpec::help_text`] names the techniques
    /// before it when not every one takes the option.
    pub help: &'static str,
    /// The techniques that take the option.
    pub takes: fn(Technique) -> bool,
    /// The value as an argument writes it; `None` when it has none (an optional value that is
    /// not given, a switch that is off). The default is what [`RenderOptions::DEFAULT`] writes.
    pub write: fn(&RenderOptions) -> Option<String>,
    /// Sets the option from an argument as `write` writes it ([`SWITCH_ON`] for a switch);
    /// the message says why a value is not one.
    pub parse: fn(&mut RenderOptions, &str) -> Result<(), String>,
    /// The value, written out, when it lies outside the valid range.
    pub invalid: fn(&RenderOptions) -> Option<String>,
    /// The valid range, in words.
    pub expected: &'static str,
}

impl OptionSpec {
    /// The command line's flag: `--upg-packet`.
    pub fn flag(&self) -> String {
        OptionName(self.name).flag()
    }

    /// The help line: `help`, after the techniques that take the option where not all do
    /// (`bpm, vcm: weigh merges ...`).
    pub fn help_text(&self) -> String {
        let takes: Vec<Technique> = Technique::ALL
            .into_iter()
            .filter(|&t| (self.takes)(t))
            .collect();
        if takes.len() == Technique::ALL.len() {
            self.help.to_string()
        } else {
            format!("{}: {}", names(&takes), self.help)
        }
    }

    /// The default as an argument writes it; `None` when it has none.
    pub fn default_value(&self) -> Option<String> {
        (self.write)(&RenderOptions::DEFAULT)
    }

    /// Whether the option differs from its default.
    pub fn is_set(&self, o: &RenderOptions) -> bool {
        (self.write)(o) != self.default_value()
    }

    /// Sets the option in `o` from an argument.
    pub fn read(&self, o: &mut RenderOptions, value: &str) -> Result<(), OptionError> {
        (self.parse)(o, value).map_err(|message| OptionError::Unreadable {
            option: OptionName(self.name),
            value: value.to_string(),
            message,
        })
    }
}

fn every(_: Technique) -> bool {
    true
}

fn never_invalid(_: &RenderOptions) -> Option<String> {
    None
}

fn number<T: std::str::FromStr>(s: &str) -> Result<T, String>
where
    T::Err: fmt::Display,
{
    s.parse().map_err(|e: T::Err| e.to_string())
}

/// A whole number of 32 bits; a value outside them is named with the range.
fn count(s: &str) -> Result<u32, String> {
    let wide: i64 = number(s)?;
    u32::try_from(wide).map_err(|_| format!("{wide} is not in 0..={}", u32::MAX))
}

fn switch(s: &str) -> Result<bool, String> {
    s.parse()
        .map_err(|_| format!("'{s}': a switch is {SWITCH_ON} or false"))
}

/// `WxH`, both sides at least 1.
fn resolution(s: &str) -> Result<[u32; 2], String> {
    let side = |v: &str| v.parse::<u32>().map_err(|_| format!("'{s}' is not WxH"));
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("'{s}' is not WxH"))?;
    let (w, h) = (side(w)?, side(h)?);
    if w == 0 || h == 0 {
        return Err(format!("'{s}' has a zero side"));
    }
    Ok([w, h])
}

/// `S,T`.
fn strategy(s: &str) -> Result<[u32; 2], String> {
    let part = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}': expected S,T (two whole numbers)"))
    };
    match s.split_once(',') {
        Some((a, b)) => Ok([part(a)?, part(b)?]),
        None => Err(format!("'{s}': expected S,T (two whole numbers)")),
    }
}

/// One of `all` by its name.
fn by_name<T: Copy>(all: &[T], name: fn(T) -> &'static str, s: &str) -> Result<T, String> {
    all.iter().copied().find(|&t| name(t) == s).ok_or_else(|| {
        let names: Vec<&str> = all.iter().map(|&t| name(t)).collect();
        format!("'{s}': expected one of {}", names.join(", "))
    })
}

/// The options table: each option of [`RenderOptions`] once, with its flag, help, default
/// (what it writes for [`RenderOptions::DEFAULT`]), the techniques that take it, its valid
/// range, and how it is written as an argument and read back. The command line's arguments,
/// validation, batch plans' keys, command lines and cell names are all derived from it.
pub static OPTIONS: &[OptionSpec] = &[
    OptionSpec {
        name: "technique",
        short: Some('t'),
        form: Form::Value {
            value_name: "TECHNIQUE",
            choices: Some(|| Technique::ALL.map(|t| (t.name(), t.description())).to_vec()),
        },
        help: "",
        takes: every,
        write: |o| Some(o.technique.name().into()),
        parse: |o, s| {
            o.technique = by_name(&Technique::ALL, Technique::name, s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "seed",
        short: None,
        form: Form::Value {
            value_name: "SEED",
            choices: None,
        },
        help: "",
        takes: every,
        write: |o| Some(o.seed.to_string()),
        parse: |o, s| {
            o.seed = number(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "camera",
        short: None,
        form: Form::Value {
            value_name: "CAMERA",
            choices: None,
        },
        help: "Camera name or index",
        takes: every,
        write: |o| o.camera.clone(),
        parse: |o, s| {
            o.camera = Some(s.to_string());
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "resolution",
        short: None,
        form: Form::Value {
            value_name: "RESOLUTION",
            choices: None,
        },
        help: "WxH, e.g. 512x512",
        takes: every,
        write: |o| o.resolution.map(|[w, h]| format!("{w}x{h}")),
        parse: |o, s| {
            o.resolution = Some(resolution(s)?);
            Ok(())
        },
        invalid: |o| match o.resolution {
            Some([w, h]) if w == 0 || h == 0 => Some(format!("{w}x{h}")),
            _ => None,
        },
        expected: "a width and a height of at least 1",
    },
    OptionSpec {
        name: "beta",
        short: None,
        form: Form::Value {
            value_name: "BETA",
            choices: None,
        },
        help: "MIS power (2 = power heuristic, 1 = balance heuristic)",
        takes: every,
        write: |o| Some(o.beta.to_string()),
        parse: |o, s| {
            o.beta = number(s)?;
            Ok(())
        },
        invalid: |o| (!(o.beta.is_finite() && o.beta >= 0.0)).then(|| o.beta.to_string()),
        expected: "a finite power >= 0 (1 = balance heuristic, 2 = power heuristic)",
    },
    OptionSpec {
        name: "radius",
        short: None,
        form: Form::Value {
            value_name: "RADIUS",
            choices: None,
        },
        help: "merge radius in world units (default: 0.003 x the scene's bounding-sphere diameter, or of the camera's view where the bounds are far larger than what it sees)",
        takes: Technique::merges,
        write: |o| o.radius.map(|r| r.to_string()),
        parse: |o, s| {
            o.radius = Some(number(s)?);
            Ok(())
        },
        invalid: |o| match o.radius {
            Some(r) if !(r.is_finite() && r > 0.0) => Some(r.to_string()),
            _ => None,
        },
        expected: "a finite radius > 0 in world units",
    },
    OptionSpec {
        name: "radius_pixels",
        short: None,
        form: Form::Value {
            value_name: "PIXELS",
            choices: None,
        },
        help: "merge radius per pixel: this many pixel footprints at the first non-specular eye vertex, shrinking like --radius (001 sec. 6.1)",
        takes: Technique::takes_pixel_radius,
        write: |o| o.radius_pixels.map(|k| k.to_string()),
        parse: |o, s| {
            o.radius_pixels = Some(number(s)?);
            Ok(())
        },
        // One radius of the two kinds is enough.
        invalid: |o| match o.radius_pixels {
            Some(k) if !(k.is_finite() && k > 0.0) => Some(k.to_string()),
            Some(k) if o.radius.is_some() => Some(format!("{k} with --radius")),
            _ => None,
        },
        expected: "a finite number of pixels > 0, without --radius",
    },
    OptionSpec {
        name: "alpha",
        short: None,
        form: Form::Value {
            value_name: "ALPHA",
            choices: None,
        },
        help: "radius shrinking exponent r_i = r_1 sqrt(i^(alpha-1)) (default 0.75)",
        takes: Technique::is_consistent,
        write: |o| o.alpha.map(|a| a.to_string()),
        parse: |o, s| {
            o.alpha = Some(number(s)?);
            Ok(())
        },
        invalid: |o| match o.alpha {
            Some(a) if !(a > 0.0 && a <= 1.0) => Some(a.to_string()),
            _ => None,
        },
        expected: "an exponent in (0, 1] (1 keeps the radius)",
    },
    OptionSpec {
        name: "max_path_length",
        short: None,
        form: Form::Value {
            value_name: "MAX_PATH_LENGTH",
            choices: None,
        },
        help: "Segments of a full path, light to eye; 0 = unbounded (default: the scene's)",
        takes: every,
        write: |o| o.max_path_length.map(|n| n.to_string()),
        parse: |o, s| {
            o.max_path_length = Some(count(s)?);
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "roulette",
        short: None,
        form: Form::Value {
            value_name: "ROULETTE",
            choices: None,
        },
        help: "Path length in segments from which Russian roulette may end paths",
        takes: every,
        write: |o| Some(o.roulette.to_string()),
        parse: |o, s| {
            o.roulette = count(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "min_path_length",
        short: None,
        form: Form::Value {
            value_name: "MIN_PATH_LENGTH",
            choices: None,
        },
        help: "Leave out paths of fewer segments (3 drops direct light)",
        takes: every,
        write: |o| Some(o.min_path_length.to_string()),
        parse: |o, s| {
            o.min_path_length = count(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "light_paths",
        short: None,
        form: Form::Value {
            value_name: "LIGHT_PATHS",
            choices: None,
        },
        help: "light sub-paths per iteration, n_VM (default: one per pixel)",
        takes: Technique::traces_light_paths,
        write: |o| o.light_paths.map(|n| n.to_string()),
        parse: |o, s| {
            o.light_paths = Some(count(s)?);
            Ok(())
        },
        invalid: |o| (o.light_paths == Some(0)).then(|| "0".to_string()),
        expected: "at least 1 light sub-path per iteration",
    },
    OptionSpec {
        name: "no_vc",
        short: None,
        form: Form::Switch,
        help: "vertex merging only",
        // Merge-only UPG is the "pristine" technique of 000 sec. 5.2.
        takes: |t| t == Technique::Vcm || t.is_upg(),
        write: |o| o.no_vc.then(|| SWITCH_ON.into()),
        parse: |o, s| {
            o.no_vc = switch(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "no_vm",
        short: None,
        form: Form::Switch,
        help: "vertex connection only",
        takes: |t| t == Technique::Vcm,
        write: |o| o.no_vm.then(|| SWITCH_ON.into()),
        parse: |o, s| {
            o.no_vm = switch(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "strategy",
        short: None,
        form: Form::Value {
            value_name: "S,T",
            choices: None,
        },
        help: "render only the technique with S light and T eye vertices (T counts the camera)",
        takes: |t| t == Technique::Bpt,
        write: |o| o.strategy.map(|[s, t]| format!("{s},{t}")),
        parse: |o, s| {
            o.strategy = Some(strategy(s)?);
            Ok(())
        },
        invalid: |o| match o.strategy {
            Some([s, t]) if t == 0 || s.saturating_add(t) < 2 => Some(format!("{s},{t}")),
            _ => None,
        },
        expected: "an existing technique S,T: T counts the camera vertex, so T >= 1 and S + T >= 2",
    },
    OptionSpec {
        name: "unweighted",
        short: None,
        form: Form::Switch,
        help: "leave out the MIS weights (with --strategy: one technique's full estimate)",
        takes: |t| t == Technique::Bpt,
        write: |o| o.unweighted.then(|| SWITCH_ON.into()),
        parse: |o, s| {
            o.unweighted = switch(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "upg_packet",
        short: None,
        form: Form::Value {
            value_name: "UPG_PACKET",
            choices: None,
        },
        help: "trace tentative rays 1 or 8 at a time",
        takes: Technique::traces_tentative_rays,
        write: |o| Some(o.upg_packet.to_string()),
        parse: |o, s| {
            o.upg_packet = count(s)?;
            Ok(())
        },
        invalid: |o| (o.upg_packet != 1 && o.upg_packet != 8).then(|| o.upg_packet.to_string()),
        expected: "1 or 8 tentative rays at a time",
    },
    OptionSpec {
        name: "upg_max_trials",
        short: None,
        form: Form::Value {
            value_name: "UPG_MAX_TRIALS",
            choices: None,
        },
        help: "trials after which a merge is dropped (and counted)",
        takes: Technique::traces_tentative_rays,
        write: |o| Some(o.upg_max_trials.to_string()),
        parse: |o, s| {
            o.upg_max_trials = count(s)?;
            Ok(())
        },
        invalid: |o| (o.upg_max_trials == 0).then(|| "0".to_string()),
        expected: "at least 1 trial",
    },
    OptionSpec {
        name: "blend_near",
        short: None,
        form: Form::Value {
            value_name: "RADII",
            choices: None,
        },
        help: "UPG makes every merge whose tentative ray is at most this many radii long",
        takes: |t| t == Technique::VcmUpg,
        write: |o| Some(o.blend_near.to_string()),
        parse: |o, s| {
            o.blend_near = number(s)?;
            Ok(())
        },
        invalid: |o| {
            (!(o.blend_near.is_finite() && o.blend_near >= 0.0)).then(|| o.blend_near.to_string())
        },
        expected: "a finite number of radii >= 0",
    },
    OptionSpec {
        name: "blend_far",
        short: None,
        form: Form::Value {
            value_name: "RADII",
            choices: None,
        },
        help: "VCM's density estimate makes every merge whose tentative ray is at least this many radii long; smooth between blend_near and this",
        takes: |t| t == Technique::VcmUpg,
        write: |o| Some(o.blend_far.to_string()),
        parse: |o, s| {
            o.blend_far = number(s)?;
            Ok(())
        },
        // Equal ends would switch at one length: a seam in the image.
        invalid: |o| match o.blend_far {
            far if !far.is_finite() => Some(far.to_string()),
            far if far <= o.blend_near => Some(format!("{far}, not above {}", o.blend_near)),
            _ => None,
        },
        expected: "a finite number of radii above blend_near",
    },
    OptionSpec {
        name: "hybrid_roughness",
        short: None,
        form: Form::Value {
            value_name: "ALPHA",
            choices: None,
        },
        help: "a merge is gathered from the light side where the vertex before it towards the light is at least this rough (an alpha: 0 smooth, 1 diffuse), else from the camera side",
        takes: |t| t == Technique::UpgHybrid,
        write: |o| Some(o.hybrid_roughness.to_string()),
        parse: |o, s| {
            o.hybrid_roughness = number(s)?;
            Ok(())
        },
        invalid: |o| {
            (!(o.hybrid_roughness.is_finite() && o.hybrid_roughness >= 0.0))
                .then(|| o.hybrid_roughness.to_string())
        },
        expected: "a finite roughness >= 0",
    },
    OptionSpec {
        name: "sampler",
        short: None,
        form: Form::Value {
            value_name: "SAMPLER",
            choices: Some(|| {
                SamplerKind::ALL
                    .map(|k| (k.name(), k.description()))
                    .to_vec()
            }),
        },
        help: "The numbers sub-paths are built from",
        takes: every,
        write: |o| Some(o.sampler.name().into()),
        parse: |o, s| {
            o.sampler = by_name(&SamplerKind::ALL, SamplerKind::name, s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "no_shading_normals",
        short: None,
        form: Form::Switch,
        help: "Render every triangle flat, ignoring the meshes' vertex normals",
        takes: every,
        write: |o| o.no_shading_normals.then(|| SWITCH_ON.into()),
        parse: |o, s| {
            o.no_shading_normals = switch(s)?;
            Ok(())
        },
        invalid: never_invalid,
        expected: "",
    },
    OptionSpec {
        name: "memory",
        short: None,
        form: Form::Value {
            value_name: "MEMORY",
            choices: Some(|| {
                MemoryLayout::ALL
                    .map(|m| (m.name(), m.description()))
                    .to_vec()
            }),
        },
        help: "how light vertices are kept: one-stage needs a fraction of the memory",
        takes: Technique::shrinks_radius,
        write: |o| Some(o.memory.name().into()),
        parse: |o, s| {
            o.memory = by_name(&MemoryLayout::ALL, MemoryLayout::name, s)?;
            Ok(())
        },
        // One-stage re-weighs the stored vertices for the next iteration's global radius; with
        // a radius per pixel they carry no radius at all (001 sec. 6.1), a pairing not built.
        invalid: |o| match (o.memory, o.density_mis, o.light_paths) {
            (MemoryLayout::OneStage, Some(d), _) => Some(format!("one-stage with {}", d.name())),
            (MemoryLayout::OneStage, _, Some(n)) => Some(format!("one-stage with {n} light paths")),
            (MemoryLayout::OneStage, _, _) if o.radius_pixels.is_some() => {
                Some("one-stage with --radius-pixels".into())
            }
            _ => None,
        },
        expected: "one-stage with one light sub-path per pixel, no density map and a global radius",
    },
    OptionSpec {
        name: "density_mis",
        short: None,
        form: Form::Value {
            value_name: "DENSITY_MIS",
            choices: Some(|| {
                DensityMis::ALL
                    .map(|d| (d.name(), d.description()))
                    .to_vec()
            }),
        },
        help: "weigh merges by the density of light vertices (002's VCM+ or VCM*)",
        takes: |t| matches!(t, Technique::Vcm | Technique::Bpm) || t.is_upg(),
        write: |o| o.density_mis.map(|d| d.name().into()),
        parse: |o, s| {
            o.density_mis = Some(by_name(&DensityMis::ALL, DensityMis::name, s)?);
            Ok(())
        },
        invalid: |o| (o.density_mis.is_some() && o.no_vm).then(|| "with no merges".to_string()),
        expected: "merges to weigh (not with no_vm)",
    },
    OptionSpec {
        name: "density_map_iterations",
        short: None,
        form: Form::Value {
            value_name: "DENSITY_MAP_ITERATIONS",
            choices: None,
        },
        help: "iterations whose light vertices fill the density map",
        takes: |t| matches!(t, Technique::Vcm | Technique::Bpm) || t.is_upg(),
        write: |o| Some(o.density_map_iterations.to_string()),
        parse: |o, s| {
            o.density_map_iterations = count(s)?;
            Ok(())
        },
        invalid: |o| (o.density_map_iterations == 0).then(|| "0".to_string()),
        expected: "at least 1 iteration",
    },
];

/// The most iterations a render may reach: far beyond any real render, and low enough that the
/// count of a continued render cannot wrap.
pub const MAX_ITERATIONS: u64 = 1 << 48;

/// The longest `time` or `snapshot` interval: 100 years.
pub const MAX_DURATION: Duration = Duration::from_secs(100 * 365 * 24 * 3600);

/// The help of the wall-clock budget, for every front end: the stopping rule and its bound.
pub const TIME_HELP: &str = "Stop after this time (e.g. 90s, 10m, 2h) from the first \
iteration: no iteration starts that would end past it, predicting each to take the mean of \
those before, so a render overshoots only by what its last iteration took beyond the mean";

/// The help of the CPU-time budget.
pub const CPU_TIME_HELP: &str = "Stop after this CPU time (e.g. 90s, 10m), all threads \
together: equal work for renders that share a machine; the same stopping rule as --time";

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
        validate_duration(name, value)?;
    }
    Ok(())
}

/// The CPU-time budget, checked as [`validate_run`] checks the wall-clock one.
pub fn validate_cpu_time(cpu_time: Option<Duration>) -> Result<(), OptionError> {
    validate_duration("cpu_time", cpu_time)
}

/// A duration option: more than zero, at most [`MAX_DURATION`].
fn validate_duration(name: &'static str, value: Option<Duration>) -> Result<(), OptionError> {
    match value {
        Some(d) if d.is_zero() => Err(OptionError::OutOfRange {
            option: OptionName(name),
            value: "0s".into(),
            expected: "a duration > 0 (e.g. 90s, 10m, 2h)",
        }),
        Some(d) if d > MAX_DURATION => Err(OptionError::Above {
            option: OptionName(name),
            value: d.as_secs(),
            limit: MAX_DURATION.as_secs(),
            why: "seconds, 100 years".into(),
        }),
        _ => Ok(()),
    }
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

/// The name of an option (or of another setting a message refers to, such as a stopping
/// condition), as data. The library writes it `` `upg_packet` ``; a front end that spells it
/// otherwise rewrites its messages with [`respell`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OptionName(pub &'static str);

impl OptionName {
    /// The command line's flag: `--upg-packet`.
    pub fn flag(self) -> String {
        format!("--{}", self.0.replace('_', "-"))
    }
}

impl fmt::Display for OptionName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}`", self.0)
    }
}

/// `message` with every option name written as [`OptionName`] writes it (`` `upg_packet` ``)
/// replaced by `spelling(name)`, where that gives one; other quoted words stay as they are.
pub fn respell(message: &str, spelling: impl Fn(&str) -> Option<String>) -> String {
    let is_name = |w: &str| {
        !w.is_empty()
            && w.chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
    };
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(open) = rest.find('`') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        let spelled = after.find('`').and_then(|close| {
            let word = &after[..close];
            is_name(word)
                .then(|| spelling(word))
                .flatten()
                .map(|s| (s, close))
        });
        match spelled {
            Some((s, close)) => {
                out.push_str(&s);
                rest = &after[close + 1..];
            }
            None => {
                out.push('`');
                rest = after;
            }
        }
    }
    out.push_str(rest);
    out
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
    #[error("{option} '{value}': {message}")]
    Unreadable {
        option: OptionName,
        value: String,
        message: String,
    },
    #[error("'{argument}' is no render option")]
    Unknown { argument: String },
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

    /// Recordings older than any of the options added since the first release load, with each
    /// missing option at the value it had then.
    #[test]
    fn recordings_without_the_later_options_load() {
        let first = toml::toml! {
            technique = "vcm"
            seed = 0
            beta = 1.0
            roulette = 5
            no_vc = false
            no_vm = true
        };
        let old: RenderOptions = toml::Value::Table(first).try_into().unwrap();
        assert_eq!(
            old,
            RenderOptions {
                technique: Technique::Vcm,
                beta: 1.0,
                roulette: 5,
                no_vm: true,
                ..RenderOptions::RECORDED
            }
        );
    }

    /// Every field of [`RenderOptions`] has one row: the serialised options name each field
    /// once, and the table names the same fields.
    #[test]
    fn every_field_has_one_row() {
        let mut names: Vec<&str> = OPTIONS.iter().map(|r| r.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), OPTIONS.len());
        let fields = match toml::Value::try_from(RenderOptions {
            camera: Some("front".into()),
            resolution: Some([1, 1]),
            radius: Some(1.0),
            radius_pixels: Some(1.0),
            alpha: Some(1.0),
            max_path_length: Some(1),
            strategy: Some([1, 1]),
            density_mis: Some(DensityMis::Plus),
            light_paths: Some(1),
            ..RenderOptions::DEFAULT
        }) {
            Ok(toml::Value::Table(t)) => t,
            other => panic!("{other:?}"),
        };
        let mut fields: Vec<&str> = fields.keys().map(String::as_str).collect();
        fields.sort_unstable();
        assert_eq!(fields, names);
    }

    #[test]
    fn library_messages_quote_names_and_front_ends_respell_them() {
        let e = OptionError::NotTaken {
            option: OptionName("upg_packet"),
            technique: Technique::Vcm,
            takes: vec![Technique::Upg, Technique::UpgCamera],
        };
        let text = e.to_string();
        assert_eq!(
            text,
            "`upg_packet` does not apply to vcm (only to upg, upg-camera)"
        );
        let flags = |name: &str| (name == "upg_packet").then(|| OptionName("upg_packet").flag());
        assert_eq!(
            respell("`embree` `upg_packet`, `not a name` `", flags),
            "`embree` --upg-packet, `not a name` `"
        );
        assert_eq!(OptionName("upg_packet").flag(), "--upg-packet");
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

    /// A per-pixel radius is a positive footprint and is not one radius twice; every technique
    /// that merges but `vcm-upg` takes it, 002's weights too, and one-stage merging refuses it.
    #[test]
    fn radius_pixels_has_a_range_and_excludes_global_radii() {
        let vcm = |radius_pixels, radius, density_mis| RenderOptions {
            technique: Technique::Vcm,
            radius_pixels: Some(radius_pixels),
            radius,
            density_mis,
            ..RenderOptions::DEFAULT
        };
        assert_eq!(vcm(1.5, None, None).validate(), Ok(()));
        for density in DensityMis::ALL {
            assert_eq!(vcm(1.5, None, Some(density)).validate(), Ok(()));
            for technique in [Technique::Upg, Technique::UpgCamera] {
                let upg = RenderOptions {
                    technique,
                    ..vcm(1.5, None, Some(density))
                };
                assert_eq!(upg.validate(), Ok(()));
            }
        }
        for bad in [
            vcm(0.0, None, None),
            vcm(f32::NAN, None, None),
            vcm(1.0, Some(0.1), None),
        ] {
            assert!(matches!(
                bad.validate(),
                Err(OptionError::OutOfRange {
                    option: OptionName("radius_pixels"),
                    ..
                })
            ));
        }
        let one_stage = RenderOptions {
            memory: MemoryLayout::OneStage,
            ..vcm(1.0, None, None)
        };
        assert!(matches!(
            one_stage.validate(),
            Err(OptionError::OutOfRange {
                option: OptionName("memory"),
                ..
            })
        ));
        for technique in Technique::ALL {
            let o = RenderOptions {
                technique,
                ..vcm(1.0, None, None)
            };
            let refused = matches!(
                o.validate(),
                Err(OptionError::NotTaken {
                    option: OptionName("radius_pixels"),
                    ..
                })
            );
            assert_eq!(refused, !technique.takes_pixel_radius(), "{technique}");
        }
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
