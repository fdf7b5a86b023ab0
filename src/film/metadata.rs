//! What vmerge records about a render next to its pixels: the technique and every option, the
//! scene and its hash, the seed, iterations, time, dropped samples, statistics and the error
//! series against a reference (000 sec. 3.4).
//!
//! In an EXR each field is one text attribute named `vmerge.<field>` (see [`Metadata::to_attributes`]),
//! so any EXR header dump shows them one by one. Numbers are decimal text; floats are written in
//! Rust's shortest form that parses back to the same bits, so a file round-trips exactly.

use crate::metrics::{Errors, Measure};
use crate::options::{RenderOptions, Technique};
use std::fmt;
use thiserror::Error;

/// Attribute names, in the order they are written.
pub mod attribute {
    pub const VERSION: &str = "vmerge.version";
    pub const TECHNIQUE: &str = "vmerge.technique";
    pub const OPTIONS: &str = "vmerge.options";
    pub const SEED: &str = "vmerge.seed";
    pub const SCENE: &str = "vmerge.scene";
    pub const SCENE_HASH: &str = "vmerge.scene_hash";
    pub const ACCEL: &str = "vmerge.accel";
    pub const ITERATIONS: &str = "vmerge.iterations";
    pub const RENDER_SECONDS: &str = "vmerge.render_seconds";
    pub const DROPPED_SAMPLES: &str = "vmerge.dropped_samples";
    pub const STATISTICS: &str = "vmerge.statistics";
    pub const REFERENCE: &str = "vmerge.reference";
    pub const TRACES: &str = "vmerge.traces";
    pub const ERRORS: &str = "vmerge.errors";
    pub const ERROR_MEASURES: &str = "vmerge.error_measures";
    /// Every attribute vmerge writes starts with this.
    pub const PREFIX: &str = "vmerge.";
}

/// A metadata attribute that is missing or does not parse.
#[derive(Debug, Error, PartialEq)]
pub enum MetadataError {
    #[error("the attribute {0} is missing")]
    Missing(&'static str),
    #[error("the attribute {attribute} is invalid: {message}")]
    Invalid {
        attribute: &'static str,
        message: String,
    },
}

fn invalid(attribute: &'static str, message: impl fmt::Display) -> MetadataError {
    MetadataError::Invalid {
        attribute,
        message: message.to_string(),
    }
}

/// A square error window of 000 Appendix A's `--trace=XxY[xW]`: "window of radius W at the
/// centre XxY" (its example `32x32x8` is a window of side 16), so the pixels
/// `[x - w, x + w) x [y - w, y + w)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceWindow {
    pub x: u32,
    pub y: u32,
    pub half_width: u32,
}

impl TraceWindow {
    /// Pixel rectangle `(x0, y0, x1, y1)`, meaning `[x0, x1) x [y0, y1)`, clipped to the image.
    pub fn rect(&self, width: u32, height: u32) -> (u32, u32, u32, u32) {
        let x0 = self.x.saturating_sub(self.half_width).min(width);
        let y0 = self.y.saturating_sub(self.half_width).min(height);
        let x1 = self.x.saturating_add(self.half_width).min(width);
        let y1 = self.y.saturating_add(self.half_width).min(height);
        (x0, y0, x1, y1)
    }
}

/// `XxYxW`, the syntax [`FromStr`](std::str::FromStr) reads.
impl fmt::Display for TraceWindow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}x{}x{}", self.x, self.y, self.half_width)
    }
}

impl std::str::FromStr for TraceWindow {
    type Err = String;

    /// `XxY` or `XxYxW` (W defaults to 2, as in 000 Appendix A).
    fn from_str(s: &str) -> Result<Self, String> {
        let parts: Vec<u32> = s
            .split('x')
            .map(|p| p.trim().parse::<u32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("'{s}' is not XxY or XxYxW (non-negative integers)"))?;
        match parts[..] {
            [x, y] => Ok(TraceWindow {
                x,
                y,
                half_width: 2,
            }),
            [x, y, w] if w > 0 => Ok(TraceWindow {
                x,
                y,
                half_width: w,
            }),
            _ => Err(format!("'{s}' is not XxY or XxYxW with W > 0")),
        }
    }
}

/// Errors of the image against the reference at one moment.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorSample {
    /// Render time so far, earlier runs of a continued render included.
    pub seconds: f64,
    pub iterations: u64,
    /// Mean absolute error over all pixels and channels.
    pub mae: f64,
    /// Root-mean-square error over all pixels and channels.
    pub rmse: f64,
    /// `[mae, rmse]` of each trace window, in the order of [`Metadata::traces`].
    pub traces: Vec<[f64; 2]>,
    /// The whole image's other measures ([`ErrorSample::OTHERS`]) where they were measured:
    /// the perceptual ones cost too much for every sample.
    pub others: Errors,
}

impl ErrorSample {
    /// The measures a sample may hold besides MAE and RMSE, in the order of their columns.
    pub const OTHERS: [Measure; 4] = [
        Measure::RelativeMse,
        Measure::LdrFlip,
        Measure::HdrFlip,
        Measure::Ssim,
    ];

    /// The whole image's value of `measure`, if measured.
    pub fn get(&self, measure: Measure) -> Option<f64> {
        match measure {
            Measure::Mae => Some(self.mae),
            Measure::Rmse => Some(self.rmse),
            other => self.others.get(other),
        }
    }

    /// The value of `measure` in trace window `window` (MAE and RMSE only), if measured.
    pub fn window(&self, window: usize, measure: Measure) -> Option<f64> {
        let [mae, rmse] = *self.traces.get(window)?;
        match measure {
            Measure::Mae => Some(mae),
            Measure::Rmse => Some(rmse),
            _ => None,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Metadata {
    /// The version of vmerge that wrote the file.
    pub vmerge_version: String,
    /// The scene file; `vmerge render` records its canonical path, which `continue` loads.
    pub scene: String,
    /// Hash of the scene file and everything it loads, so a changed scene is noticed.
    pub scene_hash: String,
    /// Technique, seed and every other option that changes the image.
    pub options: RenderOptions,
    /// Name of the ray-query backend (not part of the image).
    pub accel: String,
    pub iterations: u64,
    pub render_seconds: f64,
    /// Samples dropped for being NaN or infinite.
    pub dropped_samples: u64,
    /// Technique-specific statistics, and `merged_seeds` after a merge.
    pub statistics: Vec<(String, String)>,
    /// Reference image the errors were measured against.
    pub reference: Option<String>,
    pub traces: Vec<TraceWindow>,
    /// The error series against `reference`, oldest first.
    pub errors: Vec<ErrorSample>,
}

impl Metadata {
    pub fn new(scene: String, scene_hash: String, options: RenderOptions, accel: &str) -> Self {
        Metadata {
            vmerge_version: env!("CARGO_PKG_VERSION").to_string(),
            scene,
            scene_hash,
            options,
            accel: accel.to_string(),
            iterations: 0,
            render_seconds: 0.0,
            dropped_samples: 0,
            statistics: Vec::new(),
            reference: None,
            traces: Vec::new(),
            errors: Vec::new(),
        }
    }

    pub fn technique(&self) -> Technique {
        self.options.technique
    }

    pub fn seed(&self) -> u64 {
        self.options.seed
    }

    /// The value of statistic `name`, if recorded.
    pub fn statistic(&self, name: &str) -> Option<&str> {
        self.statistics
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The fields as `(attribute name, text)` pairs. Empty optional fields (no statistics, no
    /// reference, no traces, no errors) are left out.
    ///
    /// - `vmerge.options`: TOML of [`RenderOptions`] without the seed ([`options_to_toml`]);
    ///   `vmerge.technique` repeats the technique's name for readers of the header;
    /// - `vmerge.statistics`: one `name<TAB>value` line per statistic, with backslash, tab,
    ///   newline and carriage return escaped as `\\`, `\t`, `\n`, `\r`;
    /// - `vmerge.traces`: the windows as `XxYxW`, separated by spaces;
    /// - `vmerge.errors`: one line per sample:
    ///   `seconds iterations mae rmse`, then `mae rmse` of each trace window, then one column
    ///   per measure that `vmerge.error_measures` names (`-` where not measured);
    /// - `vmerge.error_measures`: the names of those last columns ([`ErrorSample::OTHERS`]),
    ///   present when a sample holds one of them (files without it have none).
    pub fn to_attributes(&self) -> Result<Vec<(&'static str, String)>, MetadataError> {
        use attribute::*;
        let mut out = vec![
            (VERSION, self.vmerge_version.clone()),
            (TECHNIQUE, self.options.technique.name().to_string()),
            (OPTIONS, options_to_toml(&self.options)?),
            (SEED, self.options.seed.to_string()),
            (SCENE, self.scene.clone()),
            (SCENE_HASH, self.scene_hash.clone()),
            (ACCEL, self.accel.clone()),
            (ITERATIONS, self.iterations.to_string()),
            (RENDER_SECONDS, self.render_seconds.to_string()),
            (DROPPED_SAMPLES, self.dropped_samples.to_string()),
        ];
        if !self.statistics.is_empty() {
            let lines: Vec<String> = self
                .statistics
                .iter()
                .map(|(n, v)| format!("{}\t{}", escape(n), escape(v)))
                .collect();
            out.push((STATISTICS, lines.join("\n")));
        }
        if let Some(reference) = &self.reference {
            out.push((REFERENCE, reference.clone()));
        }
        if !self.traces.is_empty() {
            let windows: Vec<String> = self.traces.iter().map(|t| t.to_string()).collect();
            out.push((TRACES, windows.join(" ")));
        }
        if !self.errors.is_empty() {
            out.push((ERRORS, self.errors_text()));
        }
        if self.has_other_measures() {
            let names: Vec<&str> = ErrorSample::OTHERS.iter().map(|m| m.name()).collect();
            out.push((ERROR_MEASURES, names.join(" ")));
        }
        Ok(out)
    }

    /// The checks `render` applies to its command line, for a render read back: the options
    /// against [`RenderOptions::validate`], the iterations within
    /// [`MAX_ITERATIONS`](crate::options::MAX_ITERATIONS), a finite non-negative time.
    pub fn validate(&self) -> Result<(), MetadataError> {
        use attribute::*;
        self.options.validate().map_err(|e| invalid(OPTIONS, e))?;
        if self.iterations > crate::options::MAX_ITERATIONS {
            return Err(invalid(
                ITERATIONS,
                format!(
                    "{} is more than the {} a render may have",
                    self.iterations,
                    crate::options::MAX_ITERATIONS
                ),
            ));
        }
        if !(self.render_seconds.is_finite() && self.render_seconds >= 0.0) {
            return Err(invalid(
                RENDER_SECONDS,
                format!("{} is not a finite time >= 0", self.render_seconds),
            ));
        }
        Ok(())
    }

    fn has_other_measures(&self) -> bool {
        self.errors.iter().any(|e| e.others.iter().next().is_some())
    }

    fn errors_text(&self) -> String {
        use std::fmt::Write;
        let others = self.has_other_measures();
        let mut text = String::new();
        for (i, e) in self.errors.iter().enumerate() {
            if i > 0 {
                text.push('\n');
            }
            // Writing to a String cannot fail.
            let _ = write!(text, "{} {} {} {}", e.seconds, e.iterations, e.mae, e.rmse);
            for [mae, rmse] in &e.traces {
                let _ = write!(text, " {mae} {rmse}");
            }
            for m in ErrorSample::OTHERS.iter().filter(|_| others) {
                let _ = match e.others.get(*m) {
                    Some(v) => write!(text, " {v}"),
                    None => write!(text, " -"),
                };
            }
        }
        text
    }

    /// Reads the fields back from the attributes `get` returns by name: the inverse of
    /// [`Metadata::to_attributes`].
    pub fn from_attributes(get: impl Fn(&str) -> Option<String>) -> Result<Self, MetadataError> {
        use attribute::*;
        let required = |name: &'static str| get(name).ok_or(MetadataError::Missing(name));
        let seed = parse_number::<u64>(SEED, &required(SEED)?)?;
        let options = options_from_toml(&required(OPTIONS)?, seed)?;
        let technique = required(TECHNIQUE)?;
        if technique != options.technique.name() {
            return Err(invalid(
                TECHNIQUE,
                format!(
                    "'{technique}' but the options say '{}'",
                    options.technique.name()
                ),
            ));
        }
        let statistics = match get(STATISTICS) {
            Some(text) => text
                .lines()
                .map(|line| {
                    let (n, v) = line
                        .split_once('\t')
                        .ok_or_else(|| invalid(STATISTICS, format!("no tab in '{line}'")))?;
                    Ok((unescape(n), unescape(v)))
                })
                .collect::<Result<_, MetadataError>>()?,
            None => Vec::new(),
        };
        let traces: Vec<TraceWindow> = match get(TRACES) {
            Some(text) => text
                .split_whitespace()
                .map(|w| w.parse().map_err(|e: String| invalid(TRACES, e)))
                .collect::<Result<_, _>>()?,
            None => Vec::new(),
        };
        let others: Vec<Measure> = match get(ERROR_MEASURES) {
            Some(text) => text
                .split_whitespace()
                .map(|name| {
                    Measure::from_name(name)
                        .filter(|m| ErrorSample::OTHERS.contains(m))
                        .ok_or_else(|| invalid(ERROR_MEASURES, format!("no measure '{name}'")))
                })
                .collect::<Result<_, _>>()?,
            None => Vec::new(),
        };
        let errors = match get(ERRORS) {
            Some(text) => text
                .lines()
                .enumerate()
                .map(|(i, line)| parse_error_sample(line, traces.len(), &others, i + 1))
                .collect::<Result<_, _>>()?,
            None => Vec::new(),
        };
        Ok(Metadata {
            vmerge_version: required(VERSION)?,
            scene: required(SCENE)?,
            scene_hash: required(SCENE_HASH)?,
            options,
            accel: required(ACCEL)?,
            iterations: parse_number(ITERATIONS, &required(ITERATIONS)?)?,
            render_seconds: parse_number(RENDER_SECONDS, &required(RENDER_SECONDS)?)?,
            dropped_samples: parse_number(DROPPED_SAMPLES, &required(DROPPED_SAMPLES)?)?,
            statistics,
            reference: get(REFERENCE),
            traces,
            errors,
        })
    }
}

fn parse_number<T: std::str::FromStr>(
    attribute: &'static str,
    text: &str,
) -> Result<T, MetadataError>
where
    T::Err: fmt::Display,
{
    text.trim()
        .parse()
        .map_err(|e| invalid(attribute, format!("'{text}': {e}")))
}

fn parse_error_sample(
    line: &str,
    traces: usize,
    others: &[Measure],
    number: usize,
) -> Result<ErrorSample, MetadataError> {
    let attribute = attribute::ERRORS;
    let fields: Vec<&str> = line.split_whitespace().collect();
    let expected = 4 + 2 * traces + others.len();
    if fields.len() != expected {
        return Err(invalid(
            attribute,
            format!(
                "line {number} has {} numbers, expected {expected} (4 + 2 per trace window + \
                 {} other measures)",
                fields.len(),
                others.len()
            ),
        ));
    }
    let float = |i: usize| parse_number::<f64>(attribute, fields[i]);
    let mut measured = Errors::default();
    for (i, m) in others.iter().enumerate() {
        let field = 4 + 2 * traces + i;
        if fields[field] != "-" {
            measured.set(*m, float(field)?);
        }
    }
    Ok(ErrorSample {
        seconds: float(0)?,
        iterations: parse_number(attribute, fields[1])?,
        mae: float(2)?,
        rmse: float(3)?,
        traces: (0..traces)
            .map(|t| Ok([float(4 + 2 * t)?, float(5 + 2 * t)?]))
            .collect::<Result<_, MetadataError>>()?,
        others: measured,
    })
}

/// TOML of every option except the seed. The seed is a u64 and TOML's integers are i64, so it
/// travels in its own attribute, `vmerge.seed`.
pub fn options_to_toml(options: &RenderOptions) -> Result<String, MetadataError> {
    let mut value = toml::Value::try_from(RenderOptions {
        seed: 0,
        ..options.clone()
    })
    .map_err(|e| invalid(attribute::OPTIONS, e))?;
    if let Some(table) = value.as_table_mut() {
        table.remove("seed");
    }
    toml::to_string(&value).map_err(|e| invalid(attribute::OPTIONS, e))
}

/// The inverse of [`options_to_toml`], with the seed given apart.
pub fn options_from_toml(text: &str, seed: u64) -> Result<RenderOptions, MetadataError> {
    let mut table: toml::Table = text.parse().map_err(|e| invalid(attribute::OPTIONS, e))?;
    table.insert("seed".into(), toml::Value::Integer(0));
    let options: RenderOptions = table
        .try_into()
        .map_err(|e| invalid(attribute::OPTIONS, e))?;
    Ok(RenderOptions { seed, ..options })
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace('\t', "\\t")
        .replace('\n', "\\n")
        .replace('\r', "\\r")
}

fn unescape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        match chars.next() {
            Some('t') => out.push('\t'),
            Some('n') => out.push('\n'),
            Some('r') => out.push('\r'),
            Some(other) => out.push(other),
            None => out.push('\\'),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn sample() -> Metadata {
        let options = RenderOptions {
            technique: Technique::Vcm,
            seed: u64::MAX,
            camera: Some("front".into()),
            resolution: Some([64, 32]),
            radius: Some(0.1),
            alpha: Some(0.75),
            beta: 1.0 / 3.0,
            ..RenderOptions::default()
        };
        let mut m = Metadata::new("/a/scene.toml".into(), "abc123".into(), options, "bvh");
        m.iterations = 12;
        m.render_seconds = 0.1 + 0.2;
        m.dropped_samples = 3;
        m.statistics = vec![
            ("photons".into(), "4096".into()),
            ("odd\tname\\".into(), "two\nlines\r".into()),
        ];
        m.reference = Some("ref.exr".into());
        m.traces = vec!["32x32x8".parse().unwrap(), "1x2".parse().unwrap()];
        m.errors = vec![
            ErrorSample {
                seconds: 1.0 / 7.0,
                iterations: 1,
                mae: 5e-324,
                rmse: 1e300,
                traces: vec![[0.1, f64::MIN_POSITIVE], [1.0 / 3.0, 2.0 / 3.0]],
                others: Errors::default(),
            },
            ErrorSample {
                seconds: 2.5,
                iterations: 2,
                mae: 0.0,
                rmse: -0.0,
                traces: vec![[7.0, 8.0], [9.0, 10.0]],
                others: {
                    let mut e = Errors::default();
                    e.set(Measure::RelativeMse, 0.25);
                    e.set(Measure::Ssim, 1.0 - 1e-9);
                    e
                },
            },
        ];
        m
    }

    fn round_trip(m: &Metadata) -> Result<Metadata, MetadataError> {
        let map: HashMap<&str, String> = m.to_attributes()?.into_iter().collect();
        Metadata::from_attributes(|name| map.get(name).cloned())
    }

    #[test]
    fn round_trips_bit_exactly() {
        let m = sample();
        let back = round_trip(&m).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.errors[1].rmse.to_bits(), (-0.0f64).to_bits());
        assert_eq!(back.options.seed, u64::MAX);
    }

    #[test]
    fn empty_optional_fields_round_trip() {
        let m = Metadata::new(
            String::new(),
            "h".into(),
            RenderOptions::default(),
            "embree",
        );
        assert_eq!(round_trip(&m).unwrap(), m);
    }

    #[test]
    fn errors_are_one_line_per_sample() {
        let map: HashMap<&str, String> = sample().to_attributes().unwrap().into_iter().collect();
        let errors = &map[attribute::ERRORS];
        assert_eq!(errors.lines().count(), 2);
        assert!(errors
            .lines()
            .next()
            .is_some_and(|l| l.ends_with(" - - - -")));
        assert_eq!(
            errors.lines().nth(1),
            Some("2.5 2 0 -0 7 8 9 10 0.25 - - 0.999999999")
        );
        assert_eq!(map[attribute::TRACES], "32x32x8 1x2x2");
        assert_eq!(
            map[attribute::ERROR_MEASURES],
            "relmse ldr-flip hdr-flip ssim"
        );
    }

    #[test]
    fn missing_and_malformed_attributes_are_named() {
        let good: HashMap<&str, String> = sample().to_attributes().unwrap().into_iter().collect();
        let without = |gone: &str| {
            let mut map = good.clone();
            map.remove(gone);
            Metadata::from_attributes(|name| map.get(name).cloned())
        };
        assert_eq!(
            without(attribute::SCENE_HASH),
            Err(MetadataError::Missing(attribute::SCENE_HASH))
        );
        let with = |name: &'static str, value: &str| {
            let mut map = good.clone();
            map.insert(name, value.into());
            Metadata::from_attributes(|n| map.get(n).cloned())
        };
        for (name, value) in [
            (attribute::ITERATIONS, "-1"),
            (attribute::SEED, "x"),
            (attribute::TECHNIQUE, "pt"),
            (attribute::OPTIONS, "beta = 'two'"),
            (attribute::ERRORS, "1 2 3"),
            (attribute::ERROR_MEASURES, "mae"),
            (attribute::TRACES, "1x2x0"),
            (attribute::STATISTICS, "no tab"),
        ] {
            let err = with(name, value).unwrap_err().to_string();
            assert!(err.contains(name), "{name}: {err}");
        }
    }

    #[test]
    fn trace_windows_follow_appendix_a() {
        let w: TraceWindow = "32x32x8".parse().unwrap();
        assert_eq!(w.rect(512, 512), (24, 24, 40, 40));
        assert_eq!(w.rect(30, 36), (24, 24, 30, 36));
        assert_eq!("5x6".parse::<TraceWindow>().unwrap().half_width, 2);
        for bad in ["", "1", "1x2x3x4", "ax2", "1x2x0", "-1x2"] {
            assert!(bad.parse::<TraceWindow>().is_err(), "{bad}");
        }
    }
}
