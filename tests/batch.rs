//! `vmerge batch`: a small plan run through GNU parallel from `--jobs`, resumed, re-run, and
//! reported (the report opened in headless Chromium); `--slurm` drivers run by hand, stage by
//! stage and task by task, with a stand-in sbatch; bad plans refused.

mod common;

use common::browser::headless_chromium;
use common::programs::{have, parallel};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::SystemTime;
use vmerge::tools::{self, batch::Plan};

fn vmerge() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vmerge"))
}

fn scene(name: &str) -> String {
    format!("{}/scenes/{name}/scene.toml", env!("CARGO_MANIFEST_DIR"))
}

/// Runs `vmerge ARGS` and returns stdout, asserting success.
fn run(args: &[&str]) -> String {
    let out = vmerge().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "vmerge {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

const TECHNIQUES: [&str; 3] = ["vcm", "upg", "upg-camera"];
const RADII: [&str; 3] = ["0_02", "0_05", "0_1"];
const SCENES: [&str; 2] = ["cornell-box", "indirect"];

fn write_plan(dir: &Path, traces: &str) -> PathBuf {
    let plan = dir.join("plan.toml");
    let text = format!(
        r#"output = "results"
resolution = [32, 32]
iterations = 4
traces = [{traces}]
[[scene]]
file = "{}"
cameras = ["front"]
reference = {{ technique = "bpt", iterations = 64, parts = 2 }}
[[scene]]
file = "{}"
cameras = ["front"]
reference = {{ technique = "bpt", iterations = 64 }}
[[group]]
techniques = ["vcm", "upg", "upg-camera"]
radius = [0.02, 0.05, 0.1]
"#,
        scene(SCENES[0]),
        scene(SCENES[1])
    );
    std::fs::write(&plan, text).unwrap();
    plan
}

/// Every cell of the plan above, by the name its parameters give it.
fn cell_names() -> Vec<String> {
    let mut names = vec![
        "cornell-box.front.reference.p0".to_string(),
        "cornell-box.front.reference.p1".into(),
        "cornell-box.front.reference".into(),
        "indirect.front.reference".into(),
    ];
    for s in SCENES {
        for t in TECHNIQUES {
            for r in RADII {
                names.push(format!("{s}.front.{t}.r{r}"));
            }
        }
    }
    names
}

/// `--jobs` piped to `parallel -j 2` until it prints nothing; returns the rounds it took.
fn run_with_parallel(plan: &Path, dir: &Path) -> usize {
    for round in 0..5 {
        let jobs = run(&["batch", plan.to_str().unwrap(), "--jobs"]);
        if jobs.trim().is_empty() {
            return round;
        }
        parallel(&jobs, dir);
    }
    panic!("--jobs still prints commands after 5 rounds");
}

fn modification_times(dir: &Path) -> BTreeMap<PathBuf, SystemTime> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "exr" || e == "png"))
        .map(|p| {
            let t = std::fs::metadata(&p).unwrap().modified().unwrap();
            (p, t)
        })
        .collect()
}

/// A report's table read back from CSV.
struct CsvTable {
    variants: Vec<String>,
    /// (radius, one value per variant).
    rows: Vec<(String, Vec<Option<f64>>)>,
    /// Each variant's best radius.
    best: Vec<String>,
}

fn read_csv(path: &Path) -> CsvTable {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    let mut rows = Vec::new();
    let mut best = Vec::new();
    for line in lines {
        let fields: Vec<&str> = line.split(',').collect();
        if fields[0] == "best" {
            best = fields[1..].iter().map(|s| s.to_string()).collect();
        } else {
            let values = fields[1..].iter().map(|v| v.parse().ok()).collect();
            rows.push((fields[0].to_string(), values));
        }
    }
    CsvTable {
        variants: header[1..].to_vec(),
        rows,
        best,
    }
}

/// The report's best-radius tables hold the final errors the cells' EXRs record, and mark
/// each technique's lowest.
fn check_tables(results: &Path) {
    for s in SCENES {
        for (metric, pick) in [("mae", 0), ("rmse", 1)] {
            let csv = results.join(format!("report/tables/{s}.front.{metric}.csv"));
            let CsvTable {
                variants,
                rows,
                best,
            } = read_csv(&csv);
            assert_eq!(variants, TECHNIQUES);
            assert_eq!(rows.len(), RADII.len());
            for (c, t) in TECHNIQUES.iter().enumerate() {
                let mut lowest: Option<(String, f64)> = None;
                for (r, radius) in RADII.iter().enumerate() {
                    let m = tools::metadata(&results.join(format!("{s}.front.{t}.r{radius}.exr")))
                        .unwrap();
                    let last = m.errors.last().expect("an error series");
                    let recorded = [last.mae, last.rmse][pick];
                    assert_eq!(rows[r].0, radius.replace('_', "."));
                    assert_eq!(rows[r].1[c], Some(recorded), "{s} {t} r {radius} {metric}");
                    if lowest.as_ref().is_none_or(|(_, v)| recorded < *v) {
                        lowest = Some((rows[r].0.clone(), recorded));
                    }
                }
                assert_eq!(best[c], lowest.unwrap().0, "{s} {t} {metric}: best radius");
            }
        }
    }
}

/// Mean pixel values of a render, for comparing two of them bit for bit.
fn pixels(path: &Path) -> Vec<[f32; 3]> {
    let (film, _) = vmerge::film::exr::read_render(path).unwrap();
    film.mean().iter().map(|p| p.to_array()).collect()
}

#[test]
fn plan_runs_through_parallel_resumes_and_reports() {
    if !have("parallel") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let plan = write_plan(dir.path(), r#""8x8x4""#);
    let plan_arg = plan.to_str().unwrap();
    let results = dir.path().join("results");
    // Reference parts, then their merge and the other scene's cells, then the rest.
    let rounds = run_with_parallel(&plan, dir.path());
    assert_eq!(rounds, 3);
    for name in cell_names() {
        assert!(results.join(format!("{name}.exr")).exists(), "{name}");
    }
    let status = run(&["batch", "status", plan_arg]);
    assert!(status.contains("22 cells: 22 done"), "{status}");

    run(&["batch", "report", plan_arg]);
    check_tables(&results);

    // Nothing left to do: no command printed, nothing rendered in-process, no file touched.
    let before = modification_times(&results);
    assert_eq!(run(&["batch", plan_arg, "--jobs"]), "");
    let out = vmerge().args(["batch", plan_arg]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("0 cells rendered"));
    assert_eq!(modification_times(&results), before);

    // A deleted cell is the one command printed, and the only file rendered again.
    let gone = results.join("indirect.front.upg.r0_05.exr");
    let original = pixels(&gone);
    std::fs::remove_file(&gone).unwrap();
    let jobs = run(&["batch", plan_arg, "--jobs"]);
    assert_eq!(jobs.lines().count(), 1, "{jobs}");
    assert!(jobs.contains(" render ") && jobs.contains("indirect.front.upg.r0_05.exr"));
    let out = vmerge().args(["batch", plan_arg]).output().unwrap();
    assert!(String::from_utf8_lossy(&out.stderr).contains("1 cells rendered"));
    let after = modification_times(&results);
    let changed: Vec<&PathBuf> = after
        .iter()
        .filter(|(p, t)| before.get(*p) != Some(t))
        .map(|(p, _)| p)
        .collect();
    assert_eq!(
        changed,
        [&gone, &gone.with_extension("png")],
        "only the deleted cell is rendered again"
    );
    assert_eq!(pixels(&gone), original);

    // An interrupted cell (written after 2 of its 4 iterations, as a signal or a snapshot
    // leaves it) continues where it stopped and ends with the same image.
    std::fs::remove_file(&gone).unwrap();
    let command = run(&["batch", plan_arg, "--jobs"]);
    let interrupted = command.trim().replace(" -n 4 ", " -n 2 ");
    assert_ne!(interrupted, command.trim());
    let status = Command::new("bash")
        .args(["-c", &interrupted])
        .current_dir(dir.path())
        .output()
        .unwrap();
    assert!(status.status.success());
    let state = run(&["batch", "status", plan_arg]);
    assert!(
        state.contains("partial  indirect.front.upg.r0_05  2 it"),
        "{state}"
    );
    let jobs = run(&["batch", plan_arg, "--jobs"]);
    assert!(
        jobs.contains(" continue ") && jobs.contains(" -n 2") && jobs.lines().count() == 1,
        "{jobs}"
    );
    assert_eq!(run_with_parallel(&plan, dir.path()), 1);
    assert_eq!(pixels(&gone), original);
    let m = tools::metadata(&gone).unwrap();
    assert_eq!((m.iterations, m.errors.last().unwrap().iterations), (4, 4));

    // A changed entry (other trace windows) re-renders the cells it makes, not the
    // references.
    write_plan(dir.path(), r#""8x8x4", "20x20x4""#);
    let dry = run(&["batch", plan_arg, "--dry-run"]);
    assert!(dry.contains("18 of 22 cells would run"), "{dry}");
    assert!(!dry.contains("reference"), "{dry}");
    write_plan(dir.path(), r#""8x8x4""#);

    check_in_chromium(&results.join("report"));
}

/// Distinct colours and strongly coloured pixels of an RGB(A) PNG.
fn colour_counts(path: &Path) -> (usize, usize) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    let channels = info.color_type.samples();
    let pixels: Vec<&[u8]> = buffer[..info.buffer_size()]
        .chunks(channels)
        .map(|p| &p[..3])
        .collect();
    let coloured = pixels
        .iter()
        .filter(|p| {
            let (lo, hi) = (p.iter().min().unwrap(), p.iter().max().unwrap());
            hi - lo > 60
        })
        .count();
    let mut distinct = pixels.clone();
    distinct.sort_unstable();
    distinct.dedup();
    (distinct.len(), coloured)
}

/// The values of `attribute="..."` in an HTML text.
fn attribute_values(html: &str, attribute: &str) -> Vec<String> {
    let key = format!(" {attribute}=\"");
    html.split(&key)
        .skip(1)
        .filter_map(|rest| rest.split('"').next().map(String::from))
        .collect()
}

/// Opens the report in headless Chromium: the screenshot shows the coloured thumbnails and
/// charts (a page of text alone is grey), and every image and link of the DOM Chromium built
/// names a file that exists.
fn check_in_chromium(report: &Path) {
    if !have("chromium") {
        return;
    }
    let index = report.join("index.html");
    let url = format!("file://{}", index.display());
    let profile = tempfile::tempdir().unwrap();
    let chromium = |extra: &[&str]| {
        headless_chromium(Path::new("chromium"), "120", "1280,2400", profile.path())
            .args(extra)
            .arg(&url)
            .output()
            .unwrap()
    };
    let shot = profile.path().join("shot.png");
    let out = chromium(&[&format!("--screenshot={}", shot.display())]);
    assert!(out.status.success() && shot.exists(), "{out:?}");
    let (distinct, coloured) = colour_counts(&shot);
    assert!(distinct > 500, "a blank screenshot: {distinct} colours");
    assert!(coloured > 20_000, "only {coloured} coloured pixels");

    let dom = chromium(&["--dump-dom"]);
    assert!(dom.status.success(), "chromium --dump-dom: {}", dom.status);
    let dom = String::from_utf8(dom.stdout).unwrap();
    let images = attribute_values(&dom, "src");
    // Per view: the reference and each technique's best cell, the radius chart, a
    // convergence chart per technique.
    assert_eq!(images.len(), SCENES.len() * (1 + 3 + 1 + 3), "{images:?}");
    assert!(images.iter().any(|i| i.contains("reference")));
    let links = attribute_values(&dom, "href");
    assert!(links.len() >= images.len());
    for target in images.iter().chain(&links) {
        assert!(!target.contains("://"), "{target} is not a relative link");
        assert!(report.join(target).exists(), "{target} is missing");
    }
}

/// A plan whose cells run from an `sbatch --array` script, each task run by hand with
/// `SLURM_ARRAY_TASK_ID` set, stage after stage.
#[test]
fn slurm_script_runs_each_task_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("plan.toml");
    std::fs::write(
        &plan,
        format!(
            r#"output = "out"
resolution = [16, 16]
iterations = 2
threads = 2
[slurm]
partition = "short"
account = "rendering"
sbatch = ["--qos=low"]
[[scene]]
file = "{}"
cameras = ["floor"]
reference = {{ iterations = 16, parts = 2 }}
[[group]]
techniques = ["vcm", "upg"]
radius = [0.05, 0.1]
"#,
            scene("cornell-box")
        ),
    )
    .unwrap();
    let plan_arg = plan.to_str().unwrap();
    let script = dir.path().join("plan.sbatch");
    run(&["batch", plan_arg, "--slurm", script.to_str().unwrap()]);
    let text = std::fs::read_to_string(&script).unwrap();
    let syntax = Command::new("bash")
        .arg("-n")
        .arg(&script)
        .status()
        .unwrap();
    assert!(syntax.success(), "bash -n: {text}");
    // An sbatch that keeps each stage's script and arguments and answers a job id.
    let fake = dir.path().join("fake");
    std::fs::create_dir(&fake).unwrap();
    let sbatch = fake.join("sbatch");
    std::fs::write(
        &sbatch,
        format!(
            "#!/usr/bin/env bash\nn=$(ls {0}/stage*.sh 2>/dev/null | wc -l)\n\
             cat > {0}/stage$n.sh\necho \"$*\" > {0}/args$n\necho \"$((100 + n));cluster\"\n",
            fake.display()
        ),
    )
    .unwrap();
    Command::new("chmod")
        .args(["+x", sbatch.to_str().unwrap()])
        .status()
        .unwrap();
    let path = format!("{}:{}", fake.display(), std::env::var("PATH").unwrap());
    let out = Command::new("bash")
        .arg(&script)
        .env("PATH", path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout),
        "stage 1: job 100 (2 cells)\nstage 2: job 101 (1 cells)\nstage 3: job 102 (4 cells)\n"
    );
    let args = |n: usize| std::fs::read_to_string(fake.join(format!("args{n}"))).unwrap();
    assert_eq!(args(0), "--parsable\n");
    assert_eq!(args(1), "--parsable --dependency=afterok:100\n");
    assert_eq!(args(2), "--parsable --dependency=afterok:101\n");
    // Two reference parts, their merge, four cells.
    let mut tasks_run = 0;
    for (stage, n) in [2, 1, 4].into_iter().enumerate() {
        let stage_script = fake.join(format!("stage{stage}.sh"));
        let text = std::fs::read_to_string(&stage_script).unwrap();
        for line in [
            format!("#SBATCH --array=0-{}\n", n - 1),
            "#SBATCH --cpus-per-task=2\n".into(),
            "#SBATCH --requeue\n".into(),
            "#SBATCH --open-mode=append\n".into(),
            "#SBATCH --partition=short\n".into(),
            "#SBATCH --account=rendering\n".into(),
            "#SBATCH --qos=low\n".into(),
        ] {
            assert!(text.contains(&line), "{line}: {text}");
        }
        // Iteration budgets give no time limit, a merge ten minutes; 16x16 pixels need
        // little beyond the allowance.
        assert_eq!(
            text.contains("#SBATCH --time=0-00:10:00\n"),
            stage == 1,
            "{text}"
        );
        assert_eq!(text.matches("--time=").count(), usize::from(stage == 1));
        assert!(text.contains("#SBATCH --mem=52"), "{text}");
        let tasks = text.lines().filter(|l| l.contains(") exec ")).count();
        assert_eq!(tasks, n);
        for i in 0..n {
            let status = Command::new("bash")
                .arg(&stage_script)
                .env("SLURM_ARRAY_TASK_ID", i.to_string())
                .current_dir(dir.path())
                .output()
                .unwrap();
            assert!(status.status.success(), "task {i}: {status:?}");
            tasks_run += 1;
        }
        let past = Command::new("bash")
            .arg(&stage_script)
            .env("SLURM_ARRAY_TASK_ID", n.to_string())
            .output()
            .unwrap();
        assert_eq!(past.status.code(), Some(2));
    }
    assert_eq!(tasks_run, 7);
    let status = run(&["batch", "status", plan_arg]);
    assert!(status.contains("7 cells: 7 done"), "{status}");
    let loaded = Plan::load(&plan).unwrap();
    assert!(loaded.cells.iter().all(|c| c.output.exists()));
    // With a submission recorded but no squeue or sacct to ask, the files alone tell.
    std::fs::write(
        dir.path().join("out/slurm-jobs.toml"),
        "[[task]]\ncell = \"cornell-box.floor.reference\"\njob = \"101\"\ntask = 0\nstage = 1\n",
    )
    .unwrap();
    let out = vmerge()
        .args(["batch", "status", plan_arg])
        .env("PATH", &fake)
        .output()
        .unwrap();
    let status = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{out:?}");
    assert!(
        status.contains("unknown  101_0      -            cornell-box.floor.reference")
            && status.contains("neither squeue nor sacct answered")
            && status.contains("7 cells: 7 done"),
        "{status}"
    );
    // A task run again (a requeue after its end) finds its cell done and does nothing.
    let before = modification_times(&dir.path().join("out"));
    let again = Command::new("bash")
        .arg(fake.join("stage2.sh"))
        .env("SLURM_ARRAY_TASK_ID", "0")
        .output()
        .unwrap();
    assert!(again.status.success(), "{again:?}");
    assert_eq!(modification_times(&dir.path().join("out")), before);
    // Nothing left: the driver holds no stage.
    run(&["batch", plan_arg, "--slurm", script.to_str().unwrap()]);
    let text = std::fs::read_to_string(&script).unwrap();
    assert!(!text.contains("sbatch --parsable"), "{text}");
}

/// Bad plans: exit code 2, a message naming the plan file and the entry, nothing written.
#[test]
fn bad_plans_exit_2_and_name_the_entry() {
    let dir = tempfile::tempdir().unwrap();
    let base = format!(
        "output = \"out\"\niterations = 2\n[[scene]]\nfile = \"{}\"\n",
        scene("cornell-box")
    );
    let cases = [
        (
            "[[group]]\ntechniques = [\"vcmx\"]\n",
            "[[group]] 1: techniques",
        ),
        (
            "[[group]]\ntechniques = [\"vcm\"]\ncolour = 3\n",
            "unknown key 'colour'",
        ),
        (
            "[[group]]\ntechniques = [\"vcm\"]\nradius = { from = 0.1, to = 0.01, steps = 3 }\n",
            "[[group]] 1: radius",
        ),
        (
            "[[group]]\ntechniques = [\"upg\"]\nalpha = 0.5\n",
            "[[group]] 1 (upg): --alpha does not apply to upg",
        ),
        (
            "[[group]]\ntechniques = [\"vcm\"]\nradius = [0.01, -1]\n",
            "radius -1",
        ),
        (
            "[[group]]\ntechniques = [\"vcm\"]\nscenes = [\"nowhere\"]\n",
            "no scene named 'nowhere'",
        ),
        (
            "[slurm]\npartition = \"short queue\"\n[[group]]\ntechniques = [\"vcm\"]\n",
            "slurm: partition: 'short queue'",
        ),
        (
            "[slurm]\naccount = \"\"\n[[group]]\ntechniques = [\"vcm\"]\n",
            "slurm: account",
        ),
        (
            "[slurm]\ntime_limit = \"soon\"\n[[group]]\ntechniques = [\"vcm\"]\n",
            "slurm: time_limit",
        ),
        (
            "[slurm]\nmem = \"lots\"\n[[group]]\ntechniques = [\"vcm\"]\n",
            "slurm: mem",
        ),
        (
            "[slurm]\nsbatch = [\"qos=low\"]\n[[group]]\ntechniques = [\"vcm\"]\n",
            "slurm: sbatch: 'qos=low'",
        ),
        (
            "[slurm]\nqueue = \"short\"\n[[group]]\ntechniques = [\"vcm\"]\n",
            "slurm: unknown key 'queue'",
        ),
        // Bounded before anything is allocated.
        (
            "[[group]]\ntechniques = [\"vcm\"]\nradius = { from = 0.01, to = 0.1, steps = 4000000000 }\n",
            "[[group]] 1: radius: steps = 4000000000",
        ),
        (
            "reference = { iterations = 4, parts = 1000000 }\n[[group]]\ntechniques = [\"vcm\"]\n",
            "reference: parts: 1000000 parts",
        ),
        (
            "[[group]]\ntechniques = [\"vcm\"]\nradius = { from = 0.01, to = 0.1, steps = 100 }\n\
             beta = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\nseeds = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]\n",
            "make 11000 cells",
        ),
        // Found before work, not after it.
        (
            "reference = \"out/cornell-box.cam0.vcm.exr\"\n[[group]]\ntechniques = [\"vcm\"]\n",
            "is what cell cornell-box.cam0.vcm of this plan writes",
        ),
        (
            "reference = { iterations = 4 }\n[[group]]\ntechniques = [\"vcm\"]\n\
             resolution = [8, 8]\ntraces = [\"12x0x2\"]\n",
            "the window at (12, 0) lies outside its 8x8 image",
        ),
    ];
    // Refused before any work, whether listed or submitted.
    for ((i, (group, expected)), mode) in cases
        .iter()
        .enumerate()
        .flat_map(|c| [(c, "--jobs"), (c, "--submit")])
    {
        let plan = dir.path().join(format!("bad{i}.toml"));
        std::fs::write(&plan, format!("{base}{group}")).unwrap();
        let out = vmerge()
            .args(["batch", plan.to_str().unwrap(), mode])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{group}: {stderr}");
        assert!(
            stderr.contains(&format!("bad{i}.toml")) && stderr.contains(expected),
            "{group}: {stderr}"
        );
        assert!(!dir.path().join("out").exists(), "{group}: wrote output");
    }
}

/// Options beyond radius and beta reach the command lines `--jobs` prints with their values:
/// a plan with 002's weights, the sampler, the density map's iterations, the light sub-paths,
/// the shortest path and merge-only techniques, run through GNU parallel, renders the pixels
/// the same plan renders in-process, each cell under a name of its own.
#[test]
fn every_option_reaches_the_job_lines_and_renders_the_in_process_pixels() {
    if !have("parallel") {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let plan_text = |output: &str| {
        format!(
            r#"output = "{output}"
resolution = [16, 12]
iterations = 4
[[scene]]
file = "{}"
cameras = ["front"]
[[group]]
techniques = ["vcm"]
radius = 0.05
density_mis = "vcm*"
sampler = "independent"
density_map_iterations = 3
light_paths = 100
min_path_length = 2
[[group]]
techniques = ["vcm"]
radius = 0.05
density_mis = "vcm+"
[[group]]
techniques = ["vcm", "upg"]
radius = 0.05
no_vc = true
"#,
            scene("cornell-box")
        )
    };
    let jobs_plan = dir.path().join("jobs.toml");
    let here_plan = dir.path().join("here.toml");
    std::fs::write(&jobs_plan, plan_text("jobs")).unwrap();
    std::fs::write(&here_plan, plan_text("here")).unwrap();

    let jobs = run(&["batch", jobs_plan.to_str().unwrap(), "--jobs"]);
    let lines: Vec<&str> = jobs.lines().collect();
    assert_eq!(lines.len(), 4, "{jobs}");
    assert!(
        lines[0].contains(" --technique vcm ")
            && lines[0].contains(" --min-path-length 2 ")
            && lines[0].contains(" --light-paths 100 ")
            && lines[0].contains(" --sampler independent ")
            && lines[0].contains(" --density-mis 'vcm*' ")
            && lines[0].contains(" --density-map-iterations 3 "),
        "{jobs}"
    );
    assert!(lines[1].contains(" --density-mis vcm+ "), "{jobs}");
    assert!(lines[2].contains(" --no-vc ") && lines[3].contains(" --no-vc "));
    parallel(&jobs, dir.path());
    assert_eq!(run(&["batch", jobs_plan.to_str().unwrap(), "--jobs"]), "");

    run(&["batch", here_plan.to_str().unwrap()]);
    let names = |folder: &str| {
        let mut names: Vec<String> = std::fs::read_dir(dir.path().join(folder))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.ends_with(".exr"))
            .collect();
        names.sort();
        names
    };
    let expected = [
        "cornell-box.front.upg.no-vc.r0_05.exr",
        "cornell-box.front.vcm.density-misvcmplus.r0_05.exr",
        "cornell-box.front.vcm.min-path-length2.light-paths100.samplerindependent.density-misvcmstar.density-map-iterations3.r0_05.exr",
        "cornell-box.front.vcm.no-vc.r0_05.exr",
    ];
    assert_eq!(names("jobs"), expected);
    assert_eq!(names("here"), expected);
    for name in expected {
        let (jobs, here) = (
            dir.path().join("jobs").join(name),
            dir.path().join("here").join(name),
        );
        assert_eq!(
            tools::metadata(&jobs).unwrap().options,
            tools::metadata(&here).unwrap().options,
            "{name}"
        );
        assert_eq!(pixels(&jobs), pixels(&here), "{name}");
    }
}
