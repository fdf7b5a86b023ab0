//! The progressive render loop: iterations, time limit, progress and reference errors.

use crate::accel::AccelKind;
use crate::color::Rgb;
use crate::files::{FileError, OutputLock};
use crate::film::{exr, png, ErrorTracker, Film, FilmError, Metadata, TraceWindow};
use crate::integrator::bpt::Bpt;
use crate::integrator::pt::PathTracer;
use crate::integrator::vcm::VertexCm;
use crate::integrator::{Counters, Integrator, RenderContext};
use crate::memory::MemoryError;
use crate::options::{OptionError, OptionName, RenderOptions, Technique};
use crate::scene::{Camera, LoadOptions, Scene, SceneError};
use cpu_time::ProcessTime;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
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
    #[error(transparent)]
    Options(#[from] OptionError),
    #[error(transparent)]
    File(#[from] FileError),
    #[error(transparent)]
    Memory(#[from] MemoryError),
    /// The final image could not be written where asked, and went elsewhere.
    #[error("{}: cannot write the image ({message}); it was written to {} instead", wanted.display(), written.display())]
    WrittenElsewhere {
        wanted: PathBuf,
        written: PathBuf,
        message: String,
    },
    /// The final image could not be written at all.
    #[error("{}: cannot write the image ({message}), nor a copy in {}; {}", wanted.display(), std::env::temp_dir().display(), match last_good {
        Some(p) => format!("the last good snapshot is {}", p.display()),
        None => "no snapshot of it remains, the render is lost".to_string(),
    })]
    Lost {
        wanted: PathBuf,
        message: String,
        last_good: Option<PathBuf>,
    },
    #[error(
        "say when to stop: {} N, {} T and/or {} T",
        OptionName("iterations"),
        OptionName("time"),
        OptionName("cpu_time")
    )]
    NoStop,
    #[error(
        "{} needs the process's CPU clock, which this system does not give",
        OptionName("cpu_time")
    )]
    NoCpuClock,
    #[error("{file}: the scene changed since this render began (hash {recorded} recorded, {now} now); use {} to continue anyway", OptionName("force"))]
    SceneChanged {
        file: PathBuf,
        recorded: String,
        now: String,
    },
}

/// Creates the integrator for `ctx.options.technique`: the one place that chooses among them,
/// above the integrators, so that their shared layer names none.
pub fn create_integrator<'a>(ctx: RenderContext<'a>) -> Box<dyn Integrator + 'a> {
    match ctx.options.technique {
        Technique::Pt => Box::new(PathTracer::new(ctx)),
        Technique::Bpt => Box::new(Bpt::new(ctx)),
        Technique::Lt
        | Technique::Ppm
        | Technique::Bpm
        | Technique::Vcm
        | Technique::Upg
        | Technique::UpgCamera
        | Technique::UpgHybrid
        | Technique::VcmUpg => Box::new(VertexCm::new(ctx)),
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
    let mut integrator = create_integrator(RenderContext {
        scene,
        camera,
        options,
    });
    let mut frame = vec![Rgb::BLACK; film.pixel_count()];
    for iteration in 0..iterations {
        frame.par_iter_mut().for_each(|p| *p = Rgb::BLACK);
        integrator.render_iteration(iteration, &mut frame);
        film.add_iteration(&frame);
    }
    Ok(film)
}

/// When a render stops: after a number of iterations (in total, a continued render's earlier
/// iterations included), after a time or a CPU time (of this run), or whichever comes first.
/// The time budgets start no iteration predicted to end past them ([`iteration_fits`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct StopAfter {
    pub iterations: Option<u64>,
    /// Wall-clock time from the first iteration of this run.
    pub time: Option<Duration>,
    /// CPU time the render's threads consume together (the process's CPU time, all threads
    /// summed): a budget of work, so renders that share a machine get equal shares of it
    /// whatever the load.
    pub cpu_time: Option<Duration>,
}

impl StopAfter {
    /// Whether anything stops the render at all.
    pub fn is_bounded(&self) -> bool {
        self.iterations.is_some() || self.time.is_some() || self.cpu_time.is_some()
    }
}

/// The stopping rule of the time budgets: whether another iteration fits in the `left`
/// seconds of a budget, for a render that has spent `spent` seconds on its `iterations`
/// iterations. The next iteration is predicted to take their mean, so the render stops early
/// rather than late; one with no iteration yet starts one if anything is left. A render thus
/// overshoots its budget only by what its last iteration took beyond the mean.
pub fn iteration_fits(left: f64, spent: f64, iterations: u64) -> bool {
    left > 0.0 && (iterations == 0 || left >= spent / iterations as f64)
}

/// The render's clocks, from the start of a run: wall time and the process's CPU time.
struct Clocks {
    wall: Instant,
    /// `None` where the system gives no process CPU clock.
    cpu: Option<ProcessTime>,
}

impl Clocks {
    fn start() -> Clocks {
        Clocks {
            wall: Instant::now(),
            cpu: ProcessTime::try_now().ok(),
        }
    }

    fn cpu(&self) -> Option<Duration> {
        self.cpu.as_ref().and_then(|c| c.try_elapsed().ok())
    }
}

/// What the loop reports as it goes: progress after every iteration, and the problems it
/// survived, for the caller to show (the library prints nothing).
#[derive(Debug)]
pub enum RunEvent<'a> {
    Iteration(&'a Progress),
    Warning(&'a RunWarning),
}

/// A problem a run survived: the render goes on, or is written.
#[derive(Debug, Error)]
pub enum RunWarning {
    #[error("removed {}, a temporary file a stopped write left", .0.display())]
    RemovedTemporary(PathBuf),
    #[error("snapshot not written: {0}; rendering on, trying again at the next snapshot")]
    SnapshotNotWritten(RenderError),
    /// The preview is a convenience; the render itself is safe.
    #[error("{0}; the render is written")]
    PreviewNotWritten(FilmError),
}

/// What the loop reports after every iteration, for a progress display.
#[derive(Clone, Debug)]
pub struct Progress {
    pub iterations: u64,
    pub elapsed: Duration,
    pub samples_per_second: f64,
    pub rays_per_second: f64,
    pub rmse: Option<f64>,
    /// The CPU time of this run, all threads together; `None` where the system gives no
    /// process CPU clock.
    pub cpu: Option<Duration>,
    /// The technique's own work counts in this run ([`Integrator::counters`]): UPG's merges
    /// and tentative rays, none for the other techniques.
    pub counters: Counters,
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
    /// The output is this job's alone while it lives.
    _lock: OutputLock,
}

/// Measures the current image against the reference, if any, and records the sample in the
/// metadata; returns its RMS error. The `last` sample of a run holds every measure and
/// replaces one recorded at the same iteration.
fn record_error(
    tracker: &mut Option<ErrorTracker>,
    film: &Film,
    metadata: &mut Metadata,
    last: bool,
) -> Option<f64> {
    let tracker = tracker.as_mut()?;
    let (mean, seconds) = (film.mean(), metadata.render_seconds);
    let sample = if last {
        tracker.measure_all(&mean, seconds, film.iterations)
    } else {
        tracker.measure(&mean, seconds, film.iterations)
    };
    if last
        && metadata
            .errors
            .last()
            .is_some_and(|e| e.iterations == film.iterations)
    {
        metadata.errors.pop();
    }
    let rmse = sample.rmse;
    metadata.errors.push(sample);
    Some(rmse)
}

/// Set by a signal handler (or a test) to stop the render after the current iteration.
pub type StopFlag = Arc<AtomicBool>;

/// Watches a render (the live preview): told after every iteration, on the render's thread
/// while the workers wait, so it must return quickly.
pub trait Observer {
    fn after_iteration(&mut self, film: &Film, metadata: &Metadata, progress: &Progress);
}

impl RenderJob<'_> {
    /// Runs iterations until `stop` says so or `stop_flag` is raised, writing a snapshot every
    /// `snapshot_every` and the final image at the end.
    pub fn run(
        &mut self,
        stop: StopAfter,
        stop_flag: &StopFlag,
        on_event: impl FnMut(RunEvent),
    ) -> Result<(), RenderError> {
        self.run_observed(stop, stop_flag, None, on_event)
    }

    /// [`run`](Self::run), telling `observer` after every iteration.
    pub fn run_observed(
        &mut self,
        stop: StopAfter,
        stop_flag: &StopFlag,
        mut observer: Option<&mut dyn Observer>,
        mut on_event: impl FnMut(RunEvent),
    ) -> Result<(), RenderError> {
        if !stop.is_bounded() {
            return Err(RenderError::NoStop);
        }
        crate::options::validate_run(stop.iterations, stop.time, self.snapshot_every)?;
        crate::options::validate_cpu_time(stop.cpu_time)?;
        for path in self.written_paths() {
            for stale in crate::film::remove_stale_temporaries(&path) {
                on_event(RunEvent::Warning(&RunWarning::RemovedTemporary(stale)));
            }
        }
        let camera = Camera::new(
            self.scene.camera(self.options.camera.as_deref())?,
            self.film.width,
            self.film.height,
        );
        let mut integrator = create_integrator(RenderContext {
            scene: self.scene,
            camera,
            options: &self.options,
        });
        let mut frame = vec![Rgb::BLACK; self.film.pixel_count()];
        let clocks = Clocks::start();
        if stop.cpu_time.is_some() && clocks.cpu.is_none() {
            return Err(RenderError::NoCpuClock);
        }
        let start = clocks.wall;
        let earlier_seconds = self.metadata.render_seconds;
        // A render whose earlier runs' CPU time is unknown (written before it was recorded)
        // predicts its iterations' CPU time from this run's alone.
        let earlier_cpu = self.metadata.cpu_seconds;
        let mut last_snapshot = start;
        let mut last_error = None::<Instant>;
        let mut rays = 0u64;
        let mut iterations_here = 0u64;
        let mut progress = None::<Progress>;
        // The output as of the last snapshot written, if one was.
        let mut last_good = None::<PathBuf>;
        loop {
            let wall = start.elapsed();
            let cpu = clocks.cpu();
            let done_iterations = stop.iterations.is_some_and(|n| self.film.iterations >= n);
            let done_time = stop.time.is_some_and(|t| {
                !iteration_fits(
                    t.as_secs_f64() - wall.as_secs_f64(),
                    earlier_seconds + wall.as_secs_f64(),
                    self.film.iterations,
                )
            });
            let done_cpu = stop.cpu_time.is_some_and(|t| {
                let Some(cpu) = cpu else {
                    // The clock failed: the budget can no longer be told, so it is spent.
                    return true;
                };
                let (spent, iterations) = match earlier_cpu {
                    Some(earlier) => (earlier + cpu.as_secs_f64(), self.film.iterations),
                    None => (cpu.as_secs_f64(), iterations_here),
                };
                !iteration_fits(t.as_secs_f64() - cpu.as_secs_f64(), spent, iterations)
            });
            self.metadata.render_seconds = earlier_seconds + wall.as_secs_f64();
            self.metadata.cpu_seconds = earlier_cpu.zip(cpu).map(|(e, c)| e + c.as_secs_f64());
            if done_iterations || done_time || done_cpu || stop_flag.load(Ordering::Relaxed) {
                break;
            }
            frame.par_iter_mut().for_each(|p| *p = Rgb::BLACK);
            let stats = integrator.render_iteration(self.film.iterations, &mut frame);
            self.film.add_iteration(&frame);
            iterations_here += 1;
            rays += stats.rays;
            self.metadata.dropped_samples += stats.dropped_samples;
            self.metadata.iterations = self.film.iterations;
            let elapsed = start.elapsed();
            let cpu = clocks.cpu();
            self.metadata.render_seconds = earlier_seconds + elapsed.as_secs_f64();
            self.metadata.cpu_seconds = earlier_cpu.zip(cpu).map(|(e, c)| e + c.as_secs_f64());
            // Errors at every power-of-two iteration (even spacing on the log-log convergence
            // charts) and otherwise at most once a second: measuring a large image costs.
            let mut rmse = None;
            let due = last_error.is_none_or(|t| t.elapsed() >= Duration::from_secs(1));
            if self.tracker.is_some() && (due || self.film.iterations.is_power_of_two()) {
                rmse = record_error(&mut self.tracker, &self.film, &mut self.metadata, false);
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
                cpu,
                // The integrator is this run's, so its totals are the run's.
                counters: integrator.counters(),
            };
            on_event(RunEvent::Iteration(&now));
            if let Some(observer) = observer.as_deref_mut() {
                observer.after_iteration(&self.film, &self.metadata, &now);
            }
            if self
                .snapshot_every
                .is_some_and(|every| last_snapshot.elapsed() >= every)
            {
                self.metadata.statistics = integrator.statistics(now.elapsed);
                match self.write() {
                    Ok(()) => last_good = Some(self.output.clone()),
                    Err(e) => on_event(RunEvent::Warning(&RunWarning::SnapshotNotWritten(e))),
                }
                last_snapshot = Instant::now();
            }
            progress = Some(now);
        }
        if iterations_here > 0 {
            record_error(&mut self.tracker, &self.film, &mut self.metadata, true);
        }
        // No iteration in this run: no work to give a rate of.
        let elapsed = progress.as_ref().map_or(Duration::ZERO, |p| p.elapsed);
        self.metadata.statistics = integrator.statistics(elapsed);
        self.write_final(last_good, &mut on_event)
    }

    /// The files a write makes: the EXR and, if wanted, its preview.
    fn written_paths(&self) -> Vec<PathBuf> {
        let mut paths = vec![self.output.clone()];
        if self.png {
            paths.push(self.output.with_extension("png"));
        }
        paths
    }

    /// Writes the final image; where that fails, writes it to the temporary directory and
    /// says so, and where that fails too, names the last good snapshot: the render is never
    /// lost silently.
    fn write_final(
        &self,
        last_good: Option<PathBuf>,
        on_event: &mut impl FnMut(RunEvent),
    ) -> Result<(), RenderError> {
        let Err(e) = exr::write_render(&self.output, &self.film, &self.metadata) else {
            if self.png {
                let preview = self.output.with_extension("png");
                let mean = self.film.mean();
                if let Err(e) =
                    png::write_preview(&preview, &mean, self.film.width, self.film.height)
                {
                    on_event(RunEvent::Warning(&RunWarning::PreviewNotWritten(e)));
                }
            }
            return Ok(());
        };
        for path in self.written_paths() {
            crate::film::remove_stale_temporaries(&path);
        }
        let name = self
            .output
            .file_name()
            .map_or("render.exr".into(), |n| n.to_string_lossy().into_owned());
        let fallback = std::env::temp_dir().join(format!("vmerge-{}-{name}", std::process::id()));
        match exr::write_render(&fallback, &self.film, &self.metadata) {
            Ok(()) => Err(RenderError::WrittenElsewhere {
                wanted: self.output.clone(),
                written: fallback,
                message: e.to_string(),
            }),
            Err(_) => Err(RenderError::Lost {
                wanted: self.output.clone(),
                message: e.to_string(),
                last_good: last_good.filter(|p| p.exists()),
            }),
        }
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
    /// The memory the render may use; `None` = what the machine has available.
    pub memory_limit: Option<u64>,
}

/// Checks the output against everything a render reads (the EXR and, if written, the
/// preview): the write must be possible and destroy no input.
fn check_output(output: &Path, png: bool, inputs: &[PathBuf]) -> Result<(), FileError> {
    crate::files::check_output(output, inputs)?;
    if png {
        let preview = output.with_extension("png");
        if preview == output {
            return Err(FileError {
                file: output.into(),
                message: "is where the PNG preview goes; name an .exr file".into(),
            });
        }
        crate::files::check_output(&preview, inputs)?;
    }
    Ok(())
}

/// The memory the job will need against the limit.
fn check_memory(
    scene: &Scene,
    options: &RenderOptions,
    pixels: u64,
    limit: Option<u64>,
) -> Result<(), MemoryError> {
    let max_path_length = match options
        .max_path_length
        .unwrap_or(scene.defaults.max_path_length)
    {
        0 => u32::MAX,
        n => n,
    };
    let need = crate::memory::estimate(
        options.technique,
        options.memory,
        pixels,
        max_path_length,
        options.roulette,
        rayon::current_num_threads(),
    );
    crate::memory::check(&need, limit)
}

impl NewRender {
    /// Everything that can be checked before the scene loads: the options, trace windows only
    /// with a reference, an output that can be written and is neither the scene file nor the
    /// reference. Returns the output's lock, so that another process writing it refuses now
    /// rather than after the scene loads: held while the scene loads, it is shared with the
    /// job, and the lock file goes when the last guard does, whether the render is written or
    /// refused.
    pub fn check(&self) -> Result<OutputLock, RenderError> {
        self.options.validate()?;
        if !self.traces.is_empty() && self.reference.is_none() {
            return Err(OptionError::Needs {
                option: OptionName("trace"),
                message: format!(
                    "error windows are measured against {}",
                    OptionName("reference")
                ),
            }
            .into());
        }
        let mut inputs = vec![self.scene.clone()];
        inputs.extend(self.reference.clone());
        check_output(&self.output, self.png, &inputs)?;
        Ok(crate::files::lock_output(&self.output)?)
    }

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
        let lock = self.check()?;
        let mut inputs = scene.inputs.clone();
        inputs.extend(self.reference.clone());
        check_output(&self.output, self.png, &inputs)?;
        let [width, height] = self.options.resolution.unwrap_or(scene.defaults.resolution);
        scene.camera(self.options.camera.as_deref())?;
        check_memory(
            scene,
            &self.options,
            width as u64 * height as u64,
            self.memory_limit,
        )?;
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
            _lock: lock,
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
    memory_limit: Option<u64>,
) -> Result<RenderJob<'_>, RenderError> {
    metadata.options.validate()?;
    let mut inputs = scene.inputs.clone();
    inputs.extend(metadata.reference.as_ref().map(PathBuf::from));
    check_output(&output, png, &inputs)?;
    let lock = crate::files::lock_output(&output)?;
    check_memory(
        scene,
        &metadata.options,
        film.pixel_count() as u64,
        memory_limit,
    )?;
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
        _lock: lock,
    })
}
