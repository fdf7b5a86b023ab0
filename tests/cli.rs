//! The command line: bad input gets a clear message naming the file, exit code 2, and no
//! output file.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use vmerge::options::RenderOptions;

fn vmerge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vmerge"))
}

/// The hash-free fingerprint of a folder: every regular file's name and bytes (named pipes
/// and other special files by name only).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Option<Vec<u8>>> {
    let mut files = BTreeMap::new();
    let mut todo = vec![dir.to_path_buf()];
    while let Some(d) = todo.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            let meta = std::fs::symlink_metadata(&path).unwrap();
            if meta.is_dir() {
                todo.push(path.clone());
            }
            let bytes = meta.is_file().then(|| std::fs::read(&path).unwrap());
            files.insert(path.strip_prefix(dir).unwrap().to_path_buf(), bytes);
        }
    }
    files
}

/// Writes a small vmerge render at `path`, altered as `changes` say: `iterations=N`,
/// `sum=V` (pixel (1, 0)'s red sum), `render_seconds=V`, `seed=N`, or any option as
/// `name=TOML value` (`technique="vcm"`, `radius=nan`).
fn forge_render(path: &Path, scene: &Path, changes: &[&str]) {
    use vmerge::film::{exr, Film, Metadata};
    let mut film = Film::new(4, 2);
    for s in film.sum.iter_mut() {
        *s = [0.5, 0.25, 1.0];
    }
    film.iterations = 2;
    let mut options = toml::Table::try_from(RenderOptions::default()).unwrap();
    let mut seconds = 1.0;
    for change in changes {
        let (key, value) = change.split_once('=').unwrap();
        match key {
            "iterations" => film.iterations = value.parse().unwrap(),
            "sum" => film.sum[1][0] = value.parse().unwrap(),
            "render_seconds" => seconds = value.parse().unwrap(),
            "seed" => {
                options.insert("seed".into(), toml::Value::Integer(value.parse().unwrap()));
            }
            _ => {
                let table: toml::Table = format!("{key} = {value}").parse().unwrap();
                options.extend(table);
            }
        }
    }
    let options: RenderOptions = options.try_into().unwrap();
    let canonical = std::fs::canonicalize(scene).unwrap_or(scene.to_path_buf());
    let mut metadata = Metadata::new(
        canonical.to_string_lossy().into_owned(),
        "forged".into(),
        options,
        "bvh",
    );
    metadata.iterations = film.iterations;
    metadata.render_seconds = seconds;
    exr::write_render(path, &film, &metadata).unwrap();
}

/// Prepares a case's working copy as its `setup` file says: `fifo NAME` (a named pipe),
/// `sparse NAME BYTES` (a large file that takes no space), `dir NAME`, `render NAME CHANGES`
/// (see [`forge_render`]).
fn set_up(work: &Path, setup: &str) {
    for line in setup.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        let path = work.join(words[1]);
        match words[0] {
            "fifo" => {
                let status = Command::new("mkfifo").arg(&path).status().unwrap();
                assert!(status.success(), "mkfifo {}", path.display());
            }
            "sparse" => {
                let file = std::fs::File::create(&path).unwrap();
                file.set_len(words[2].parse().unwrap()).unwrap();
            }
            "dir" => std::fs::create_dir(&path).unwrap(),
            "render" => forge_render(&path, &work.join("scene.toml"), &words[2..]),
            other => panic!("unknown setup step {other}"),
        }
    }
}

/// Every case under tests/fixtures/bad/ must be refused with exit code 2 and a short message
/// holding each line of its `expect` file, writing nothing and leaving its inputs as they
/// were. A case runs in a copy of its folder: `vmerge` with the arguments of its `args` file
/// (one per line, `{out}` the output folder) or else a one-iteration render of its scene.toml,
/// after the steps of its `setup` file.
#[test]
fn bad_inputs_exit_2_and_write_nothing() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bad");
    let mut cases: Vec<_> = std::fs::read_dir(&fixtures)
        .expect("tests/fixtures/bad exists")
        .map(|e| e.expect("readable fixture").path())
        .collect();
    cases.sort();
    assert!(
        cases.len() >= 60,
        "expected the bad-input fixtures, found {}",
        cases.len()
    );
    let mut failures = Vec::new();
    for case in cases {
        let name = case.file_name().unwrap().to_string_lossy().into_owned();
        let read = |file: &str| std::fs::read_to_string(case.join(file)).ok();
        let expect = read("expect").unwrap_or_else(|| panic!("{name}: no expect file"));
        let temp = tempfile::tempdir().unwrap();
        let (work, out) = (temp.path().join("case"), temp.path().join("out"));
        std::fs::create_dir(&work).unwrap();
        std::fs::create_dir(&out).unwrap();
        for entry in std::fs::read_dir(&case).unwrap() {
            let path = entry.unwrap().path();
            let file = path.file_name().unwrap();
            if !["args", "expect", "setup"].contains(&&*file.to_string_lossy()) {
                std::fs::copy(&path, work.join(file)).unwrap();
            }
        }
        set_up(&work, &read("setup").unwrap_or_default());
        let before = snapshot(&work);
        let out_text = out.to_string_lossy().into_owned();
        let args: Vec<String> = match read("args") {
            Some(text) => text
                .split_terminator('\n')
                .map(|a| a.replace("{out}", &out_text))
                .collect(),
            None => [
                "render",
                "--iterations",
                "1",
                "--resolution",
                "8x8",
                "--accel",
                "bvh",
                "-o",
                &format!("{out_text}/out.exr"),
                "scene.toml",
            ]
            .map(String::from)
            .to_vec(),
        };
        let result = vmerge()
            .args(&args)
            .current_dir(&work)
            .env("TMPDIR", &out)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        let mut problems = Vec::new();
        if result.status.code() != Some(2) {
            problems.push(format!("exit {:?}", result.status.code()));
        }
        if stderr.contains("panicked") {
            problems.push("panicked".into());
        }
        if stderr.len() > 2000 {
            problems.push(format!("a message of {} bytes", stderr.len()));
        }
        for line in expect.lines().filter(|l| !l.is_empty()) {
            if !stderr.contains(line) {
                problems.push(format!("no '{line}' in the message"));
            }
        }
        let written: Vec<_> = std::fs::read_dir(&out).unwrap().collect();
        if !written.is_empty() {
            problems.push(format!("wrote {written:?}"));
        }
        if snapshot(&work) != before {
            problems.push("changed its inputs".into());
        }
        if !problems.is_empty() {
            failures.push(format!("{name}: {}\n  {stderr}", problems.join("; ")));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn missing_input_files_exit_2() {
    for args in [
        vec!["average", "does-not-exist.exr"],
        vec!["errors", "a-missing.exr", "b-missing.exr"],
        vec!["continue", "missing-render.exr"],
    ] {
        let result = vmerge().args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains("missing"), "{args:?}: {stderr}");
    }
}

/// Options that mean nothing for the technique, or a technique that does not exist, are
/// refused before anything renders, naming the option.
#[test]
fn meaningless_strategies_exit_2() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    for (args, expected) in [
        (vec!["-t", "vcm", "--strategy", "1,2"], "--strategy"),
        (vec!["-t", "pt", "--unweighted"], "--unweighted"),
        (vec!["-t", "bpt", "--strategy", "2,0"], "--strategy 2,0"),
        (vec!["-t", "bpt", "--strategy", "two"], "--strategy"),
    ] {
        let out = tempfile::tempdir().unwrap();
        let result = vmerge()
            .args(["render", "--iterations", "1", "--resolution", "8x8", "-o"])
            .arg(out.path().join("out.exr"))
            .args(&args)
            .arg(&scene)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
        let written: Vec<_> = std::fs::read_dir(out.path()).unwrap().collect();
        assert!(written.is_empty(), "{args:?}: wrote {written:?}");
    }
}

/// Starts a render of the Cornell box into `output` for `seconds`, with snapshots every 100 ms
/// and the fallback directory `tmp`.
fn snapshotting_render(output: &Path, tmp: &Path, seconds: &str) -> std::process::Child {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    vmerge()
        .args([
            "render",
            "--resolution",
            "16x16",
            "--accel",
            "bvh",
            "--threads",
            "1",
        ])
        .args(["--snapshot", "100ms", "--time", seconds, "-o"])
        .arg(output)
        .arg(&scene)
        .env("TMPDIR", tmp)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
}

fn wait_for(path: &Path) {
    let start = std::time::Instant::now();
    while !path.exists() {
        assert!(
            start.elapsed().as_secs() < 30,
            "{} never appeared",
            path.display()
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Removes a directory that a render keeps writing snapshots into: a snapshot's temporary file
/// created while the directory is emptied makes one removal fail, so try again.
fn remove_while_written(dir: &Path) {
    for _ in 0..50 {
        match std::fs::remove_dir_all(dir) {
            Ok(()) => return,
            Err(e) if e.kind() == std::io::ErrorKind::DirectoryNotEmpty => {}
            Err(e) => panic!("removing {}: {e}", dir.display()),
        }
    }
    panic!("{} kept being written to", dir.display());
}

/// The output directory vanishes mid-render: snapshots fail with a warning, the render goes
/// on, and the final image goes to the temporary directory, which the message names; the exit
/// code says the image is not where it was asked for.
#[test]
fn a_vanished_output_directory_loses_no_render() {
    let temp = tempfile::tempdir().unwrap();
    let (dir, tmp) = (temp.path().join("out"), temp.path().join("tmp"));
    std::fs::create_dir(&dir).unwrap();
    std::fs::create_dir(&tmp).unwrap();
    let output = dir.join("render.exr");
    let child = snapshotting_render(&output, &tmp, "2s");
    wait_for(&output);
    remove_while_written(&dir);
    let result = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("snapshot not written"), "{stderr}");
    assert!(
        stderr.contains("trying again at the next snapshot"),
        "{stderr}"
    );
    let written: Vec<PathBuf> = std::fs::read_dir(&tmp)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(written.len(), 1, "{written:?}");
    assert!(
        stderr.contains(&format!(
            "it was written to {} instead",
            written[0].display()
        )),
        "{stderr}"
    );
    let (film, metadata) = vmerge::film::exr::read_render(&written[0]).unwrap();
    assert!(film.iterations > 1 && metadata.iterations == film.iterations);
}

/// Snapshots that fail while the directory is gone are retried: once it is back, the next
/// snapshot and the final image land where asked.
#[test]
fn failed_snapshots_are_retried() {
    let temp = tempfile::tempdir().unwrap();
    let (dir, tmp) = (temp.path().join("out"), temp.path().join("tmp"));
    std::fs::create_dir(&dir).unwrap();
    std::fs::create_dir(&tmp).unwrap();
    let output = dir.join("render.exr");
    let child = snapshotting_render(&output, &tmp, "2s");
    wait_for(&output);
    remove_while_written(&dir);
    std::thread::sleep(std::time::Duration::from_millis(400));
    std::fs::create_dir(&dir).unwrap();
    let result = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(0), "{stderr}");
    assert!(stderr.contains("snapshot not written"), "{stderr}");
    let (film, _) = vmerge::film::exr::read_render(&output).unwrap();
    assert!(film.iterations > 1);
    assert_eq!(std::fs::read_dir(&tmp).unwrap().count(), 0);
}

/// A render removes the temporary files a killed write of its output left, and says so; a
/// `usemtl` naming no material is a warning that names it.
#[test]
fn stale_temporaries_go_and_unknown_materials_are_named() {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bad/bad-fov");
    let temp = tempfile::tempdir().unwrap();
    for file in ["room.obj", "room.mtl"] {
        let text = std::fs::read_to_string(fixture.join(file)).unwrap();
        std::fs::write(
            temp.path().join(file),
            text.replace("usemtl floor", "usemtl flor"),
        )
        .unwrap();
    }
    let scene = std::fs::read_to_string(fixture.join("scene.toml")).unwrap();
    std::fs::write(
        temp.path().join("scene.toml"),
        scene.replace("fov = 190.0", "fov = 40.0"),
    )
    .unwrap();
    // No process has an id above the kernel's maximum (4194304).
    let stale = temp.path().join(".out.exr.tmp-4294967295-3");
    std::fs::write(&stale, "half a snapshot").unwrap();
    let result = vmerge()
        .args(["render", "-n", "1", "--resolution", "8x8", "--accel", "bvh"])
        .args(["-o", "out.exr", "scene.toml"])
        .current_dir(temp.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(0), "{stderr}");
    assert!(!stale.exists(), "{stderr}");
    assert!(
        stderr.contains("removed ./.out.exr.tmp-4294967295-3"),
        "{stderr}"
    );
    assert!(
        stderr.contains("room.obj: line 10: usemtl 'flor' names no material (known: floor, light)"),
        "{stderr}"
    );
}

/// Every technique with every option it takes set to a value other than its default: the
/// command line its options write ([`RenderOptions::to_args`], what `batch --jobs` prints)
/// renders, through the binary's own arguments, an image whose recorded options are the same.
#[test]
fn options_written_as_arguments_come_back_from_the_image() {
    use vmerge::options::{DensityMis, MemoryLayout, SamplerKind, Technique, OPTIONS};
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box/scene.toml");
    for technique in Technique::ALL {
        let all = RenderOptions {
            technique,
            seed: 7,
            camera: Some("floor".into()),
            resolution: Some([8, 6]),
            beta: 1.5,
            radius: Some(0.07),
            // Excludes `radius` (tests/vcm.rs renders with it).
            radius_pixels: None,
            alpha: Some(0.5),
            max_path_length: Some(6),
            roulette: 2,
            no_vc: true,
            no_vm: technique != Technique::Vcm,
            strategy: Some([1, 2]),
            unweighted: true,
            upg_packet: 8,
            upg_max_trials: 50,
            blend_near: 1.0,
            blend_far: 3.0,
            hybrid_roughness: 0.35,
            density_mis: Some(DensityMis::Star),
            density_map_iterations: 2,
            no_shading_normals: true,
            light_paths: Some(20),
            // One-stage takes neither a density map nor another light path count.
            memory: MemoryLayout::TwoStage,
            min_path_length: 2,
            sampler: SamplerKind::Independent,
        };
        // What the technique does not take keeps its default.
        let mut options = RenderOptions {
            technique,
            ..RenderOptions::DEFAULT
        };
        for spec in OPTIONS.iter().filter(|s| (s.takes)(technique)) {
            if let Some(value) = (spec.write)(&all) {
                spec.read(&mut options, &value).unwrap();
            }
        }
        assert_eq!(options.validate(), Ok(()), "{options:?}");
        let out = tempfile::tempdir().unwrap();
        let exr = out.path().join("out.exr");
        let args = options.to_args();
        let result = vmerge()
            .args(["render", "-n", "1", "--accel", "bvh", "--no-png", "-o"])
            .arg(&exr)
            .args(&args)
            .arg(&scene)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(0), "{args:?}: {stderr}");
        let recorded = vmerge::tools::metadata(&exr).unwrap().options;
        assert_eq!(recorded, options, "{args:?}");
    }
}

/// `--preview` at an address another process holds is the user's mistake: exit 2 before any
/// work, a message naming the flag, and no image written.
#[test]
fn preview_address_in_use_exits_2_and_names_the_flag() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = taken.local_addr().unwrap().to_string();
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/bad/plan-trace-outside");
    let temp = tempfile::tempdir().unwrap();
    for file in ["scene.toml", "room.obj", "room.mtl"] {
        std::fs::copy(fixture.join(file), temp.path().join(file)).unwrap();
    }
    let result = vmerge()
        .args(["render", "-n", "1", "--resolution", "8x8", "--accel", "bvh"])
        .args(["--preview", &address, "-o", "out.exr", "scene.toml"])
        .current_dir(temp.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains(&format!("--preview {address}")), "{stderr}");
    assert!(stderr.len() < 2000, "{stderr}");
    assert!(!temp.path().join("out.exr").exists(), "{stderr}");
    assert!(!temp.path().join("out.png").exists(), "{stderr}");
    drop(taken);
}
