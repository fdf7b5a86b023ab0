//! The `vmerge` command line: parses arguments, calls the library, prints.

use anyhow::{Context, Result};
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Arg, ArgAction, ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use vmerge::accel::AccelKind;
use vmerge::options::{Form, OptionSpec, RenderOptions, OPTIONS, SWITCH_ON};

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
    /// Print the error measures of image A against the reference B, one `name value` line
    /// each: mean absolute and RMS error, relative MSE, LDR-FLIP and HDR-FLIP, SSIM (the last
    /// three need images of at least 11x11 pixels).
    Errors {
        a: PathBuf,
        b: PathBuf,
        /// Print only these measures' values, on one line in the order given (repeatable; `-`
        /// for one the images are too small for).
        #[arg(long, value_parser = measure_parser())]
        measure: Vec<Measure>,
        /// Print only the relative MSE, mean of (a - b)^2 / (b^2 + 0.01): `--measure relmse`.
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
    /// Stop after N iterations (one sample per pixel each).
    #[arg(long, short = 'n')]
    iterations: Option<u64>,
    /// Stop after this time (e.g. 90s, 10m, 2h).
    #[arg(long, value_parser = vmerge::options::parse_duration)]
    time: Option<Duration>,
    /// Output EXR; a PNG preview is written next to it.
    #[arg(long, short = 'o', default_value = "render.exr")]
    output: PathBuf,
    /// Worker threads (default: all cores); the image does not depend on it.
    #[arg(long)]
    threads: Option<usize>,
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
    /// Accept a scene with flaws, each with a warning, instead of rejecting it: Phong materials
    /// with kd + ks > 1 are scaled down, missing textures leave their material's constant,
    /// missing meshes are skipped and a missing sky image gives a constant sky.
    #[arg(long)]
    lenient: bool,
    /// The memory the render may use, e.g. 8G (default: what the machine has available).
    #[arg(long, value_parser = vmerge::memory::parse_size)]
    memory_limit: Option<u64>,
    #[command(flatten)]
    preview: PreviewArg,
    #[command(flatten)]
    options: OptionArgs,
}

/// The render options, one argument per row of the library's table ([`OPTIONS`]): its flag,
/// value name, help, default and accepted values; the values are read by the table's reader.
struct OptionArgs(RenderOptions);

fn option_arg(spec: &'static OptionSpec) -> Arg {
    let mut arg = Arg::new(spec.name).long(spec.name.replace('_', "-"));
    if let Some(c) = spec.short {
        arg = arg.short(c);
    }
    if !spec.help.is_empty() {
        arg = arg.help(spec.help_text());
    }
    match spec.form {
        Form::Switch => arg.action(ArgAction::SetTrue),
        Form::Value {
            value_name,
            choices,
        } => {
            arg = arg.value_name(value_name).action(ArgAction::Set);
            if let Some(default) = spec.default_value() {
                arg = arg.default_value(default);
            }
            match choices {
                Some(choices) => arg.value_parser(PossibleValuesParser::new(
                    choices()
                        .into_iter()
                        .map(|(n, d)| PossibleValue::new(n).help(d)),
                )),
                None => arg.value_parser(move |s: &str| {
                    let mut scratch = RenderOptions::DEFAULT;
                    (spec.parse)(&mut scratch, s).map(|()| s.to_string())
                }),
            }
        }
    }
}

impl Args for OptionArgs {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        OPTIONS
            .iter()
            .fold(cmd, |cmd, spec| cmd.arg(option_arg(spec)))
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

impl FromArgMatches for OptionArgs {
    fn from_arg_matches(matches: &ArgMatches) -> Result<Self, clap::Error> {
        let mut options = OptionArgs(RenderOptions::DEFAULT);
        options.update_from_arg_matches(matches)?;
        Ok(options)
    }

    fn update_from_arg_matches(&mut self, matches: &ArgMatches) -> Result<(), clap::Error> {
        for spec in OPTIONS {
            let value = match spec.form {
                Form::Switch => matches.get_flag(spec.name).then_some(SWITCH_ON),
                Form::Value { .. } => matches.get_one::<String>(spec.name).map(String::as_str),
            };
            if let Some(value) = value {
                spec.read(&mut self.0, value).map_err(|e| {
                    clap::Error::raw(
                        clap::error::ErrorKind::ValueValidation,
                        with_flags(&e.to_string()),
                    )
                })?;
            }
        }
        Ok(())
    }
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

/// The ray-query backends.
fn accel_parser() -> impl TypedValueParser<Value = AccelKind> {
    by_name(
        AccelKind::ALL,
        AccelKind::name,
        AccelKind::description,
        "no such backend",
    )
}

fn parse_trace(s: &str) -> Result<vmerge::film::TraceWindow, String> {
    s.parse()
}

/// A library message as the command line writes it: option names as flags (`--upg-packet`
/// for the library's `` `upg_packet` ``), where the command line has such a flag.
fn with_flags(message: &str) -> String {
    fn longs(cmd: &clap::Command, found: &mut Vec<String>) {
        found.extend(
            cmd.get_arguments()
                .filter_map(|a| a.get_long().map(str::to_string)),
        );
        for sub in cmd.get_subcommands() {
            longs(sub, found);
        }
    }
    let mut flags = Vec::new();
    longs(&Cli::command(), &mut flags);
    vmerge::options::respell(message, |name| {
        let long = name.replace('_', "-");
        flags.contains(&long).then(|| format!("--{long}"))
    })
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", with_flags(&format!("{e:#}")));
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
        Command::Errors {
            a,
            b,
            mut measure,
            relative,
        } => {
            if relative {
                measure.push(Measure::RelativeMse);
            }
            // Scripts asking for pixel-wise measures only need not wait for FLIP.
            let selection = if !measure.is_empty() && measure.iter().all(|m| m.is_pointwise()) {
                Selection::Pointwise
            } else {
                Selection::All
            };
            let errors = tools::errors(&a, &b, selection)?;
            if measure.is_empty() {
                for (m, value) in errors.iter() {
                    println!("{m} {value}");
                }
                return Ok(());
            }
            // `-` for a measure the images are too small for.
            let values: Vec<String> = measure
                .iter()
                .map(|&m| errors.get(m).map_or("-".into(), |v| v.to_string()))
                .collect();
            println!("{}", values.join(" "));
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
    let setup = vmerge::render::NewRender {
        scene: args.scene,
        options: args.options.0,
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
    let _reserved = setup.check()?;
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
    let output = args.output.clone().unwrap_or_else(|| args.input.clone());
    // Before the input is read: another writer finishing meanwhile would be overwritten. A
    // lock that cannot be taken is reported after the input's own error, if it has one.
    let reserved = vmerge::files::lock_output(&output);
    let (film, metadata) = vmerge::film::exr::read_render(&args.input)?;
    let _reserved = reserved?;
    let scene = vmerge::render::load_for_continue(&metadata, args.accel, args.force)?;
    print_warnings(&scene);
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
    let server = viewer
        .serve(address)
        .with_context(|| format!("--address {address}"))?;
    if let Some(w) = server.warning() {
        eprintln!("warning: {w}");
    }
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
        .map(|address| {
            vmerge::preview::LivePreview::start(address, &job, stop)
                .with_context(|| format!("--preview {address}"))
        })
        .transpose()?;
    if let Some(p) = &preview {
        eprintln!("preview at http://{}/", p.address());
        if let Some(w) = p.warning() {
            eprintln!("warning: {w}");
        }
    }
    let observer = preview
        .as_mut()
        .map(|p| p as &mut dyn vmerge::render::Observer);
    job.run_observed(stop, &flag, observer, |event| {
        let p = match event {
            vmerge::render::RunEvent::Iteration(p) => p,
            vmerge::render::RunEvent::Warning(w) => {
                bar.suspend(|| eprintln!("warning: {w}"));
                return;
            }
        };
        bar.set_position(p.iterations);
        let mut msg = format!(
            "{:.2} Msamples/s, {:.2} Mrays/s",
            p.samples_per_second / 1e6,
            p.rays_per_second / 1e6
        );
        if let Some(rmse) = p.rmse {
            msg.push_str(&format!(", rmse {rmse:.4e}"));
        }
        if let Some(upg) = vmerge::integrator::upg::UpgCounters::from_named(&p.counters) {
            let seconds = p.elapsed.as_secs_f64().max(1e-9);
            msg.push_str(&format!(
                ", upg {:.2} trials/merge, {:.2} Mmerges/s, {:.2} Mtentative rays/s, {} capped",
                upg.trials as f64 / upg.merges as f64,
                upg.merges as f64 / seconds / 1e6,
                upg.tentative_rays as f64 / seconds / 1e6,
                upg.capped
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
        } else if let Some(p) = cause.downcast_ref::<vmerge::preview::PreviewError>() {
            // An address the user named that cannot be had; other failures are the system's.
            matches!(p, vmerge::preview::PreviewError::Address { .. })
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

use vmerge::metrics::{Measure, Selection};
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
    #[arg(long, conflicts_with_all = ["dry_run", "slurm", "submit", "cell"])]
    jobs: bool,
    /// Submit the plan to Slurm: one array job per stage (reference parts, their merges, the
    /// cells measured against them), each after the one before (afterok); prints the job ids
    /// and records them for `batch status`.
    #[arg(long, conflicts_with_all = ["dry_run", "slurm", "cell"])]
    submit: bool,
    /// Write what --submit runs as a script to edit first: run it with bash to submit.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["dry_run", "cell"])]
    slurm: Option<PathBuf>,
    /// Bring the cell of this name up to date (what each Slurm array task runs).
    #[arg(long, value_name = "NAME", conflicts_with = "dry_run")]
    cell: Option<String>,
    #[arg(long, value_parser = accel_parser(), default_value = AccelKind::default_kind().name())]
    accel: AccelKind,
}

#[derive(Subcommand)]
enum BatchCommand {
    /// Show each cell: done, partial, missing or stale; and, once submitted, its Slurm task:
    /// queued, running, done or failed.
    Status { plan: PathBuf },
    /// Write OUTPUT/report/index.html (thumbnails, tables, charts) from the cells that exist.
    Report { plan: PathBuf },
}

fn warn_blocked(blocked: usize) {
    if blocked > 0 {
        eprintln!(
            "{blocked} cells cannot run: their reference file is not there (see batch status)"
        );
    }
}

fn measure_parser() -> impl TypedValueParser<Value = Measure> {
    by_name(
        Measure::ALL,
        Measure::name,
        Measure::label,
        "no such measure",
    )
}

fn metric_parser() -> impl TypedValueParser<Value = Metric> {
    by_name(Metric::ALL, Metric::name, Metric::label, "no such metric")
}

fn batch(args: BatchArgs) -> Result<()> {
    let program = std::env::current_exe().context("finding the vmerge executable")?;
    match (args.command, args.plan) {
        (Some(BatchCommand::Status { plan }), _) => {
            let plan = Plan::load(&plan)?;
            print!("{}", batch::status(&plan));
            if let Some(slurm) = batch::slurm_status(&plan)? {
                print!("{slurm}");
            }
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
                let (stages, blocked) = batch::slurm(&plan, &program, &script)?;
                let tasks: Vec<String> = stages.iter().map(|n| n.to_string()).collect();
                eprintln!(
                    "wrote {} ({} stages of {} array tasks); submit with: bash {}",
                    script.display(),
                    stages.len(),
                    tasks.join(", "),
                    script.display()
                );
                warn_blocked(blocked);
            } else if args.submit {
                let submission = batch::submit(&plan, &program)?;
                for (k, (job, tasks)) in submission.jobs.iter().enumerate() {
                    println!("{job}");
                    eprintln!("stage {}: job {job} ({tasks} cells)", k + 1);
                }
                if submission.jobs.is_empty() {
                    eprintln!("nothing to submit: every cell that can run is done");
                }
                warn_blocked(submission.blocked);
            } else if let Some(name) = args.cell {
                set_threads(plan.threads)?;
                let flag = stop_on_signal()?;
                // Plain lines for the task's log: the action, then any warnings.
                let done = batch::run_one(&plan, &name, args.accel, &flag, &mut |e| match e {
                    batch::Event::Cell { name, action } => {
                        eprintln!("{name}: {}", batch::describe_action(action))
                    }
                    batch::Event::Warning(w) => eprintln!("warning: {w}"),
                    batch::Event::RunWarning(w) => eprintln!("warning: {w}"),
                    _ => {}
                })?;
                // A cell stopped short must not count as done to the stages after it.
                if !done {
                    anyhow::bail!("{name}: stopped before its budget was spent; it continues from its snapshot when run again");
                }
                eprintln!("{name}: done");
            } else {
                set_threads(plan.threads)?;
                let flag = stop_on_signal()?;
                let mut bar = batch::ProgressBar::default();
                let ran = batch::run(&plan, args.accel, &flag, &mut |e| match e {
                    batch::Event::Warning(w) => bar.suspend(|| eprintln!("warning: {w}")),
                    batch::Event::RunWarning(w) => bar.suspend(|| eprintln!("warning: {w}")),
                    _ => bar.show(e),
                })?;
                bar.finish();
                eprintln!("{ran} cells rendered");
            }
        }
    }
    Ok(())
}
