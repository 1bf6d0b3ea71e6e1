//! Hardening III (issue 51): nothing of the user's lost, nothing merged or
//! fitted that does not belong. Each case through the real binary; each
//! failed on main 4005c11.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn lucent_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).current_dir(dir).output().unwrap()
}

/// As [`lucent_in`], but killed (and the test failed) after `limit_s`: a hang is a failure, not a stuck test.
fn lucent_within(dir: &Path, args: &[&str], limit_s: u64) -> Output {
    let child = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let pid = child.id();
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let flag = done.clone();
    let watchdog = std::thread::spawn(move || {
        let start = std::time::Instant::now();
        while start.elapsed().as_secs() < limit_s {
            if flag.load(std::sync::atomic::Ordering::SeqCst) {
                return false;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        // SAFETY: a signal to the child this test started (not yet reaped: we hold it).
        unsafe { libc::kill(pid as libc::pid_t, libc::SIGKILL) };
        true
    });
    let o = child.wait_with_output().unwrap();
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    assert!(!watchdog.join().unwrap(), "lucent {} ran longer than {limit_s} s (a hang)", args.join(" "));
    o
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn ok(o: &Output, what: &str) {
    assert!(o.status.success(), "{what}: {}\n{}", stdout(o), stderr(o));
}

/// A refusal: non-zero exit, `error:` with every piece of `says`, no panic.
fn refused(o: &Output, says: &[&str], what: &str) {
    let e = stderr(o);
    assert!(!o.status.success(), "{what}: exit 0\n{e}");
    assert!(e.contains("error") && !e.contains("panicked"), "{what}: {e}");
    for s in says {
        assert!(e.contains(s), "{what}: the message does not say {s:?}: {e}");
    }
}

fn s(p: &Path) -> String {
    p.to_str().unwrap().to_string()
}

fn write_exr(path: &Path, w: usize, h: usize, value: f32) {
    let plane = vec![value; w * h];
    lucent::exr::write_channels(path, w, h, &[("R", &plane), ("G", &plane), ("B", &plane)]).unwrap();
}

/// Data loss: `run --force optics` and a rerun that refreshes the report
/// keep the user's files in the stage folders (named in a warning), a
/// lucent file the user edited is kept beside the new one, and the user's
/// files do not make a stage out of date.
#[test]
fn data_loss_reruns_keep_the_users_files_in_stage_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    std::fs::write(
        d.join("p.toml"),
        format!("[project]\nname = \"p\"\n[[sample]]\nname = \"s\"\nrecipe = {:?}\n", s(&recipe)),
    )
    .unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--out", "o"]);
    ok(&o, "first run");
    assert!(d.join("o/optics/manifest.json").is_file() && d.join("o/report/manifest.json").is_file());
    std::fs::write(d.join("o/optics/notes.txt"), "the user's optics notes").unwrap();
    std::fs::create_dir_all(d.join("o/report/mine")).unwrap();
    std::fs::write(d.join("o/report/notes.txt"), "the user's report notes").unwrap();
    std::fs::write(d.join("o/report/mine/plot.svg"), "<svg/>").unwrap();
    // The user's files alone do not make a stage out of date.
    let o = lucent_in(d, &["run", "p.toml", "--out", "o"]);
    ok(&o, "rerun");
    assert!(stdout(&o).contains("up to date"), "{}", stdout(&o));
    // --force optics reruns optics and refreshes the report.
    let o = lucent_in(d, &["run", "p.toml", "--out", "o", "--force", "optics"]);
    ok(&o, "run --force optics");
    assert_eq!(std::fs::read_to_string(d.join("o/optics/notes.txt")).unwrap(), "the user's optics notes");
    assert_eq!(std::fs::read_to_string(d.join("o/report/notes.txt")).unwrap(), "the user's report notes");
    assert_eq!(std::fs::read_to_string(d.join("o/report/mine/plot.svg")).unwrap(), "<svg/>");
    let e = stderr(&o);
    assert!(e.contains("warning") && e.contains("optics/notes.txt"), "{e}");
    // A file lucent wrote and the user edited: the new run writes its own, the user's is kept beside it.
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("o/optics/manifest.json")).unwrap()).unwrap();
    let listed: Vec<String> =
        manifest["outputs"].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_string()).collect();
    assert!(!listed.iter().any(|f| f.contains("notes")), "the user's file listed as lucent's: {listed:?}");
    assert_eq!(manifest["files"].as_array().unwrap().len(), listed.len(), "every output with its hash");
    let edited = listed.iter().find(|f| f.ends_with(".csv")).expect("a CSV output").clone();
    std::fs::write(d.join("o/optics").join(&edited), "the user's edit").unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--out", "o"]);
    ok(&o, "rerun after an edit");
    let yours = d.join("o/optics").join(format!("{edited}.yours"));
    assert_eq!(std::fs::read_to_string(&yours).unwrap(), "the user's edit");
    assert_ne!(std::fs::read_to_string(d.join("o/optics").join(&edited)).unwrap(), "the user's edit");
    assert!(stderr(&o).contains(&format!("{edited}.yours")), "{}", stderr(&o));
    // A second run into a folder a live run holds is refused clearly; a stale lock is replaced.
    let host = std::fs::read_to_string("/proc/sys/kernel/hostname").unwrap_or_default().trim().to_string();
    std::fs::write(d.join("o/.lucent-lock"), format!("{} {host}\n", std::process::id())).unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--out", "o", "--force", "optics"]);
    refused(&o, &["another lucent run", &format!("pid {}", std::process::id()), ".lucent-lock"], "a locked folder");
    assert!(!stderr(&o).contains("did not write"), "{}", stderr(&o));
    std::fs::write(d.join("o/.lucent-lock"), format!("999999999 {host}\n")).unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--out", "o", "--force", "optics"]);
    ok(&o, "a stale lock");
    assert!(stderr(&o).contains("stale lock"), "{}", stderr(&o));
    assert!(!d.join("o/.lucent-lock").exists(), "the run left its lock");
    // No hidden previous result is left behind.
    let names: Vec<String> = std::fs::read_dir(d.join("o"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().all(|n| !n.contains("previous")), "{names:?}");
}

/// Hangs: a path count no machine finishes is refused at once, with the
/// documented maximum, by every command (and project key) that takes one.
#[test]
fn hang_path_counts_beyond_the_maximum_are_refused_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("m.csv"), "1,2,1\n2,4,2\n1,2,1\n").unwrap();
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let r = s(&recipe);
    let slab = ["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9"];
    let huge = "18446744073709551615";
    let mut sharded: Vec<&str> = slab.to_vec();
    sharded.extend(["--paths", huge, "--shard", "0/2", "--out", "o"]);
    let mut plain: Vec<&str> = slab.to_vec();
    plain.extend(["--paths", "1000000000001", "--out", "o"]);
    for args in [
        sharded,
        plain,
        vec![
            "fit",
            "--recipe",
            &r,
            "--measured",
            "m.csv:45/0",
            "--measured-pixel-mm",
            "0.1",
            "--free",
            "weight_percent",
            "--paths",
            huge,
            "--out",
            "o",
        ],
        vec!["bench", "surface", "--paths", huge],
    ] {
        let o = lucent_within(d, &args, 60);
        refused(&o, &["--paths", "1000000000000"], &args.join(" "));
    }
    // The same range for the project's keys.
    std::fs::write(
        d.join("p.toml"),
        format!(
            "[project]\nname = \"p\"\n[bssrdf]\npixels = 9\npaths = 10000000000000\n[[sample]]\nname = \"s\"\nrecipe = {r:?}\n"
        ),
    )
    .unwrap();
    let o = lucent_within(d, &["run", "p.toml", "--out", "o"], 60);
    refused(&o, &["[bssrdf] paths", "1000000000000"], "[bssrdf] paths = 1e13");
    assert!(!d.join("o").exists(), "a refused run wrote o/");
}

/// Signals: SIGHUP (a closed terminal) stops a command like SIGTERM:
/// exit 130, a message, nothing half-written; a render keeps its labelled
/// partial result.
#[test]
fn signals_sighup_is_handled_like_sigterm() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let recipe = std::fs::read_to_string(root().join("fixtures/samples/IOL1068-09.toml")).unwrap();
    let recipe = recipe.replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.02 }");
    std::fs::write(d.join("a.toml"), recipe).unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["optics", "a.toml", "--uncertainty", "100000", "--wavelengths", "380:780:1", "--out", "u"])
        .current_dir(d)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    // SAFETY: a signal to our own child process.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGHUP) }, 0);
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "SIGHUP: {:?} {}", o.status, stderr(&o));
    assert!(stderr(&o).contains("interrupted"), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 1, "SIGHUP left files behind");
    // A render: the finished passes are written as a labelled partial render.
    let out = d.join("r");
    let scene = root().join("fixtures/render/plaque_dense.toml");
    let args =
        ["render", scene.to_str().unwrap(), "--spp", "1000000", "--size", "32x24", "--out", out.to_str().unwrap()];
    let (status, text) = crate::common::signal_n_after(&args, "rendering", 1, libc::SIGHUP);
    assert_eq!(status.code(), Some(130), "SIGHUP during a render: {text}");
    assert!(text.contains("SIGHUP"), "no message: {text}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("render.json")).unwrap()).unwrap();
    assert_eq!(json["interrupted"], true);
}

const SCENE: &str = "fixtures/render/demo.toml";

fn render_shard(dir: &Path, out: &Path, k: u32) -> Output {
    let spec = format!("{k}/2");
    let scene = root().join(SCENE);
    lucent_in(
        dir,
        &[
            "render",
            &s(&scene),
            "--quiet",
            "--size",
            "12x9",
            "--spp",
            "6",
            "--seed",
            "3",
            "--out",
            &s(out),
            "--shard",
            &spec,
        ],
    )
}

fn merge(dir: &Path, shards: &[&Path], out: &Path) -> Output {
    let mut args = vec!["merge".to_string()];
    args.extend(shards.iter().map(|p| s(p)));
    args.extend(["--out".to_string(), s(out)]);
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    lucent_in(dir, &a)
}

/// Merged what does not belong: a copied or linked accumulator of another
/// shard, counters edited in shard.json, two shards into one folder, and a
/// merge --out that leads into a shard folder are refused; shards of one
/// run given their flags in another spelling merge.
#[cfg(unix)]
#[test]
fn shards_merge_only_what_belongs_to_the_run() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (a0, a1) = (d.join("a0"), d.join("a1"));
    ok(&render_shard(d, &a0, 0), "shard 0");
    ok(&render_shard(d, &a1, 1), "shard 1");
    ok(&merge(d, &[&a0, &a1], &d.join("good")), "merge");
    // Shard 1's accumulator copied into shard 0's folder.
    let (c0, c1) = (d.join("c0"), d.join("c1"));
    for (from, to) in [(&a0, &c0), (&a1, &c1)] {
        std::fs::create_dir_all(to).unwrap();
        for f in std::fs::read_dir(from).unwrap() {
            let f = f.unwrap().path();
            std::fs::copy(&f, to.join(f.file_name().unwrap())).unwrap();
        }
    }
    std::fs::copy(c1.join("render.acc"), c0.join("render.acc")).unwrap();
    let o = merge(d, &[&c0, &c1], &d.join("m1"));
    refused(&o, &["c0/render.acc", "shard 1 of 2", "shard 0 of 2"], "a copied accumulator");
    assert!(!d.join("m1").exists());
    // … or linked.
    std::fs::remove_file(c0.join("render.acc")).unwrap();
    std::os::unix::fs::symlink(c1.join("render.acc"), c0.join("render.acc")).unwrap();
    let o = merge(d, &[&c0, &c1], &d.join("m2"));
    refused(&o, &["c0/render.acc", "symbolic link"], "a linked accumulator");
    // Counters edited in shard.json.
    std::fs::remove_file(c0.join("render.acc")).unwrap();
    std::fs::copy(a0.join("render.acc"), c0.join("render.acc")).unwrap();
    let json = std::fs::read_to_string(c0.join("shard.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let events = v["counters"]["events"].as_u64().unwrap();
    v["counters"]["events"] = serde_json::json!(events * 10);
    std::fs::write(c0.join("shard.json"), serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let o = merge(d, &[&c0, &c1], &d.join("m3"));
    refused(&o, &["c0/render.acc", "counters", "edited"], "edited counters");
    // Two shards into one --out: the second is refused, the first kept.
    let both = d.join("both");
    ok(&render_shard(d, &both, 0), "shard 0 into both/");
    let before = std::fs::read(both.join("render.acc")).unwrap();
    let o = render_shard(d, &both, 1);
    refused(&o, &["already holds shard 0 of 2", "its own folder"], "a second shard into one folder");
    assert_eq!(std::fs::read(both.join("render.acc")).unwrap(), before);
    // A retry of the same shard into its own folder is fine.
    ok(&render_shard(d, &both, 0), "shard 0 again");
    // merge --out through a link into a shard folder.
    std::os::unix::fs::symlink(&a0, d.join("link")).unwrap();
    let o = merge(d, &[&a0, &a1], &d.join("link/merged"));
    refused(&o, &["must not be or contain a shard folder"], "merge --out into a shard through a link");
    assert!(!a0.join("merged").exists());
    // The same run with its flags in another order, as --flag=value, and the scene by a relative path.
    let b0 = d.join("b0");
    ok(&render_shard(d, &b0, 0), "shard 0 (b)");
    let b1 = d.join("b1");
    let o = lucent_in(
        &root(),
        &["render", "--seed=3", SCENE, "--shard=1/2", "--spp=6", "--out", &s(&b1), "--size", "12x9", "--quiet"],
    );
    ok(&o, "shard 1 (b), respelled");
    let o = merge(d, &[&b0, &b1], &d.join("bm"));
    ok(&o, "merge of respelled shards");
    let (_, _, x) = lucent::exr::read_channels(&d.join("bm/render.exr"), &["R"]).unwrap();
    let (_, _, y) = lucent::exr::read_channels(&d.join("good/render.exr"), &["R"]).unwrap();
    assert_eq!(x, y, "the respelled shards' merge differs from the first merge");
}

fn slice(d: &Path, name: &str, centre: f64) -> PathBuf {
    let rows: Vec<String> = (0..21)
        .map(|i: i32| {
            (0..21)
                .map(|j: i32| {
                    let v = 1.0 + 100.0 * (-((i - 10).pow(2) + (j - 10).pow(2)) as f64 / 8.0).exp();
                    format!("{:.6}", if i == 10 && j == 10 { centre } else { v })
                })
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    let p = d.join(name);
    std::fs::write(&p, rows.join("\n") + "\n").unwrap();
    p
}

fn fit_args<'a>(recipe: &'a str, measured: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut v = vec!["fit", "--recipe", recipe, "--measured", measured, "--free", "weight_percent", "--paths", "1000"];
    v.extend_from_slice(extra);
    v.extend(["--out", "fo"]);
    v
}

/// Fitted what does not belong: a measured slice whose sidecar gives
/// another wavelength or other angles than it is used for, or a negative
/// pixel, is refused with both values and the file named.
#[test]
fn measured_slices_carry_their_metadata() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let recipe = s(&root().join("fixtures/samples/IOL1068-09.toml"));
    slice(d, "m.csv", 101.0);
    std::fs::write(
        d.join("m.csv.json"),
        r#"{"pixel_mm": 0.2, "wavelength_nm": 650, "theta_i_deg": 45, "theta_o_deg": 0}"#,
    )
    .unwrap();
    let o = lucent_within(d, &fit_args(&recipe, "m.csv:45/0", &["--wavelength", "550"]), 60);
    refused(&o, &["m.csv.json", "650 nm", "550 nm"], "a 650 nm slice fitted at 550 nm");
    let o = lucent_within(d, &fit_args(&recipe, "m.csv:30/0", &["--wavelength", "650"]), 60);
    refused(&o, &["m.csv.json", "45/", "30/"], "a 45/0 slice used as 30/0");
    slice(d, "neg.csv", -5.0);
    let o = lucent_within(d, &fit_args(&recipe, "neg.csv:45/0", &["--measured-pixel-mm", "0.2"]), 60);
    refused(&o, &["neg.csv", "negative", "column 10, row 10"], "a negative pixel");
    assert!(!d.join("fo").exists());
    // Inside `lucent run`, a slice without a pixel size names the project key.
    std::fs::write(d.join("bare.csv"), "1,2,1\n2,4,2\n1,2,1\n").unwrap();
    std::fs::write(
        d.join("p.toml"),
        format!(
            "[project]\nname = \"p\"\n[fit]\nfree = [\"weight_percent\"]\n[[sample]]\nname = \"s\"\nrecipe = {recipe:?}\n\
             [[sample.measured]]\nconfig = \"45/0\"\nfile = \"bare.csv\"\n"
        ),
    )
    .unwrap();
    let o = lucent_within(d, &["run", "p.toml", "--out", "o"], 60);
    refused(&o, &["measured pixel_mm", "bare.csv"], "a slice without pixel size in a project");
    assert!(!stderr(&o).contains("--measured-pixel-mm"), "{}", stderr(&o));
}

fn write_render_with_variance(path: &Path, w: usize, h: usize, value: f32, variance: f32) {
    let plane = vec![value; w * h];
    let var = vec![variance; w * h];
    lucent::exr::write_channels(
        path,
        w,
        h,
        &[
            ("R", &plane),
            ("G", &plane),
            ("B", &plane),
            ("variance.R", &var),
            ("variance.G", &var),
            ("variance.B", &var),
        ],
    )
    .unwrap();
}

/// Photo variance: a variance image of another size, with a negative or
/// NaN value, or implausibly large (1e30) is refused naming the
/// photo-variance file (not the render's); a radiance image given as the
/// variance gets a warning.
#[test]
fn photo_variance_is_checked_against_the_photo() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (w, h) = (64, 48);
    // A photo with a little noise, a render close to it.
    let photo: Vec<f32> = (0..w * h).map(|i| 0.5 + 0.01 * (((i * 7919) % 101) as f32 / 101.0 - 0.5)).collect();
    lucent::exr::write_channels(&d.join("photo.exr"), w, h, &[("R", &photo), ("G", &photo), ("B", &photo)]).unwrap();
    write_render_with_variance(&d.join("render.exr"), w, h, 0.5, 1e-6);
    let compare = |var: &str, out: &str| {
        lucent_in(
            d,
            &["compare", "--photo", "photo.exr", "--render", "render.exr", "--photo-variance", var, "--out", out],
        )
    };
    write_exr(&d.join("huge.exr"), w, h, 1e30);
    refused(&compare("huge.exr", "c1"), &["huge.exr", "photo variance", "100"], "1e30 variance");
    write_exr(&d.join("negative.exr"), w, h, -1e-4);
    let o = compare("negative.exr", "c2");
    refused(&o, &["negative.exr", "≥ 0"], "negative variance");
    assert!(!stderr(&o).contains("render.exr:"), "blamed on the render: {}", stderr(&o));
    write_exr(&d.join("nan.exr"), w, h, f32::NAN);
    refused(&compare("nan.exr", "c3"), &["nan.exr", "finite"], "NaN variance");
    write_exr(&d.join("small.exr"), w / 2, h / 2, 1e-6);
    refused(&compare("small.exr", "c4"), &["small.exr", "32 × 24"], "variance of another size");
    // A radiance image (a render's R, G, B without variance layers) given as the photo's variance: a warning, named.
    write_exr(&d.join("radiance.exr"), w, h, 0.5);
    let o = compare("radiance.exr", "c5");
    ok(&o, "radiance as variance");
    assert!(stderr(&o).contains("warning") && stderr(&o).contains("radiance.exr"), "{}", stderr(&o));
    for out in ["c1", "c2", "c3", "c4"] {
        assert!(!d.join(out).exists(), "a refused compare wrote {out}");
    }
}

/// Misleading: a dangling link and a loop of links as --out are said as
/// such; scene and index values that were taken silently are refused with
/// the key named.
#[cfg(unix)]
#[test]
fn misleading_links_and_silently_taken_values_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let recipe = s(&root().join("fixtures/samples/IOL1068-09.toml"));
    std::os::unix::fs::symlink(d.join("nowhere"), d.join("dangling")).unwrap();
    std::os::unix::fs::symlink(d.join("loop"), d.join("loop")).unwrap();
    for (out, says) in [("dangling", "symbolic link to"), ("loop", "loop of symbolic links")] {
        let o = lucent_in(d, &["optics", &recipe, "--wavelength", "550", "--out", out]);
        refused(&o, &[out, says], out);
        assert!(!stderr(&o).contains("is not a folder") && !stderr(&o).contains("No such file"), "{}", stderr(&o));
    }
    let bad = root().join("tests/bad");
    let o = lucent_in(d, &["render", &s(&bad.join("misleading/spp_per_pass_zero.toml")), "--out", "r"]);
    refused(&o, &["spp_per_pass_zero.toml", "spp_per_pass", "at least 1"], "spp_per_pass = 0");
    let o = lucent_in(d, &["render", &s(&bad.join("nonsense/transform_mirror.toml")), "--out", "r"]);
    refused(&o, &["transform_mirror.toml", "transform", "mirrors"], "a mirroring transform");
    let o = lucent_in(d, &["render", &s(&bad.join("nonsense/transform_vanishing.toml")), "--out", "r"]);
    refused(&o, &["transform_vanishing.toml", "transform", "vanish"], "a vanishing transform");
    let o =
        lucent_in(d, &["optics", &s(&bad.join("index/formula_half_pair.toml")), "--wavelength", "550", "--out", "x"]);
    refused(&o, &["formula_half_pair.yml", "formula 2", "pairs"], "formula 2 with 2 coefficients");
    // A CSV slice: a bad line is shown with its text; a UTF-8 byte-order mark is read past.
    let o = lucent_in(
        d,
        &["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--paths", "100"]
            .into_iter()
            .chain(["--pixel-mm", "0.1", "--quiet", "--out", "sim"])
            .collect::<Vec<_>>(),
    );
    ok(&o, "a simulated slice");
    let row = ["1"; 9].join(",");
    std::fs::write(d.join("bom.csv"), format!("\u{feff}{}\n", [row.as_str(); 9].join("\n"))).unwrap();
    let o = lucent_in(
        d,
        &[
            "bssrdf",
            "compare",
            "--measured",
            "bom.csv",
            "--measured-pixel-mm",
            "0.1",
            "--simulated",
            "sim",
            "--out",
            "bc",
        ],
    );
    ok(&o, "a CSV slice with a byte-order mark");
    let o = lucent_in(
        d,
        &[
            "bssrdf",
            "compare",
            "--measured",
            &s(&bad.join("slice/semicolons.csv")),
            "--measured-pixel-mm",
            "0.1",
            "--simulated",
            "sim",
            "--out",
            "bs",
        ],
    );
    refused(&o, &["semicolons.csv", "line 1", "1;2;1", "semicolons"], "a CSV with semicolons");
    // A slice wider than 1 m: said with the flags, not the simulator's pixel_m.
    let o = lucent_in(
        d,
        &["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--paths", "10"]
            .into_iter()
            .chain(["--pixel-mm", "1e300", "--out", "zz"])
            .collect::<Vec<_>>(),
    );
    refused(&o, &["--pixel-mm 1e300", "1000 mm"], "--pixel-mm 1e300");
    assert!(!stderr(&o).contains("pixel_m "), "{}", stderr(&o));
    assert!(!d.join("r").exists() && !d.join("x").exists() && !d.join("zz").exists());
}

/// Another project's results: `lucent run` into the output folder of a
/// different project is refused (naming both); an earlier version of the
/// same project (with a [bssrdf] since removed) leaves no BSSRDF in the
/// report of the project without one.
#[test]
fn a_run_reports_only_its_own_projects_stages() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let r = s(&root().join("fixtures/samples/IOL1068-09.toml"));
    let project = |name: &str, bssrdf: bool| {
        let b = if bssrdf { "[bssrdf]\npixels = 9\npaths = 2000\nconfigs = \"45/0\"\n" } else { "" };
        format!("[project]\nname = \"{name}\"\n{b}[[sample]]\nname = \"s\"\nrecipe = {r:?}\n")
    };
    std::fs::write(d.join("a.toml"), project("a", true)).unwrap();
    std::fs::write(d.join("b.toml"), project("b", false)).unwrap();
    std::fs::write(d.join("a2.toml"), project("a", false)).unwrap();
    ok(&lucent_in(d, &["run", "a.toml", "--out", "o"]), "project a");
    assert!(std::fs::read_to_string(d.join("o/report/index.html")).unwrap().contains("BSSRDF slices"));
    let before = std::fs::read(d.join("o/report/index.html")).unwrap();
    let o = lucent_in(d, &["run", "b.toml", "--out", "o"]);
    refused(&o, &["o: holds the results of project \"a\"", "not of \"b\"", "--out"], "another project's folder");
    assert_eq!(std::fs::read(d.join("o/report/index.html")).unwrap(), before, "the refused run changed the report");
    // The same project without its [bssrdf]: the old slices are not in its report.
    ok(&lucent_in(d, &["run", "a2.toml", "--out", "o"]), "project a without [bssrdf]");
    let html = std::fs::read_to_string(d.join("o/report/index.html")).unwrap();
    assert!(!html.contains("BSSRDF slices"), "an earlier plan's bssrdf in the report");
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("o/report/metrics.json")).unwrap()).unwrap();
    assert!(metrics["manifests"].get("bssrdf").is_none(), "{}", metrics["manifests"]);
    assert!(metrics["stages"]["bssrdf"]["wall_s"].is_null(), "{}", metrics["stages"]);
}

/// A scene error inside `lucent run` names the user's project file, its
/// `[render] scene` and the key in the user's scene file, not the
/// `input_scene.toml` the run writes from it; no stage runs a render.
#[test]
fn a_scene_error_in_a_run_names_the_users_files() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let r = s(&root().join("fixtures/samples/IOL1068-09.toml"));
    let scene = s(&root().join("tests/bad/misleading/spp_per_pass_zero.toml"));
    std::fs::write(
        d.join("p.toml"),
        format!(
            "[project]\nname = \"p\"\n[render]\nscene = {scene:?}\nspp = 1\n[[sample]]\nname = \"s\"\nrecipe = {r:?}\n"
        ),
    )
    .unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--out", "o"]);
    refused(&o, &["p.toml: [render] scene", "spp_per_pass_zero.toml: [render] spp_per_pass"], "a run's bad scene");
    assert!(!stderr(&o).contains("input_scene.toml"), "{}", stderr(&o));
    assert!(!d.join("o/render").exists() && !d.join("o/render.failed").exists());
}

/// A scene of tests/bad/misleading/spp_per_pass_zero.toml (a 60 × 40 mm
/// box, camera 0.21 m away) with `edit` applied to its text.
fn scene_with(d: &Path, name: &str, edit: &dyn Fn(String) -> String) -> String {
    let text = std::fs::read_to_string(root().join("tests/bad/misleading/spp_per_pass_zero.toml")).unwrap();
    let text = text.replace("spp_per_pass = 0   # was taken as 1 without a word", "");
    std::fs::write(d.join(name), edit(text)).unwrap();
    name.to_string()
}

/// Implausible geometry is refused with the key named: a finite environment
/// sphere the camera is outside of, and an object (1e12 mm) around the camera.
#[test]
fn the_camera_is_inside_the_sphere_and_outside_the_object() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let sphere = scene_with(d, "sphere.toml", &|t| {
        t.replace("projection = \"infinite\"", "projection = \"finite-sphere\"\nradius_m = 0.01")
    });
    let o = lucent_in(d, &["render", &sphere, "--out", "r", "--spp", "1"]);
    refused(&o, &["sphere.toml", "[environment] radius_m", "camera", "outside the sphere"], "radius 0.01 m");
    let big = scene_with(d, "big.toml", &|t| t.replace("size_mm = [60.0, 40.0, 6.35]", "size_mm = [1e12, 1e12, 1e12]"));
    let o = lucent_in(d, &["render", &big, "--out", "r", "--spp", "1"]);
    refused(&o, &["big.toml", "[object] size_mm", "around the camera"], "a 1e12 mm object");
    assert!(!d.join("r").exists());
    // The scene as given renders.
    let fine = scene_with(d, "fine.toml", &|t| t);
    ok(&lucent_in(d, &["render", &fine, "--out", "r", "--spp", "1", "--size", "16x12"]), "the scene as given");
}

/// Messages in the user's units: a flag in degrees or micrometres is not
/// said as the library's radians or metres, nor a tiny value in 300 digits.
#[test]
fn messages_name_the_flags_in_the_users_units() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let synth = ["surface", "synth", "--model", "ggx", "--alpha", "0.1", "--size", "16", "--out", "s.x3p"];
    let o = lucent_in(d, &[&synth[..], &["--tilt-deg", "89"]].concat());
    refused(&o, &["tilt-deg 89", "85.9°"], "--tilt-deg 89");
    assert!(!stderr(&o).contains("1.55"), "radians: {}", stderr(&o));
    let o = lucent_in(d, &[&synth[..], &["--tilt-azimuth-deg", "inf"]].concat());
    refused(&o, &["tilt-azimuth-deg inf"], "--tilt-azimuth-deg inf");
    let slab =
        ["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--paths", "10"];
    let o = lucent_in(d, &[&slab[..], &["--beam-fwhm-um", "0", "--out", "b"]].concat());
    refused(&o, &["--beam-fwhm-um 0", "micrometres"], "--beam-fwhm-um 0");
    assert!(!stderr(&o).contains("beam_fwhm_m"), "{}", stderr(&o));
    let o = lucent_in(d, &[&slab[..], &["--pixel-mm", "1e-300", "--out", "b"]].concat());
    refused(&o, &["1e-300 mm"], "--pixel-mm 1e-300");
    assert!(!stderr(&o).contains("0.0000000000"), "{}", stderr(&o));
    assert!(!d.join("b").exists() && !d.join("s.x3p").exists());
}

/// A text grid's bad line is quoted with its number; a UTF-8 byte-order
/// mark is read past (height maps; a slice's ragged row).
#[test]
fn csv_bad_lines_are_quoted() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("h.csv"), "\u{feff}# pitch = 1 um\n1,2,3\n4,x5,6\n").unwrap();
    let o = lucent_in(d, &["surface", "fit", "h.csv", "--out", "f"]);
    refused(&o, &["h.csv: line 3", "\"x5\"", "\"4,x5,6\""], "a bad token");
    std::fs::write(d.join("r.csv"), "# pitch = 1 um\n1,2,3\n4,5\n").unwrap();
    let o = lucent_in(d, &["surface", "fit", "r.csv", "--out", "f"]);
    refused(&o, &["r.csv: line 3", "\"4,5\"", "line 2"], "a short row");
    std::fs::write(d.join("s.csv"), "1,2,1\n2,4\n1,2,1\n").unwrap();
    std::fs::write(d.join("sim.csv"), "1,2,1\n2,4,2\n1,2,1\n").unwrap();
    let o = lucent_in(
        d,
        &[
            "bssrdf",
            "compare",
            "--measured",
            "s.csv",
            "--measured-pixel-mm",
            "0.1",
            "--simulated",
            "sim.csv",
            "--out",
            "c",
        ],
    );
    refused(&o, &["s.csv", "line 2", "\"2,4\""], "a slice's short row");
}

/// A full disk (here a file-size limit) while writing: the error names the
/// output the user asked for, not the hidden staging folder it was written in.
#[cfg(unix)]
#[test]
fn a_failed_write_names_the_users_output_path() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let script = format!(
        "ulimit -f 2; trap '' XFSZ; exec {} bssrdf --mu-s 1000 --mu-a 1 --g 0.8 --n 1.5 --pixels 9 --paths 100 \
         --quiet --out out",
        env!("CARGO_BIN_EXE_lucent")
    );
    let o = Command::new("sh").args(["-c", &script]).current_dir(d).output().unwrap();
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("out/bssrdf.") && e.contains("File too large"), "{e}");
    assert!(!e.contains("staging") && !e.contains(".tmp"), "{e}");
    assert!(std::fs::read_dir(d).unwrap().count() == 0, "left behind in the folder");
}

/// Calibration plausibility: the rational model from 3 views, a pose with
/// the calibration's board transposed, a 1 km sample on a 25 mm board.
#[test]
fn calibration_plausibility() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let img = |n: &str| s(&root().join(format!("fixtures/camera/chessboard/left{n}.jpg")));
    let three = [img("01"), img("02"), img("03")];
    let mut args: Vec<&str> = vec!["calibrate", "--images"];
    args.extend(three.iter().map(String::as_str));
    args.extend(["--board", "9x6", "--square-mm", "25", "--model", "rational", "--out", "r.json"]);
    let o = lucent_in(d, &args);
    refused(&o, &["--model rational", "3 views", "at least 6"], "rational from 3 views");
    assert!(!d.join("r.json").exists());
    let all = s(&root().join("fixtures/camera/chessboard"));
    ok(
        &lucent_in(d, &["calibrate", "--images", &all, "--board", "9x6", "--square-mm", "25", "--out", "c.json"]),
        "9x6",
    );
    let pose = ["pose", "--camera", "c.json", "--image", &three[0], "--square-mm", "25", "--out", "p.json"];
    let o = lucent_in(d, &[&pose[..], &["--board", "6x9"]].concat());
    refused(&o, &["--board 6x9", "9x6", "swapped"], "a transposed board");
    let o = lucent_in(
        d,
        &[&pose[..], &["--board", "9x6", "--sample-corner", "1,1", "--sample-size-mm", "1e6,1e6,6"]].concat(),
    );
    refused(&o, &["--sample-size-mm", "1000000 mm", "board"], "a 1 km sample");
    assert!(!d.join("p.json").exists());
    ok(
        &lucent_in(
            d,
            &[&pose[..], &["--board", "9x6", "--sample-corner", "1,1", "--sample-size-mm", "60,40,6"]].concat(),
        ),
        "pose",
    );
}

/// An inverted chart (a negative) is said to be inverted, not blamed on
/// the corner order; an all-negative one is refused.
#[test]
fn an_inverted_colour_chart_is_said_so() {
    use lucent_colour::chart::{draw_chart, SampleOptions};
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let corners = [[40.0, 30.0], [560.0, 55.0], [540.0, 390.0], [25.0, 360.0]];
    let arg = corners.iter().flatten().map(|v: &f64| v.to_string()).collect::<Vec<_>>().join(",");
    let xyz: Vec<[f64; 3]> = lucent_colour::data::colorchecker_2014().iter().map(|p| p.xyz()).collect();
    let write = |name: &str, f: &dyn Fn(f64) -> f64, background: f32| {
        let patches: Vec<[f64; 3]> = xyz.iter().map(|c| c.map(f)).collect();
        let data = draw_chart(600, 420, corners, &patches, &SampleOptions::default(), [background; 3]).unwrap();
        lucent::imageio::write_exr(&d.join(name), &lucent::imageio::RgbImage::new(600, 420, data).unwrap()).unwrap();
    };
    write("negative.exr", &|v| 0.95 - v, 0.9);
    write("minus.exr", &|v| -v, -0.01);
    let o = lucent_in(d, &["colour", "calibrate", "--image", "negative.exr", "--corners", &arg, "--out", "n"]);
    let e = stderr(&o);
    assert!(e.contains("warning") && e.contains("inverted") && !e.contains("order of the corners"), "{e}");
    let o = lucent_in(d, &["colour", "calibrate", "--image", "minus.exr", "--corners", &arg, "--out", "m"]);
    refused(&o, &["minus.exr", "inverted", "negative"], "an all-negative chart");
    assert!(!stderr(&o).contains("order of the corners") && !d.join("m").exists(), "{}", stderr(&o));
}

/// A long optics study stops at Ctrl-C after the group of draws under way:
/// exit 130, the reason said, nothing written.
#[cfg(unix)]
#[test]
fn an_optics_uncertainty_study_stops_at_ctrl_c() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let text = std::fs::read_to_string(root().join("fixtures/samples/IOL1068-09.toml")).unwrap();
    let text = text.replacen("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.02 }", 1);
    assert!(text.contains("sd = 0.02"), "the fixture's weight_percent moved");
    std::fs::write(d.join("u.toml"), text).unwrap();
    let (u, out) = (s(&d.join("u.toml")), s(&d.join("uo")));
    let (status, e) =
        crate::common::interrupt_after(&["optics", &u, "--uncertainty", "100000", "--out", &out], "draws in");
    assert_eq!(status.code(), Some(130), "{e}");
    assert!(e.contains("stopped after") && e.contains("nothing was written"), "{e}");
    assert!(!d.join("uo").exists(), "written after Ctrl-C");
}

/// A command killed after writing its files — here by SIGPIPE, its output
/// piped into a reader that has gone (`lucent render … | head -c 0`) — leaves
/// its folder marked as lucent's, so the next run into it is not refused
/// as a folder "holding files lucent did not write"; a command that fails
/// before writing leaves nothing.
#[test]
fn a_render_killed_by_a_closed_pipe_leaves_a_folder_the_next_run_may_use() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let plaque = root().join("fixtures/render/plaque_dense.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["render", &s(&plaque), "--spp", "1", "--out", "r"])
        .current_dir(d)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let status = child.wait().unwrap();
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(status.signal(), Some(libc::SIGPIPE), "the render is killed by its closed pipe: {status:?}");
    assert!(d.join("r/render.exr").is_file() && d.join("r/render.json").is_file(), "it wrote its files first");
    let o = lucent_in(d, &["render", &s(&plaque), "--spp", "1", "--out", "r"]);
    ok(&o, "a render into the folder a killed render wrote");
    let o = lucent_in(d, &["render", "missing.toml", "--out", "gone"]);
    refused(&o, &["missing.toml"], "render of a missing scene");
    assert!(!d.join("gone").exists(), "a run that wrote nothing leaves no folder");
}
