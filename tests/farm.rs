//! The farm recipes on real engines: a wedged plan in chunks, one variant failing on purpose
//! (ω = 1.95 goes unstable at frame 5), run by `bash plan/slurm.sh` on a single-node Slurm
//! brought up here (munge and Slurm 22.05 from Debian, `.ci/deps` installs them; the daemons
//! run from a generated `slurm.conf` in a temporary folder and are stopped by their PIDs) and by
//! `bash plan/parallel.sh` with GNU parallel. Every stable variant ends with the frames of a
//! direct bake, the failure is reported by `drape plan --status` (exit 1), and only the failed
//! variant's later chunks are held back (Slurm 22.05 leaves them pending,
//! "DependencyNeverSatisfied"). These are the commands `docs/farm.md` gives; a task requeued in
//! the middle of a chunk resumes from its checkpoint. Where a daemon cannot start the test fails
//! saying why.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command};
use std::time::{Duration, Instant};

const SCENE: &str = r#"{ "name": "h", "frames": 30, "substeps": 10, "backend": "cpu",
    "solver": { "iterations": 10 }, "output": { "gltf": "none" },
    "garments": [{ "name": "cloth", "resolution": [20, 20], "pins": [[0, 0], [-1, 0]] }] }"#;

fn drape(dir: &Path, args: &[&str]) -> std::process::Output {
    common::drape(dir, args)
}

fn frames_hash(bake: &Path) -> String {
    let text = std::fs::read_to_string(bake.join("report.json")).unwrap();
    let r: serde_json::Value = serde_json::from_str(&text).unwrap();
    r["frames_hash"].as_str().unwrap().to_string()
}

/// Plans the wedge in chunks of 10 frames into `dir/NAME` and bakes the stable variants
/// directly into `dir/direct_<omega>`.
fn plan(dir: &Path, name: &str) -> PathBuf {
    common::write(dir, "h.json", SCENE);
    let out = drape(
        dir,
        &[
            "plan",
            "h.json",
            "--wedge",
            "solver.omega=1.0,1.3,1.95",
            "--chunk",
            "10",
            "--cpus",
            "1",
            "--out",
            name,
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    dir.join(name)
}

/// What `drape plan --status` says of a finished plan: the two stable variants done with the
/// frames of direct bakes, ω = 1.95 failed, exit 1.
fn assert_finished(dir: &Path, plan: &Path) {
    let status = drape(dir, &["plan", "--status", plan.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&status.stdout).to_string();
    assert_eq!(status.status.code(), Some(1), "{text}");
    assert!(text.contains("2 of 3 variants done"), "{text}");
    assert!(
        text.contains("h_solver.omega-1.95: failed at frame"),
        "{text}"
    );
    for omega in ["1.0", "1.3"] {
        let direct = dir.join(format!("direct_{omega}"));
        if !direct.exists() {
            let out = drape(
                dir,
                &[
                    "bake",
                    "h.json",
                    "--omega",
                    omega,
                    "--out",
                    direct.to_str().unwrap(),
                ],
            );
            assert!(out.status.success(), "{}", common::stderr(&out));
        }
        let planned = plan.join(format!("bakes/h_solver.omega-{omega}"));
        assert_eq!(frames_hash(&planned), frames_hash(&direct), "ω = {omega}");
        assert!(
            text.contains(&format!("h_solver.omega-{omega}: done: 30 of 30 frames")),
            "{text}"
        );
    }
}

/// A single-node Slurm (munged, slurmctld, slurmd) in `root`, stopped when dropped.
struct Slurm {
    root: PathBuf,
    conf: PathBuf,
    daemons: Vec<(String, PathBuf)>,
    munge: Option<Child>,
}

impl Slurm {
    fn start(root: &Path) -> Slurm {
        for d in ["state", "spool", "log", "run", "munge"] {
            std::fs::create_dir_all(root.join(d)).unwrap();
        }
        let key = root.join("munge/munge.key");
        let bytes: Vec<u8> = (0..1024u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        std::fs::write(&key, bytes).unwrap();
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o400)).unwrap();
        let socket = root.join("munge/munge.socket");
        let munge = Command::new("munged")
            .args(["--foreground", "--force"])
            .arg(format!("--key-file={}", key.display()))
            .arg(format!("--socket={}", socket.display()))
            .arg(format!(
                "--pid-file={}",
                root.join("munge/munged.pid").display()
            ))
            .arg(format!(
                "--log-file={}",
                root.join("munge/munged.log").display()
            ))
            .arg(format!(
                "--seed-file={}",
                root.join("munge/munged.seed").display()
            ))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("munged (apt package munge, .ci/deps) cannot start: {e}"));
        let host = String::from_utf8(Command::new("hostname").arg("-s").output().unwrap().stdout)
            .unwrap()
            .trim()
            .to_string();
        let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
        // The daemons run as whoever runs the test (root on CI).
        let user = String::from_utf8(Command::new("id").arg("-un").output().unwrap().stdout)
            .unwrap()
            .trim()
            .to_string();
        // Ports of this process's own, so a Slurm already on the machine is left alone.
        // Two ports per Slurm this process starts (the tests run side by side).
        static STARTED: std::sync::atomic::AtomicU16 = std::sync::atomic::AtomicU16::new(0);
        let nth = STARTED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let port = 20000 + (std::process::id() % 5000) as u16 * 4 + 2 * nth;
        let conf = root.join("slurm.conf");
        let r = root.display();
        std::fs::write(
            &conf,
            format!(
                "ClusterName=drapetest\nSlurmctldHost={host}\nAuthType=auth/munge\n\
                 AuthInfo=socket={sock}\nCredType=cred/munge\nSlurmUser={user}\nSlurmdUser={user}\n\
                 StateSaveLocation={r}/state\nSlurmdSpoolDir={r}/spool\n\
                 SlurmctldPidFile={r}/run/slurmctld.pid\nSlurmdPidFile={r}/run/slurmd.pid\n\
                 SlurmctldLogFile={r}/log/slurmctld.log\nSlurmdLogFile={r}/log/slurmd.log\n\
                 SlurmctldPort={port}\nSlurmdPort={}\nProctrackType=proctrack/linuxproc\n\
                 TaskPlugin=task/none\nJobAcctGatherType=jobacct_gather/none\n\
                 SelectType=select/cons_tres\nSelectTypeParameters=CR_Core\nReturnToService=2\n\
                 MpiDefault=none\nNodeName={host} CPUs={cpus} State=UNKNOWN\n\
                 PartitionName=main Nodes={host} Default=YES MaxTime=INFINITE State=UP\n",
                port + 1,
                sock = socket.display(),
            ),
        )
        .unwrap();
        let mut slurm = Slurm {
            root: root.to_path_buf(),
            conf,
            daemons: Vec::new(),
            munge: Some(munge),
        };
        let deadline = Instant::now() + Duration::from_secs(20);
        while !socket.exists() {
            assert!(
                Instant::now() < deadline,
                "munged made no socket: {}",
                slurm.logs()
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        for (daemon, args) in [("slurmctld", vec!["-c"]), ("slurmd", vec![])] {
            let status = Command::new(daemon)
                .args(args)
                .env("SLURM_CONF", &slurm.conf)
                .status()
                .unwrap_or_else(|e| {
                    panic!("{daemon} (apt package slurm-wlm, .ci/deps) cannot start: {e}")
                });
            assert!(
                status.success(),
                "{daemon} exited {status}: {}",
                slurm.logs()
            );
            slurm
                .daemons
                .push((daemon.to_string(), root.join(format!("run/{daemon}.pid"))));
        }
        // Until the node takes jobs.
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let out = slurm
                .command("sinfo")
                .args(["-h", "-o", "%t"])
                .output()
                .unwrap();
            let state = String::from_utf8_lossy(&out.stdout).trim().to_string();
            if state == "idle" {
                break;
            }
            assert!(
                Instant::now() < deadline,
                "the node is {state:?}, not idle: {}",
                slurm.logs()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
        slurm
    }

    /// Runs `PLAN/slurm.sh` from `dir`, as `docs/farm.md` says, and checks that it submitted.
    fn submit(&self, plan: &Path, dir: &Path) {
        let out = self
            .command("bash")
            .arg(plan.join("slurm.sh"))
            .current_dir(dir)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", common::stderr(&out));
    }

    /// Runs a Slurm command to its end and returns what it printed; it must succeed.
    fn run(&self, program: &str, args: &[&str]) -> String {
        let out = self.command(program).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{program} {args:?}: {}",
            common::stderr(&out)
        );
        String::from_utf8_lossy(&out.stdout).to_string()
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Waits until nothing runs or can still run: every job left is pending on a dependency
    /// that can never be met (a failed variant's later chunks), for 8 s in a row. Returns them
    /// (`JOBID_TASK`), cancelled.
    fn wait_settled(&self, within: Duration) -> Vec<String> {
        let deadline = Instant::now() + within;
        let mut settled_since: Option<Instant> = None;
        loop {
            let queue = self
                .run("squeue", &["-h", "-o", "%i %T %r"])
                .trim()
                .to_string();
            let stuck = queue.lines().all(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                f.len() == 3 && f[1] == "PENDING" && f[2].starts_with("Dependency")
            });
            if stuck {
                let since = *settled_since.get_or_insert_with(Instant::now);
                if since.elapsed() > Duration::from_secs(8) {
                    let left: Vec<String> = queue
                        .lines()
                        .filter_map(|l| l.split_whitespace().next())
                        .map(str::to_string)
                        .collect();
                    if !left.is_empty() {
                        let _ = self.command("scancel").arg("--state=PENDING").status();
                    }
                    return left;
                }
            } else {
                settled_since = None;
            }
            assert!(Instant::now() < deadline, "jobs still queued:\n{queue}");
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    fn logs(&self) -> String {
        ["log/slurmctld.log", "log/slurmd.log", "munge/munged.log"]
            .iter()
            .map(|f| {
                let text = std::fs::read_to_string(self.root.join(f)).unwrap_or_default();
                let tail: Vec<&str> = text.lines().rev().take(5).collect();
                format!(
                    "{f}: {}",
                    tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
                )
            })
            .collect::<Vec<_>>()
            .join("; ")
    }
}

impl Drop for Slurm {
    fn drop(&mut self) {
        for (_, pid) in self.daemons.iter().rev() {
            if let Some(pid) = std::fs::read_to_string(pid)
                .ok()
                .and_then(|p| p.trim().parse::<i32>().ok())
            {
                // SAFETY: stopping the daemon this test started.
                unsafe { libc::kill(pid, libc::SIGTERM) };
            }
        }
        if let Some(mut m) = self.munge.take() {
            let _ = m.kill();
            let _ = m.wait();
        }
    }
}

#[test]
fn the_docs_give_the_recipes_this_test_runs() {
    let farm = std::fs::read_to_string("docs/farm.md").unwrap();
    for recipe in [
        "bash plan/slurm.sh",
        "bash plan/parallel.sh",
        "drape plan --status plan",
    ] {
        assert!(
            farm.contains(recipe),
            "docs/farm.md does not give `{recipe}`"
        );
    }
}

#[test]
fn a_wedged_chunked_plan_runs_on_a_real_slurm() {
    let dir = common::temp_dir();
    let d = dir.path();
    let slurm = Slurm::start(&d.join("slurm"));
    let plan = plan(d, "plan");
    let started = Instant::now();
    slurm.submit(&plan, d);
    let stuck = slurm.wait_settled(Duration::from_secs(300));
    eprintln!(
        "Slurm ran the plan in {:.1} s (settled 8 s before); left pending: {stuck:?}",
        started.elapsed().as_secs_f64()
    );
    assert_finished(d, &plan);
    // Every chunk of the stable variants ran (task logs: the 3 first chunks, then 2 and 2);
    // the failed variant's later chunks (task 3 of chunks 2 and 3) never could.
    let logs = std::fs::read_dir(plan.join("logs")).unwrap().count();
    assert_eq!(logs, 3 + 2 + 2);
    assert_eq!(stuck.len(), 2, "{stuck:?}");
    assert!(stuck.iter().all(|j| j.ends_with("_3")), "{stuck:?}");
}

#[test]
fn a_wedged_chunked_plan_runs_with_gnu_parallel() {
    let dir = common::temp_dir();
    let d = dir.path();
    let plan = plan(d, "plan");
    let out = Command::new("bash")
        .arg(plan.join("parallel.sh"))
        .current_dir(d)
        .output()
        .unwrap_or_else(|e| panic!("bash cannot run: {e}"));
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}{}", common::stderr(&out));
    assert_finished(d, &plan);
}

#[test]
fn a_chunked_plan_runs_with_the_openjd_runner_after_the_plan_moved() {
    // `openjd run` (openjd-cli 0.8.0, which `.ci/deps` installs into target/openjd) runs a
    // variant's last chunk step with the steps it depends on: its own chunks, one after
    // another. Each variant has its own chain (a step's dependencies are all-or-nothing), so
    // ω = 1.95 failing in its first chunk leaves ω = 1.0's chain free to run. The plan's paths
    // go through the job parameter `PlanDir` (by default the template's folder), so a plan
    // moved after planning (as a worker that sees it at another path would) still runs, to a
    // direct bake's frames.
    let openjd = std::env::current_dir()
        .unwrap()
        .join("target/openjd/bin/openjd");
    assert!(
        openjd.is_file(),
        "{} is missing: run .ci/deps (it installs openjd-cli from PyPI)",
        openjd.display()
    );
    let dir = common::temp_dir();
    let d = dir.path();
    plan(d, "planned");
    std::fs::rename(d.join("planned"), d.join("moved")).unwrap();
    let template = d.join("moved/job.yaml");
    let check = Command::new(&openjd)
        .arg("check")
        .arg(&template)
        .output()
        .unwrap();
    assert!(check.status.success(), "{}", common::stderr(&check));
    // Every chunk step after the first depends on the same variant's chunk before, only.
    let text = std::fs::read_to_string(&template).unwrap();
    let mut step = String::new();
    let mut chained = 0;
    for line in text.lines() {
        if let Some(name) = line.strip_prefix("- name: ") {
            step = name.trim_matches('"').to_string();
        } else if let Some(on) = line.strip_prefix("  - dependsOn: ") {
            let (chunk, variant) = step.split_once(' ').unwrap();
            let k: u32 = chunk.trim_start_matches("bake_").parse().unwrap();
            assert_eq!(on.trim_matches('"'), format!("bake_{:02} {variant}", k - 1));
            chained += 1;
        }
    }
    assert_eq!(
        chained, 6,
        "two later chunks for each of three variants:\n{text}"
    );
    let chain = |variant: &str| {
        Command::new(&openjd)
            .arg("run")
            .arg(&template)
            .args([
                "--step",
                &format!("bake_03 {variant}"),
                "--run-dependencies",
            ])
            .output()
            .unwrap()
    };
    let failed = chain("h_solver.omega-1.95");
    assert!(
        !failed.status.success(),
        "ω = 1.95 goes unstable in its first chunk"
    );
    let out = chain("h_solver.omega-1.0");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && !text.contains("ERROR"), "{text}");
    let direct = d.join("direct_1.0");
    let out = drape(
        d,
        &[
            "bake",
            "h.json",
            "--omega",
            "1.0",
            "--out",
            direct.to_str().unwrap(),
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let planned = d.join("moved/bakes/h_solver.omega-1.0");
    assert_eq!(frames_hash(&planned), frames_hash(&direct));
}

/// A bake long enough to be caught between checkpoints: 200 frames of a 60 × 60 sheet,
/// a checkpoint every 10.
const LONG: &str = r#"{ "name": "long", "frames": 200, "substeps": 10, "backend": "cpu",
    "checkpoint_every": 10, "solver": { "iterations": 10 }, "output": { "gltf": "none" },
    "garments": [{ "name": "cloth", "resolution": [60, 60], "pins": [[0, 0], [-1, 0]] }] }"#;

#[test]
fn a_slurm_task_requeued_mid_chunk_resumes_from_its_checkpoint() {
    // Pre-emption as a farm does it: `scontrol requeue` while the first of two chunks bakes
    // past its first checkpoint. Slurm signals the task (drape checkpoints and stops), queues
    // it again, and the same line runs again with `--resume`: the chunk goes on from its
    // checkpoint, the second chunk from the first's end, to the frames of a bake that never
    // stopped.
    let dir = common::temp_dir();
    let d = dir.path();
    let slurm = Slurm::start(&d.join("slurm"));
    common::write(d, "long.json", LONG);
    let out = drape(
        d,
        &[
            "plan",
            "long.json",
            "--chunk",
            "100",
            "--cpus",
            "1",
            "--out",
            "plan",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let plan = d.join("plan");
    slurm.submit(&plan, d);
    let bake = plan.join("bakes/long");
    let started = Instant::now();
    // A bake in progress writes into a staging folder beside its own (`.long.tmp-PID`).
    let bakes = plan.join("bakes");
    let checkpointed = || {
        std::fs::read_dir(&bakes).is_ok_and(|folders| {
            folders.flatten().any(|f| {
                f.file_name().to_string_lossy().starts_with(".long.tmp-")
                    && std::fs::read_dir(f.path().join("checkpoints")).is_ok_and(|entries| {
                        entries
                            .flatten()
                            .any(|e| e.file_name().to_string_lossy().ends_with(".ckpt"))
                    })
            })
        })
    };
    while !checkpointed() {
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "no checkpoint in {}: {}",
            bakes.display(),
            slurm.logs()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let queue = slurm.run("squeue", &["-h", "-o", "%i %T %j"]);
    let job = queue
        .lines()
        .find(|l| l.ends_with(" RUNNING drape-chunk_01"))
        .and_then(|l| l.split_whitespace().next())
        .unwrap_or_else(|| panic!("chunk 1 is not running after its first checkpoint:\n{queue}"))
        .to_string();
    slurm.run("scontrol", &["requeue", &job]);
    // Slurm holds a requeued job back for a while (its begin time moves on); an operator
    // releases it at once, as here.
    std::thread::sleep(Duration::from_millis(500));
    slurm.run(
        "scontrol",
        &["update", &format!("JobId={job}"), "StartTime=now"],
    );
    slurm.wait_settled(Duration::from_secs(400));
    let elapsed = started.elapsed().as_secs_f64();
    let text = std::fs::read_to_string(bake.join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(report["frames_baked"], 200, "{text}");
    // The requeued chunk's log (appended to, run after run) says where its second run went on
    // from: a checkpoint inside the chunk, not its start.
    let log = std::fs::read_to_string(plan.join("logs/drape-chunk_01_1.out")).unwrap();
    let after: Vec<u64> = log
        .lines()
        .filter_map(|l| l.strip_prefix("resumed after frame "))
        .filter_map(|l| l.split_whitespace().next()?.parse().ok())
        .collect();
    assert!(
        after.len() == 1 && (10..100).contains(&after[0]),
        "chunk 1 did not resume from a checkpoint inside it:\n{log}"
    );
    eprintln!(
        "requeued {job} after its first checkpoint, resumed after frame {}; done {elapsed:.1} s after the submission",
        after[0]
    );
    let direct = d.join("direct");
    let out = drape(d, &["bake", "long.json", "--out", direct.to_str().unwrap()]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    assert_eq!(frames_hash(&bake), frames_hash(&direct));
}
