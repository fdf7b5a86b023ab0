//! `vmerge batch --submit` on a real Slurm cluster: the test starts its own single node on this
//! machine (`munged`, `slurmctld` and `slurmd` on localhost, as root, with a generated
//! `slurm.conf` and everything in a temporary folder) and stops the daemons by their pids
//! afterwards. Where the daemons cannot start (not root, Slurm or MUNGE not installed), it says
//! why and skips; scripts/setup-debian --tests installs slurm-wlm and munge.
//!
//! Accounting storage is left out (no slurmdbd): `batch status` reads the states from
//! `squeue`, which keeps finished jobs for `MinJobAge`; `jobcomp/filetxt` records each
//! finished job in the cluster's folder for whoever wants to read them.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// One cluster at a time: the node has two CPUs, and the tests time their plans.
static CLUSTER: Mutex<()> = Mutex::new(());

const TOOLS: [&str; 7] = [
    "munged",
    "slurmctld",
    "slurmd",
    "sbatch",
    "squeue",
    "scontrol",
    "scancel",
];

fn scene(name: &str) -> String {
    format!("{}/scenes/{name}/scene.toml", env!("CARGO_MANIFEST_DIR"))
}

/// A single-node cluster; dropping it stops its daemons.
struct Cluster {
    dir: tempfile::TempDir,
    conf: PathBuf,
    daemons: Vec<(&'static str, Child)>,
}

impl Drop for Cluster {
    fn drop(&mut self) {
        // Controller and node first, so that no task is left to the node's absence.
        for (_, child) in self.daemons.iter_mut().rev() {
            let _ = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
            let start = Instant::now();
            while start.elapsed() < Duration::from_secs(10) {
                if matches!(child.try_wait(), Ok(Some(_))) {
                    break;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Why the cluster cannot start here, if it cannot.
fn missing() -> Option<String> {
    let uid = Command::new("id").arg("-u").output().ok()?;
    if String::from_utf8_lossy(&uid.stdout).trim() != "0" {
        return Some("not root: slurmd must run as root to start tasks as their user".into());
    }
    let absent: Vec<&str> = TOOLS
        .iter()
        .copied()
        .filter(|t| {
            !Command::new("sh")
                .args(["-c", &format!("command -v {t}")])
                .stdout(Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
        })
        .collect();
    (!absent.is_empty()).then(|| {
        format!(
            "{} not on the PATH (the daemons are in /usr/sbin; scripts/setup-debian --tests \
             installs slurm-wlm and munge)",
            absent.join(", ")
        )
    })
}

/// Two ports free now, for the controller and the node (held together, so they differ).
fn free_ports() -> [u16; 2] {
    let listeners = [(); 2].map(|()| std::net::TcpListener::bind("127.0.0.1:0").unwrap());
    listeners.map(|l| l.local_addr().unwrap().port())
}

fn total_memory_mib() -> u64 {
    let text = std::fs::read_to_string("/proc/meminfo").unwrap();
    let line = text.lines().find(|l| l.starts_with("MemTotal:")).unwrap();
    line.split_whitespace()
        .nth(1)
        .unwrap()
        .parse::<u64>()
        .unwrap()
        / 1024
}

impl Cluster {
    /// Starts the daemons and waits (at most 60 s) for the node to be idle; `Err` says why it
    /// could not.
    fn start() -> Result<Cluster, String> {
        if let Some(why) = missing() {
            return Err(why);
        }
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().to_path_buf();
        for sub in ["munge", "state", "spool"] {
            std::fs::create_dir(d.join(sub)).unwrap();
        }
        // The daemons reach into the folder as root; tempdir makes it private.
        let key = d.join("munge/munge.key");
        let mut random = Vec::new();
        std::io::Read::read_to_end(
            &mut std::io::Read::take(std::fs::File::open("/dev/urandom").unwrap(), 1024),
            &mut random,
        )
        .unwrap();
        std::fs::write(&key, random).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o400)).unwrap();
        let socket = d.join("munge/munge.socket");
        let conf = d.join("slurm.conf");
        let ports = free_ports();
        let p = |name: &str| d.join(name).to_string_lossy().into_owned();
        std::fs::write(
            &conf,
            format!(
                "ClusterName=vmergetest
SlurmctldHost=localhost
SlurmctldPort={}
SlurmdPort={}
AuthType=auth/munge
AuthInfo=socket={}
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation={}
SlurmdSpoolDir={}
SlurmctldPidFile={}
SlurmdPidFile={}
SlurmctldLogFile={}
SlurmdLogFile={}
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobCompType=jobcomp/filetxt
JobCompLoc={}
MinJobAge=3600
KillWait=10
NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 RealMemory={} State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
",
                ports[0],
                ports[1],
                socket.display(),
                p("state"),
                p("spool"),
                p("slurmctld.pid"),
                p("slurmd.pid"),
                p("slurmctld.log"),
                p("slurmd.log"),
                p("jobcomp.txt"),
                total_memory_mib() / 2,
            ),
        )
        .unwrap();
        let mut cluster = Cluster {
            dir,
            conf,
            daemons: Vec::new(),
        };
        let spawn = |cluster: &mut Cluster, name: &'static str, args: &[String]| {
            let out = std::fs::File::create(d.join(format!("{name}.out"))).unwrap();
            let child = Command::new(name)
                .args(args)
                .env("SLURM_CONF", &cluster.conf)
                .stdin(Stdio::null())
                .stdout(out.try_clone().unwrap())
                .stderr(out)
                .spawn()
                .map_err(|e| format!("{name} does not start: {e}"))?;
            cluster.daemons.push((name, child));
            Ok::<(), String>(())
        };
        spawn(
            &mut cluster,
            "munged",
            &[
                "--foreground".into(),
                "--force".into(),
                format!("--key-file={}", key.display()),
                format!("--socket={}", socket.display()),
                format!("--pid-file={}", p("munge/munged.pid")),
                format!("--log-file={}", p("munge/munged.log")),
                format!("--seed-file={}", p("munge/munged.seed")),
            ],
        )?;
        cluster.wait_for("munged's socket", Duration::from_secs(20), |_| {
            socket.exists()
        })?;
        let conf = cluster.conf.to_string_lossy().into_owned();
        spawn(
            &mut cluster,
            "slurmctld",
            &["-D".into(), "-i".into(), "-f".into(), conf.clone()],
        )?;
        spawn(
            &mut cluster,
            "slurmd",
            &[
                "-D".into(),
                "-N".into(),
                "localhost".into(),
                "-f".into(),
                conf,
            ],
        )?;
        cluster.wait_for("the node to be idle", Duration::from_secs(60), |c| {
            c.slurm("sinfo", &["--noheader", "--format=%T"])
                .is_some_and(|o| o.trim() == "idle")
        })?;
        Ok(cluster)
    }

    /// Polls `ready` every 200 ms for at most `limit`; a daemon that ends meanwhile, or the
    /// limit, is an error with the daemons' output.
    fn wait_for(
        &mut self,
        what: &str,
        limit: Duration,
        ready: impl Fn(&Cluster) -> bool,
    ) -> Result<(), String> {
        let start = Instant::now();
        loop {
            if ready(self) {
                return Ok(());
            }
            let ended = self
                .daemons
                .iter_mut()
                .find_map(|(name, child)| Some((*name, child.try_wait().ok()??)));
            if let Some((name, status)) = ended {
                return Err(format!(
                    "{name} ended ({status}) while waiting for {what}: {}",
                    self.logs()
                ));
            }
            if start.elapsed() > limit {
                return Err(format!(
                    "no {what} after {} s: {}",
                    limit.as_secs(),
                    self.logs()
                ));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// The ends of the daemons' logs.
    fn logs(&self) -> String {
        let mut text = String::new();
        for name in [
            "munged.out",
            "munge/munged.log",
            "slurmctld.out",
            "slurmctld.log",
            "slurmd.out",
            "slurmd.log",
        ] {
            if let Ok(log) = std::fs::read_to_string(self.dir.path().join(name)) {
                let lines: Vec<&str> = log.lines().collect();
                let tail = lines[lines.len().saturating_sub(8)..].join("\n");
                text.push_str(&format!("\n--- {name}\n{tail}"));
            }
        }
        text
    }

    /// A Slurm command's standard output, or `None` when it fails.
    fn slurm(&self, program: &str, args: &[&str]) -> Option<String> {
        let out = Command::new(program)
            .args(args)
            .env("SLURM_CONF", &self.conf)
            .output()
            .ok()?;
        out.status
            .success()
            .then(|| String::from_utf8_lossy(&out.stdout).into_owned())
    }

    fn vmerge(&self, args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_vmerge"))
            .args(args)
            .env("SLURM_CONF", &self.conf)
            .output()
            .unwrap()
    }

    /// `vmerge ARGS`, which must succeed; its standard output.
    fn run(&self, args: &[&str]) -> String {
        let out = self.vmerge(args);
        assert!(
            out.status.success(),
            "vmerge {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    }

    /// Every array task of `jobs` as squeue has it: `12_3` to `RUNNING`.
    fn squeue(&self, jobs: &[String]) -> HashMap<String, String> {
        let out = self
            .slurm(
                "squeue",
                &[
                    "--noheader",
                    "--array",
                    "--states=all",
                    "--format=%i|%T",
                    &format!("--jobs={}", jobs.join(",")),
                ],
            )
            .unwrap_or_default();
        out.lines()
            .filter_map(|l| l.trim().split_once('|'))
            .map(|(id, state)| (id.to_string(), state.to_string()))
            .collect()
    }

    /// One field of `scontrol show job ID` (`JobState`, `Restarts`, `ExitCode`).
    fn scontrol(&self, id: &str, field: &str) -> String {
        let out = self
            .slurm("scontrol", &["show", "job", id])
            .unwrap_or_default();
        out.split_whitespace()
            .find_map(|w| w.strip_prefix(&format!("{field}=")))
            .unwrap_or("")
            .to_string()
    }

    /// Waits (at most `limit`) until `done` holds of the tasks' states, with the daemons'
    /// logs and the states in the message when it does not.
    fn wait_jobs(
        &mut self,
        jobs: &[String],
        limit: Duration,
        what: &str,
        done: impl Fn(&HashMap<String, String>) -> bool,
    ) {
        let result = self.wait_for(what, limit, |c| done(&c.squeue(jobs)));
        if let Err(e) = result {
            panic!("{e}\nstates: {:?}", self.squeue(jobs));
        }
    }
}

/// Whether every state of `states` is one a task ends in.
fn all_ended(states: &HashMap<String, String>) -> bool {
    !states.is_empty()
        && states.values().all(|s| {
            !matches!(
                s.as_str(),
                "PENDING" | "RUNNING" | "CONFIGURING" | "COMPLETING" | "REQUEUED"
            )
        })
}

/// The cluster, or `None` with the reason printed (skipped).
fn cluster() -> Option<Cluster> {
    match Cluster::start() {
        Ok(c) => Some(c),
        Err(why) => {
            eprintln!("skipped: no local Slurm cluster: {why}");
            None
        }
    }
}

/// Mean pixel values of a render, for comparing two of them bit for bit.
fn pixels(path: &Path) -> Vec<[f32; 3]> {
    let (film, _) = vmerge::film::exr::read_render(path).unwrap();
    film.mean().iter().map(|p| p.to_array()).collect()
}

/// `batch status`'s Slurm lines: task id to (word, Slurm state, cell).
fn status_tasks(status: &str) -> HashMap<String, (String, String, String)> {
    status
        .lines()
        .filter_map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            match words[..] {
                [word, id, state, cell]
                    if id.contains('_')
                        && ["queued", "running", "done", "failed"].contains(&word) =>
                {
                    Some((id.into(), (word.into(), state.into(), cell.into())))
                }
                _ => None,
            }
        })
        .collect()
}

/// `batch status` agrees with squeue on every task it lists, and lists `count`.
fn check_status_agrees(cluster: &Cluster, plan: &str, jobs: &[String], count: usize) -> String {
    let status = cluster.run(&["batch", "status", plan]);
    let squeue = cluster.squeue(jobs);
    let tasks = status_tasks(&status);
    assert_eq!(tasks.len(), count, "{status}");
    for (id, (_, state, _)) in &tasks {
        // A task may move on between the two questions; ended tasks may not.
        let now = squeue.get(id).map_or("not in squeue", String::as_str);
        assert!(
            now == state || !all_ended(&HashMap::from([(id.clone(), state.clone())])),
            "{id}: status says {state}, squeue {now}\n{status}"
        );
    }
    assert!(status.contains("(from squeue)"), "{status}");
    status
}

/// 2 scenes x 2 techniques x 2 radii, each scene's reference in two parts: three stages.
fn write_plan(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let plan = dir.join("plan.toml");
    std::fs::write(
        &plan,
        format!(
            r#"output = "results"
resolution = [16, 16]
iterations = 4
threads = 1
traces = ["4x4x4"]
[slurm]
time_limit = "10m"
sbatch = ["--comment=vmerge-test"]
[[scene]]
file = "{}"
cameras = ["front"]
reference = {{ technique = "bpt", iterations = 16, parts = 2 }}
[[scene]]
file = "{}"
cameras = ["front"]
reference = {{ technique = "bpt", iterations = 16, parts = 2 }}
[[group]]
techniques = ["vcm", "upg"]
radius = [0.05, 0.1]
"#,
            scene("cornell-box"),
            scene("indirect")
        ),
    )
    .unwrap();
    plan
}

#[test]
fn submitted_plan_runs_in_stages_and_matches_in_process() {
    let _one = CLUSTER.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut cluster) = cluster() else {
        return;
    };
    let work = tempfile::tempdir().unwrap();
    let here = write_plan(&work.path().join("in-process"));
    let there = write_plan(&work.path().join("slurm"));
    let there_arg = there.to_str().unwrap();

    let start = Instant::now();
    cluster.run(&["batch", here.to_str().unwrap()]);
    let in_process = start.elapsed();

    let start = Instant::now();
    let jobs: Vec<String> = cluster
        .run(&["batch", there_arg, "--submit"])
        .lines()
        .map(str::to_string)
        .collect();
    assert_eq!(jobs.len(), 3, "parts, merges, cells: {jobs:?}");
    // Each later stage waits on the one before.
    for k in 1..3 {
        let dependency = cluster.scontrol(&jobs[k], "Dependency");
        assert!(
            dependency.is_empty() || dependency.contains(&format!("afterok:{}", jobs[k - 1])),
            "stage {k}: {dependency}"
        );
    }
    let status = check_status_agrees(&cluster, there_arg, &jobs, 14);
    let cells = status_tasks(&status);
    assert!(
        cells
            .iter()
            .filter(|(id, _)| id.starts_with(&format!("{}_", jobs[2])))
            .all(|(_, (word, _, _))| word == "queued"),
        "the cells wait for their references: {status}"
    );
    // Submitting again while its cells wait would give a cell two tasks.
    let twice = cluster.vmerge(&["batch", there_arg, "--submit"]);
    assert_eq!(twice.status.code(), Some(1), "{twice:?}");
    assert!(String::from_utf8_lossy(&twice.stderr).contains("still queued or running"));
    cluster.wait_jobs(
        &jobs,
        Duration::from_secs(150),
        "the plan's tasks to end",
        all_ended,
    );
    let under_slurm = start.elapsed();
    eprintln!(
        "14 cells: {:.1} s in-process, {:.1} s through Slurm",
        in_process.as_secs_f64(),
        under_slurm.as_secs_f64()
    );

    let states = cluster.squeue(&jobs);
    assert_eq!(states.len(), 14, "{states:?}");
    assert!(states.values().all(|s| s == "COMPLETED"), "{states:?}");
    let status = check_status_agrees(&cluster, there_arg, &jobs, 14);
    assert!(status.contains("14 cells: 14 done"), "{status}");
    assert!(
        status.contains("0 queued, 0 running, 14 done, 0 failed"),
        "{status}"
    );
    for (id, (word, _, _)) in status_tasks(&status) {
        assert_eq!(word, "done");
        assert_eq!(cluster.scontrol(&id, "JobState"), "COMPLETED", "{id}");
    }
    let plan = vmerge::tools::batch::Plan::load(&there).unwrap();
    for cell in &plan.cells {
        let local = here
            .parent()
            .unwrap()
            .join("results")
            .join(format!("{}.exr", cell.name));
        assert_eq!(pixels(&cell.output), pixels(&local), "{}", cell.name);
    }
    cluster.run(&["batch", "report", there_arg]);
    assert!(there
        .parent()
        .unwrap()
        .join("results/report/index.html")
        .exists());
    // Nothing is left to submit.
    let again = cluster.vmerge(&["batch", there_arg, "--submit"]);
    assert!(
        again.status.success() && again.stdout.is_empty(),
        "{again:?}"
    );
}

#[test]
fn cancelled_task_continues_when_requeued_and_broken_scene_fails_once() {
    let _one = CLUSTER.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut cluster) = cluster() else {
        return;
    };
    let work = tempfile::tempdir().unwrap();
    let broken = work.path().join("broken.toml");
    std::fs::write(&broken, "[camera\nthis is not a scene\n").unwrap();
    let write = |dir: &Path, scenes: &[&str]| {
        std::fs::create_dir_all(dir).unwrap();
        let mut text = String::from(
            "output = \"results\"\nresolution = [96, 96]\niterations = 300\nthreads = 1\n\
             snapshot = \"1s\"\n",
        );
        for s in scenes {
            text.push_str(&format!("[[scene]]\nfile = \"{s}\"\n"));
        }
        text.push_str("[[group]]\ntechniques = [\"bpt\"]\n");
        let plan = dir.join("plan.toml");
        std::fs::write(&plan, text).unwrap();
        plan
    };
    let cornell = scene("cornell-box");
    let here = write(&work.path().join("in-process"), &[&cornell]);
    let there = write(
        &work.path().join("slurm"),
        &[&cornell, broken.to_str().unwrap()],
    );
    let there_arg = there.to_str().unwrap();
    let start = Instant::now();
    cluster.run(&["batch", here.to_str().unwrap()]);
    let uninterrupted = start.elapsed();

    let jobs: Vec<String> = cluster
        .run(&["batch", there_arg, "--submit"])
        .lines()
        .map(str::to_string)
        .collect();
    assert_eq!(jobs.len(), 1, "{jobs:?}");
    let good = format!("{}_0", jobs[0]);
    let bad = format!("{}_1", jobs[0]);
    let cell = there
        .parent()
        .unwrap()
        .join("results/cornell-box.cam0.bpt.exr");
    // Cancelled after its first snapshot, while it runs.
    cluster
        .wait_for("the cell's first snapshot", Duration::from_secs(60), |c| {
            cell.exists() && c.squeue(&jobs).get(&good).is_some_and(|s| s == "RUNNING")
        })
        .unwrap();
    cluster.slurm("scancel", &[&good]).unwrap();
    cluster.wait_jobs(&jobs, Duration::from_secs(60), "the cancel", all_ended);
    let states = cluster.squeue(&jobs);
    assert_eq!(states[&good], "CANCELLED", "{states:?}");
    assert_eq!(states[&bad], "FAILED", "{states:?}");
    let status = check_status_agrees(&cluster, there_arg, &jobs, 2);
    assert!(
        status.contains("partial  cornell-box.cam0.bpt"),
        "cancelled before its budget ran out ({uninterrupted:?} in-process): {status}"
    );
    assert!(
        status.contains("0 queued, 0 running, 0 done, 2 failed"),
        "{status}"
    );

    // Requeued, it continues from its snapshot to the uninterrupted image. Slurm holds a
    // requeued job for two minutes (its BeginTime) before it may start again: released at once.
    cluster.slurm("scontrol", &["requeue", &good]).unwrap();
    cluster
        .wait_for(
            "the requeued task's release",
            Duration::from_secs(30),
            |c| {
                c.slurm(
                    "scontrol",
                    &["update", &format!("JobId={good}"), "StartTime=now"],
                )
                .is_some()
            },
        )
        .unwrap();
    cluster.wait_jobs(&jobs, Duration::from_secs(120), "the requeued task", |s| {
        s.get(&good).is_some_and(|s| s == "COMPLETED")
    });
    let log = std::fs::read_to_string(
        there
            .parent()
            .unwrap()
            .join(format!("results/slurm-{}_0.log", jobs[0])),
    )
    .unwrap();
    assert!(log.contains("cornell-box.cam0.bpt: continue"), "{log}");
    let local = here
        .parent()
        .unwrap()
        .join("results/cornell-box.cam0.bpt.exr");
    assert_eq!(pixels(&cell), pixels(&local));
    assert_eq!(cluster.scontrol(&good, "Restarts"), "1");

    // The broken scene failed its task once, with the scene's error in its log, exit code 2.
    assert_eq!(cluster.scontrol(&bad, "JobState"), "FAILED");
    assert_eq!(cluster.scontrol(&bad, "ExitCode"), "2:0");
    assert_eq!(cluster.scontrol(&bad, "Restarts"), "0");
    let log = std::fs::read_to_string(
        there
            .parent()
            .unwrap()
            .join(format!("results/slurm-{}_1.log", jobs[0])),
    )
    .unwrap();
    assert_eq!(log.matches("error:").count(), 1, "{log}");
    assert!(log.contains("broken.toml"), "{log}");
    let status = check_status_agrees(&cluster, there_arg, &jobs, 2);
    assert!(
        status.contains("0 queued, 0 running, 1 done, 1 failed"),
        "{status}"
    );
}
