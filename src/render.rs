//! The progressive render loop: iterations, time limit, progress and reference errors.

use crate::accel::AccelKind;
use crate::color::Rgb;
use crate::film::{exr, png, ErrorTracker, Film, FilmError, Metadata, TraceWindow};
use crate::integrator::{self, RenderContext, Technique, UpgCounters};
use crate::scene::{Camera, LoadOptions, Scene, SceneError};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum RenderError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Film(#[from] FilmError),
    #[error("say when to stop: --iterations N and/or --time T")]
    NoStop,
    #[error("--strategy and --unweighted apply to --technique bpt, not {0}")]
    BptOnly(&'static str),
    #[error("--strategy {0},{1}: no such technique (t counts the camera vertex, so t >= 1 and s + t >= 2)")]
    NoSuchStrategy(u32, u32),
    #[error("--no-vc, --no-vm and --alpha do not apply to upg and upg-camera (both connect and merge, at a fixed radius)")]
    UpgOptions,
    #[error("--upg-packet {0}: tentative rays go 1 or 8 at a time")]
    UpgPacket(u32),
    #[error("--upg-max-trials must be at least 1")]
    UpgMaxTrials,
    #[error("{file}: the scene changed since this render began (hash {recorded} recorded, {now} now); use --force to continue anyway")]
    SceneChanged {
        file: PathBuf,
        recorded: String,
        now: String,
    },
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
    /// Render every triangle flat, ignoring the meshes' vertex normals (applied when the scene
    /// is loaded).
    #[serde(default)]
    pub no_shading_normals: bool,
}

fn default_upg_packet() -> u32 {
    1
}

fn default_upg_max_trials() -> u32 {
    crate::integrator::upg::acceptance::DEFAULT_MAX_TRIALS
}

impl RenderOptions {
    /// Rejects combinations of options that do not mean anything.
    pub fn validate(&self) -> Result<(), RenderError> {
        if (self.strategy.is_some() || self.unweighted) && self.technique != Technique::Bpt {
            return Err(RenderError::BptOnly(self.technique.name()));
        }
        let upg = matches!(self.technique, Technique::Upg | Technique::UpgCamera);
        if upg && (self.no_vc || self.no_vm || self.alpha.is_some()) {
            return Err(RenderError::UpgOptions);
        }
        if self.upg_packet != 1 && self.upg_packet != 8 {
            return Err(RenderError::UpgPacket(self.upg_packet));
        }
        if self.upg_max_trials == 0 {
            return Err(RenderError::UpgMaxTrials);
        }
        if let Some([s, t]) = self.strategy {
            if t == 0 || s + t < 2 {
                return Err(RenderError::NoSuchStrategy(s, t));
            }
        }
        Ok(())
    }
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
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
            upg_packet: default_upg_packet(),
            upg_max_trials: default_upg_max_trials(),
            no_shading_normals: false,
        }
    }
}

/// Renders `iterations` iterations of `options.technique` and returns the film: the library
/// call behind `vmerge render --iterations N` without progress, time limit or files.
pub fn render_iterations(
    scene: &Scene,
    options: &RenderOptions,
    iterations: u64,
) -> Result<Film, SceneError> {
    let [width, height] = options.resolution.unwrap_or(scene.defaults.resolution);
    let camera = Camera::new(scene.camera(options.camera.as_deref())?, width, height);
    let mut film = Film::new(width, height);
    let mut integrator = integrator::create(RenderContext {
        scene,
        camera,
        options,
    });
    let mut frame = vec![Rgb::BLACK; film.pixel_count()];
    for iteration in 0..iterations {
        frame.fill(Rgb::BLACK);
        integrator.render_iteration(iteration, &mut frame);
        film.add_iteration(&frame);
    }
    Ok(film)
}

/// When a render stops: after a number of iterations (in total, a continued render's earlier
/// iterations included), after a time (of this run), or whichever comes first.
#[derive(Clone, Copy, Debug, Default)]
pub struct StopAfter {
    pub iterations: Option<u64>,
    pub time: Option<Duration>,
}

/// What the loop reports after every iteration, for a progress display.
#[derive(Clone, Debug)]
pub struct Progress {
    pub iterations: u64,
    pub elapsed: Duration,
    pub samples_per_second: f64,
    pub rays_per_second: f64,
    pub rmse: Option<f64>,
    /// UPG's merges and tentative rays in this run (zero for the other techniques).
    pub upg: UpgCounters,
}

impl Progress {
    /// UPG's rates for the metadata and the progress line, when it merged at all.
    pub fn upg_statistics(&self) -> Option<Vec<(String, String)>> {
        let seconds = self.elapsed.as_secs_f64().max(1e-9);
        (self.upg.merges > 0).then(|| {
            vec![
                (
                    "upg_merges_per_second".into(),
                    format!("{:.0}", self.upg.merges as f64 / seconds),
                ),
                (
                    "upg_tentative_rays_per_second".into(),
                    format!("{:.0}", self.upg.tentative_rays as f64 / seconds),
                ),
            ]
        })
    }
}

/// The state of a render: its film, its metadata and what it needs to go on.
pub struct RenderJob<'a> {
    pub scene: &'a Scene,
    pub options: RenderOptions,
    pub film: Film,
    pub metadata: Metadata,
    /// Errors against a reference image, recorded in the metadata.
    pub tracker: Option<ErrorTracker>,
    /// Where snapshots and the final image go.
    pub output: PathBuf,
    pub png: bool,
    pub snapshot_every: Option<Duration>,
}

/// Measures the current image against the reference, if any, and records the sample in the
/// metadata; returns its RMS error.
fn record_error(
    tracker: &Option<ErrorTracker>,
    film: &Film,
    metadata: &mut Metadata,
) -> Option<f64> {
    let sample = tracker
        .as_ref()?
        .measure(&film.mean(), metadata.render_seconds, film.iterations);
    let rmse = sample.rmse;
    metadata.errors.push(sample);
    Some(rmse)
}

/// Set by a signal handler (or a test) to stop the render after the current iteration.
pub type StopFlag = Arc<AtomicBool>;

impl RenderJob<'_> {
    /// Runs iterations until `stop` says so or `stop_flag` is raised, writing a snapshot every
    /// `snapshot_every` and the final image at the end.
    pub fn run(
        &mut self,
        stop: StopAfter,
        stop_flag: &StopFlag,
        mut on_progress: impl FnMut(&Progress),
    ) -> Result<(), RenderError> {
        let camera = Camera::new(
            self.scene.camera(self.options.camera.as_deref())?,
            self.film.width,
            self.film.height,
        );
        let mut integrator = integrator::create(RenderContext {
            scene: self.scene,
            camera,
            options: &self.options,
        });
        let mut frame = vec![Rgb::BLACK; self.film.pixel_count()];
        let start = Instant::now();
        let earlier_seconds = self.metadata.render_seconds;
        let mut last_snapshot = start;
        let mut last_error = None::<Instant>;
        let mut rays = 0u64;
        let mut upg = UpgCounters::default();
        let mut iterations_here = 0u64;
        let mut progress = None::<Progress>;
        loop {
            let done_iterations = stop.iterations.is_some_and(|n| self.film.iterations >= n);
            let done_time = stop.time.is_some_and(|t| start.elapsed() >= t);
            if done_iterations || done_time || stop_flag.load(Ordering::Relaxed) {
                break;
            }
            frame.fill(Rgb::BLACK);
            let stats = integrator.render_iteration(self.film.iterations, &mut frame);
            self.film.add_iteration(&frame);
            iterations_here += 1;
            rays += stats.rays;
            upg = upg + stats.upg;
            self.metadata.dropped_samples += stats.dropped_samples;
            self.metadata.iterations = self.film.iterations;
            let elapsed = start.elapsed();
            self.metadata.render_seconds = earlier_seconds + elapsed.as_secs_f64();
            // Errors at every power-of-two iteration (even spacing on the log-log convergence
            // charts) and otherwise at most once a second: measuring a large image costs.
            let mut rmse = None;
            let due = last_error.is_none_or(|t| t.elapsed() >= Duration::from_secs(1));
            if self.tracker.is_some() && (due || self.film.iterations.is_power_of_two()) {
                rmse = record_error(&self.tracker, &self.film, &mut self.metadata);
                last_error = Some(Instant::now());
            }
            let seconds = elapsed.as_secs_f64().max(1e-9);
            let now = Progress {
                iterations: self.film.iterations,
                elapsed,
                samples_per_second: (iterations_here * self.film.pixel_count() as u64) as f64
                    / seconds,
                rays_per_second: rays as f64 / seconds,
                rmse,
                upg,
            };
            on_progress(&now);
            let statistics = |progress: &Progress| {
                let mut all = integrator.statistics();
                all.extend(progress.upg_statistics().unwrap_or_default());
                all
            };
            if self
                .snapshot_every
                .is_some_and(|every| last_snapshot.elapsed() >= every)
            {
                self.metadata.statistics = statistics(&now);
                self.write()?;
                last_snapshot = Instant::now();
            }
            progress = Some(now);
        }
        let recorded = self.metadata.errors.last().map(|e| e.iterations);
        if iterations_here > 0 && recorded != Some(self.film.iterations) {
            record_error(&self.tracker, &self.film, &mut self.metadata);
        }
        self.metadata.statistics = integrator.statistics();
        if let Some(rates) = progress.as_ref().and_then(Progress::upg_statistics) {
            self.metadata.statistics.extend(rates);
        }
        self.write()
    }

    /// Writes the image (and its preview) atomically.
    pub fn write(&self) -> Result<(), RenderError> {
        exr::write_render(&self.output, &self.film, &self.metadata)?;
        if self.png {
            png::write_preview(
                &self.output.with_extension("png"),
                &self.film.mean(),
                self.film.width,
                self.film.height,
            )?;
        }
        Ok(())
    }
}

/// A render about to start: everything `vmerge render` was told.
pub struct NewRender {
    pub scene: PathBuf,
    pub options: RenderOptions,
    pub accel: AccelKind,
    pub lenient: bool,
    pub output: PathBuf,
    pub png: bool,
    pub snapshot_every: Option<Duration>,
    pub reference: Option<PathBuf>,
    pub traces: Vec<TraceWindow>,
}

impl NewRender {
    pub fn load_scene(&self) -> Result<Scene, SceneError> {
        crate::scene::load(
            &self.scene,
            &LoadOptions {
                accel: self.accel,
                lenient: self.lenient,
                shading_normals: !self.options.no_shading_normals,
            },
        )
    }

    /// The job over `scene`, with a fresh film and the reference loaded and checked.
    pub fn job<'a>(&self, scene: &'a Scene) -> Result<RenderJob<'a>, RenderError> {
        let [width, height] = self.options.resolution.unwrap_or(scene.defaults.resolution);
        scene.camera(self.options.camera.as_deref())?;
        let canonical = std::fs::canonicalize(&self.scene).unwrap_or_else(|_| self.scene.clone());
        let mut metadata = Metadata::new(
            canonical.to_string_lossy().into_owned(),
            scene.source_hash.clone(),
            self.options.clone(),
            scene.accel.name(),
        );
        metadata.traces = self.traces.clone();
        let tracker = match &self.reference {
            Some(path) => {
                metadata.reference = Some(path.to_string_lossy().into_owned());
                let image = exr::read_image(path)?;
                Some(ErrorTracker::new(
                    image,
                    path,
                    width,
                    height,
                    self.traces.clone(),
                )?)
            }
            None => None,
        };
        Ok(RenderJob {
            scene,
            options: self.options.clone(),
            film: Film::new(width, height),
            metadata,
            tracker,
            output: self.output.clone(),
            png: self.png,
            snapshot_every: self.snapshot_every,
        })
    }
}

/// Loads the scene a render was made from, refusing one whose files changed since unless
/// `force`.
pub fn load_for_continue(
    metadata: &Metadata,
    accel: AccelKind,
    force: bool,
) -> Result<Scene, RenderError> {
    let path = PathBuf::from(&metadata.scene);
    let scene = crate::scene::load(
        &path,
        &LoadOptions {
            accel,
            lenient: false,
            shading_normals: !metadata.options.no_shading_normals,
        },
    )?;
    if scene.source_hash != metadata.scene_hash && !force {
        return Err(RenderError::SceneChanged {
            file: path,
            recorded: metadata.scene_hash.clone(),
            now: scene.source_hash.clone(),
        });
    }
    Ok(scene)
}

/// The job that goes on with a render read from its EXR: same options and seed, next
/// iteration index, same reference and trace windows.
pub fn continued_job(
    scene: &Scene,
    film: Film,
    metadata: Metadata,
    output: PathBuf,
    png: bool,
    snapshot_every: Option<Duration>,
) -> Result<RenderJob<'_>, RenderError> {
    let tracker = match &metadata.reference {
        Some(path) => {
            let path = PathBuf::from(path);
            let image = exr::read_image(&path)?;
            Some(ErrorTracker::new(
                image,
                &path,
                film.width,
                film.height,
                metadata.traces.clone(),
            )?)
        }
        None => None,
    };
    Ok(RenderJob {
        scene,
        options: metadata.options.clone(),
        film,
        metadata,
        tracker,
        output,
        png,
        snapshot_every,
    })
}
