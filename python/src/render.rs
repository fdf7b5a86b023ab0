//! Scenes and renders: loading a scene, rendering it at once or progressively, continuing a
//! render. Renders run with the GIL released; Ctrl-C stops them at the end of an iteration.

use crate::errors::{self, Interrupted};
use crate::result::{image_array, RenderResult};
use numpy::PyArray3;
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyFloat, PyInt, PyList, PyString};
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use vmerge::accel::AccelKind;
use vmerge::film::{Film, Metadata};
use vmerge::render::{NewRender, Observer, Progress, RenderJob, RunEvent, StopAfter, StopFlag};
use vmerge::scene::{LoadOptions, Scene};

/// How often a waiting call looks for Ctrl-C.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// A loaded scene, with the load's warnings.
#[pyclass(name = "Scene", module = "vmerge", frozen)]
pub struct PyScene {
    scene: Arc<Scene>,
    path: PathBuf,
    lenient: bool,
    accel: AccelKind,
    shading_normals: bool,
}

pub fn accel_kind(name: Option<&str>) -> PyResult<AccelKind> {
    match name {
        None => Ok(AccelKind::default_kind()),
        Some(n) => AccelKind::ALL
            .into_iter()
            .find(|k| k.name() == n)
            .ok_or_else(|| {
                let names: Vec<&str> = AccelKind::ALL.iter().map(|k| k.name()).collect();
                PyValueError::new_err(format!(
                    "`accel` '{n}': expected one of {}",
                    names.join(", ")
                ))
            }),
    }
}

fn load(
    py: Python<'_>,
    path: PathBuf,
    lenient: bool,
    accel: AccelKind,
    shading_normals: bool,
) -> PyResult<PyScene> {
    let options = LoadOptions {
        accel,
        lenient,
        shading_normals,
    };
    let scene = py
        .detach(|| vmerge::scene::load(&path, &options))
        .map_err(errors::scene)?;
    Ok(PyScene {
        scene: Arc::new(scene),
        path,
        lenient,
        accel,
        shading_normals,
    })
}

/// Loads a scene (TOML or pbrt-v4): its problems raise `SceneError` naming the file and the
/// entry; with `lenient`, flaws that can be repaired become warnings (`Scene.warnings`).
#[pyfunction]
#[pyo3(signature = (path, lenient = false, accel = None))]
pub fn load_scene(
    py: Python<'_>,
    path: PathBuf,
    lenient: bool,
    accel: Option<&str>,
) -> PyResult<PyScene> {
    load(py, path, lenient, accel_kind(accel)?, true)
}

#[pymethods]
impl PyScene {
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The load's warnings, one message each.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.scene.warnings.iter().map(|w| w.to_string()).collect()
    }

    /// The scene's default resolution, (width, height).
    #[getter]
    fn resolution(&self) -> (u32, u32) {
        let [w, h] = self.scene.defaults.resolution;
        (w, h)
    }

    /// The cameras' names, the first being the default.
    #[getter]
    fn cameras(&self) -> Vec<String> {
        self.scene.cameras.iter().map(|c| c.name.clone()).collect()
    }

    #[getter]
    fn triangles(&self) -> usize {
        self.scene.geometry.triangles.len()
    }

    #[getter]
    fn lights(&self) -> usize {
        self.scene.lights.len()
    }

    /// The merge radius when none is given, for the default camera (`Scene::default_radius`).
    #[getter]
    fn default_radius(&self) -> PyResult<f32> {
        let desc = self.scene.camera(None).map_err(errors::scene)?;
        let [w, h] = self.scene.defaults.resolution;
        Ok(self
            .scene
            .default_radius(&vmerge::scene::Camera::new(desc, w, h)))
    }

    #[getter]
    fn accel(&self) -> &'static str {
        self.scene.accel.name()
    }

    fn __repr__(&self) -> String {
        format!(
            "vmerge.Scene('{}', {} triangles, {} lights)",
            self.path.display(),
            self.scene.geometry.triangles.len(),
            self.scene.lights.len()
        )
    }
}

/// A time budget: seconds as a number, or a text like the command line's (`90s`, `10m`).
fn duration(name: &str, value: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Duration>> {
    let Some(value) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    if value.is_instance_of::<PyString>() {
        let text: String = value.extract()?;
        return vmerge::options::parse_duration(&text)
            .map(Some)
            .map_err(|e| PyValueError::new_err(format!("`{name}` {e}")));
    }
    if value.is_instance_of::<PyInt>() || value.is_instance_of::<PyFloat>() {
        let seconds: f64 = value.extract()?;
        return Duration::try_from_secs_f64(seconds).map(Some).map_err(|_| {
            PyValueError::new_err(format!("`{name}` {seconds}: expected seconds >= 0"))
        });
    }
    Err(PyTypeError::new_err(format!(
        "`{name}` takes seconds or a text like '90s', '10m'"
    )))
}

/// Sets the number of worker threads renders use (default: one per core), once, before the
/// first render; the image does not depend on it.
#[pyfunction]
pub fn set_threads(threads: usize) -> PyResult<()> {
    vmerge::options::validate_threads(threads).map_err(errors::option)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .map_err(|e| {
            PyRuntimeError::new_err(format!(
                "`threads` can be set once, before the first render: {e}"
            ))
        })
}

/// Everything a render needs, checked, owning what it borrows so that it can run on any
/// thread.
struct Prepared {
    scene: Arc<Scene>,
    /// A fresh render, or a render read back to go on with.
    start: Start,
    output: PathBuf,
    png: bool,
    snapshot: Option<Duration>,
    memory_limit: Option<u64>,
    stop: StopAfter,
    /// Holds the output when the caller named none; removed with the render.
    _scratch: Option<tempfile::TempDir>,
}

enum Start {
    New(Box<NewRender>),
    Continue(Film, Box<Metadata>),
}

/// What a render run ends with: the film and metadata, written to the output.
type Outcome = Result<(Film, Metadata), vmerge::render::RenderError>;

impl Prepared {
    /// The output the caller named, or one in a scratch folder of its own.
    fn output(output: Option<PathBuf>) -> PyResult<(PathBuf, Option<tempfile::TempDir>)> {
        match output {
            Some(path) => Ok((path, None)),
            None => {
                let dir = tempfile::Builder::new()
                    .prefix("vmerge-")
                    .tempdir()
                    .map_err(|e| PyRuntimeError::new_err(format!("a scratch folder: {e}")))?;
                Ok((dir.path().join("render.exr"), Some(dir)))
            }
        }
    }

    /// Runs the render on this thread, `on_event` told of every iteration.
    fn run(
        &self,
        flag: &StopFlag,
        observer: Option<&mut dyn Observer>,
        on_event: impl FnMut(RunEvent),
    ) -> Outcome {
        let mut job: RenderJob = match &self.start {
            Start::New(setup) => setup.job(&self.scene)?,
            Start::Continue(film, metadata) => vmerge::render::continued_job(
                &self.scene,
                film.clone(),
                (**metadata).clone(),
                self.output.clone(),
                self.png,
                self.snapshot,
                self.memory_limit,
            )?,
        };
        job.run_observed(self.stop, flag, observer, on_event)?;
        let RenderJob { film, metadata, .. } = job;
        Ok((film, metadata))
    }
}

/// The arguments every render takes beside the options.
struct RunArgs<'py> {
    iterations: Option<u64>,
    time: Option<Bound<'py, PyAny>>,
    cpu_time: Option<Bound<'py, PyAny>>,
    output: Option<PathBuf>,
    png: bool,
    snapshot: Option<Bound<'py, PyAny>>,
    memory_limit: Option<u64>,
}

impl RunArgs<'_> {
    /// The stop, snapshot interval and output, checked as the command line checks them.
    fn checked(
        self,
        earlier_iterations: u64,
    ) -> PyResult<(
        StopAfter,
        Option<Duration>,
        PathBuf,
        Option<tempfile::TempDir>,
    )> {
        let time = duration("time", self.time.as_ref())?;
        let snapshot = duration("snapshot", self.snapshot.as_ref())?;
        let cpu_time = duration("cpu_time", self.cpu_time.as_ref())?;
        vmerge::options::validate_run(self.iterations, time, snapshot).map_err(errors::option)?;
        vmerge::options::validate_cpu_time(cpu_time).map_err(errors::option)?;
        if self.iterations.is_none() && time.is_none() && cpu_time.is_none() {
            return Err(errors::render(vmerge::render::RenderError::NoStop));
        }
        // Any budget beyond iterations and time keeps its default: none.
        #[allow(clippy::needless_update)]
        let stop = StopAfter {
            iterations: self
                .iterations
                .map(|n| earlier_iterations.saturating_add(n)),
            time,
            cpu_time,
            ..StopAfter::default()
        };
        let (output, scratch) = Prepared::output(self.output)?;
        Ok((stop, snapshot, output, scratch))
    }
}

#[allow(clippy::too_many_arguments)]
fn prepare_new(
    py: Python<'_>,
    scene: &PyScene,
    technique: Option<&str>,
    args: RunArgs<'_>,
    reference: Option<PathBuf>,
    traces: Option<&Bound<'_, PyList>>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Prepared> {
    let kwargs = match kwargs {
        Some(k) => k.copy()?,
        None => PyDict::new(py),
    };
    if let Some(t) = technique {
        if kwargs.contains("technique")? {
            return Err(PyTypeError::new_err("technique given twice"));
        }
        kwargs.set_item("technique", t)?;
    }
    let options = crate::options::from_kwargs(Some(&kwargs))?;
    let traces = crate::result::traces_from(traces)?;
    let png = args.png && args.output.is_some();
    let memory_limit = args.memory_limit;
    let (stop, snapshot, output, scratch) = args.checked(0)?;
    // The scene loads with shading normals unless told otherwise; a render without them needs
    // the scene loaded so.
    let loaded = if options.no_shading_normals == scene.shading_normals {
        load(
            py,
            scene.path.clone(),
            scene.lenient,
            scene.accel,
            !options.no_shading_normals,
        )?
        .scene
    } else {
        scene.scene.clone()
    };
    let setup = NewRender {
        scene: scene.path.clone(),
        options,
        accel: scene.accel,
        lenient: scene.lenient,
        output: output.clone(),
        png,
        snapshot_every: snapshot,
        reference,
        traces,
        memory_limit,
    };
    setup.check().map_err(errors::render)?;
    Ok(Prepared {
        scene: loaded,
        start: Start::New(Box::new(setup)),
        output,
        png,
        snapshot,
        memory_limit,
        stop,
        _scratch: scratch,
    })
}

/// A run's warnings as Python warnings.
pub fn warn_all(py: Python<'_>, warnings: &[String]) -> PyResult<()> {
    for w in warnings {
        let message = std::ffi::CString::new(w.replace('\0', " "))
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
        PyErr::warn(
            py,
            &py.get_type::<pyo3::exceptions::PyRuntimeWarning>(),
            &message,
            1,
        )?;
    }
    Ok(())
}

/// The result of a finished run; after Ctrl-C, `Interrupted` carrying it.
fn finish(
    py: Python<'_>,
    outcome: Outcome,
    warnings: &[String],
    interrupt: Option<PyErr>,
) -> PyResult<RenderResult> {
    warn_all(py, warnings)?;
    let (film, metadata) = outcome.map_err(errors::render)?;
    let result = RenderResult::new(film, metadata);
    match interrupt {
        None => Ok(result),
        Some(e) if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) => {
            let iterations = result.film.iterations;
            let err = Interrupted::new_err(format!(
                "stopped after {iterations} iterations; the render so far is in `result`"
            ));
            err.value(py).setattr("result", Py::new(py, result)?)?;
            Err(err)
        }
        // A signal handler of the caller's raised something else: that is what it wants.
        Some(e) => Err(e),
    }
}

/// Runs on this thread with the GIL released, looking for Ctrl-C after every iteration.
fn execute(py: Python<'_>, prepared: Prepared) -> PyResult<RenderResult> {
    let flag = StopFlag::default();
    let mut interrupt = None;
    let mut warnings = Vec::new();
    let outcome = py.detach(|| {
        prepared.run(&flag, None, |event| match event {
            RunEvent::Iteration(_) => {
                if let Err(e) = Python::attach(|py| py.check_signals()) {
                    interrupt = Some(e);
                    flag.store(true, Ordering::SeqCst);
                }
            }
            RunEvent::Warning(w) => warnings.push(w.to_string()),
        })
    });
    finish(py, outcome, &warnings, interrupt)
}

/// Renders `scene` with `technique` for `iterations`, `time` and/or `cpu_time` (seconds, or a text like
/// `'90s'`), every render option of the command line as a keyword (`radius=0.01`,
/// `upg_packet=8`, `resolution=(64, 64)`), validated as the command line validates them.
/// Without `output` nothing stays on disk; with it the render is written there too (and a PNG
/// preview with `png`). Ctrl-C stops at the end of the current iteration and raises
/// `Interrupted`, whose `result` is the render so far.
#[pyfunction]
#[pyo3(signature = (scene, technique = None, *, iterations = None, time = None, cpu_time = None, output = None,
    png = false, reference = None, traces = None, snapshot = None, memory_limit = None,
    **options))]
#[allow(clippy::too_many_arguments)]
pub fn render<'py>(
    py: Python<'py>,
    scene: PyRef<'py, PyScene>,
    technique: Option<&str>,
    iterations: Option<u64>,
    time: Option<Bound<'py, PyAny>>,
    cpu_time: Option<Bound<'py, PyAny>>,
    output: Option<PathBuf>,
    png: bool,
    reference: Option<PathBuf>,
    traces: Option<Bound<'py, PyList>>,
    snapshot: Option<Bound<'py, PyAny>>,
    memory_limit: Option<u64>,
    options: Option<Bound<'py, PyDict>>,
) -> PyResult<RenderResult> {
    let args = RunArgs {
        iterations,
        time,
        cpu_time,
        output,
        png,
        snapshot,
        memory_limit,
    };
    let prepared = prepare_new(
        py,
        &scene,
        technique,
        args,
        reference,
        traces.as_ref(),
        options.as_ref(),
    )?;
    execute(py, prepared)
}

/// The film and metadata of a `Result`, or of the vmerge render at a path.
fn render_of(py: Python<'_>, source: &Bound<'_, PyAny>) -> PyResult<(Film, Metadata)> {
    if let Ok(result) = source.cast::<RenderResult>() {
        let r = result.get();
        return Ok((r.film.clone(), r.metadata.clone()));
    }
    let path: PathBuf = source
        .extract()
        .map_err(|_| PyTypeError::new_err("a vmerge.Result or the path of a vmerge render"))?;
    py.detach(|| vmerge::film::exr::read_render(&path))
        .map_err(errors::film)
}

/// Goes on with a render (a `Result`, or the path of a vmerge EXR) with its scene, options and
/// seed, from its next iteration: `iterations` more, and/or for `time` more. The scene must
/// not have changed since, unless `force`. Written to `output` when given, never over the
/// input unless named so. Ctrl-C as in `render`.
#[pyfunction]
#[pyo3(signature = (render, *, iterations = None, time = None, cpu_time = None, output = None, png = false,
    force = false, accel = None, snapshot = None, memory_limit = None))]
#[allow(clippy::too_many_arguments)]
pub fn continue_render<'py>(
    py: Python<'py>,
    render: Bound<'py, PyAny>,
    iterations: Option<u64>,
    time: Option<Bound<'py, PyAny>>,
    cpu_time: Option<Bound<'py, PyAny>>,
    output: Option<PathBuf>,
    png: bool,
    force: bool,
    accel: Option<&str>,
    snapshot: Option<Bound<'py, PyAny>>,
    memory_limit: Option<u64>,
) -> PyResult<RenderResult> {
    let accel = accel_kind(accel)?;
    let (film, metadata) = render_of(py, &render)?;
    let png = png && output.is_some();
    let args = RunArgs {
        iterations,
        time,
        cpu_time,
        output,
        png,
        snapshot,
        memory_limit,
    };
    let (stop, snapshot, output, scratch) = args.checked(film.iterations)?;
    let scene = py
        .detach(|| vmerge::render::load_for_continue(&metadata, accel, force))
        .map_err(errors::render)?;
    let prepared = Prepared {
        scene: Arc::new(scene),
        start: Start::Continue(film, Box::new(metadata)),
        output,
        png,
        snapshot,
        memory_limit,
        stop,
        _scratch: scratch,
    };
    execute(py, prepared)
}

/// One step of a progressive render: the image so far and the rates.
#[pyclass(name = "Step", module = "vmerge", frozen)]
pub struct Step {
    pixels: Vec<vmerge::color::Rgb>,
    width: u32,
    height: u32,
    #[pyo3(get)]
    iterations: u64,
    /// Render time so far, in seconds.
    #[pyo3(get)]
    seconds: f64,
    /// RMS error against the reference, when one was given and measured at this iteration.
    #[pyo3(get)]
    rmse: Option<f64>,
    #[pyo3(get)]
    samples_per_second: f64,
    #[pyo3(get)]
    rays_per_second: f64,
}

#[pymethods]
impl Step {
    /// The mean radiance so far, float32, shape (height, width, 3).
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        image_array(py, &self.pixels, self.width, self.height)
    }

    fn __repr__(&self) -> String {
        format!(
            "vmerge.Step({} iterations, {:.3} s)",
            self.iterations, self.seconds
        )
    }
}

impl Step {
    fn of(film: &Film, metadata: &Metadata, progress: Option<&Progress>) -> Self {
        Step {
            pixels: film.mean(),
            width: film.width,
            height: film.height,
            iterations: film.iterations,
            seconds: metadata.render_seconds,
            rmse: progress.and_then(|p| p.rmse),
            samples_per_second: progress.map_or(0.0, |p| p.samples_per_second),
            rays_per_second: progress.map_or(0.0, |p| p.rays_per_second),
        }
    }
}

enum Message {
    Step(Box<Step>),
    Done(Box<(Outcome, Vec<String>)>),
}

/// Sends a step every `every` iterations, waiting while the consumer has not taken the last.
struct Stepper {
    every: u64,
    sender: SyncSender<Message>,
}

impl Observer for Stepper {
    fn after_iteration(&mut self, film: &Film, metadata: &Metadata, progress: &Progress) {
        if film.iterations.is_multiple_of(self.every) {
            // A consumer that went away stopped the render too; nothing to tell.
            let _ = self.sender.send(Message::Step(Box::new(Step::of(
                film,
                metadata,
                Some(progress),
            ))));
        }
    }
}

/// An iterator over the steps of a render that runs on a thread of its own; `result` is the
/// finished render once the iterator is exhausted.
#[pyclass(name = "Progressive", module = "vmerge")]
pub struct Progressive {
    receiver: Option<std::sync::Mutex<Receiver<Message>>>,
    thread: Option<JoinHandle<()>>,
    flag: StopFlag,
    last_iterations: u64,
    result: Option<Py<RenderResult>>,
}

impl Progressive {
    fn receive(&self, py: Python<'_>, timeout: Duration) -> Result<Message, RecvTimeoutError> {
        let Some(receiver) = &self.receiver else {
            return Err(RecvTimeoutError::Disconnected);
        };
        py.detach(|| {
            let guard = receiver.lock().unwrap_or_else(|p| p.into_inner());
            guard.recv_timeout(timeout)
        })
    }

    /// Waits for the render's end (skipping steps), then ends the thread.
    fn done(
        &mut self,
        py: Python<'_>,
        message: Message,
        interrupt: Option<PyErr>,
    ) -> PyResult<Option<Step>> {
        let mut message = message;
        loop {
            match message {
                Message::Done(done) => {
                    let (outcome, warnings) = *done;
                    self.receiver = None;
                    if let Some(thread) = self.thread.take() {
                        py.detach(|| thread.join())
                            .map_err(|_| PyRuntimeError::new_err("the render thread failed"))?;
                    }
                    let result = finish(py, outcome, &warnings, interrupt)?;
                    let last = (result.film.iterations != self.last_iterations)
                        .then(|| Step::of(&result.film, &result.metadata, None));
                    self.result = Some(Py::new(py, result)?);
                    return Ok(last);
                }
                Message::Step(_) => {
                    message = self
                        .receive(py, Duration::MAX)
                        .map_err(|_| PyRuntimeError::new_err("the render thread failed"))?;
                }
            }
        }
    }
}

#[pymethods]
impl Progressive {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<Step>> {
        loop {
            if self.receiver.is_none() {
                return Ok(None);
            }
            match self.receive(py, SIGNAL_POLL) {
                Ok(Message::Step(step)) => {
                    self.last_iterations = step.iterations;
                    return Ok(Some(*step));
                }
                Ok(done) => return self.done(py, done, None),
                Err(RecvTimeoutError::Timeout) => {
                    if let Err(e) = py.check_signals() {
                        self.flag.store(true, Ordering::SeqCst);
                        let mut message = self.receive(py, Duration::MAX);
                        // Steps still queued belong to the stopped render.
                        while let Ok(Message::Step(_)) = message {
                            message = self.receive(py, Duration::MAX);
                        }
                        let message = message
                            .map_err(|_| PyRuntimeError::new_err("the render thread failed"))?;
                        return self.done(py, message, Some(e)).map(|_| None);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    self.receiver = None;
                    return Err(PyRuntimeError::new_err("the render thread failed"));
                }
            }
        }
    }

    /// The finished render, once the iterator is exhausted (`None` before).
    #[getter]
    fn result(&self, py: Python<'_>) -> Option<Py<RenderResult>> {
        self.result.as_ref().map(|r| r.clone_ref(py))
    }

    /// Stops the render at the end of its current iteration; the iterator then ends.
    fn stop(&self) {
        self.flag.store(true, Ordering::SeqCst);
    }

    /// Stops the render at the end of its current iteration and returns it: what a loop over
    /// the steps calls after Ctrl-C reached its own code, where a `KeyboardInterrupt` is raised
    /// rather than `Interrupted`.
    fn finish(&mut self, py: Python<'_>) -> PyResult<Py<RenderResult>> {
        self.flag.store(true, Ordering::SeqCst);
        while self.receiver.is_some() {
            self.__next__(py)?;
        }
        self.result
            .as_ref()
            .map(|r| r.clone_ref(py))
            .ok_or_else(|| PyRuntimeError::new_err("the render thread failed"))
    }
}

impl Drop for Progressive {
    fn drop(&mut self) {
        self.flag.store(true, Ordering::SeqCst);
        // Dropping the receiver frees a render waiting to hand over a step.
        self.receiver = None;
        if let Some(thread) = self.thread.take() {
            // A render thread that failed has nothing left to clean up.
            let _ = thread.join();
        }
    }
}

/// `render`, as an iterator that yields a `Step` (the image so far, iterations, time, rates)
/// every `every` iterations and once more at the end where the last iteration was not one of
/// them; the finished render is then the iterator's `result`. The render runs on its own
/// thread, one step ahead of the consumer at most. Ctrl-C while waiting for a step stops it
/// at the end of its iteration and raises `Interrupted` with the render so far.
#[pyfunction]
#[pyo3(signature = (scene, technique = None, *, every = 1, iterations = None, time = None, cpu_time = None,
    output = None, png = false, reference = None, traces = None, snapshot = None,
    memory_limit = None, **options))]
#[allow(clippy::too_many_arguments)]
pub fn render_progressive<'py>(
    py: Python<'py>,
    scene: PyRef<'py, PyScene>,
    technique: Option<&str>,
    every: u64,
    iterations: Option<u64>,
    time: Option<Bound<'py, PyAny>>,
    cpu_time: Option<Bound<'py, PyAny>>,
    output: Option<PathBuf>,
    png: bool,
    reference: Option<PathBuf>,
    traces: Option<Bound<'py, PyList>>,
    snapshot: Option<Bound<'py, PyAny>>,
    memory_limit: Option<u64>,
    options: Option<Bound<'py, PyDict>>,
) -> PyResult<Progressive> {
    if every == 0 {
        return Err(PyValueError::new_err(
            "`every` 0: expected at least 1 iteration",
        ));
    }
    let args = RunArgs {
        iterations,
        time,
        cpu_time,
        output,
        png,
        snapshot,
        memory_limit,
    };
    let prepared = prepare_new(
        py,
        &scene,
        technique,
        args,
        reference,
        traces.as_ref(),
        options.as_ref(),
    )?;
    let flag = StopFlag::default();
    let (sender, receiver) = sync_channel(1);
    let thread_flag = flag.clone();
    let thread = std::thread::Builder::new()
        .name("vmerge-render".into())
        .spawn(move || {
            let mut stepper = Stepper {
                every,
                sender: sender.clone(),
            };
            let mut warnings = Vec::new();
            let outcome = prepared.run(&thread_flag, Some(&mut stepper), |event| {
                if let RunEvent::Warning(w) = event {
                    warnings.push(w.to_string());
                }
            });
            let _ = sender.send(Message::Done(Box::new((outcome, warnings))));
        })
        .map_err(|e| PyRuntimeError::new_err(format!("starting the render thread: {e}")))?;
    Ok(Progressive {
        receiver: Some(std::sync::Mutex::new(receiver)),
        thread: Some(thread),
        flag,
        last_iterations: 0,
        result: None,
    })
}
