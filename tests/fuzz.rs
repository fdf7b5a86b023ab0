//! Mutation fuzzing of everything vmerge reads: scene files, OBJ and MTL files (from the
//! shipped scenes and the bad-input fixtures) and the EXR renders `continue` and `merge` read.
//! Inputs are mutated by byte flips, truncation, number swaps, line duplication and deletion,
//! with a fixed seed; every one must load or fail with an error naming its file, never panic,
//! abort or hang.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};
use vmerge::accel::AccelKind;
use vmerge::film::{exr, ErrorSample, Film, Metadata};
use vmerge::options::{RenderOptions, Technique};
use vmerge::scene::LoadOptions;

/// splitmix64: a small, fixed-seed generator, so that a failure repeats.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Numbers that sit at the edges of what the readers accept.
const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "1",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e39",
    "-1e39",
    "1e-40",
    "1e30",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "-9223372036854775808",
    "0.5",
    "2",
    "1e8",
    "3e38",
    "",
];

/// One mutation of `input`: a flipped byte, a cut, a number swapped for an edge value, a
/// duplicated or deleted line, or a burst of random bytes.
fn mutate(input: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut out = input.to_vec();
    for _ in 0..1 + rng.below(3) {
        match rng.below(6) {
            0 if !out.is_empty() => {
                let i = rng.below(out.len());
                out[i] ^= 1 << rng.below(8);
            }
            1 => out.truncate(rng.below(out.len() + 1)),
            2 => {
                // Swap the number at a random position for one of NUMBERS.
                let numeric = |b: u8| b.is_ascii_digit() || b == b'.' || b == b'-' || b == b'e';
                let starts: Vec<usize> = (0..out.len())
                    .filter(|&i| out[i].is_ascii_digit() && (i == 0 || !numeric(out[i - 1])))
                    .collect();
                if !starts.is_empty() {
                    let start = starts[rng.below(starts.len())];
                    let end = (start..out.len())
                        .find(|&i| !numeric(out[i]))
                        .unwrap_or(out.len());
                    let number = NUMBERS[rng.below(NUMBERS.len())].as_bytes();
                    out.splice(start..end, number.iter().copied());
                }
            }
            3 | 4 => {
                let lines: Vec<&[u8]> = out.split_inclusive(|&b| b == b'\n').collect();
                if !lines.is_empty() {
                    let i = rng.below(lines.len());
                    let mut new: Vec<u8> = Vec::with_capacity(out.len() * 2);
                    for (k, line) in lines.iter().enumerate() {
                        if k != i || rng.below(2) == 0 {
                            new.extend_from_slice(line);
                        }
                        if k == i {
                            new.extend_from_slice(line);
                        }
                    }
                    out = new;
                }
            }
            _ => {
                let at = rng.below(out.len() + 1);
                let burst: Vec<u8> = (0..1 + rng.below(8)).map(|_| rng.next() as u8).collect();
                out.splice(at..at, burst);
            }
        }
    }
    out
}

/// A scene folder: its files by name, and the name of the scene file.
struct SceneSource {
    files: Vec<(String, Vec<u8>)>,
}

/// The shipped scenes, then the bad-input fixtures; and how many are shipped.
fn scene_sources() -> (Vec<SceneSource>, usize) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut dirs: Vec<PathBuf> = Vec::new();
    let mut shipped = 0;
    for parent in ["scenes", "tests/fixtures/bad"] {
        let mut found: Vec<PathBuf> = std::fs::read_dir(root.join(parent))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|d| d.join("scene.toml").is_file())
            .collect();
        found.sort();
        if parent == "scenes" {
            shipped = found.len();
        }
        dirs.extend(found);
    }
    let sources = dirs
        .into_iter()
        .map(|dir| {
            let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().path())
                .filter(|p| {
                    let ext = p.extension().map(|e| e.to_string_lossy().into_owned());
                    // Large fixtures (the long-line cases) would slow every mutation down.
                    matches!(ext.as_deref(), Some("toml" | "obj" | "mtl"))
                        && p.metadata().unwrap().len() < 20_000
                })
                .map(|p| {
                    let name = p.file_name().unwrap().to_string_lossy().into_owned();
                    (name, std::fs::read(&p).unwrap())
                })
                .collect();
            files.sort();
            SceneSource { files }
        })
        .collect();
    (sources, shipped)
}

/// A small render with every metadata field filled, as `continue` and `merge` read it.
fn render_bytes(dir: &Path) -> Vec<u8> {
    let mut film = Film::new(6, 3);
    for (i, s) in film.sum.iter_mut().enumerate() {
        *s = [i as f64 * 0.25, 1.0, 0.5];
    }
    film.iterations = 3;
    let options = RenderOptions {
        technique: Technique::Vcm,
        radius: Some(0.01),
        seed: 7,
        ..RenderOptions::default()
    };
    let mut metadata = Metadata::new("scene.toml".into(), "abc".into(), options, "bvh");
    metadata.iterations = 3;
    metadata.render_seconds = 1.5;
    metadata.statistics = vec![("photons".into(), "18".into())];
    metadata.reference = Some("ref.exr".into());
    metadata.traces = vec!["2x1x1".parse().unwrap()];
    metadata.errors = vec![ErrorSample {
        seconds: 0.5,
        iterations: 1,
        mae: 0.1,
        rmse: 0.2,
        traces: vec![[0.3, 0.4]],
    }];
    let path = dir.join("seed.exr");
    exr::write_render(&path, &film, &metadata).unwrap();
    std::fs::read(path).unwrap()
}

/// What one input did.
enum Outcome {
    Loaded,
    /// A clean error: its message names `file`.
    Refused,
    Bad(String),
}

fn judge(result: std::thread::Result<Result<(), String>>, file: &str) -> Outcome {
    match result {
        Ok(Ok(())) => Outcome::Loaded,
        Ok(Err(message)) if message.contains("panicked") => Outcome::Bad(message),
        Ok(Err(message)) if message.contains(file) => Outcome::Refused,
        Ok(Err(message)) => Outcome::Bad(format!("the message does not name {file}: {message}")),
        Err(_) => Outcome::Bad("panicked".into()),
    }
}

#[test]
fn mutated_inputs_load_or_fail_cleanly() {
    const INPUTS: usize = 21_000;
    const WORKERS: u64 = 2;
    let (sources, shipped) = scene_sources();
    assert!(
        sources.len() >= 20 && shipped > 0,
        "found {} scene folders",
        sources.len()
    );
    let temp = tempfile::tempdir().unwrap();
    let exr_seed = render_bytes(temp.path());
    let done = AtomicUsize::new(0);
    let counts = Mutex::new([0usize; 2]);
    let failure = Mutex::new(None::<String>);
    let finished = AtomicBool::new(false);
    let start = Instant::now();
    std::thread::scope(|scope| {
        // A hang is a failure too: nothing joins a hung worker, so the watchdog ends the run.
        scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                if start.elapsed() > Duration::from_secs(300) {
                    eprintln!("fuzz: no progress after 300 s; an input hangs");
                    std::process::exit(1);
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        let workers: Vec<_> = (0..WORKERS)
            .map(|w| {
                let (sources, exr_seed, done, counts, failure) =
                    (&sources, &exr_seed, &done, &counts, &failure);
                let dir = temp.path().join(format!("worker-{w}"));
                scope.spawn(move || {
                    std::fs::create_dir(&dir).unwrap();
                    let mut rng = Rng(0x5eed_0000 + w);
                    let mut loaded_refused = [0usize; 2];
                    while done.fetch_add(1, Ordering::Relaxed) < INPUTS {
                        if failure.lock().unwrap().is_some() {
                            break;
                        }
                        let (file, outcome) = if rng.below(3) == 0 {
                            let bytes = mutate(exr_seed, &mut rng);
                            let path = dir.join("render.exr");
                            std::fs::write(&path, &bytes).unwrap();
                            let result = catch_unwind(|| {
                                exr::read_render(&path)
                                    .map(|_| ())
                                    .map_err(|e| e.to_string())
                            });
                            ("render.exr".to_string(), judge(result, "render.exr"))
                        } else {
                            // Half from the shipped scenes, which load, so that mutations
                            // reach past the first check.
                            let source = if rng.below(2) == 0 {
                                &sources[rng.below(shipped)]
                            } else {
                                &sources[rng.below(sources.len())]
                            };
                            let target = rng.below(source.files.len());
                            for (k, (name, bytes)) in source.files.iter().enumerate() {
                                let bytes = if k == target {
                                    mutate(bytes, &mut rng)
                                } else {
                                    bytes.clone()
                                };
                                std::fs::write(dir.join(name), bytes).unwrap();
                            }
                            let options = LoadOptions {
                                accel: AccelKind::Bvh,
                                lenient: rng.below(2) == 0,
                                shading_normals: true,
                            };
                            let scene = dir.join("scene.toml");
                            let result = catch_unwind(AssertUnwindSafe(|| {
                                vmerge::scene::load(&scene, &options)
                                    .map(|_| ())
                                    .map_err(|e| e.to_string())
                            }));
                            // An error may name any of the scene's files, or a path it
                            // names (a mesh the mutation renamed), which lies in `dir`.
                            let dir_text = dir.to_string_lossy().into_owned();
                            let named = match &result {
                                Ok(Err(m)) => source
                                    .files
                                    .iter()
                                    .map(|(n, _)| n.as_str())
                                    .chain([dir_text.as_str(), "/dev/"])
                                    .find(|n| m.contains(n))
                                    .unwrap_or("scene.toml")
                                    .to_string(),
                                _ => "scene.toml".to_string(),
                            };
                            let outcome = judge(result, &named);
                            (source.files[target].0.clone(), outcome)
                        };
                        match outcome {
                            Outcome::Loaded => loaded_refused[0] += 1,
                            Outcome::Refused => loaded_refused[1] += 1,
                            Outcome::Bad(why) => {
                                let kept = dir.join(format!("failing-{file}"));
                                let _ = std::fs::copy(dir.join(&file), &kept);
                                *failure.lock().unwrap() =
                                    Some(format!("{}: {why}", kept.display()));
                            }
                        }
                        for (n, d) in counts.lock().unwrap().iter_mut().zip(loaded_refused) {
                            *n += d;
                        }
                        loaded_refused = [0; 2];
                    }
                })
            })
            .collect();
        for w in workers {
            w.join().unwrap();
        }
        finished.store(true, Ordering::Relaxed);
    });
    if let Some(f) = failure.into_inner().unwrap() {
        // Keep the failing input for a look.
        let kept = temp.keep();
        panic!("{f} (inputs kept in {})", kept.display());
    }
    let [loaded, refused] = counts.into_inner().unwrap();
    let elapsed = start.elapsed();
    eprintln!(
        "fuzz: {} inputs in {:.1} s: {loaded} loaded, {refused} refused cleanly",
        loaded + refused,
        elapsed.as_secs_f64()
    );
    assert!(loaded + refused >= 20_000);
    assert!(
        refused > 1000 && loaded > 1000,
        "{loaded} loaded, {refused} refused"
    );
}

/// Plans as the tests and the documentation write them, over the shipped scenes (paths made
/// absolute; the first [`WRITTEN`]), and the bad-plan fixtures with their files: each a set of `(name, bytes)` of
/// which `plan.toml`, or the fixture's plan, is mutated.
const WRITTEN: usize = 3;

/// A plan's files, `(name, bytes)`, and which of them is the plan.
struct PlanSource {
    files: Vec<(String, Vec<u8>)>,
    plan: String,
}

fn plan_sources() -> Vec<PlanSource> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes = root.join("scenes").to_string_lossy().into_owned();
    let sweep = std::fs::read_to_string(root.join("docs/corners-sweep.toml"))
        .unwrap()
        .replace("../scenes", &scenes)
        .replace("../target/batch/corners-sweep", "out");
    let written = [
        sweep,
        format!(
            "output = \"results\"\nresolution = [32, 32]\niterations = 4\ntraces = [\"8x8x4\"]\n\
             [[scene]]\nfile = \"{scenes}/cornell-box/scene.toml\"\ncameras = [\"front\"]\n\
             reference = {{ technique = \"bpt\", iterations = 64, parts = 2 }}\n\
             [[group]]\ntechniques = [\"vcm\", \"upg\", \"upg-camera\"]\nradius = [0.02, 0.05, 0.1]\n"
        ),
        format!(
            "output = \"out\"\nresolution = [16, 16]\niterations = 2\nthreads = 2\n\
             [slurm]\npartition = \"short\"\naccount = \"rendering\"\nsbatch = [\"--qos=low\"]\n\
             [[scene]]\nfile = \"{scenes}/cornell-box/scene.toml\"\nname = \"box\"\n\
             reference = {{ iterations = 16, parts = 2 }}\n\
             [[group]]\ntechniques = [\"vcm\", \"upg\"]\nradius = [0.05, 0.1]\nbeta = [1, 2]\n\
             seeds = [1, 2]\nmin_path_length = 2\n[[group]]\ntechniques = [\"bpt\"]\n\
             scenes = [\"box\"]\nbudget = \"2s\"\n"
        ),
    ];
    let mut sources: Vec<_> = written
        .into_iter()
        .map(|text| PlanSource {
            files: vec![("plan.toml".to_string(), text.into_bytes())],
            plan: "plan.toml".into(),
        })
        .collect();
    let bad = root.join("tests/fixtures/bad");
    let mut cases: Vec<_> = std::fs::read_dir(&bad)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("plan-")
        })
        .collect();
    cases.sort();
    for case in cases {
        let args = std::fs::read_to_string(case.join("args")).unwrap();
        let plan = args.lines().last().unwrap().to_string();
        let files = std::fs::read_dir(&case)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .map(|p| {
                let name = p.file_name().unwrap().to_string_lossy().into_owned();
                (name, std::fs::read(&p).unwrap())
            })
            .filter(|(name, _)| !["args", "expect", "setup"].contains(&name.as_str()))
            .collect();
        sources.push(PlanSource { files, plan });
    }
    sources
}

/// Mutated plans load or are refused with a message naming the plan, never panic, abort or
/// hang; a plan that loads also gives its status and dry run, which must write nothing.
#[test]
fn mutated_plans_load_or_fail_cleanly() {
    use vmerge::tools::batch::{self, Plan};
    const INPUTS: usize = 15_000;
    let sources = plan_sources();
    assert!(sources.len() >= 15, "found {} plans", sources.len());
    let temp = tempfile::tempdir().unwrap();
    let finished = AtomicBool::new(false);
    let start = Instant::now();
    let (mut loaded, mut refused) = (0usize, 0usize);
    std::thread::scope(|scope| {
        scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                if start.elapsed() > Duration::from_secs(120) {
                    eprintln!("fuzz: no progress after 120 s; a plan hangs");
                    std::process::exit(1);
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        let mut rng = Rng(0x91a2_0000);
        for i in 0..INPUTS {
            let dir = temp.path().join(format!("plan-{i}"));
            std::fs::create_dir(&dir).unwrap();
            // Half from the written plans, which load, so that mutations reach past the
            // first check.
            let pick = if rng.below(2) == 0 {
                WRITTEN
            } else {
                sources.len()
            };
            let PlanSource {
                files,
                plan: plan_name,
            } = &sources[rng.below(pick)];
            for (name, bytes) in files {
                let bytes = if name == plan_name {
                    mutate(bytes, &mut rng)
                } else {
                    bytes.clone()
                };
                std::fs::write(dir.join(name), bytes).unwrap();
            }
            let plan_file = dir.join(plan_name);
            let before = std::fs::read_dir(&dir).unwrap().count();
            let result = catch_unwind(|| {
                Plan::load(&plan_file).map(|plan| {
                    batch::status(&plan);
                    batch::dry_run(&plan);
                })
            });
            match result {
                Ok(Ok(())) => loaded += 1,
                Ok(Err(e)) if e.to_string().contains(plan_name.as_str()) => refused += 1,
                Ok(Err(e)) => panic!("{}: the message does not name it: {e}", plan_file.display()),
                Err(_) => panic!("{}: panicked", plan_file.display()),
            }
            let after = std::fs::read_dir(&dir).unwrap().count();
            assert_eq!(before, after, "{}: wrote files", plan_file.display());
            std::fs::remove_dir_all(&dir).unwrap();
        }
        finished.store(true, Ordering::Relaxed);
    });
    eprintln!(
        "fuzz: {} plans in {:.1} s: {loaded} loaded, {refused} refused cleanly",
        loaded + refused,
        start.elapsed().as_secs_f64()
    );
    assert!(
        loaded > 1000 && refused > 1000,
        "{loaded} loaded, {refused} refused"
    );
}
