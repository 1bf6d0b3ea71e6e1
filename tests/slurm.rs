//! `lucent run --executor slurm` on a real one-node Slurm cluster started
//! on localhost for the test (munged with a generated key, slurmctld and
//! slurmd in the foreground as child processes, a temporary slurm.conf;
//! Debian's `slurm-wlm` and `munge`, installed by scripts/install-deps.sh).
//! A project's slices and render run as 4 shards each and are merged; the
//! results equal the local executor's, the stage keys are the same (a
//! local rerun finds the stages up to date), and a shard killed with
//! `scancel` is resubmitted.

use std::io::Read;
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The daemons of a one-node cluster; stopped (and its jobs cancelled) when dropped.
struct Cluster {
    dir: tempfile::TempDir,
    conf: PathBuf,
    children: Vec<(String, Child)>,
}

impl Cluster {
    fn logs(&self) -> String {
        let mut s = String::new();
        for f in ["munged.log", "slurmctld.log", "slurmd.log", "slurmctld.out", "slurmd.out", "munged.out"] {
            let text = std::fs::read_to_string(self.dir.path().join(f)).unwrap_or_default();
            let lines: Vec<&str> = text.lines().collect();
            s.push_str(&format!("--- {f}\n{}\n", lines[lines.len().saturating_sub(30)..].join("\n")));
        }
        s
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    fn spawn(&mut self, name: &str, mut c: Command) {
        let out = std::fs::File::create(self.dir.path().join(format!("{name}.out"))).expect("log file");
        let err = out.try_clone().expect("log file");
        let child = c.stdin(Stdio::null()).stdout(out).stderr(err).spawn();
        match child {
            Ok(ch) => self.children.push((name.to_string(), ch)),
            Err(e) => panic!("cannot start {name}: {e} (install slurm-wlm and munge: bash scripts/install-deps.sh)"),
        }
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = self.command("scancel").arg("--user").arg(whoami()).status();
        // Daemons in reverse order of starting.
        while let Some((_, mut ch)) = self.children.pop() {
            // SAFETY: kill(2) on our own child's pid.
            unsafe { libc::kill(ch.id() as i32, libc::SIGTERM) };
            let t = Instant::now();
            while t.elapsed() < Duration::from_secs(5) {
                if let Ok(Some(_)) = ch.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = ch.kill();
            let _ = ch.wait();
        }
    }
}

fn whoami() -> String {
    let o = Command::new("id").arg("-un").output().expect("id");
    String::from_utf8_lossy(&o.stdout).trim().to_string()
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").expect("bind").local_addr().expect("addr").port()
}

fn hostname() -> String {
    let o = Command::new("hostname").arg("-s").output().expect("hostname");
    String::from_utf8_lossy(&o.stdout).trim().to_string()
}

/// Starts munged, slurmctld and slurmd; fails with their logs when the node does not come up.
fn start_cluster() -> Cluster {
    // A short path: the munge socket's path must fit a sockaddr_un.
    let dir = tempfile::Builder::new().prefix("lucent-slurm-").tempdir_in("/tmp").expect("temp dir");
    let d = dir.path().to_path_buf();
    for sub in ["state", "spool", "munge"] {
        std::fs::create_dir_all(d.join(sub)).expect("mkdir");
    }
    let mut cluster = Cluster { dir, conf: d.join("slurm.conf"), children: Vec::new() };
    let key = d.join("munge/munge.key");
    let o = Command::new("mungekey").arg("--create").arg("--keyfile").arg(&key).output();
    match o {
        Ok(o) if o.status.success() => {}
        other => panic!("mungekey failed: {other:?} (install munge: bash scripts/install-deps.sh)"),
    }
    let socket = d.join("munge/munge.sock");
    let mut munged = Command::new("munged");
    munged
        .arg("--foreground")
        .arg("--force")
        .arg(format!("--key-file={}", key.display()))
        .arg(format!("--socket={}", socket.display()))
        .arg(format!("--pid-file={}", d.join("munge/munged.pid").display()))
        .arg(format!("--log-file={}", d.join("munged.log").display()))
        .arg(format!("--seed-file={}", d.join("munge/seed").display()));
    cluster.spawn("munged", munged);
    let t = Instant::now();
    while !socket.exists() {
        assert!(t.elapsed() < Duration::from_secs(10), "munged did not start:\n{}", cluster.logs());
        std::thread::sleep(Duration::from_millis(50));
    }
    let host = hostname();
    let cpus = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let user = whoami();
    let conf = format!(
        "ClusterName=lucenttest\nSlurmctldHost={host}(127.0.0.1)\nSlurmUser={user}\nSlurmdUser={user}\n\
         SlurmctldPort={}\nSlurmdPort={}\nAuthType=auth/munge\nAuthInfo=socket={sock}\nCredType=cred/munge\n\
         StateSaveLocation={d}/state\nSlurmdSpoolDir={d}/spool\nSlurmctldPidFile={d}/slurmctld.pid\n\
         SlurmdPidFile={d}/slurmd.pid\nSlurmctldLogFile={d}/slurmctld.log\nSlurmdLogFile={d}/slurmd.log\n\
         ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\nSelectType=select/cons_tres\n\
         SelectTypeParameters=CR_CPU\nSchedulerType=sched/builtin\nReturnToService=2\nMpiDefault=none\n\
         JobAcctGatherType=jobacct_gather/none\nAccountingStorageType=accounting_storage/none\n\
         JobCompType=jobcomp/none\nMinJobAge=30\nKillWait=2\nInactiveLimit=0\n\
         NodeName={host} NodeAddr=127.0.0.1 CPUs={cpus} State=UNKNOWN\n\
         PartitionName=debug Nodes={host} Default=YES MaxTime=INFINITE State=UP\n",
        free_port(),
        free_port(),
        sock = socket.display(),
        d = d.display(),
    );
    std::fs::write(&cluster.conf, conf).expect("slurm.conf");
    let mut ctld = cluster.command("slurmctld");
    ctld.arg("-D").arg("-i").arg("-f").arg(&cluster.conf);
    cluster.spawn("slurmctld", ctld);
    let mut slurmd = cluster.command("slurmd");
    slurmd.arg("-D").arg("-f").arg(&cluster.conf);
    cluster.spawn("slurmd", slurmd);
    let t = Instant::now();
    loop {
        let o = cluster.command("sinfo").args(["-h", "-o", "%T"]).output();
        if let Ok(o) = &o
            && String::from_utf8_lossy(&o.stdout).trim() == "idle"
        {
            break;
        }
        let exited = cluster
            .children
            .iter_mut()
            .find_map(|(name, ch)| ch.try_wait().ok().flatten().map(|st| format!("{name} exited with {st}")));
        if let Some(e) = exited {
            panic!("{e}:\n{}", cluster.logs());
        }
        assert!(t.elapsed() < Duration::from_secs(20), "the node did not become idle ({o:?}):\n{}", cluster.logs());
        std::thread::sleep(Duration::from_millis(200));
    }
    cluster
}

fn project(dir: &Path, kill_marker: &Path) -> PathBuf {
    let f = root().join("fixtures");
    let text = format!(
        r#"[project]
name = "cluster"
seed = 5

[optics]
wavelengths = "500:600:50"

[bssrdf]
configs = "45/0"
pixels = 21
pixel_mm = 0.2
paths = 3000
phase = "hg"

[render]
scene = "{f}/render/demo.toml"
spp = 8
size = "16x12"

[[sample]]
name = "s1"
recipe = "{f}/samples/IOL1068-09.toml"

[executor]
shards = 4
retries = 2
time_limit = "10:00"
# The first task 1 to start waits, so that the test can kill it.
setup = ["if [ \"${{SLURM_ARRAY_TASK_ID:-}}\" = 1 ] && mkdir {m} 2>/dev/null; then sleep 120; fi"]
"#,
        f = f.display(),
        m = kill_marker.display(),
    );
    let p = dir.join("project.toml");
    std::fs::write(&p, text).expect("project");
    p
}

fn lucent(cluster: &Cluster, args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(args)
        .current_dir(root())
        .env("SLURM_CONF", &cluster.conf)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run lucent")
}

fn finish(cluster: &Cluster, mut ch: Child, what: &str) -> String {
    let t = Instant::now();
    let status = loop {
        if let Some(st) = ch.try_wait().expect("wait") {
            break st;
        }
        if t.elapsed() > Duration::from_secs(120) {
            let _ = ch.kill();
            panic!("{what}: no end after 120 s:\n{}", cluster.logs());
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let (mut out, mut err) = (String::new(), String::new());
    ch.stdout.take().expect("stdout").read_to_string(&mut out).expect("read");
    ch.stderr.take().expect("stderr").read_to_string(&mut err).expect("read");
    assert!(status.success(), "{what} failed:\n{out}\n{err}\n{}", cluster.logs());
    out
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
        .expect("json")
}

fn exr(path: &Path, names: &[&str]) -> Vec<Vec<f32>> {
    lucent::exr::read_channels(path, names).expect("exr").2
}

fn close(a: &[Vec<f32>], b: &[Vec<f32>], rel: f32, what: &str) {
    for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
        assert!((x - y).abs() <= rel * x.abs().max(f32::MIN_POSITIVE), "{what}: {x} vs {y}");
    }
}

#[test]
fn slurm_executor_matches_the_local_one_and_resubmits_a_killed_shard() {
    let cluster = start_cluster();
    let dir = tempfile::tempdir().expect("temp");
    let marker = cluster.dir.path().join("killed-once");
    let proj = project(dir.path(), &marker);
    let (local, remote) = (dir.path().join("local"), dir.path().join("slurm"));
    let (p, l, r) = (proj.to_str().unwrap(), local.to_str().unwrap(), remote.to_str().unwrap());
    finish(&cluster, lucent(&cluster, &["run", p, "--out", l, "--executor", "local"]), "local run");
    let run = lucent(&cluster, &["run", p, "--out", r, "--executor", "slurm"]);
    // Kill the task that waits (array task 1 of the first job array) once it runs.
    let t = Instant::now();
    while !marker.exists() {
        assert!(t.elapsed() < Duration::from_secs(60), "no array task 1 started:\n{}", cluster.logs());
        std::thread::sleep(Duration::from_millis(100));
    }
    let task = loop {
        let o = cluster.command("squeue").args(["-h", "-t", "RUNNING", "-o", "%i"]).output().expect("squeue");
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        if let Some(id) = text.lines().map(str::trim).find(|l| l.ends_with("_1")) {
            break id.to_string();
        }
        assert!(t.elapsed() < Duration::from_secs(60), "task 1 not running: {text}\n{}", cluster.logs());
        std::thread::sleep(Duration::from_millis(100));
    };
    let st = cluster.command("scancel").arg(&task).status().expect("scancel");
    assert!(st.success());
    let out = finish(&cluster, run, "slurm run");
    assert!(out.contains("resubmitting"), "{out}");
    assert!(out.contains("submitted merge job"), "{out}");
    // The plan came first, and the progress lines count the shards.
    let plan = out.find("plan: Slurm job arrays of 4 shards per long command").expect("the plan");
    assert!(plan < out.find("submitted job array").expect("an array"), "{out}");
    assert!(out.contains("bssrdf      on the cluster: each slice ([bssrdf] paths = 3000) as 4 shards"), "{out}");
    assert!(out.contains("render      on the cluster: each render ([render] spp = 8) as 4 shards"), "{out}");
    assert!(out.contains(": 4 shards of `lucent bssrdf` (array indices 0-3)"), "{out}");
    assert!(out.contains(": 1 shard of `lucent bssrdf` (array indices 1)"), "the resubmission: {out}");
    // The same results as the local executor's (sums in another order: to rounding).
    let (sl, sr) = (json(&local.join("bssrdf/s1/summary.json")), json(&remote.join("bssrdf/s1/summary.json")));
    assert_eq!(sl["paths"], sr["paths"]);
    assert_eq!(sl["events"], sr["events"]);
    let (a, b) = (sl["sum"].as_f64().unwrap(), sr["sum"].as_f64().unwrap());
    assert!((a - b).abs() <= 1e-11 * a.abs(), "{a} vs {b}");
    close(
        &exr(&local.join("bssrdf/s1/bssrdf.exr"), &["Y"]),
        &exr(&remote.join("bssrdf/s1/bssrdf.exr"), &["Y"]),
        2.0 * f32::EPSILON,
        "slice",
    );
    let (rl, rr) = (json(&local.join("render/s1/render.json")), json(&remote.join("render/s1/render.json")));
    assert_eq!(rl["samples"], rr["samples"]);
    assert_eq!(rl["scattering_events"], rr["scattering_events"]);
    let names = ["R", "G", "B", "spp"];
    close(
        &exr(&local.join("render/s1/render.exr"), &names),
        &exr(&remote.join("render/s1/render.exr"), &names),
        2.0 * f32::EPSILON,
        "render",
    );
    // The same stage folders and keys; no shard folders left.
    for stage in ["bssrdf", "render"] {
        let (ml, mr) =
            (json(&local.join(stage).join("manifest.json")), json(&remote.join(stage).join("manifest.json")));
        assert_eq!(ml["key"], mr["key"], "{stage}");
        assert_eq!(ml["outputs"], mr["outputs"], "{stage}");
        // The same commands, each with its own output folder.
        let commands =
            |m: &serde_json::Value, out: &Path| m["commands"].to_string().replace(out.to_str().unwrap(), "OUT");
        assert_eq!(commands(&ml, &local), commands(&mr, &remote), "{stage}");
    }
    assert!(!remote.join(".lucent-shards").read_dir().map(|mut d| d.next().is_some()).unwrap_or(false));
    // A local rerun finds them up to date.
    let again = finish(&cluster, lucent(&cluster, &["run", p, "--out", r, "--executor", "local"]), "rerun");
    for stage in ["bssrdf", "render"] {
        assert!(status_of(&again, stage).contains("up to date"), "{stage}: {again}");
    }
    // --emit: the slices' job array and merge job written, submitted by hand,
    // then `lucent run` merges their shards instead of tracing again.
    let (emitted, jobs) = (dir.path().join("emitted"), dir.path().join("jobs"));
    let (e, j) = (emitted.to_str().unwrap(), jobs.to_str().unwrap());
    let out = finish(&cluster, lucent(&cluster, &["run", p, "--out", e, "--emit", "slurm", j]), "emit");
    assert!(status_of(&out, "bssrdf").contains("written as batch jobs"), "{out}");
    assert!(!emitted.join("bssrdf/manifest.json").exists());
    let st = cluster.command("bash").arg(jobs.join("submit.sh")).current_dir(root()).status().expect("bash");
    assert!(st.success());
    let t = Instant::now();
    loop {
        let o = cluster.command("squeue").args(["-h", "-o", "%i"]).output().expect("squeue");
        if String::from_utf8_lossy(&o.stdout).trim().is_empty() {
            break;
        }
        assert!(t.elapsed() < Duration::from_secs(60), "emitted jobs still queued:\n{}", cluster.logs());
        std::thread::sleep(Duration::from_millis(200));
    }
    let out = finish(&cluster, lucent(&cluster, &["run", p, "--out", e, "--until", "bssrdf"]), "run after the jobs");
    assert!(status_of(&out, "bssrdf").contains("ran"), "{out}");
    let se = json(&emitted.join("bssrdf/s1/summary.json"));
    assert_eq!(se["events"], sl["events"]);
    let b = se["sum"].as_f64().unwrap();
    assert!((a - b).abs() <= 1e-11 * a.abs(), "{a} vs {b}");
    assert_eq!(json(&emitted.join("bssrdf/manifest.json"))["key"], json(&local.join("bssrdf/manifest.json"))["key"]);
}

/// The status line of `stage` in `lucent run`'s output.
fn status_of(out: &str, stage: &str) -> String {
    out.lines().find(|l| l.contains(&format!("] {stage} "))).unwrap_or("").to_string()
}

#[test]
fn emitted_jobs_are_slurm_arrays_and_kubernetes_indexed_jobs() {
    let dir = tempfile::tempdir().expect("temp");
    let proj = project(dir.path(), &dir.path().join("marker"));
    let p = proj.to_str().unwrap();
    for kind in ["slurm", "k8s"] {
        let (out, jobs) = (dir.path().join(format!("out-{kind}")), dir.path().join(format!("jobs-{kind}")));
        let o = lucent_cli(&["run", p, "--out", out.to_str().unwrap(), "--emit", kind, jobs.to_str().unwrap()]);
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(o.status.success(), "{text}{}", String::from_utf8_lossy(&o.stderr));
        assert!(status_of(&text, "bssrdf").contains("written as batch jobs"), "{text}");
        assert!(status_of(&text, "optics").contains("ran"), "{text}");
        assert!(!out.join("bssrdf/manifest.json").exists(), "the stage waits for its jobs");
        if kind == "slurm" {
            let array = std::fs::read_to_string(jobs.join("lucent-01-bssrdf.array.sbatch")).expect("array script");
            assert!(array.contains("#SBATCH --array=0-3\n") && array.contains("#SBATCH --time=10:00\n"), "{array}");
            // Each task runs its shard's job file, not a rebuilt command line.
            assert!(array.contains(" job run \"") && array.contains("/job-$SLURM_ARRAY_TASK_ID.json\""), "{array}");
            let exec = array.lines().find(|l| l.starts_with("exec ")).expect("the task's command");
            assert!(!exec.contains("--shard") && !exec.contains("--paths"), "{array}");
            let merge = std::fs::read_to_string(jobs.join("lucent-01-bssrdf.merge.sbatch")).expect("merge script");
            assert!(
                merge.contains(" merge ") && merge.contains(&format!("--out {}", out.join("bssrdf/s1").display())),
                "{merge}"
            );
            let submit = std::fs::read_to_string(jobs.join("submit.sh")).expect("submit.sh");
            assert!(submit.contains("--dependency=afterok:"), "{submit}");
        } else {
            let job = std::fs::read_to_string(jobs.join("lucent-01-bssrdf.yaml")).expect("manifest");
            for s in ["kind: Job", "completionMode: Indexed", "completions: 4", "/job-$(JOB_COMPLETION_INDEX).json\""] {
                assert!(job.contains(s), "{s}: {job}");
            }
            assert!(!job.contains("\"--shard\""), "{job}");
        }
        // The shards' job files: shard K's job, beside (not in) its folder.
        let shards: Vec<PathBuf> = std::fs::read_dir(out.join(".lucent-shards"))
            .expect("the shards' folder")
            .map(|e| e.expect("entry").path())
            .collect();
        assert!(!shards.is_empty());
        for (dir, k) in shards.iter().flat_map(|d| (0..4).map(move |k| (d, k))) {
            let file = dir.join(format!("job-{k}.json"));
            let job: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&file).expect("a job file")).expect("JSON");
            assert_eq!(job["bssrdf"]["shard"], format!("{k}/4"), "{}", file.display());
            assert_eq!(job["bssrdf"]["out"], dir.join(k.to_string()).display().to_string());
            assert!(lucent::cli::jobs::read_job(&file).is_ok(), "`lucent job run` reads {}", file.display());
        }
    }
    // --emit needs shards.
    let text = std::fs::read_to_string(&proj).expect("project").replace("shards = 4", "shards = 1");
    std::fs::write(&proj, text).expect("project");
    let o = lucent_cli(&["run", p, "--out", dir.path().join("x").to_str().unwrap(), "--emit", "slurm", "jobs"]);
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("shards"));
}

/// `--executor slurm` without its settings is refused with the keys named,
/// before anything runs; with them, the plan is printed before any stage
/// (here only optics runs: nothing is submitted, no cluster needed).
#[test]
fn slurm_runs_need_their_settings_and_print_their_plan() {
    let dir = tempfile::tempdir().expect("temp");
    let proj = project(dir.path(), &dir.path().join("marker"));
    let p = proj.to_str().unwrap();
    let text = std::fs::read_to_string(&proj).expect("project");
    let cut = text.find("[executor]").expect("an [executor] table");
    let bare = dir.path().join("bare.toml");
    std::fs::write(&bare, &text[..cut]).expect("project");
    let out = dir.path().join("out-bare");
    let o = lucent_cli(&["run", bare.to_str().unwrap(), "--executor", "slurm", "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    for key in ["[executor]", "shards", "partition", "time_limit", "cpus_per_task"] {
        assert!(err.contains(key), "{key}: {err}");
    }
    assert!(!out.exists(), "nothing ran");
    let out = dir.path().join("out-plan");
    let o = lucent_cli(&["run", p, "--executor", "slurm", "--until", "optics", "--out", out.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(o.status.success(), "{text}{}", String::from_utf8_lossy(&o.stderr));
    let plan = text.find("plan: Slurm job arrays of 4 shards per long command").expect("the plan");
    assert!(plan < text.find("] optics ").expect("optics ran"), "{text}");
    assert!(text.contains("bssrdf      on the cluster") && text.contains("render      on the cluster"), "{text}");
    assert!(text.contains("here: short commands"), "{text}");
}

fn lucent_cli(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).current_dir(root()).output().expect("run lucent")
}
