//! The `vmerge` command line: parses arguments, calls the library, prints.

use anyhow::{Context, Result};
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, Parser, Subcommand};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use vmerge::accel::AccelKind;
use vmerge::options::{DensityMis, OptionName, RenderOptions, SamplerKind, Technique};

/// The options' defaults, as the library writes them.
const DEFAULT: RenderOptions = RenderOptions::DEFAULT;

#[derive(Parser)]
#[command(
    name = "vmerge",
    version,
    about = "Physically based renderer: PT, BPT, VCM and UPG"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene.
    Render(RenderArgs),
    /// Continue a render from its EXR, with the scene, options and seed recorded in it.
    Continue(ContinueArgs),
    /// Merge renders of the same scene and options (different seeds), weighted by iterations.
    Merge {
        output: PathBuf,
        inputs: Vec<PathBuf>,
    },
    /// Write a plain EXR (RGB only, no vmerge data).
    Bake { output: PathBuf, input: PathBuf },
    /// Drop the error series from a render.
    Strip { output: PathBuf, input: PathBuf },
    /// Write the relative difference |a - b| / b of two images.
    Diff {
        output: PathBuf,
        a: PathBuf,
        b: PathBuf,
    },
    /// Print the mean absolute and RMS error between two images (B the reference).
    Errors {
        a: PathBuf,
        b: PathBuf,
        /// Print the relative MSE, mean of (a - b)^2 / (b^2 + 0.01), instead.
        #[arg(long)]
        relative: bool,
    },
    /// Print the mean RGB of an image.
    Average { input: PathBuf },
    /// Print the render time recorded in a render.
    Time { input: PathBuf },
    /// Print the error series of a render as CSV.
    Measurements { input: PathBuf },
    /// Print the trace windows of a render.
    Traces { input: PathBuf },
    /// Draw convergence charts (PNG or SVG by the output's extension).
    Plot {
        output: PathBuf,
        inputs: Vec<PathBuf>,
        /// One chart per trace window.
        #[arg(long)]
        traces: bool,
        /// The error drawn: mean absolute (mae) or RMS (rmse).
        #[arg(long, value_parser = metric_parser(), default_value = "rmse")]
        metric: Metric,
    },
    /// Serve a page showing renders: exposure, metadata, error chart, split comparison.
    View {
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Where to serve (loopback unless told otherwise).
        #[arg(long, value_name = "ADDR", default_value = vmerge::preview::DEFAULT_ADDRESS)]
        address: SocketAddr,
    },
    /// Run a plan of renders (or print its cells' commands), show its state, write its report.
    Batch(BatchArgs),
}

/// `--preview [ADDR]`: a live page of the render at ADDR (default: loopback, any free port).
#[derive(Args)]
struct PreviewArg {
    /// Serve a live page of the render (default 127.0.0.1:0: loopback, a free port; the URL is printed).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = vmerge::preview::DEFAULT_ADDRESS)]
    preview: Option<SocketAddr>,
}

#[derive(Args)]
struct RenderArgs {
    /// The scene file: TOML, or pbrt-v4 (`.pbrt`).
    scene: PathBuf,
    #[arg(long, short = 't', value_parser = technique_parser(), default_value = DEFAULT.technique.name())]
    technique: Technique,
    /// Stop after N iterations (one sample per pixel each).
    #[arg(long, short = 'n')]
    iterations: Option<u64>,
    /// Stop after this time (e.g. 90s, 10m, 2h).
    #[arg(long, value_parser = vmerge::options::parse_duration)]
    time: Option<Duration>,
    /// Output EXR; a PNG preview is written next to it.
    #[arg(long, short = 'o', default_value = "render.exr")]
    output: PathBuf,
    #[arg(long, default_value_t = DEFAULT.seed)]
    seed: u64,
    /// Worker threads (default: all cores); the image does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Camera name or index.
    #[arg(long)]
    camera: Option<String>,
    /// WxH, e.g. 512x512.
    #[arg(long, value_parser = parse_resolution)]
    resolution: Option<[u32; 2]>,
    #[arg(long, value_parser = accel_parser(), default_value = AccelKind::default_kind().name())]
    accel: AccelKind,
    /// Reference image: record the error series in the output.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Error window XxYxW: centre (X, Y), half-width W (repeatable; needs --reference).
    #[arg(long = "trace", value_parser = parse_trace)]
    traces: Vec<vmerge::film::TraceWindow>,
    /// Write the image every interval (e.g. 10m).
    #[arg(long, value_parser = vmerge::options::parse_duration)]
    snapshot: Option<Duration>,
    /// Do not write the PNG preview.
    #[arg(long)]
    no_png: bool,
    /// Clamp Phong materials with kd + ks > 1 instead of rejecting the scene.
    #[arg(long)]
    lenient: bool,
    /// The memory the render may use, e.g. 8G (default: what the machine has available).
    #[arg(long, value_parser = vmerge::memory::parse_size)]
    memory_limit: Option<u64>,
    #[command(flatten)]
    preview: PreviewArg,
    #[command(flatten)]
    technique_options: TechniqueArgs,
}

#[derive(Args)]
struct TechniqueArgs {
    /// MIS power (2 = power heuristic, 1 = balance heuristic).
    #[arg(long, default_value_t = DEFAULT.beta)]
    beta: f32,
    /// Merge radius in world units (default: 0.003 x the scene's bounding-sphere diameter).
    #[arg(long)]
    radius: Option<f32>,
    /// Radius shrinking exponent r_i = r_1 sqrt(i^(alpha-1)) (default 0.75 for vcm, ppm, bpm).
    #[arg(long)]
    alpha: Option<f32>,
    /// Segments of a full path, light to eye; 0 = unbounded (default: the scene's).
    #[arg(long)]
    max_path_length: Option<u32>,
    /// Path length in segments from which Russian roulette may end paths.
    #[arg(long, default_value_t = DEFAULT.roulette)]
    roulette: u32,
    /// Vertex merging only (vcm).
    #[arg(long)]
    no_vc: bool,
    /// Vertex connection only (vcm).
    #[arg(long)]
    no_vm: bool,
    /// Render every triangle flat, ignoring the meshes' vertex normals.
    #[arg(long)]
    no_shading_normals: bool,
    /// bpt: render only the technique with S light and T eye vertices (T counts the camera).
    #[arg(long, value_name = "S,T", value_parser = parse_strategy)]
    strategy: Option<[u32; 2]>,
    /// bpt: leave out the MIS weights (with --strategy: one technique's full estimate).
    #[arg(long)]
    unweighted: bool,
    /// upg, upg-camera: trace tentative rays 1 or 8 at a time.
    #[arg(long, default_value_t = DEFAULT.upg_packet)]
    upg_packet: u32,
    /// upg, upg-camera: trials after which a merge is dropped (and counted).
    #[arg(long, default_value_t = DEFAULT.upg_max_trials)]
    upg_max_trials: u32,
    /// vcm, bpm: weigh merges by the density of light vertices (002's VCM+ or VCM*).
    #[arg(long, value_parser = density_mis_parser())]
    density_mis: Option<DensityMis>,
    /// vcm, bpm: iterations whose light vertices fill the density map.
    #[arg(long, default_value_t = DEFAULT.density_map_iterations)]
    density_map_iterations: u32,
    /// Light sub-paths per iteration, n_VM (default: one per pixel).
    #[arg(long)]
    light_paths: Option<u32>,
    /// Leave out paths of fewer segments (3 drops direct light).
    #[arg(long, default_value_t = DEFAULT.min_path_length)]
    min_path_length: u32,
    /// The numbers sub-paths are built from.
    #[arg(long, value_parser = sampler_parser(), default_value = DEFAULT.sampler.name())]
    sampler: SamplerKind,
}

#[derive(Args)]
struct ContinueArgs {
    /// A render written by `vmerge render` (or a snapshot of one).
    input: PathBuf,
    /// Render N more iterations.
    #[arg(long, short = 'n')]
    iterations: Option<u64>,
    /// Render for this much more time.
    #[arg(long, value_parser = vmerge::options::parse_duration)]
    time: Option<Duration>,
    /// Where to write (default: over the input).
    #[arg(long, short = 'o')]
    output: Option<PathBuf>,
    /// Continue although the scene files changed since the render began.
    #[arg(long)]
    force: bool,
    #[arg(long)]
    threads: Option<usize>,
    #[arg(long, value_parser = accel_parser(), default_value = AccelKind::default_kind().name())]
    accel: AccelKind,
    #[arg(long, value_parser = vmerge::options::parse_duration)]
    snapshot: Option<Duration>,
    #[arg(long)]
    no_png: bool,
    /// The memory the render may use, e.g. 8G (default: what the machine has available).
    #[arg(long, value_parser = vmerge::memory::parse_size)]
    memory_limit: Option<u64>,
    #[command(flatten)]
    preview: PreviewArg,
}

/// A parser of one of `all` by its name, with the descriptions in `--help`.
fn by_name<T: Copy + Send + Sync + 'static, const N: usize>(
    all: [T; N],
    name: fn(T) -> &'static str,
    description: fn(T) -> &'static str,
    unknown: &'static str,
) -> impl TypedValueParser<Value = T> {
    let names = all.map(|t| PossibleValue::new(name(t)).help(description(t)));
    PossibleValuesParser::new(names)
        .try_map(move |given| all.into_iter().find(|&t| name(t) == given).ok_or(unknown))
}

fn technique_parser() -> impl TypedValueParser<Value = Technique> {
    by_name(
        Technique::ALL,
        Technique::name,
        Technique::description,
        "no such technique",
    )
}

/// 002's heuristics.
fn density_mis_parser() -> impl TypedValueParser<Value = DensityMis> {
    by_name(
        DensityMis::ALL,
        DensityMis::name,
        DensityMis::description,
        "no such heuristic",
    )
}

fn sampler_parser() -> impl TypedValueParser<Value = SamplerKind> {
    by_name(
        SamplerKind::ALL,
        SamplerKind::name,
        SamplerKind::description,
        "no such sampler",
    )
}

/// The ray-query backends.
fn accel_parser() -> impl TypedValueParser<Value = AccelKind> {
    by_name(
        AccelKind::ALL,
        AccelKind::name,
        AccelKind::description,
        "no such backend",
    )
}

fn parse_resolution(s: &str) -> Result<[u32; 2], String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("'{s}' is not WxH"))?;
    let w: u32 = w.parse().map_err(|_| format!("'{s}' is not WxH"))?;
    let h: u32 = h.parse().map_err(|_| format!("'{s}' is not WxH"))?;
    if w == 0 || h == 0 {
        return Err(format!("'{s}' has a zero side"));
    }
    Ok([w, h])
}

fn parse_strategy(s: &str) -> Result<[u32; 2], String> {
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .map_err(|_| format!("'{s}': expected S,T (two whole numbers)"))
    };
    match s.split_once(',') {
        Some((a, b)) => Ok([parse(a)?, parse(b)?]),
        None => Err(format!("'{s}': expected S,T (two whole numbers)")),
    }
}

fn parse_trace(s: &str) -> Result<vmerge::film::TraceWindow, String> {
    s.parse()
}

fn main() -> ExitCode {
    OptionName::spell_as_flags();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            // Bad input (scenes, files, options) is exit code 2; anything else 1.
            if is_input_error(&e) {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    use vmerge::tools;
    match cli.command {
        Command::Render(args) => render(args),
        Command::Continue(args) => resume(args),
        Command::Merge { output, inputs } => Ok(tools::merge(&output, &inputs)?),
        Command::Bake { output, input } => Ok(tools::bake(&output, &input)?),
        Command::Strip { output, input } => Ok(tools::strip(&output, &input)?),
        Command::Diff { output, a, b } => Ok(tools::diff(&output, &a, &b)?),
        Command::Errors { a, b, relative } => {
            if relative {
                println!("{}", tools::relative_mse(&a, &b)?);
            } else {
                let (mae, rmse) = tools::errors(&a, &b)?;
                println!("{mae} {rmse}");
            }
            Ok(())
        }
        Command::Average { input } => {
            let [r, g, b] = tools::average(&input)?;
            println!("{r} {g} {b}");
            Ok(())
        }
        Command::Time { input } => {
            println!("{}", tools::metadata(&input)?.render_seconds);
            Ok(())
        }
        Command::Measurements { input } => {
            print!("{}", tools::measurements(&input)?);
            Ok(())
        }
        Command::Traces { input } => {
            for t in tools::traces(&input)? {
                println!("{}x{}x{}", t.x, t.y, t.half_width);
            }
            Ok(())
        }
        Command::Plot {
            output,
            inputs,
            traces,
            metric,
        } => Ok(tools::plot(&output, &inputs, traces, metric)?),
        Command::View { files, address } => view(&files, address),
        Command::Batch(args) => batch(args),
    }
}

fn set_threads(threads: Option<usize>) -> Result<()> {
    if let Some(n) = threads {
        vmerge::options::validate_threads(n)?;
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .context("setting the thread count")?;
    }
    Ok(())
}

fn render(args: RenderArgs) -> Result<()> {
    vmerge::options::validate_run(args.iterations, args.time, args.snapshot)?;
    set_threads(args.threads)?;
    let t = args.technique_options;
    let options = RenderOptions {
        technique: args.technique,
        seed: args.seed,
        camera: args.camera,
        resolution: args.resolution,
        beta: t.beta,
        radius: t.radius,
        alpha: t.alpha,
        max_path_length: t.max_path_length,
        roulette: t.roulette,
        no_vc: t.no_vc,
        no_vm: t.no_vm,
        strategy: t.strategy,
        unweighted: t.unweighted,
        upg_packet: t.upg_packet,
        upg_max_trials: t.upg_max_trials,
        density_mis: t.density_mis,
        density_map_iterations: t.density_map_iterations,
        no_shading_normals: t.no_shading_normals,
        light_paths: t.light_paths,
        min_path_length: t.min_path_length,
        sampler: t.sampler,
    };
    let setup = vmerge::render::NewRender {
        scene: args.scene,
        options,
        accel: args.accel,
        lenient: args.lenient,
        output: args.output,
        png: !args.no_png,
        snapshot_every: args.snapshot,
        reference: args.reference,
        traces: args.traces,
        memory_limit: args.memory_limit,
    };
    let stop = StopAfter {
        iterations: args.iterations,
        time: args.time,
    };
    if stop.iterations.is_none() && stop.time.is_none() {
        anyhow::bail!(vmerge::render::RenderError::NoStop);
    }
    // Checked again by the library; here before the scene loads, so a mistake costs nothing.
    setup.check()?;
    let loading = std::time::Instant::now();
    let scene = setup.load_scene()?;
    print_warnings(&scene);
    eprintln!(
        "loaded {} in {:.2} s ({} triangles, {} spheres, {} lights)",
        scene.source.display(),
        loading.elapsed().as_secs_f64(),
        scene.geometry.triangles.len(),
        scene.geometry.spheres.len(),
        scene.lights.len()
    );
    let job = setup.job(&scene)?;
    run_job(job, stop, args.preview.preview)
}

/// The load's warnings, one line each on stderr.
fn print_warnings(scene: &vmerge::scene::Scene) {
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
}

fn resume(args: ContinueArgs) -> Result<()> {
    vmerge::options::validate_run(args.iterations, args.time, args.snapshot)?;
    set_threads(args.threads)?;
    let (film, metadata) = vmerge::film::exr::read_render(&args.input)?;
    let scene = vmerge::render::load_for_continue(&metadata, args.accel, args.force)?;
    print_warnings(&scene);
    let output = args.output.unwrap_or(args.input);
    let job = vmerge::render::continued_job(
        &scene,
        film,
        metadata,
        output,
        !args.no_png,
        args.snapshot,
        args.memory_limit,
    )?;
    let stop = StopAfter {
        // The library refuses a total beyond its limit, which saturating keeps above it.
        iterations: args
            .iterations
            .map(|n| job.film.iterations.saturating_add(n)),
        time: args.time,
    };
    if stop.iterations.is_none() && stop.time.is_none() {
        anyhow::bail!(vmerge::render::RenderError::NoStop);
    }
    run_job(job, stop, args.preview.preview)
}

use vmerge::render::{RenderJob, StopAfter};

fn view(files: &[PathBuf], address: SocketAddr) -> Result<()> {
    let viewer = vmerge::preview::Viewer::load(files)?;
    let server = viewer.serve(address)?;
    let (stop, stopped) = std::sync::mpsc::channel();
    ctrlc::set_handler(move || {
        // The receiver lives until main returns.
        let _ = stop.send(());
    })
    .context("installing the signal handler")?;
    eprintln!("view at http://{}/ (Ctrl-C stops)", server.address());
    // Either a signal, or the handler is gone: stop in both cases.
    let _ = stopped.recv();
    Ok(())
}

/// A stop flag raised by the first Ctrl-C or termination signal, so the render (or the batch's
/// current cell) finishes its iteration and writes its image; a second signal quits at once.
fn stop_on_signal() -> Result<vmerge::render::StopFlag> {
    let flag = vmerge::render::StopFlag::default();
    let handler_flag = flag.clone();
    ctrlc::set_handler(move || {
        if handler_flag.swap(true, std::sync::atomic::Ordering::SeqCst) {
            std::process::exit(130);
        }
    })
    .context("installing the signal handler")?;
    Ok(flag)
}

fn run_job(mut job: RenderJob, stop: StopAfter, preview: Option<SocketAddr>) -> Result<()> {
    let flag = stop_on_signal()?;
    let bar = indicatif::ProgressBar::new(stop.iterations.unwrap_or(0));
    bar.set_style(
        indicatif::ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos} it {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut preview = preview
        .map(|address| vmerge::preview::LivePreview::start(address, &job, stop))
        .transpose()?;
    if let Some(p) = &preview {
        eprintln!("preview at http://{}/", p.address());
    }
    let observer = preview
        .as_mut()
        .map(|p| p as &mut dyn vmerge::render::Observer);
    job.run_observed(stop, &flag, observer, |p| {
        bar.set_position(p.iterations);
        let mut msg = format!(
            "{:.2} Msamples/s, {:.2} Mrays/s",
            p.samples_per_second / 1e6,
            p.rays_per_second / 1e6
        );
        if let Some(rmse) = p.rmse {
            msg.push_str(&format!(", rmse {rmse:.4e}"));
        }
        if p.upg.merges > 0 {
            let seconds = p.elapsed.as_secs_f64().max(1e-9);
            msg.push_str(&format!(
                ", upg {:.2} trials/merge, {:.2} Mmerges/s, {:.2} Mtentative rays/s, {} capped",
                p.upg.trials as f64 / p.upg.merges as f64,
                p.upg.merges as f64 / seconds / 1e6,
                p.upg.tentative_rays as f64 / seconds / 1e6,
                p.upg.capped
            ));
        }
        bar.set_message(msg);
    })?;
    // The page stops with the render.
    drop(preview);
    bar.finish();
    eprintln!(
        "wrote {} ({} iterations, {:.1} s{})",
        job.output.display(),
        job.film.iterations,
        job.metadata.render_seconds,
        if job.metadata.dropped_samples > 0 {
            format!(
                ", {} non-finite samples dropped",
                job.metadata.dropped_samples
            )
        } else {
            String::new()
        }
    );
    Ok(())
}

/// Whether an error is the user's input (a scene, a file, an option) rather than the system.
fn is_input_error(e: &anyhow::Error) -> bool {
    use vmerge::film::FilmError;
    use vmerge::options::OptionError;
    use vmerge::render::RenderError;
    let film = |f: &FilmError| !matches!(f, FilmError::Write { .. });
    e.chain().any(|cause| {
        if let Some(f) = cause.downcast_ref::<FilmError>() {
            film(f)
        } else if let Some(r) = cause.downcast_ref::<RenderError>() {
            match r {
                RenderError::Film(f) => film(f),
                // The system failed to take the image, not the user's input.
                RenderError::WrittenElsewhere { .. } | RenderError::Lost { .. } => false,
                _ => true,
            }
        } else if let Some(b) = cause.downcast_ref::<vmerge::tools::batch::BatchError>() {
            b.is_input()
        } else {
            cause.downcast_ref::<vmerge::scene::SceneError>().is_some()
                || cause.downcast_ref::<OptionError>().is_some()
                || cause.downcast_ref::<vmerge::files::FileError>().is_some()
                || cause
                    .downcast_ref::<vmerge::memory::MemoryError>()
                    .is_some()
        }
    })
}

// `vmerge batch`: plans of renders (src/tools/batch).

use vmerge::tools::batch::{self, Plan};
use vmerge::tools::Metric;

#[derive(Args)]
#[command(args_conflicts_with_subcommands = true, arg_required_else_help = true)]
struct BatchArgs {
    #[command(subcommand)]
    command: Option<BatchCommand>,
    /// The plan (TOML): run every cell that needs it, references first.
    plan: Option<PathBuf>,
    /// List what would run, without running it.
    #[arg(long)]
    dry_run: bool,
    /// Print one shell command per cell that can run now (for parallel -j N or xargs -P N);
    /// run them, then ask again until nothing is printed.
    #[arg(long, conflicts_with_all = ["dry_run", "slurm"])]
    jobs: bool,
    /// Write an sbatch --array script with one array task per cell that can run now.
    #[arg(long, value_name = "FILE", conflicts_with = "dry_run")]
    slurm: Option<PathBuf>,
    #[arg(long, value_parser = accel_parser(), default_value = AccelKind::default_kind().name())]
    accel: AccelKind,
}

#[derive(Subcommand)]
enum BatchCommand {
    /// Show each cell: done, partial, missing or stale.
    Status { plan: PathBuf },
    /// Write OUTPUT/report/index.html (thumbnails, tables, charts) from the cells that exist.
    Report { plan: PathBuf },
}

fn metric_parser() -> impl TypedValueParser<Value = Metric> {
    by_name(Metric::ALL, Metric::name, Metric::label, "no such metric")
}

fn batch(args: BatchArgs) -> Result<()> {
    let program = std::env::current_exe().context("finding the vmerge executable")?;
    match (args.command, args.plan) {
        (Some(BatchCommand::Status { plan }), _) => {
            print!("{}", batch::status(&Plan::load(&plan)?))
        }
        (Some(BatchCommand::Report { plan }), _) => {
            let index = batch::report(&Plan::load(&plan)?)?;
            eprintln!("wrote {}", index.display());
        }
        (None, None) => anyhow::bail!("say which plan: vmerge batch PLAN.toml"),
        (None, Some(file)) => {
            let plan = Plan::load(&file)?;
            if args.dry_run {
                print!("{}", batch::dry_run(&plan));
            } else if args.jobs {
                let (lines, later) = batch::jobs(&plan, &program)?;
                for line in &lines {
                    println!("{line}");
                }
                if later > 0 {
                    eprintln!("{later} more cells wait for these; ask again once they are done");
                }
            } else if let Some(script) = args.slurm {
                let (tasks, later) = batch::slurm(&plan, &program, &script)?;
                eprintln!("wrote {} ({tasks} array tasks)", script.display());
                if later > 0 {
                    eprintln!("{later} more cells wait for these; write the script again once they are done");
                }
            } else {
                set_threads(plan.threads)?;
                let flag = stop_on_signal()?;
                let mut bar = batch::ProgressBar::default();
                let ran = batch::run(&plan, args.accel, &flag, &mut |e| match e {
                    batch::Event::Warning(w) => bar.suspend(|| eprintln!("warning: {w}")),
                    _ => bar.show(e),
                })?;
                bar.finish();
                eprintln!("{ran} cells rendered");
            }
        }
    }
    Ok(())
}
