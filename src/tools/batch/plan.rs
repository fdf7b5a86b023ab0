//! Reading a plan file (DESIGN.md, "Output") and expanding it into its cells.
//!
//! Keys, at the top level (defaults for everything below), in `[[scene]]` and in `[[group]]`:
//! `budget = "20m"` or `iterations = N` (a cell's budget), `seeds = [..]`, `resolution`,
//! `traces = ["XxYxW", ..]`, and any option of [`OPTIONS`] by its field name (`min_path_length =
//! 3`, `no_vc = true`, ...); a lower level overrides a higher one. Only at the top: `output`,
//! `threads` (per cell), `snapshot`, `metric`, and a `[slurm]` table (`partition`, `account`,
//! `time_limit`, `mem`, `sbatch = ["--qos=low", ..]`) for submitted plans. A scene: `file`, `name`, `cameras`,
//! `reference`. A group: `techniques`, `radius` (a number, a list or a sweep `{ from, to,
//! steps, spacing = "log" | "linear" }`), `beta` (a number or a list), `scenes` (names; all when
//! absent). A reference: a file (`{camera}` stands for the camera's name) or a table
//! `{ technique = "bpt", budget | iterations, parts = K, seed, options... }`.

use super::cell::{Budget, Cell, CellKind, ReferenceSource};
use super::slurm::SlurmSettings;
use super::BatchError;
use crate::files::Kind;
use crate::film::TraceWindow;
use crate::options::{Form, RenderOptions, Technique, OPTIONS};
use crate::tools::Metric;
use std::collections::{HashMap, HashSet};
use std::path::{Component, Path, PathBuf};
use std::time::Duration;

/// A plan, expanded: its cells in the order they are run (references first).
#[derive(Clone, Debug)]
pub struct Plan {
    /// The plan file as given.
    pub file: PathBuf,
    /// Where the cells go (`output`, relative to the plan file).
    pub output: PathBuf,
    /// Threads per cell (`--threads`; the cores of a Slurm array task); `None` = all.
    pub threads: Option<usize>,
    /// Snapshot interval of every cell, so that a killed cell keeps most of its work.
    pub snapshot: Option<Duration>,
    /// The error that picks a technique's best cell in the report.
    pub metric: Metric,
    /// How the plan's jobs are submitted to Slurm.
    pub slurm: SlurmSettings,
    pub cells: Vec<Cell>,
    /// The scenes and cameras, in plan order, as `(scene name, camera name)`.
    pub views: Vec<(String, String)>,
}

/// The first seed of a reference unless the plan gives one: far from the cells' seeds, since a
/// cell and its reference with one seed would share their eye sub-paths' random numbers and
/// the measured error would come out too low.
pub const REFERENCE_SEED: u64 = 1 << 32;

/// The most cells a plan may expand to, checked before any is made. A cell is a render of
/// seconds to hours, so 10,000 is far beyond any study (000 ch. 4 runs a few hundred) and
/// keeps the passes over all cells that are quadratic in their number (expansion, status,
/// planning) well under a second; without it a sweep of `steps = 1000000000` asks for more
/// memory than there is before anything runs.
pub const MAX_CELLS: u64 = 10_000;

/// Keys that are not options, by the level that takes them.
const TOP_KEYS: &[&str] = &[
    "output",
    "threads",
    "snapshot",
    "metric",
    "slurm",
    "scene",
    "group",
    "budget",
    "iterations",
    "seeds",
    "resolution",
    "traces",
];
const SCENE_KEYS: &[&str] = &[
    "file",
    "name",
    "cameras",
    "reference",
    "budget",
    "iterations",
    "seeds",
    "resolution",
    "traces",
];
const GROUP_KEYS: &[&str] = &[
    "techniques",
    "radius",
    "beta",
    "scenes",
    "budget",
    "iterations",
    "seeds",
    "resolution",
    "traces",
];
const REFERENCE_KEYS: &[&str] = &["technique", "budget", "iterations", "parts", "seed"];
const SLURM_KEYS: &[&str] = &["partition", "account", "time_limit", "mem", "sbatch"];

/// Options a plan gives the cells of a level, by their own keys or by expansion:
/// `techniques`, `seeds`, `cameras`, `resolution`, `beta`, `radius`.
const EXPANDED: &[&str] = &[
    "technique",
    "seed",
    "camera",
    "resolution",
    "beta",
    "radius",
];

/// Options set by a level of the plan under their field names.
fn is_option(key: &str) -> bool {
    OPTIONS.iter().any(|r| r.name == key) && !EXPANDED.contains(&key)
}

/// Reads the parts of a plan file that name one entry, for messages.
struct Reader<'a> {
    file: &'a Path,
}

impl Reader<'_> {
    fn error(&self, entry: &str, message: impl std::fmt::Display) -> BatchError {
        BatchError::Plan {
            file: self.file.to_path_buf(),
            message: format!("{entry}: {message}"),
        }
    }

    fn check_keys(
        &self,
        entry: &str,
        table: &toml::Table,
        allowed: &[&str],
    ) -> Result<(), BatchError> {
        for key in table.keys() {
            if !allowed.contains(&key.as_str()) && !is_option(key) {
                return Err(self.error(entry, format!("unknown key '{key}'")));
            }
        }
        Ok(())
    }

    fn string(&self, entry: &str, v: &toml::Value) -> Result<String, BatchError> {
        v.as_str()
            .map(str::to_string)
            .ok_or_else(|| self.error(entry, format!("expected a string, found {v}")))
    }

    fn number(&self, entry: &str, v: &toml::Value) -> Result<f64, BatchError> {
        match v {
            toml::Value::Float(f) => Ok(*f),
            toml::Value::Integer(i) => Ok(*i as f64),
            _ => Err(self.error(entry, format!("expected a number, found {v}"))),
        }
    }

    fn count(&self, entry: &str, v: &toml::Value) -> Result<u64, BatchError> {
        v.as_integer()
            .and_then(|i| u64::try_from(i).ok())
            .ok_or_else(|| self.error(entry, format!("expected a whole number >= 0, found {v}")))
    }

    /// One value or a non-empty list of values, each read by `one`.
    fn one_or_list<T>(
        &self,
        entry: &str,
        v: &toml::Value,
        one: impl Fn(&Self, &str, &toml::Value) -> Result<T, BatchError>,
    ) -> Result<Vec<T>, BatchError> {
        match v {
            toml::Value::Array(items) if !items.is_empty() => {
                items.iter().map(|x| one(self, entry, x)).collect()
            }
            toml::Value::Array(_) => Err(self.error(entry, "an empty list")),
            x => Ok(vec![one(self, entry, x)?]),
        }
    }

    /// A number or a list of numbers.
    fn numbers(&self, entry: &str, v: &toml::Value) -> Result<Vec<f64>, BatchError> {
        self.one_or_list(entry, v, Self::number)
    }

    fn strings(&self, entry: &str, v: &toml::Value) -> Result<Vec<String>, BatchError> {
        self.one_or_list(entry, v, Self::string)
    }

    fn budget(&self, entry: &str, table: &toml::Table) -> Result<Option<Budget>, BatchError> {
        match (table.get("budget"), table.get("iterations")) {
            (Some(_), Some(_)) => Err(self.error(entry, "give budget or iterations, not both")),
            (Some(b), None) => {
                let text = self.string(&format!("{entry}: budget"), b)?;
                parse_duration(&text)
                    .map(|d| Some(Budget::Time(d)))
                    .map_err(|e| self.error(&format!("{entry}: budget"), e))
            }
            (None, Some(n)) => match self.count(&format!("{entry}: iterations"), n)? {
                0 => Err(self.error(entry, "iterations = 0 renders nothing")),
                n => Ok(Some(Budget::Iterations(n))),
            },
            (None, None) => Ok(None),
        }
    }

    fn resolution(&self, entry: &str, v: &toml::Value) -> Result<[u32; 2], BatchError> {
        let sides = self.numbers(entry, v)?;
        match sides[..] {
            [w, h] if w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 => {
                Ok([w as u32, h as u32])
            }
            _ => Err(self.error(entry, "expected [width, height], whole numbers >= 1")),
        }
    }

    fn traces(&self, entry: &str, v: &toml::Value) -> Result<Vec<TraceWindow>, BatchError> {
        match v {
            toml::Value::Array(items) => items
                .iter()
                .map(|t| {
                    self.string(entry, t)?
                        .parse()
                        .map_err(|e: String| self.error(entry, e))
                })
                .collect(),
            _ => Err(self.error(entry, "expected a list of \"XxYxW\" windows")),
        }
    }

    fn seeds(&self, entry: &str, v: &toml::Value) -> Result<Vec<u64>, BatchError> {
        match v {
            toml::Value::Array(items) if !items.is_empty() => {
                items.iter().map(|s| self.count(entry, s)).collect()
            }
            _ => Err(self.error(entry, "expected a non-empty list of seeds")),
        }
    }

    /// The radii of a group: a number, a list, or a sweep.
    fn radii(&self, entry: &str, v: &toml::Value) -> Result<Vec<f32>, BatchError> {
        let values = match v {
            toml::Value::Table(sweep) => self.sweep(entry, sweep)?,
            other => self.numbers(entry, other)?,
        };
        values
            .into_iter()
            .map(|r| {
                if r.is_finite() && r > 0.0 {
                    Ok(r as f32)
                } else {
                    Err(self.error(entry, format!("radius {r}: expected a finite radius > 0")))
                }
            })
            .collect()
    }

    /// `{ from, to, steps, spacing }`: `steps` radii from `from` to `to`, evenly spaced on a
    /// log or a linear scale, rounded to three significant digits so that names and tables
    /// read well.
    fn sweep(&self, entry: &str, sweep: &toml::Table) -> Result<Vec<f64>, BatchError> {
        for key in sweep.keys() {
            if !["from", "to", "steps", "spacing"].contains(&key.as_str()) {
                return Err(self.error(entry, format!("unknown key '{key}' in the sweep")));
            }
        }
        let get = |key: &str| {
            sweep
                .get(key)
                .ok_or_else(|| self.error(entry, format!("the sweep needs '{key}'")))
        };
        let from = self.number(entry, get("from")?)?;
        let to = self.number(entry, get("to")?)?;
        let steps = self.count(entry, get("steps")?)?;
        if steps > MAX_CELLS {
            return Err(self.error(
                entry,
                format!("steps = {steps}: more than the {MAX_CELLS} cells a plan may have"),
            ));
        }
        let spacing = match sweep.get("spacing") {
            Some(s) => self.string(entry, s)?,
            None => "log".into(),
        };
        if !(from > 0.0 && to > from && steps >= 2) {
            return Err(self.error(entry, "a sweep needs 0 < from < to and steps >= 2"));
        }
        let log = match spacing.as_str() {
            "log" => true,
            "linear" => false,
            other => {
                return Err(self.error(
                    entry,
                    format!("spacing '{other}': expected \"log\" or \"linear\""),
                ))
            }
        };
        Ok((0..steps)
            .map(|i| {
                let t = i as f64 / (steps - 1) as f64;
                let r = if log {
                    from * (to / from).powf(t)
                } else {
                    from + (to - from) * t
                };
                round_significant(r, 3)
            })
            .collect())
    }
}

impl Reader<'_> {
    /// The `[slurm]` table: names and `#SBATCH` lines that reach a shell script and Slurm's
    /// parser, so each is held to the characters Slurm takes there.
    fn slurm(&self, v: &toml::Value) -> Result<SlurmSettings, BatchError> {
        let table = v
            .as_table()
            .ok_or_else(|| self.error("slurm", "expected a table [slurm]"))?;
        for key in table.keys() {
            if !SLURM_KEYS.contains(&key.as_str()) {
                return Err(self.error("slurm", format!("unknown key '{key}'")));
            }
        }
        let name = |key: &str| -> Result<Option<String>, BatchError> {
            let Some(v) = table.get(key) else {
                return Ok(None);
            };
            let entry = format!("slurm: {key}");
            let text = self.string(&entry, v)?;
            let allowed = |c: char| c.is_ascii_alphanumeric() || "_-.,".contains(c);
            if text.is_empty() || !text.chars().all(allowed) {
                return Err(self.error(
                    &entry,
                    format!("'{text}': expected a name of letters, digits and _ - . ,"),
                ));
            }
            Ok(Some(text))
        };
        let mut settings = SlurmSettings {
            partition: name("partition")?,
            account: name("account")?,
            ..SlurmSettings::default()
        };
        if let Some(v) = table.get("time_limit") {
            let text = self.string("slurm: time_limit", v)?;
            settings.time_limit =
                Some(parse_duration(&text).map_err(|e| self.error("slurm: time_limit", e))?);
        }
        if let Some(v) = table.get("mem") {
            let text = self.string("slurm: mem", v)?;
            settings.mem =
                Some(crate::memory::parse_size(&text).map_err(|e| self.error("slurm: mem", e))?);
        }
        if let Some(v) = table.get("sbatch") {
            for line in self.strings("slurm: sbatch", v)? {
                let fits =
                    line.starts_with('-') && line.len() > 1 && !line.chars().any(char::is_control);
                if !fits {
                    return Err(self.error(
                        "slurm: sbatch",
                        format!("'{line}': expected an sbatch option such as \"--qos=low\", on one line"),
                    ));
                }
                settings.sbatch.push(line);
            }
        }
        Ok(settings)
    }
}

fn round_significant(x: f64, digits: i32) -> f64 {
    let scale = 10f64.powi(digits - 1 - x.abs().log10().floor() as i32);
    (x * scale).round() / scale
}

/// A plan's duration: [`crate::options::parse_duration`], and more than zero.
pub fn parse_duration(s: &str) -> Result<Duration, String> {
    let d = crate::options::parse_duration(s)?;
    if d.is_zero() {
        return Err(format!("'{}' is not a positive duration", s.trim()));
    }
    Ok(d)
}

/// The settings a level passes down to the levels below it.
#[derive(Clone)]
struct Inherited {
    budget: Option<Budget>,
    seeds: Vec<u64>,
    resolution: Option<[u32; 2]>,
    traces: Vec<TraceWindow>,
    /// Option keys and their values, in the order the levels set them.
    options: toml::Table,
}

impl Inherited {
    fn below(&self, r: &Reader, entry: &str, table: &toml::Table) -> Result<Self, BatchError> {
        let mut next = self.clone();
        if let Some(b) = r.budget(entry, table)? {
            next.budget = Some(b);
        }
        if let Some(s) = table.get("seeds") {
            next.seeds = r.seeds(&format!("{entry}: seeds"), s)?;
        }
        if let Some(v) = table.get("resolution") {
            next.resolution = Some(r.resolution(&format!("{entry}: resolution"), v)?);
        }
        if let Some(v) = table.get("traces") {
            next.traces = r.traces(&format!("{entry}: traces"), v)?;
        }
        for (key, value) in table {
            if is_option(key) {
                next.options.insert(key.clone(), value.clone());
            }
        }
        Ok(next)
    }

    /// The render options of a cell: the defaults with the plan's options over them.
    fn options(
        &self,
        r: &Reader,
        entry: &str,
        technique: Technique,
        extra: &[(&str, toml::Value)],
    ) -> Result<RenderOptions, BatchError> {
        let defaults = RenderOptions {
            technique,
            resolution: self.resolution,
            ..RenderOptions::DEFAULT
        };
        let mut table = match toml::Value::try_from(defaults) {
            Ok(toml::Value::Table(t)) => t,
            _ => return Err(r.error(entry, "the default options do not serialise")),
        };
        for (key, value) in self.options.iter() {
            table.insert(key.clone(), value.clone());
        }
        for (key, value) in extra {
            table.insert((*key).to_string(), value.clone());
        }
        let options: RenderOptions = table
            .try_into()
            .map_err(|e: toml::de::Error| r.error(entry, e.message()))?;
        options
            .validate()
            .map_err(|e| r.error(&format!("{entry} ({technique})"), e))?;
        Ok(options)
    }
}

/// The name a scene goes by in cell names: its `name`, or its folder's name for a
/// `scene.toml`, or its file's stem.
fn scene_name(file: &Path) -> String {
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned());
    match stem.as_deref() {
        Some("scene") | None => file
            .parent()
            .and_then(|p| p.file_name())
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".into()),
        Some(s) => s.to_string(),
    }
}

/// `path` absolute, with its longest existing ancestor resolved (links followed) and the rest
/// appended, so that two spellings of one file compare equal whether or not it exists yet.
fn resolve(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut rest = Vec::new();
    let mut base = absolute.as_path();
    loop {
        if let Ok(mut resolved) = std::fs::canonicalize(base) {
            // What follows does not exist and so holds no links: `..` there is lexical.
            for part in rest.iter().rev() {
                match part {
                    Component::ParentDir => {
                        resolved.pop();
                    }
                    Component::CurDir => {}
                    other => resolved.push(other.as_os_str()),
                }
            }
            return resolved;
        }
        let mut parts = base.components();
        match parts.next_back() {
            Some(last) if parts.as_path() != base => {
                rest.push(last);
                base = parts.as_path();
            }
            _ => return absolute,
        }
    }
}

/// The resolution a TOML scene renders at when the plan gives none: its `[render]`
/// resolution, or the format's default. `None` for a pbrt scene or one that cannot be read
/// (loading it says why).
fn scene_resolution(scene: &Path) -> Option<[u32; 2]> {
    if crate::scene::pbrt::is_pbrt(scene) {
        return None;
    }
    let text = crate::files::read_text(scene, Kind::Scene).ok()?;
    let table = text.parse::<toml::Table>().ok()?;
    let Some(given) = table.get("render").and_then(|r| r.get("resolution")) else {
        return Some(crate::scene::RenderDefaults::default().resolution);
    };
    let side = |i: usize| {
        given
            .get(i)
            .and_then(toml::Value::as_integer)
            .and_then(|v| u32::try_from(v).ok())
            .filter(|&v| v > 0)
    };
    Some([side(0)?, side(1)?])
}

/// The existing files a TOML scene file names by a string value (meshes, textures, sky
/// images), relative to its folder. A scene that cannot be read names none here; loading it
/// reports why.
fn named_files(scene: &Path) -> Vec<PathBuf> {
    fn walk(value: &toml::Value, dir: &Path, out: &mut Vec<PathBuf>) {
        match value {
            toml::Value::String(s) if !s.is_empty() => {
                let path = dir.join(s);
                if path.is_file() {
                    out.push(path);
                }
            }
            toml::Value::Array(items) => items.iter().for_each(|v| walk(v, dir, out)),
            toml::Value::Table(t) => t.values().for_each(|v| walk(v, dir, out)),
            _ => {}
        }
    }
    let Ok(text) = crate::files::read_text(scene, Kind::Scene) else {
        return Vec::new();
    };
    let Ok(table) = text.parse::<toml::Table>() else {
        return Vec::new();
    };
    let dir = scene.parent().unwrap_or(Path::new(""));
    let mut out = Vec::new();
    table.values().for_each(|v| walk(v, dir, &mut out));
    out
}

/// Characters a name part may keep; everything else becomes `-`, so names stay file names.
fn clean(part: &str) -> String {
    part.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '-'
            }
        })
        .collect()
}

impl Plan {
    /// Reads and expands `file`. Every problem names the file and the entry.
    pub fn load(file: &Path) -> Result<Plan, BatchError> {
        let r = Reader { file };
        // A plan is read like a scene file: a regular file (never a FIFO) within its limit.
        let text = crate::files::read_text(file, Kind::Scene).map_err(|e| BatchError::Plan {
            file: file.into(),
            message: e.message,
        })?;
        let top: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| BatchError::Plan {
                file: file.into(),
                message: e.to_string(),
            })?;
        r.check_keys("the top level", &top, TOP_KEYS)?;
        let dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
        let output = match top.get("output") {
            Some(v) => dir.join(r.string("output", v)?),
            None => return Err(r.error("the top level", "needs output = \"FOLDER\"")),
        };
        let threads = match top.get("threads") {
            Some(v) => match r.count("threads", v)? {
                0 => return Err(r.error("threads", "at least 1")),
                n => Some(n as usize),
            },
            None => None,
        };
        let snapshot = match top.get("snapshot") {
            Some(v) => Some(
                parse_duration(&r.string("snapshot", v)?).map_err(|e| r.error("snapshot", e))?,
            ),
            None => Some(Duration::from_secs(60)),
        };
        let metric = match top.get("metric") {
            Some(v) => {
                let name = r.string("metric", v)?;
                Metric::from_name(&name).ok_or_else(|| {
                    let names: Vec<&str> = Metric::ALL.iter().map(|m| m.name()).collect();
                    r.error("metric", format!("'{name}': expected {}", names.join(", ")))
                })?
            }
            None => Metric::Mae,
        };
        let slurm = match top.get("slurm") {
            Some(v) => r.slurm(v)?,
            None => SlurmSettings::default(),
        };
        let root = Inherited {
            budget: None,
            seeds: vec![RenderOptions::DEFAULT.seed],
            resolution: None,
            traces: Vec::new(),
            options: toml::Table::new(),
        }
        .below(&r, "the top level", &top)?;
        let tables = |key: &str| -> Result<Vec<toml::Table>, BatchError> {
            match top.get(key) {
                None => Ok(Vec::new()),
                Some(toml::Value::Array(items)) => items
                    .iter()
                    .enumerate()
                    .map(|(i, v)| {
                        v.as_table()
                            .cloned()
                            .ok_or_else(|| r.error(&format!("[[{key}]] {}", i + 1), "not a table"))
                    })
                    .collect(),
                Some(_) => Err(r.error(key, format!("expected [[{key}]] tables"))),
            }
        };
        let scenes = tables("scene")?;
        let groups = tables("group")?;
        if scenes.is_empty() || groups.is_empty() {
            return Err(r.error("the top level", "needs [[scene]] and [[group]] entries"));
        }
        let mut plan = Plan {
            file: file.into(),
            output: output.clone(),
            threads,
            snapshot,
            metric,
            slurm,
            cells: Vec::new(),
            views: Vec::new(),
        };
        let mut renders = Vec::new();
        let mut scene_names: Vec<String> = Vec::new();
        for (i, scene) in scenes.iter().enumerate() {
            let entry = format!("[[scene]] {}", i + 1);
            r.check_keys(&entry, scene, SCENE_KEYS)?;
            let scene_file = match scene.get("file") {
                Some(v) => dir.join(r.string(&format!("{entry}: file"), v)?),
                None => return Err(r.error(&entry, "needs file = \"SCENE.toml\"")),
            };
            let name = match scene.get("name") {
                Some(v) => clean(&r.string(&format!("{entry}: name"), v)?),
                None => clean(&scene_name(&scene_file)),
            };
            if scene_names.contains(&name) {
                return Err(r.error(&entry, format!("a second scene named '{name}' (set name)")));
            }
            scene_names.push(name.clone());
            let entry = format!("[[scene]] {name}");
            let at_scene = root.below(&r, &entry, scene)?;
            let cameras: Vec<Option<String>> = match scene.get("cameras") {
                Some(v) => r
                    .strings(&format!("{entry}: cameras"), v)?
                    .into_iter()
                    .map(Some)
                    .collect(),
                None => vec![None],
            };
            for camera in cameras {
                let camera_name = camera.as_deref().map_or("cam0".to_string(), clean);
                plan.views.push((name.clone(), camera_name.clone()));
                let view = ViewSetup {
                    scene: &name,
                    camera: &camera,
                    camera_name: &camera_name,
                    scene_file: &scene_file,
                };
                let reference = match scene.get("reference") {
                    Some(v) => Some(plan.add_reference(&r, &entry, &at_scene, &view, v)?),
                    None => None,
                };
                for (g, group) in groups.iter().enumerate() {
                    let group_entry = format!("[[group]] {}", g + 1);
                    r.check_keys(&group_entry, group, GROUP_KEYS)?;
                    if let Some(list) = group.get("scenes") {
                        let wanted = r.strings(&format!("{group_entry}: scenes"), list)?;
                        if !wanted.contains(&name) {
                            continue;
                        }
                    }
                    let at_group = at_scene.below(&r, &group_entry, group)?;
                    renders.extend(plan.group_cells(
                        &r,
                        &group_entry,
                        group,
                        &at_group,
                        &view,
                        reference.clone(),
                    )?);
                    let made = plan.cells.len() + renders.len();
                    if made as u64 > MAX_CELLS {
                        return Err(r.error(
                            &group_entry,
                            format!(
                                "brings the plan to {made} cells, more than the {MAX_CELLS} a \
                                 plan may have"
                            ),
                        ));
                    }
                }
            }
        }
        for (g, group) in groups.iter().enumerate() {
            if let Some(list) = group.get("scenes") {
                let entry = format!("[[group]] {}: scenes", g + 1);
                for wanted in r.strings(&entry, list)? {
                    if !scene_names.contains(&wanted) {
                        return Err(r.error(&entry, format!("no scene named '{wanted}'")));
                    }
                }
            }
        }
        plan.cells.extend(renders);
        for (i, cell) in plan.cells.iter().enumerate() {
            if let Some(earlier) = plan.cells[..i].iter().find(|c| c.name == cell.name) {
                if earlier.options != cell.options || earlier.budget != cell.budget {
                    return Err(r.error(
                        &cell.name,
                        "two entries make this cell with different options or budgets",
                    ));
                }
            }
        }
        // Entries that make the same cell twice (the same options) run it once.
        let mut seen = HashSet::new();
        plan.cells.retain(|c| seen.insert(c.name.clone()));
        plan.check_traces(&r)?;
        plan.check_files(&r)?;
        Ok(plan)
    }

    /// Trace windows must touch the cell's image (the plan's resolution, else a TOML scene's
    /// own): one wholly outside would be found only once the cell had rendered. A pbrt
    /// scene's resolution is known once it loads, where the render checks its windows.
    fn check_traces(&self, r: &Reader) -> Result<(), BatchError> {
        let mut scenes: HashMap<&Path, Option<[u32; 2]>> = HashMap::new();
        for cell in &self.cells {
            if cell.traces.is_empty() {
                continue;
            }
            let resolution = match cell.options.resolution {
                Some(res) => Some(res),
                None => *scenes
                    .entry(&cell.scene_file)
                    .or_insert_with(|| scene_resolution(&cell.scene_file)),
            };
            let Some([width, height]) = resolution else {
                continue;
            };
            for t in &cell.traces {
                let (x0, y0, x1, y1) = t.rect(width, height);
                if x0 >= x1 || y0 >= y1 {
                    return Err(r.error(
                        &format!("traces of cell {}", cell.name),
                        format!(
                            "the window at ({}, {}) lies outside its {width}x{height} image",
                            t.x, t.y
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// Nothing the plan writes may land on what it reads, whatever the names: every cell's
    /// EXR and PNG preview, the report's folder and the Slurm record against the plan file,
    /// the scene files and the files they name, and the reference files. A reference file
    /// that a cell of the plan writes is a cycle that could never finish. Paths compare
    /// resolved, so two spellings of one file are one file.
    fn check_files(&self, r: &Reader) -> Result<(), BatchError> {
        // The folder, or one it would be made in, must not be a file.
        let file = self
            .output
            .ancestors()
            .find(|a| !a.as_os_str().is_empty() && std::fs::metadata(a).is_ok_and(|m| !m.is_dir()));
        if let Some(file) = file {
            return Err(r.error(
                "output",
                format!("{} is a file, not a folder", file.display()),
            ));
        }
        let outputs = self.outputs();
        for cell in &self.cells {
            if let Some(ReferenceSource::File(f)) = &cell.reference {
                if let Some(writer) = outputs.get(&resolve(f)) {
                    return Err(r.error(
                        &format!("[[scene]] {}: reference", cell.scene),
                        format!(
                            "{} is what {writer} of this plan writes; a cell cannot wait for \
                             the plan's own output",
                            f.display()
                        ),
                    ));
                }
            }
        }
        let report = resolve(&self.output.join("report"));
        for (input, what) in self.inputs() {
            let target = resolve(&input);
            let writer = if target.starts_with(&report) {
                Some("the report")
            } else {
                outputs.get(&target).map(String::as_str)
            };
            if let Some(writer) = writer {
                return Err(r.error(
                    "output",
                    format!(
                        "{writer} would be written over {what} {}; choose another output folder",
                        input.display()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Everything the plan writes into its output folder, resolved, with what writes it.
    fn outputs(&self) -> HashMap<PathBuf, String> {
        let mut out = HashMap::new();
        out.insert(
            resolve(&self.output.join(super::slurm::RECORD)),
            format!("the Slurm record {}", super::slurm::RECORD),
        );
        for cell in &self.cells {
            out.insert(resolve(&cell.output), format!("cell {}", cell.name));
            out.insert(
                resolve(&cell.output.with_extension("png")),
                format!("the preview of cell {}", cell.name),
            );
        }
        out
    }

    /// The files the plan reads: itself, the scene files, the files a scene file names, and
    /// reference files; each with what it is, for messages.
    fn inputs(&self) -> Vec<(PathBuf, &'static str)> {
        let mut inputs = vec![(self.file.clone(), "the plan file")];
        let mut seen = HashSet::new();
        for cell in &self.cells {
            if seen.insert(cell.scene_file.clone()) {
                inputs.push((cell.scene_file.clone(), "the scene file"));
                for named in named_files(&cell.scene_file) {
                    inputs.push((named, "a file the scene reads"));
                }
            }
            if let Some(ReferenceSource::File(f)) = &cell.reference {
                if seen.insert(f.clone()) {
                    inputs.push((f.clone(), "the reference"));
                }
            }
        }
        inputs
    }

    /// Refuses a plan whose reference file is not there: run in-process it could never
    /// finish, since no cell of the plan makes it (`--jobs` and Slurm list such cells as
    /// waiting instead, for a reference made elsewhere).
    pub fn check_references(&self) -> Result<(), BatchError> {
        for cell in &self.cells {
            if let Some(ReferenceSource::File(f)) = &cell.reference {
                if !f.exists() {
                    return Err(BatchError::Plan {
                        file: self.file.clone(),
                        message: format!(
                            "[[scene]] {}: reference: {} does not exist, and no cell of the \
                             plan makes it; render it first or give a reference table",
                            cell.scene,
                            f.display()
                        ),
                    });
                }
            }
        }
        Ok(())
    }

    /// Checks that `file` (the `--slurm` script) neither is a folder nor lands on anything the
    /// plan reads or writes.
    pub fn check_script(&self, file: &Path) -> Result<(), BatchError> {
        let refuse = |message: String| BatchError::Flag {
            flag: "--slurm",
            message: format!("{}: {message}", file.display()),
        };
        if file.is_dir() {
            return Err(refuse("is a folder; name the script file".into()));
        }
        let target = resolve(file);
        if let Some(writer) = self.outputs().get(&target) {
            return Err(refuse(format!("is where {writer} goes")));
        }
        if let Some((_, what)) = self.inputs().iter().find(|(f, _)| resolve(f) == target) {
            return Err(refuse(format!("is {what}; writing would destroy it")));
        }
        Ok(())
    }

    fn cell_path(&self, name: &str) -> PathBuf {
        self.output.join(format!("{name}.exr"))
    }

    /// The reference of one scene and camera: a file, or cells rendering it.
    fn add_reference(
        &mut self,
        r: &Reader,
        entry: &str,
        inherited: &Inherited,
        view: &ViewSetup,
        value: &toml::Value,
    ) -> Result<ReferenceSource, BatchError> {
        let entry = format!("{entry}: reference");
        let table = match value {
            toml::Value::String(file) => {
                let file = file.replace("{camera}", view.camera_name);
                let dir = self.file.parent().unwrap_or(Path::new(""));
                return Ok(ReferenceSource::File(dir.join(file)));
            }
            toml::Value::Table(t) => t,
            _ => return Err(r.error(&entry, "expected a file or a table")),
        };
        r.check_keys(&entry, table, REFERENCE_KEYS)?;
        let technique = match table.get("technique") {
            Some(v) => {
                let name = r.string(&entry, v)?;
                Technique::from_name(&name)
                    .ok_or_else(|| r.error(&entry, format!("unknown technique '{name}'")))?
            }
            None => Technique::Bpt,
        };
        let settings = Inherited {
            budget: None,
            ..inherited.clone()
        }
        .below(r, &entry, table)?;
        let budget = settings
            .budget
            .ok_or_else(|| r.error(&entry, "needs budget = \"TIME\" or iterations = N"))?;
        let parts = match table.get("parts") {
            Some(v) => r.count(&format!("{entry}: parts"), v)?.max(1),
            None => 1,
        };
        if self.cells.len() as u64 + parts + 1 > MAX_CELLS {
            return Err(r.error(
                &format!("{entry}: parts"),
                format!("{parts} parts: more than the {MAX_CELLS} cells a plan may have"),
            ));
        }
        let seed = match table.get("seed") {
            Some(v) => r.count(&format!("{entry}: seed"), v)?,
            None => REFERENCE_SEED,
        };
        let base = format!("{}.{}.reference", view.scene, view.camera_name);
        let mut options = settings.options(r, &entry, technique, &[])?;
        options.camera = view.camera.clone();
        if parts == 1 {
            self.cells.push(Cell {
                name: base.clone(),
                output: self.cell_path(&base),
                kind: CellKind::Reference,
                scene: view.scene.into(),
                camera: view.camera_name.into(),
                scene_file: view.scene_file.into(),
                options: RenderOptions { seed, ..options },
                budget,
                reference: None,
                traces: Vec::new(),
                variant: "reference".into(),
            });
            return Ok(ReferenceSource::Cell(self.cells.len() - 1));
        }
        let mut part_cells = Vec::new();
        for k in 0..parts {
            let name = format!("{base}.p{k}");
            part_cells.push(self.cells.len());
            self.cells.push(Cell {
                output: self.cell_path(&name),
                name,
                kind: CellKind::Reference,
                scene: view.scene.into(),
                camera: view.camera_name.into(),
                scene_file: view.scene_file.into(),
                options: RenderOptions {
                    seed: seed + k,
                    ..options.clone()
                },
                budget: budget.split(parts),
                reference: None,
                traces: Vec::new(),
                variant: "reference part".into(),
            });
        }
        self.cells.push(Cell {
            output: self.cell_path(&base),
            name: base,
            kind: CellKind::Merge { parts: part_cells },
            scene: view.scene.into(),
            camera: view.camera_name.into(),
            scene_file: view.scene_file.into(),
            options: RenderOptions { seed, ..options },
            budget,
            reference: None,
            traces: Vec::new(),
            variant: "reference".into(),
        });
        Ok(ReferenceSource::Cell(self.cells.len() - 1))
    }

    /// The render cells of one group for one scene and camera.
    fn group_cells(
        &self,
        r: &Reader,
        entry: &str,
        group: &toml::Table,
        inherited: &Inherited,
        view: &ViewSetup,
        reference: Option<ReferenceSource>,
    ) -> Result<Vec<Cell>, BatchError> {
        let techniques: Vec<Technique> = match group.get("techniques") {
            Some(v) => r
                .strings(&format!("{entry}: techniques"), v)?
                .iter()
                .map(|name| {
                    Technique::from_name(name).ok_or_else(|| {
                        r.error(
                            &format!("{entry}: techniques"),
                            format!("unknown technique '{name}'"),
                        )
                    })
                })
                .collect::<Result<_, _>>()?,
            None => return Err(r.error(entry, "needs techniques = [..]")),
        };
        let radii: Vec<Option<f32>> = match group.get("radius") {
            Some(v) => r
                .radii(&format!("{entry}: radius"), v)?
                .into_iter()
                .map(Some)
                .collect(),
            None => vec![None],
        };
        let betas: Vec<f32> = match group.get("beta") {
            Some(v) => r
                .numbers(&format!("{entry}: beta"), v)?
                .into_iter()
                .map(|b| b as f32)
                .collect(),
            None => vec![RenderOptions::DEFAULT.beta],
        };
        let budget = inherited
            .budget
            .ok_or_else(|| r.error(entry, "no budget: set budget or iterations here or above"))?;
        // Counted before any cell is made: the lists multiply. The plan's total is checked
        // after each group, which this bounds.
        let count = techniques
            .iter()
            .map(|t| if t.merges() { radii.len() as u64 } else { 1 })
            .sum::<u64>()
            .saturating_mul(betas.len() as u64)
            .saturating_mul(inherited.seeds.len() as u64);
        if count > MAX_CELLS {
            return Err(r.error(
                entry,
                format!(
                    "techniques x radii x betas x seeds make {count} cells: more than the \
                     {MAX_CELLS} cells a plan may have"
                ),
            ));
        }
        let mut cells = Vec::new();
        for &technique in &techniques {
            // Radii are for the techniques that merge; the others get one cell.
            let radii: &[Option<f32>] = if technique.merges() { &radii } else { &[None] };
            for &beta in &betas {
                let base = inherited.options(
                    r,
                    entry,
                    technique,
                    &[("beta", toml::Value::Float(beta as f64))],
                )?;
                let variant = variant_name(&base);
                for &radius in radii {
                    for &seed in &inherited.seeds {
                        let options = RenderOptions {
                            radius,
                            seed,
                            camera: view.camera.clone(),
                            ..base.clone()
                        };
                        options.validate().map_err(|e| r.error(entry, e))?;
                        let mut name = format!("{}.{}.{variant}", view.scene, view.camera_name);
                        if let Some(radius) = radius {
                            name.push_str(&format!(".r{}", number_part(radius)));
                        }
                        if seed != RenderOptions::DEFAULT.seed {
                            name.push_str(&format!(".s{seed}"));
                        }
                        cells.push(Cell {
                            output: self.cell_path(&name),
                            name,
                            kind: CellKind::Render,
                            scene: view.scene.into(),
                            camera: view.camera_name.into(),
                            scene_file: view.scene_file.into(),
                            options,
                            budget,
                            reference: reference.clone(),
                            traces: inherited.traces.clone(),
                            variant: variant.clone(),
                        });
                    }
                }
            }
        }
        Ok(cells)
    }
}

struct ViewSetup<'a> {
    scene: &'a str,
    camera: &'a Option<String>,
    camera_name: &'a str,
    scene_file: &'a Path,
}

/// A number in a file name: `0.01` as `0_01`.
fn number_part(x: f32) -> String {
    x.to_string().replace('.', "_").replace('-', "m")
}

/// The technique and every other option that differs from its default, but those a cell's name
/// carries on its own (radius, seed, camera) and the resolution: `vcm`,
/// `upg.no-vc.min-path-length3`, `vcm.beta1`, `vcm.density-misvcmstar`. Column names of the
/// report's tables and the middle of cell names: every value that changes the image gives
/// another name.
pub fn variant_name(o: &RenderOptions) -> String {
    let mut name = o.technique.name().to_string();
    for spec in OPTIONS {
        if matches!(
            spec.name,
            "technique" | "seed" | "camera" | "radius" | "resolution"
        ) || !spec.is_set(o)
        {
            continue;
        }
        name.push('.');
        name.push_str(&spec.name.replace('_', "-"));
        if let (Form::Value { .. }, Some(value)) = (spec.form, (spec.write)(o)) {
            name.push_str(&value_part(&value));
        }
    }
    name
}

/// A value in a file name: `0.5` as `0_5`, `1,2` as `1_2`, `vcm*` as `vcmstar`, `vcm+` as
/// `vcmplus`.
fn value_part(value: &str) -> String {
    value
        .replace(['.', ','], "_")
        .replace('*', "star")
        .replace('+', "plus")
}
