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
        others: Default::default(),
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

/// The file a refusal must name: one of the scene's `files` it mentions, or a path in `dir`
/// (a file a mutation renamed) or under `/dev/`; `scene` when it mentions none (and so fails).
fn named_file(
    result: &std::thread::Result<Result<(), String>>,
    files: &[(String, Vec<u8>)],
    dir: &Path,
    scene: &str,
) -> String {
    let dir_text = dir.to_string_lossy().into_owned();
    match result {
        Ok(Err(m)) => files
            .iter()
            .map(|(n, _)| n.as_str())
            .chain([dir_text.as_str(), "/dev/"])
            .find(|n| m.contains(n))
            .unwrap_or(scene)
            .to_string(),
        _ => scene.to_string(),
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
                            let named = named_file(&result, &source.files, &dir, "scene.toml");
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

// pbrt-v4 scene files and PLY meshes.

/// The pbrt scene that loads the generated PLY meshes: a small area light and the mesh.
const PLY_SCENE: &str = "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
WorldBegin\nAttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n  \
Translate 0 0 2\n  Shape \"sphere\" \"float radius\" 0.2\nAttributeEnd\n\
Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n\
Shape \"plymesh\" \"string filename\" \"mesh.ply\"\n";

/// A pbrt scene folder (its .pbrt and .ply files; the scene is `scene.pbrt`), and for a
/// generated PLY the offsets of its binary list-length bytes in the file.
struct PbrtSource {
    files: Vec<(String, Vec<u8>)>,
    list_lengths: Vec<usize>,
}

/// A quad and a triangle with normals and uvs, as a PLY in `format` (ascii,
/// binary_little_endian or binary_big_endian); positions as `real` (float or double), indices
/// as `index` (int or uint). Returns the file and the offsets of its list-length bytes.
fn ply_seed(format: &str, real: &str, index: &str) -> (Vec<u8>, Vec<usize>) {
    let positions = [
        [-1.0, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
        [0.0, 0.0, 0.5],
    ];
    let faces: [&[u32]; 2] = [&[0, 1, 2, 3], &[0, 1, 4]];
    let mut out = format!(
        "ply\nformat {format} 1.0\ncomment generated\nelement vertex {}\n\
         property {real} x\nproperty {real} y\nproperty {real} z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float u\nproperty float v\n\
         element face {}\nproperty list uchar {index} vertex_indices\nend_header\n",
        positions.len(),
        faces.len()
    )
    .into_bytes();
    let mut list_lengths = Vec::new();
    let big = format == "binary_big_endian";
    let put = |out: &mut Vec<u8>, bytes: [u8; 8], n: usize| {
        let bytes = &bytes[..n];
        if big {
            out.extend(bytes.iter().rev());
        } else {
            out.extend_from_slice(bytes);
        }
    };
    for p in &positions {
        let extra = [0.0, 0.0, 1.0, p[0] * 0.5 + 0.5, p[1] * 0.5 + 0.5];
        if format == "ascii" {
            let all: Vec<String> = p.iter().chain(&extra).map(|x| x.to_string()).collect();
            out.extend_from_slice(format!("{}\n", all.join(" ")).as_bytes());
            continue;
        }
        for (k, x) in p.iter().chain(&extra).enumerate() {
            if k < 3 && real == "double" {
                put(&mut out, f64::to_le_bytes(*x), 8);
            } else {
                let mut b = [0; 8];
                b[..4].copy_from_slice(&(*x as f32).to_le_bytes());
                put(&mut out, b, 4);
            }
        }
    }
    for f in faces {
        if format == "ascii" {
            let all: Vec<String> = f.iter().map(|i| i.to_string()).collect();
            out.extend_from_slice(format!("{} {}\n", f.len(), all.join(" ")).as_bytes());
            continue;
        }
        list_lengths.push(out.len());
        out.push(f.len() as u8);
        for i in f {
            let mut b = [0; 8];
            b[..4].copy_from_slice(&i.to_le_bytes());
            put(&mut out, b, 4);
        }
    }
    (out, list_lengths)
}

/// The shipped pbrt scenes (the fixtures' twins and any under scenes/), the bad-input pbrt
/// fixtures, and the generated PLYs; and how many load (the shipped and generated ones).
fn pbrt_sources() -> (Vec<PbrtSource>, usize) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let read = |dir: &Path| -> PbrtSource {
        let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                let ext = p.extension().map(|e| e.to_string_lossy().into_owned());
                // Large fixtures (the long-line cases) would slow every mutation down.
                matches!(ext.as_deref(), Some("pbrt" | "ply"))
                    && p.metadata().unwrap().len() < 20_000
            })
            .map(|p| {
                let name = p.file_name().unwrap().to_string_lossy().into_owned();
                (name, std::fs::read(&p).unwrap())
            })
            .collect();
        files.sort();
        PbrtSource {
            files,
            list_lengths: Vec::new(),
        }
    };
    let mut sources = Vec::new();
    for (format, real, index) in [
        ("ascii", "float", "int"),
        ("binary_little_endian", "float", "int"),
        ("binary_big_endian", "double", "uint"),
        ("binary_little_endian", "double", "uint"),
    ] {
        let (ply, list_lengths) = ply_seed(format, real, index);
        sources.push(PbrtSource {
            files: vec![
                ("mesh.ply".into(), ply),
                ("scene.pbrt".into(), PLY_SCENE.as_bytes().to_vec()),
            ],
            list_lengths,
        });
    }
    let mut dirs: Vec<PathBuf> = Vec::new();
    for parent in ["scenes", "tests/fixtures", "tests/fixtures/bad"] {
        let Ok(entries) = std::fs::read_dir(root.join(parent)) else {
            continue;
        };
        let mut found: Vec<PathBuf> = entries
            .map(|e| e.unwrap().path())
            .filter(|d| d.join("scene.pbrt").is_file())
            .collect();
        found.sort();
        dirs.extend(found);
    }
    let loads = sources.len()
        + dirs
            .iter()
            .filter(|d| !d.parent().unwrap().ends_with("bad"))
            .count();
    sources.extend(dirs.iter().map(|d| read(d)));
    (sources, loads)
}

/// Element counts at the edges of what a PLY reader must refuse before it allocates.
const PLY_COUNTS: &[&str] = &[
    "0",
    "1",
    "2",
    "3",
    "6",
    "255",
    "65536",
    "4294967295",
    "4294967296",
    "1099511627776",
    "18446744073709551615",
    "-1",
    "x",
];

/// Property types, the valid ones in both spellings and a few that are not.
const PLY_TYPES: &[&str] = &[
    "char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8", "int16",
    "uint16", "int32", "uint32", "float32", "float64", "list", "string", "",
];

/// One PLY-specific mutation: an element count or a property type swapped for an edge value, a
/// binary list-length byte changed (or an ASCII face's count), or the file cut short; else a
/// generic one.
fn mutate_ply(input: &[u8], list_lengths: &[usize], rng: &mut Rng) -> Vec<u8> {
    let end = input
        .windows(11)
        .position(|w| w == b"end_header\n")
        .map_or(input.len(), |i| i + 11);
    let (header, body) = input.split_at(end);
    let header = String::from_utf8_lossy(header);
    let mut lines: Vec<String> = header.split_inclusive('\n').map(String::from).collect();
    let pick = |lines: &[String], prefix: &str, rng: &mut Rng| {
        let found: Vec<usize> = (0..lines.len())
            .filter(|&i| lines[i].starts_with(prefix))
            .collect();
        (!found.is_empty()).then(|| found[rng.below(found.len())])
    };
    match rng.below(5) {
        0 => {
            if let Some(i) = pick(&lines, "element ", rng) {
                let name = lines[i].split_whitespace().nth(1).unwrap_or("vertex");
                let count = PLY_COUNTS[rng.below(PLY_COUNTS.len())];
                lines[i] = format!("element {name} {count}\n");
            }
        }
        1 => {
            if let Some(i) = pick(&lines, "property ", rng) {
                let mut words: Vec<&str> = lines[i].split_whitespace().collect();
                // The scalar's type, or a list's count or item type.
                let at = 1 + rng.below(words.len().saturating_sub(2).max(1));
                if at < words.len() {
                    words[at] = PLY_TYPES[rng.below(PLY_TYPES.len())];
                }
                lines[i] = format!("{}\n", words.join(" "));
            }
        }
        2 => {
            let mut out = input.to_vec();
            let value = [0u8, 1, 2, 3, 4, 5, 100, 127, 128, 255][rng.below(10)];
            if !list_lengths.is_empty() {
                out[list_lengths[rng.below(list_lengths.len())]] = value;
            } else {
                // ASCII: a face line's leading count.
                let text = String::from_utf8_lossy(body);
                let mut body_lines: Vec<String> =
                    text.split_inclusive('\n').map(String::from).collect();
                let faces: Vec<usize> = (0..body_lines.len())
                    .filter(|&i| body_lines[i].split_whitespace().count() <= 5)
                    .collect();
                if !faces.is_empty() {
                    let i = faces[rng.below(faces.len())];
                    let rest: Vec<&str> = body_lines[i].split_whitespace().skip(1).collect();
                    body_lines[i] = format!("{value} {}\n", rest.join(" "));
                }
                out.truncate(end);
                out.extend(body_lines.concat().into_bytes());
            }
            return out;
        }
        3 => {
            // Mostly within the body, where the counts are trusted.
            let at = if rng.below(4) == 0 {
                rng.below(end + 1)
            } else {
                end + rng.below(body.len() + 1)
            };
            return input[..at].to_vec();
        }
        _ => return mutate(input, rng),
    }
    let mut out = lines.concat().into_bytes();
    out.extend_from_slice(body);
    out
}

/// Runs the vmerge binary on a scene the library refused: it must exit 2 with a short message
/// and write nothing. None when it does; else what went wrong.
fn binary_refuses(dir: &Path, lenient: bool) -> Option<String> {
    let out = dir.join("out.exr");
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_vmerge"));
    command.args([
        "render",
        "--iterations",
        "1",
        "--resolution",
        "8x8",
        "--accel",
        "bvh",
    ]);
    if lenient {
        command.arg("--lenient");
    }
    let mut child = command
        .arg("-o")
        .arg(&out)
        .arg(dir.join("scene.pbrt"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            return Some("the binary still runs after 30 s".into());
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut stderr = Vec::new();
    std::io::Read::read_to_end(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
    let stderr = String::from_utf8_lossy(&stderr);
    if status.code() != Some(2) || stderr.len() >= 2000 || out.exists() {
        let _ = std::fs::remove_file(&out);
        return Some(format!(
            "the binary: {status}, {} bytes on stderr: {}",
            stderr.len(),
            stderr.chars().take(2000).collect::<String>()
        ));
    }
    None
}

#[test]
fn mutated_pbrt_and_ply_inputs_load_or_fail_cleanly() {
    const INPUTS: usize = 30_000;
    const WORKERS: u64 = 2;
    // One refused input in this many also goes through the binary.
    const BINARY_EVERY: usize = 40;
    let (sources, loads) = pbrt_sources();
    assert!(
        sources.len() >= 25 && loads >= 5,
        "found {} pbrt scenes, {loads} that load",
        sources.len()
    );
    let temp = tempfile::tempdir().unwrap();
    let root = temp.path();
    let done = AtomicUsize::new(0);
    let counts = Mutex::new([0usize; 3]);
    let failure = Mutex::new(None::<String>);
    let finished = AtomicBool::new(false);
    // Milliseconds from the start to the last input finished: a hang is no progress.
    let progress = std::sync::atomic::AtomicU64::new(0);
    let start = Instant::now();
    std::thread::scope(|scope| {
        scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                let last = Duration::from_millis(progress.load(Ordering::Relaxed));
                if start.elapsed().saturating_sub(last) > Duration::from_secs(60) {
                    eprintln!("fuzz: no progress for 60 s; an input hangs");
                    std::process::exit(1);
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        });
        let workers: Vec<_> = (0..WORKERS)
            .map(|w| {
                let (sources, done, counts, failure, progress) =
                    (&sources, &done, &counts, &failure, &progress);
                let dir = root.join(format!("pbrt-worker-{w}"));
                scope.spawn(move || {
                    let mut rng = Rng(0x9b27_0000 + w);
                    loop {
                        let n = done.fetch_add(1, Ordering::Relaxed);
                        if n >= INPUTS || failure.lock().unwrap().is_some() {
                            break;
                        }
                        // A fresh folder each time: a mutation may rename a file.
                        let _ = std::fs::remove_dir_all(&dir);
                        std::fs::create_dir(&dir).unwrap();
                        // Half from the scenes that load, so that mutations reach the builder.
                        let source = if rng.below(2) == 0 {
                            &sources[rng.below(loads)]
                        } else {
                            &sources[rng.below(sources.len())]
                        };
                        let target = rng.below(source.files.len());
                        for (k, (name, bytes)) in source.files.iter().enumerate() {
                            let bytes = if k != target {
                                bytes.clone()
                            } else if name.ends_with(".ply") && rng.below(4) != 0 {
                                mutate_ply(bytes, &source.list_lengths, &mut rng)
                            } else {
                                mutate(bytes, &mut rng)
                            };
                            std::fs::write(dir.join(name), bytes).unwrap();
                        }
                        let options = LoadOptions {
                            accel: AccelKind::Bvh,
                            lenient: rng.below(2) == 0,
                            shading_normals: true,
                        };
                        let mut longest_warning = 0;
                        let result = catch_unwind(AssertUnwindSafe(|| {
                            vmerge::scene::load(&dir.join("scene.pbrt"), &options)
                                .map(|scene| {
                                    longest_warning = scene
                                        .warnings
                                        .iter()
                                        .map(|w| w.message.len())
                                        .max()
                                        .unwrap_or(0);
                                })
                                .map_err(|e| e.to_string())
                        }));
                        let too_long = matches!(&result, Ok(Err(m)) if m.len() >= 2000);
                        let named = named_file(&result, &source.files, &dir, "scene.pbrt");
                        let mut outcome = match judge(result, &named) {
                            Outcome::Refused if too_long => {
                                Outcome::Bad("a message of 2,000 bytes or more".into())
                            }
                            Outcome::Loaded if longest_warning >= 2000 => {
                                Outcome::Bad(format!("a warning of {longest_warning} bytes"))
                            }
                            outcome => outcome,
                        };
                        let mut ran_binary = false;
                        if matches!(outcome, Outcome::Refused) && n % BINARY_EVERY == 0 {
                            ran_binary = true;
                            if let Some(why) = binary_refuses(&dir, options.lenient) {
                                outcome = Outcome::Bad(why);
                            }
                        }
                        let mut counts = counts.lock().unwrap();
                        match outcome {
                            Outcome::Loaded => counts[0] += 1,
                            Outcome::Refused => counts[1] += 1,
                            Outcome::Bad(why) => {
                                let kept = root.join(format!("failing-pbrt-{w}"));
                                let _ = std::fs::rename(&dir, &kept);
                                *failure.lock().unwrap() = Some(format!(
                                    "{} ({}, lenient {}): {why}",
                                    kept.display(),
                                    source.files[target].0,
                                    options.lenient
                                ));
                            }
                        }
                        counts[2] += usize::from(ran_binary);
                        progress.store(start.elapsed().as_millis() as u64, Ordering::Relaxed);
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
        let kept = temp.keep();
        panic!("{f} (inputs kept in {})", kept.display());
    }
    let [loaded, refused, binary] = counts.into_inner().unwrap();
    eprintln!(
        "fuzz pbrt/ply: {} inputs in {:.1} s: {loaded} loaded, {refused} refused cleanly \
         ({binary} of them also by the binary)",
        loaded + refused,
        start.elapsed().as_secs_f64()
    );
    assert!(loaded + refused >= INPUTS - 1);
    assert!(
        refused > 1000 && loaded > 1000,
        "{loaded} loaded, {refused} refused"
    );
}

/// How many of [`plan_sources`] are written plans, which load (the rest are fixtures).
const WRITTEN: usize = 3;

/// A plan's files, `(name, bytes)`, and which of them is the plan.
struct PlanSource {
    files: Vec<(String, Vec<u8>)>,
    plan: String,
}

/// Plans as the tests and the documentation write them, over the shipped scenes (paths made
/// absolute), then the bad-plan fixtures with their files; the plan of each is mutated.
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
