//! The live preview of a running render: the render's thread copies the film's sums between
//! iterations (at most a few times a second), a thread of its own converts them for the page.

use super::server::{Content, Server, StateQuery};
use super::{error_rows, ImageData, PreviewError};
use crate::film::{Film, Metadata};
use crate::integrator::upg::UpgCounters;
use crate::render::{Observer, Progress, RenderJob, StopAfter};
use serde::Serialize;
use std::net::SocketAddr;
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// How long `/state?since=F` waits for a newer frame before it answers anyway.
pub(crate) const LONG_POLL: Duration = Duration::from_secs(1);

/// The shortest time between two copies of the film: a few updates a second.
const MIN_INTERVAL: Duration = Duration::from_millis(250);

/// Between two copies at least this many times the last copy's duration passes, so that
/// copying a huge film costs at most 1% of the render's time.
const COPY_SHARE: u32 = 100;

/// The progress as the page shows it; times in seconds.
#[derive(Clone, Debug, Default, Serialize)]
struct ProgressView {
    iteration: u64,
    elapsed: f64,
    remaining: Option<f64>,
    samples_per_second: f64,
    rays_per_second: f64,
    upg_merges_per_second: Option<f64>,
    upg_tentative_rays_per_second: Option<f64>,
    /// The share of UPG's merges gathered from the camera side (`upg-hybrid` splits them).
    upg_camera_side_share: Option<f64>,
}

/// What the render's thread hands the converting thread.
struct Snapshot {
    sum: Vec<[f64; 3]>,
    iterations: u64,
    progress: ProgressView,
    new_errors: Vec<[f64; 4]>,
}

#[derive(Default)]
struct State {
    /// Counts the images published; the page asks for newer ones.
    frame: u64,
    image: Option<ImageData>,
    progress: ProgressView,
    errors: Vec<[f64; 4]>,
    finished: bool,
}

struct Live {
    state: Mutex<State>,
    changed: Condvar,
    title: String,
    info: Vec<(String, String)>,
    width: u32,
    height: u32,
    reference: Option<ImageData>,
}

impl Live {
    fn lock(&self) -> MutexGuard<'_, State> {
        // A panic elsewhere leaves the state readable: every update is a whole assignment.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl Content for Live {
    fn state(&self, query: StateQuery) -> String {
        let mut state = self.lock();
        if let Some(since) = query.since {
            let deadline = Instant::now() + LONG_POLL;
            while state.frame <= since && !state.finished {
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    break;
                }
                state = self
                    .changed
                    .wait_timeout(state, left)
                    .unwrap_or_else(PoisonError::into_inner)
                    .0;
            }
        }
        let mut images = vec![serde_json::json!({
            "name": "render",
            "iteration": state.image.as_ref().map(|i| i.iteration),
        })];
        if self.reference.is_some() {
            images.push(serde_json::json!({ "name": "reference", "iteration": null }));
        }
        let from = query.errors_from.min(state.errors.len());
        serde_json::json!({
            "mode": "render",
            "title": self.title,
            "frame": state.frame,
            "finished": state.finished,
            "width": self.width,
            "height": self.height,
            "progress": state.progress,
            "info": [{ "name": "render", "rows": self.info }],
            "images": images,
            "reference": self.reference.as_ref().map(|_| 1),
            "series": [{ "name": "render", "from": from, "rows": state.errors[from..] }],
        })
        .to_string()
    }

    fn image(&self, index: usize) -> Option<ImageData> {
        match index {
            0 => self.lock().image.clone(),
            1 => self.reference.clone(),
            _ => None,
        }
    }
}

/// The live preview of one render: serves the page while it lives, and is told of every
/// iteration as the render's [`Observer`]. Dropping it stops the server.
pub struct LivePreview {
    server: Server,
    live: Arc<Live>,
    snapshots: Option<Sender<Snapshot>>,
    returned: Receiver<Vec<[f64; 3]>>,
    buffer: Option<Vec<[f64; 3]>>,
    converter: Option<JoinHandle<()>>,
    next_copy: Instant,
    errors_sent: usize,
    stop: StopAfter,
    start_iterations: u64,
}

impl LivePreview {
    /// Serves the page of `job` (which is about to run until `stop`) at `address`.
    pub fn start(
        address: SocketAddr,
        job: &RenderJob,
        stop: StopAfter,
    ) -> Result<Self, PreviewError> {
        let (width, height) = (job.film.width, job.film.height);
        let reference = job.tracker.as_ref().map(|t| {
            let r = t.reference();
            ImageData::from_rgb(r.width, r.height, 0, &r.pixels)
        });
        let live = Arc::new(Live {
            state: Mutex::new(State {
                errors: error_rows(&job.metadata.errors),
                ..State::default()
            }),
            changed: Condvar::new(),
            title: title(&job.metadata),
            info: info(&job.metadata, stop, width, height),
            width,
            height,
            reference,
        });
        let server = Server::start(address, live.clone())?;
        let (snapshots, received) = mpsc::channel::<Snapshot>();
        let (give_back, returned) = mpsc::channel();
        let converting = live.clone();
        let converter = std::thread::Builder::new()
            .name("preview-convert".into())
            .spawn(move || {
                for snapshot in received {
                    let image =
                        ImageData::from_sums(width, height, snapshot.iterations, &snapshot.sum);
                    // The render may have finished and stopped taking buffers back.
                    let _ = give_back.send(snapshot.sum);
                    let mut state = converting.lock();
                    state.frame += 1;
                    state.image = Some(image);
                    state.progress = snapshot.progress;
                    state.errors.extend(snapshot.new_errors);
                    drop(state);
                    converting.changed.notify_all();
                }
            })
            .map_err(|e| PreviewError::Bind {
                address,
                message: format!("cannot start a thread: {e}"),
            })?;
        Ok(LivePreview {
            server,
            live,
            snapshots: Some(snapshots),
            returned,
            buffer: Some(Vec::with_capacity(job.film.pixel_count())),
            converter: Some(converter),
            next_copy: Instant::now(),
            errors_sent: job.metadata.errors.len(),
            stop,
            start_iterations: job.film.iterations,
        })
    }

    /// Where the page is served.
    pub fn address(&self) -> SocketAddr {
        self.server.address()
    }

    /// A warning for the user when the page is reachable from other machines (see
    /// [`Server::warning`]).
    pub fn warning(&self) -> Option<String> {
        self.server.warning()
    }

    fn progress_view(&self, progress: &Progress) -> ProgressView {
        let elapsed = progress.elapsed.as_secs_f64();
        let here = progress
            .iterations
            .saturating_sub(self.start_iterations)
            .max(1);
        let by_iterations = self
            .stop
            .iterations
            .map(|n| n.saturating_sub(progress.iterations) as f64 * elapsed / here as f64);
        let by_time = self.stop.time.map(|t| (t.as_secs_f64() - elapsed).max(0.0));
        let remaining = match (by_iterations, by_time) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        let seconds = elapsed.max(1e-9);
        let upg = UpgCounters::from_named(&progress.counters);
        ProgressView {
            iteration: progress.iterations,
            elapsed,
            remaining,
            samples_per_second: progress.samples_per_second,
            rays_per_second: progress.rays_per_second,
            upg_merges_per_second: upg.map(|u| u.merges as f64 / seconds),
            upg_tentative_rays_per_second: upg.map(|u| u.tentative_rays as f64 / seconds),
            upg_camera_side_share: upg.map(|u| u.camera_merges as f64 / u.merges as f64),
        }
    }
}

impl Observer for LivePreview {
    fn after_iteration(&mut self, film: &Film, metadata: &Metadata, progress: &Progress) {
        let now = Instant::now();
        if now < self.next_copy {
            return;
        }
        // No buffer back yet: the converter is still at the last copy, so skip this one.
        let Some(mut sum) = self.buffer.take().or_else(|| self.returned.try_recv().ok()) else {
            return;
        };
        sum.clear();
        sum.extend_from_slice(&film.sum);
        let new_errors = error_rows(metadata.errors.get(self.errors_sent..).unwrap_or_default());
        self.errors_sent = metadata.errors.len();
        let snapshot = Snapshot {
            sum,
            iterations: film.iterations,
            progress: self.progress_view(progress),
            new_errors,
        };
        if let Some(snapshots) = &self.snapshots {
            // The converter only ends when this preview drops the sender.
            let _ = snapshots.send(snapshot);
        }
        self.next_copy = now + MIN_INTERVAL.max(now.elapsed() * COPY_SHARE);
    }
}

impl Drop for LivePreview {
    fn drop(&mut self) {
        self.snapshots = None;
        if let Some(converter) = self.converter.take() {
            // A converter that panicked has nothing left to clean up.
            let _ = converter.join();
        }
        self.live.lock().finished = true;
        self.live.changed.notify_all();
        // `server` drops after this, which stops the workers and closes the port.
    }
}

/// The page's title: the scene's folder (scene files are mostly `scene.toml`) and technique.
fn title(metadata: &Metadata) -> String {
    let path = std::path::Path::new(&metadata.scene);
    let name = path
        .parent()
        .and_then(|p| p.file_name())
        .or_else(|| path.file_name())
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| metadata.scene.clone());
    format!("{name} · {}", metadata.technique().name())
}

/// The options and scene as rows of the page's table.
fn info(metadata: &Metadata, stop: StopAfter, width: u32, height: u32) -> Vec<(String, String)> {
    let mut rows = vec![
        ("scene".to_string(), metadata.scene.clone()),
        ("resolution".into(), format!("{width}x{height}")),
        ("accel".into(), metadata.accel.clone()),
        ("threads".into(), rayon::current_num_threads().to_string()),
    ];
    let mut until = Vec::new();
    if let Some(n) = stop.iterations {
        until.push(format!("{n} iterations"));
    }
    if let Some(t) = stop.time {
        until.push(format!("{:.0} s", t.as_secs_f64()));
    }
    if let Some(t) = stop.cpu_time {
        until.push(format!("{:.0} CPU s", t.as_secs_f64()));
    }
    rows.push(("stop after".into(), until.join(" or ")));
    if let Some(reference) = &metadata.reference {
        rows.push(("reference".into(), reference.clone()));
    }
    if let Ok(serde_json::Value::Object(options)) = serde_json::to_value(&metadata.options) {
        for (name, value) in options {
            if name == "resolution" {
                // The row above has the resolution in use, the option may say "default".
                continue;
            }
            let text = match value {
                serde_json::Value::Null => "default".to_string(),
                serde_json::Value::String(s) => s,
                other => other.to_string(),
            };
            rows.push((name, text));
        }
    }
    rows
}
