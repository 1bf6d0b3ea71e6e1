//! The hardening corpus (tests/bad/{data-loss,hang,nonsense,misleading,
//! leftovers,panic}/, see tests/bad/README.md): hostile or mistaken inputs
//! through the real binary, one test per class. Every case must end with a
//! clear `error:` naming the problem, without a panic, and leave the user's
//! files and folders as they were.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn bad(group: &str) -> PathBuf {
    root().join("tests/bad").join(group)
}

fn lucent_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).current_dir(dir).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Every file and folder under `dir` (relative name → bytes; folders empty).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_path_buf();
            if p.is_dir() {
                out.insert(rel, vec![]);
                stack.push(p);
            } else {
                out.insert(rel, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// A refusal: non-zero exit, `error:` with every piece of `says`, no panic.
fn refused(o: &Output, says: &[&str], what: &str) {
    let e = stderr(o);
    assert!(!o.status.success(), "{what}: exit 0\n{e}");
    assert!(e.contains("error:") && !e.contains("panicked"), "{what}: {e}");
    for s in says {
        assert!(e.contains(s), "{what}: the message does not say {s:?}: {e}");
    }
}

fn write_exr(path: &Path, w: usize, h: usize, value: f32) {
    let plane = vec![value; w * h];
    lucent::exr::write_channels(path, w, h, &[("R", &plane), ("G", &plane), ("B", &plane)]).unwrap();
}

/// A user's working folder: their own optics/ and report/ folders and a file.
fn users_folder(dir: &Path) {
    for sub in ["optics", "report"] {
        std::fs::create_dir_all(dir.join(sub)).unwrap();
        std::fs::write(dir.join(sub).join("notes.txt"), format!("the user's {sub} notes")).unwrap();
    }
    std::fs::write(dir.join("thesis.tex"), "the user's thesis").unwrap();
}

#[test]
fn data_loss_names_become_folders_only_after_validation_and_foreign_folders_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let work = tmp.path().join("work");
    std::fs::create_dir_all(&work).unwrap();
    users_folder(&work);
    let before = snapshot(&work);
    let mut files: Vec<PathBuf> = std::fs::read_dir(bad("data-loss")).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    assert!(files.len() >= 10);
    for f in &files {
        // Run from the user's folder without --out: the default output folder would be lucent-out/NAME.
        let o = lucent_in(&work, &["run", f.to_str().unwrap()]);
        let key = if f.file_name().unwrap().to_string_lossy().starts_with("camera") { "camera" } else { "name" };
        refused(&o, &[f.file_name().unwrap().to_str().unwrap(), key], &f.display().to_string());
        assert_eq!(snapshot(&work), before, "{} changed the working folder", f.display());
    }
    // A valid project with --out the user's folder (or its parent): refused, nothing touched.
    let project = tmp.path().join("p.toml");
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    std::fs::write(&project, format!("[project]\nname = \"p\"\n[[sample]]\nname = \"s\"\nrecipe = {:?}\n", recipe))
        .unwrap();
    for out in [work.to_str().unwrap(), "."] {
        let o = lucent_in(&work, &["run", project.to_str().unwrap(), "--out", out, "--until", "optics"]);
        refused(&o, &["lucent did not write"], out);
        assert_eq!(snapshot(&work), before);
    }
    // A file (or a foreign folder) where a stage folder goes is refused, not moved aside.
    let out = tmp.path().join("run");
    let o = lucent_in(tmp.path(), &["run", project.to_str().unwrap(), "--out", "run", "--until", "optics"]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::remove_dir_all(out.join("optics")).unwrap();
    std::fs::write(out.join("optics"), "a file of the user's").unwrap();
    let o = lucent_in(tmp.path(), &["run", project.to_str().unwrap(), "--out", "run", "--until", "optics"]);
    refused(&o, &["optics", "is not a folder", "leaves it alone"], "file as stage folder");
    assert_eq!(std::fs::read_to_string(out.join("optics")).unwrap(), "a file of the user's");
    assert!(!out.join(".optics.previous").exists());
    std::fs::remove_file(out.join("optics")).unwrap();
    std::fs::create_dir(out.join("optics")).unwrap();
    std::fs::write(out.join("optics/mine.txt"), "x").unwrap();
    let o = lucent_in(tmp.path(), &["run", project.to_str().unwrap(), "--out", "run", "--until", "optics"]);
    refused(&o, &["optics", "did not write"], "foreign stage folder");
    assert!(out.join("optics/mine.txt").is_file() && !out.join(".optics.previous").exists());
    // Every command with an output folder refuses the user's folder.
    let photo = tmp.path().join("photo.exr");
    write_exr(&photo, 64, 48, 0.5);
    let w = work.to_str().unwrap();
    let p = photo.to_str().unwrap();
    let r = recipe.to_str().unwrap();
    let plaque = root().join("fixtures/render/plaque_dense.toml");
    let commands: Vec<Vec<&str>> = vec![
        vec!["optics", r, "--wavelength", "550", "--out", w],
        vec!["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--paths", "10"],
        vec!["render", plaque.to_str().unwrap(), "--spp", "1", "--out", w],
        vec!["compare", "--photo", p, "--render", p, "--out", w],
        vec!["env", "fit-scale", plaque.to_str().unwrap(), "--photo", p, "--out", w],
        vec!["env", "brackets", p, "--exposures", "1,2", "--out-dir", w],
        vec!["report", project.to_str().unwrap(), "--run", out.to_str().unwrap(), "--out", w],
    ];
    for mut args in commands {
        if args[0] == "bssrdf" {
            args.extend(["--out", w]);
        }
        let o = lucent_in(tmp.path(), &args);
        refused(&o, &["lucent did not write"], &args.join(" "));
        assert_eq!(snapshot(&work), before, "{args:?}");
    }
}

#[test]
fn hang_sizes_and_counts_have_stated_limits() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path().to_str().unwrap();
    let scene = bad("hang").join("sigma_s_1e15.toml");
    let o = lucent_in(tmp.path(), &["render", scene.to_str().unwrap(), "--out", "o"]);
    refused(&o, &["sigma_s_1e15.toml", "sigma_s_per_m", "1e7"], "σs = 1e15");
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let r = recipe.to_str().unwrap();
    for (args, says) in [
        (vec!["optics", r, "--wavelength", "550", "--phase-entries", "2000000000", "--out", "o"], "0 … 100000"),
        (vec!["optics", r, "--wavelength", "550", "--uncertainty", "1000000000", "--out", "o"], "2 … 100000"),
        (vec!["raw", "clipped", "x.dng", "--dilate", "1000000", "--out", "m.png"], "0 … 100"),
        (vec!["render", scene.to_str().unwrap(), "--threads", "100000", "--out", "o"], "--threads"),
        (
            vec!["bssrdf", "--mu-s", "1e15", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--paths", "10", "--out", "o"],
            "1e7",
        ),
        // The work of a Mie series grows with |m·x|, of a phase table with wavelengths × entries.
        (vec!["mie", "--size-parameter", "5", "--relative-index", "1e10"], "|m·x|"),
        (vec!["optics", r, "--wavelengths", "400:700:0.01", "--out", "o"], "phase-table values"),
        (
            vec!["env", "paste", "m.exr", "--chessboard", "100000x100000", "--fov", "60", "--out", "p.exr"],
            "at most 200",
        ),
        (vec!["bench", "mie", "--repeats", "4000000000"], "1 … 1000"),
        // A device where a text file is expected is read up to a bound, not until the memory is full.
        (vec!["optics", "/dev/zero", "--out", "o"], "/dev/zero"),
        (vec!["render", "/dev/zero", "--out", "o"], "/dev/zero"),
    ] {
        let o = lucent_in(tmp.path(), &args);
        refused(&o, &[says], &args.join(" "));
    }
    assert_eq!(std::fs::read_dir(t).unwrap().count(), 0, "a refused run wrote into {t}");
}

#[test]
fn nonsense_is_refused_by_the_one_validator_of_each_quantity() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (positive, negative, black) = (d.join("photo.exr"), d.join("negative.exr"), d.join("black.exr"));
    write_exr(&positive, 64, 48, 0.5);
    write_exr(&negative, 64, 48, -0.5);
    write_exr(&black, 64, 48, 0.0);
    let s = |p: &Path| p.to_str().unwrap().to_string();
    // compare: a negative or black photo.
    for photo in [&negative, &black] {
        let o = lucent_in(d, &["compare", "--photo", &s(photo), "--render", &s(&positive), "--out", "c"]);
        refused(&o, &[&s(photo), "black or negative"], "compare");
    }
    // env fit-scale: a negative or black photo of the board gives no scale.
    let plaque = root().join("fixtures/render/plaque_dense.toml");
    for photo in [&negative, &black] {
        let o = lucent_in(d, &["env", "fit-scale", &s(&plaque), "--photo", &s(photo), "--spp", "1", "--out", "f"]);
        refused(&o, &["black or negative", "scale must be > 0"], "fit-scale");
    }
    // bssrdf compare: an RGB EXR is not a slice.
    let sim = d.join("sim");
    let o = lucent_in(
        d,
        &[
            "bssrdf",
            "--mu-s",
            "1000",
            "--mu-a",
            "1",
            "--g",
            "0.8",
            "--n",
            "1.5",
            "--pixels",
            "9",
            "--paths",
            "100",
            "--quiet",
            "--out",
            &s(&sim),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let rgb = d.join("rgb_slice.exr");
    write_exr(&rgb, 9, 9, 1.0);
    let o = lucent_in(
        d,
        &[
            "bssrdf",
            "compare",
            "--measured",
            &s(&rgb),
            "--measured-pixel-mm",
            "0.1",
            "--simulated",
            &s(&sim),
            "--out",
            "bc",
        ],
    );
    refused(&o, &["rgb_slice.exr", "no Y"], "RGB slice");
    // env merge: one file twice; a negative linear bracket.
    let a = root().join("tests/bad/env/bracket_16x8_a.png");
    let o = lucent_in(d, &["env", "merge", &s(&a), &s(&a), "--exposures", "1,4", "--out", "m.exr"]);
    refused(&o, &["bracket_16x8_a.png", "same file"], "merge twice");
    let neg = d.join("neg_bracket.exr");
    write_exr(&neg, 16, 8, -1.0);
    let pos = d.join("pos_bracket.exr");
    write_exr(&pos, 16, 8, 1.0);
    let o = lucent_in(d, &["env", "merge", &s(&pos), &s(&neg), "--exposures", "1,4", "--out", "m.exr"]);
    refused(&o, &["neg_bracket.exr", "negative"], "negative bracket");
    // fit: one slice given twice.
    let slice = d.join("slice.csv");
    std::fs::write(&slice, "1,2,1\n2,4,2\n1,2,1\n").unwrap();
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let m1 = format!("{}:45/0", s(&slice));
    let m2 = format!("{}/./slice.csv:45/0", s(d));
    let o = lucent_in(
        d,
        &[
            "fit",
            "--recipe",
            &s(&recipe),
            "--measured",
            &m1,
            &m2,
            "--measured-pixel-mm",
            "0.1",
            "--free",
            "weight_percent",
            "--out",
            "fo",
        ],
    );
    refused(&o, &["same file", "once"], "fit twice");
    // surface fit: a 1e300 spike is no height.
    let spike = bad("nonsense").join("spike_1e300.csv");
    let o = lucent_in(d, &["surface", "fit", &s(&spike), "--pitch-um", "1", "--out", "sf"]);
    refused(&o, &["spike_1e300.csv", "beyond", "wrong unit"], "surface spike");
    // A 1 × 1 environment map is not equirectangular.
    std::fs::copy(bad("nonsense").join("env_map_1x1.toml"), d.join("env_map_1x1.toml")).unwrap();
    write_exr(&d.join("map_1x1.exr"), 1, 1, 1.0);
    let o = lucent_in(d, &["render", "env_map_1x1.toml", "--out", "r"]);
    refused(&o, &["env_map_1x1.toml", "map_1x1.exr", "[environment] map"], "1 × 1 map");
    for out in ["c", "f", "bc", "m.exr", "fo", "sf", "r"] {
        assert!(!d.join(out).exists(), "a refused run left {out}");
    }
}

#[test]
fn misleading_values_are_named_where_they_are_written() {
    let tmp = tempfile::tempdir().unwrap();
    for (file, says) in [
        ("bssrdf_pixel_mm_negative.toml", "[bssrdf] pixel_mm"),
        ("bssrdf_pixels_zero.toml", "[bssrdf] pixels"),
        ("bssrdf_time_negative.toml", "[bssrdf] time_s"),
        ("sample_weight_negative.toml", "weight_percent"),
    ] {
        let o = lucent_in(tmp.path(), &["run", bad("misleading").join(file).to_str().unwrap(), "--out", "o"]);
        refused(&o, &[file, says], file);
        assert!(!stderr(&o).contains("unexpected argument"), "{}", stderr(&o));
    }
    for file in ["fov_zero.toml", "fov_180.toml"] {
        let o = lucent_in(tmp.path(), &["render", bad("misleading").join(file).to_str().unwrap(), "--out", "o"]);
        refused(&o, &[file, "vertical_fov_deg", "between 0 and 180"], file);
        assert!(!stderr(&o).contains("NaN"), "{}", stderr(&o));
    }
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "a refused run wrote something");
}

#[cfg(unix)]
#[test]
fn leftovers_failing_and_interrupted_runs_leave_nothing_unmarked() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A failing command leaves no (empty) output folder, nor the folders above it.
    let o = lucent_in(
        d,
        &["bssrdf", "compare", "--measured", "missing.csv", "--simulated", "missing", "--out", "a/b/compare"],
    );
    refused(&o, &["missing.csv"], "bssrdf compare");
    let o = lucent_in(d, &["render", "missing.toml", "--out", "r/out"]);
    refused(&o, &["missing.toml"], "render");
    assert_eq!(std::fs::read_dir(d).unwrap().count(), 0, "a failing run left {:?}", snapshot(d).keys());
    // SIGTERM to `lucent run` during the bssrdf stage: the stage is marked failed.
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let project = d.join("p.toml");
    std::fs::write(
        &project,
        format!("[project]\nname = \"p\"\n[bssrdf]\npixels = 9\ntime_s = 60\n[[sample]]\nname = \"s\"\nrecipe = {recipe:?}\n"),
    )
    .unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--out", "o", "--until", "optics"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let child = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["run", "p.toml", "--out", "o"])
        .current_dir(d)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until the bssrdf stage has started.
    let start = std::time::Instant::now();
    while !d.join("o/bssrdf/log.txt").exists() && start.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    std::thread::sleep(std::time::Duration::from_millis(1500));
    // SAFETY: a signal to the child this test started.
    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    let o = child.wait_with_output().unwrap();
    refused(&o, &["interrupted", "bssrdf.failed"], "SIGTERM during lucent run");
    assert_eq!(o.status.code(), Some(130), "a stopped run exits 130 (interrupted): {}", stderr(&o));
    let names: Vec<String> = std::fs::read_dir(d.join("o"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.contains(&"bssrdf.failed".to_string()), "{names:?}");
    assert!(!names.contains(&"bssrdf".to_string()), "an interrupted stage folder without its failed mark: {names:?}");
    assert!(names.iter().all(|n| !n.contains("previous") && !n.contains("staging")), "{names:?}");
    assert!(d.join("o/optics/manifest.json").is_file(), "the earlier stage is intact");
}

/// Leftovers: the files of one result (an image and its sidecar JSON, a
/// pose's scene and view) are written together or not at all. A folder
/// where the sidecar goes makes `raw decode` and `undistort` fail before
/// any of their files appears, and no temporary file stays.
#[test]
fn leftovers_the_files_of_one_result_are_written_together_or_not_at_all() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_exr(&d.join("lin.exr"), 16, 12, 0.3);
    let truth = root().join("fixtures/demo/truth_colour.json");
    let o = lucent_in(d, &["synth", "raw", "lin.exr", "cap.dng", "--truth", truth.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::create_dir(d.join("dec.json")).unwrap();
    let o = lucent_in(d, &["raw", "decode", "cap.dng", "dec.exr", "--preview", "dec.png"]);
    refused(&o, &["dec.json"], "raw decode with a folder where its metadata goes");
    assert!(!d.join("dec.exr").exists() && !d.join("dec.png").exists(), "{:?}", snapshot(d).keys());
    // undistort: a photo of the demo camera's size, a folder where u.json goes.
    let camera = root().join("fixtures/demo/truth_camera.json");
    write_exr(&d.join("photo.exr"), 640, 480, 0.2);
    std::fs::create_dir(d.join("u.json")).unwrap();
    let o = lucent_in(d, &["undistort", "--camera", camera.to_str().unwrap(), "photo.exr", "u.exr"]);
    refused(&o, &["u.json"], "undistort with a folder where its sidecar goes");
    assert!(!d.join("u.exr").exists(), "{:?}", snapshot(d).keys());
    // The same commands write both files when they can.
    let o = lucent_in(d, &["raw", "decode", "cap.dng", "ok.exr", "--preview", "ok.png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(["ok.exr", "ok.json", "ok.png"].iter().all(|f| d.join(f).is_file()), "{:?}", snapshot(d).keys());
    let names: Vec<String> = snapshot(d).keys().map(|p| p.display().to_string()).collect();
    assert!(names.iter().all(|n| !n.contains(".tmp")), "temporary files left: {names:?}");
}

/// Leftovers: SIGTERM (a batch system's stop) or Ctrl-C during `lucent
/// fit` stops the fit at the end of the simulation under way: exit 130
/// (interrupted), nothing written, no output or staging folder left.
#[test]
fn leftovers_a_stopped_fit_writes_nothing_and_exits_130() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // A 21 × 21 measured slice: a bright centre on a weak floor.
    let rows: Vec<String> = (0..21)
        .map(|i: i32| {
            (0..21)
                .map(|j: i32| format!("{:.6}", 1.0 + 100.0 * (-((i - 10).pow(2) + (j - 10).pow(2)) as f64 / 8.0).exp()))
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect();
    std::fs::write(d.join("m.csv"), rows.join("\n") + "\n").unwrap();
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let measured = format!("{}:45/0", d.join("m.csv").display());
    let out = d.join("fits/f");
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let args = [
            "fit",
            "--recipe",
            recipe.to_str().unwrap(),
            "--measured",
            &measured,
            "--measured-pixel-mm",
            "0.2",
            "--free",
            "weight_percent",
            "--paths",
            "50000000",
            "--out",
            out.to_str().unwrap(),
        ];
        let (status, text) = crate::common::signal_n_after(&args, "Ctrl-C stops", 1, signal);
        assert_eq!(status.code(), Some(130), "signal {signal}: {text}");
        assert!(text.contains("interrupted") && text.contains("nothing was written"), "{text}");
        assert!(!text.contains("panicked"), "{text}");
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 1, "signal {signal} left {:?}", snapshot(d).keys());
    }
}

/// Leftovers: SIGTERM or Ctrl-C during a command that has no rounds to
/// finish (`optics --uncertainty`, here a 100 000-draw study over 401
/// wavelengths that takes a minute) ends it as interrupted: exit 130 and a
/// message, not death by the signal (143 for SIGTERM), and nothing written.
#[test]
fn leftovers_any_command_stopped_by_sigterm_or_ctrl_c_exits_130_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let recipe = std::fs::read_to_string(root().join("fixtures/samples/IOL1068-09.toml")).unwrap();
    let recipe = recipe.replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.02 }");
    std::fs::write(d.join("a.toml"), recipe).unwrap();
    for signal in [libc::SIGTERM, libc::SIGINT] {
        let child = Command::new(env!("CARGO_BIN_EXE_lucent"))
            .args(["optics", "a.toml", "--uncertainty", "100000", "--wavelengths", "380:780:1", "--out", "u"])
            .current_dir(d)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(1500));
        // SAFETY: sends a signal to our own child process.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
        let o = child.wait_with_output().unwrap();
        let text = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(130), "signal {signal}: {:?} {text}", o.status);
        assert!(text.contains("interrupted"), "{text}");
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 1, "signal {signal} left {:?}", snapshot(d).keys());
    }
}

/// Data loss: an output never replaces a file the same command reads (the
/// photo, the map, the camera given with `--camera` as a sidecar's name),
/// two outputs never share a path, and `run --emit` writes only into a
/// folder of its own.
#[test]
fn data_loss_an_output_never_replaces_an_input() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    write_exr(&d.join("map.exr"), 16, 8, 1.0);
    std::fs::create_dir(d.join("cal")).unwrap();
    std::fs::write(d.join("cal/camera.json"), "{}").unwrap();
    std::fs::write(d.join("photo.exr"), "photo").unwrap();
    std::fs::write(d.join("ccm.json"), "{}").unwrap();
    std::fs::write(d.join("photo.dng"), "raw").unwrap();
    // Files of the user's under the names of sidecars, without the main output beside them.
    std::fs::write(d.join("photo_dec.json"), "my notes").unwrap();
    std::fs::write(d.join("my_residuals.png"), "my plot").unwrap();
    std::fs::write(d.join("notes.json"), "my notes").unwrap();
    let before = snapshot(d);
    for (args, says) in [
        (vec!["env", "view", "map.exr", "--fov", "60", "--size", "16x12", "--out", "map.exr"], "over the input"),
        (vec!["env", "orient", "map.exr", "--yaw", "30", "--out", "./map.exr"], "over the input"),
        (vec!["env", "convert", "map.exr", "map.exr"], "over the input"),
        (vec!["undistort", "--camera", "cal/camera.json", "photo.exr", "cal/camera.png"], "cal/camera.json"),
        (vec!["undistort", "--camera", "cal/camera.json", "photo.exr", "photo.exr"], "over the input"),
        (vec!["colour", "apply", "--ccm", "ccm.json", "photo.exr", "photo.exr"], "over the input"),
        // The clipping mask over the RAW photo it is made from.
        (vec!["raw", "clipped", "photo.dng", "--out", "./photo.dng"], "over the input"),
        (
            vec![
                "pose",
                "--camera",
                "cal/camera.json",
                "--image",
                "photo.exr",
                "--board",
                "9x6",
                "--square-mm",
                "20",
                "--out",
                "cal/camera.json",
            ],
            "over the input",
        ),
        (vec!["raw", "decode", "photo.dng", "w.exr", "--preview", "w.exr"], "the same file"),
        (vec!["raw", "decode", "photo.dng", "photo_dec.exr"], "photo_dec.json exists"),
        // The merge's report beside its map.
        (vec!["env", "merge", "map.exr", "photo.exr", "--exposures", "1,2", "--out", "notes.exr"], "notes.json exists"),
        // A photo's name given as the camera file (the images from a folder).
        (
            vec!["calibrate", "--images", "cal", "--board", "9x6", "--square-mm", "20", "--out", "photo.exr"],
            "JSON file",
        ),
        (vec!["env", "convert", "map.exr", "m2.exr", "--matrix", "0,0,0;0,0,0;0,0,0"], "black"),
        (
            vec!["calibrate", "--images", "cal/*.jpg", "--board", "9x6", "--square-mm", "20", "--out", "my.json"],
            "my_residuals.png exists",
        ),
    ] {
        let o = lucent_in(d, &args);
        refused(&o, &[says], &args.join(" "));
    }
    assert_eq!(snapshot(d), before, "a refused command changed the folder");
    // `lucent run --emit slurm DIR` into a folder of the user's (their own submit.sh).
    let project = d.join("p.toml");
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    std::fs::write(
        &project,
        format!(
            "[project]\nname = \"p\"\n[executor]\nkind = \"slurm\"\nshards = 2\n[[sample]]\nname = \"s\"\nrecipe = {:?}\n",
            recipe.display().to_string()
        ),
    )
    .unwrap();
    std::fs::create_dir(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/submit.sh"), "my own").unwrap();
    let o = lucent_in(d, &["run", "p.toml", "--emit", "slurm", "mine", "--out", "o"]);
    refused(&o, &["mine"], "--emit into a folder of the user's");
    assert_eq!(std::fs::read_to_string(d.join("mine/submit.sh")).unwrap(), "my own");
}

/// Panics: an environment radiance a 32-bit render cannot hold (1e300, or a
/// scale that makes it so) is refused with its key, for a constant sky as
/// for a map.
#[test]
fn panic_environment_radiance_beyond_what_a_render_can_store_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let scene = std::fs::read_to_string(root().join("fixtures/render/plaque_dense.toml")).unwrap();
    assert!(scene.contains("constant = "), "the scene has a constant sky");
    let line = scene.lines().find(|l| l.starts_with("constant = ")).unwrap().to_string();
    for (name, replacement, says) in [
        ("huge.toml", "constant = [1e300, 1e300, 1e300]".to_string(), "constant"),
        ("scaled.toml", format!("{line}\nscale = 1e300"), "1e30"),
    ] {
        std::fs::write(d.join(name), scene.replace(&line, &replacement)).unwrap();
        let o = lucent_in(d, &["render", name, "--size", "16x12", "--spp", "1", "--out", "o"]);
        refused(&o, &[name, says], name);
        assert_ne!(o.status.code(), Some(4), "{}", stderr(&o));
        assert!(!d.join("o").exists());
    }
}

/// Nonsense and misleading, second round: values a command used to accept
/// or report under another name, each refused (or warned about) where it
/// is written.
#[test]
fn nonsense_second_round_is_refused_where_it_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let r = recipe.to_str().unwrap();
    let transform = bad("nonsense").join("transform_with_lift.toml");
    let twice = bad("nonsense").join("measured_twice.toml");
    let size = bad("misleading").join("render_size_zero.toml");
    write_exr(&d.join("p.exr"), 16, 12, 0.5);
    write_exr(&d.join("r.exr"), 16, 12, 0.4);
    let scene = std::fs::read_to_string(root().join("fixtures/render/plaque_dense.toml")).unwrap();
    assert!(scene.contains("u = [1.0, 0.0, 0.0]"));
    std::fs::write(d.join("u100.toml"), scene.replace("u = [1.0, 0.0, 0.0]", "u = [100.0, 0.0, 0.0]")).unwrap();
    let recipe_text = std::fs::read_to_string(&recipe).unwrap();
    assert!(recipe_text.contains("diameter_um = 2.2"));
    std::fs::write(d.join("metres.toml"), recipe_text.replace("diameter_um = 2.2", "diameter_um = 2.2e-6")).unwrap();
    for (args, says) in [
        // --g and --n are the recipe's: given with it they were silently ignored.
        (vec!["bssrdf", "--recipe", r, "--g", "0.9", "--paths", "10", "--out", "o"], vec!["--g"]),
        (vec!["bssrdf", "--recipe", r, "--configs", "45/0,45/0", "--paths", "10", "--out", "o"], vec!["45/0", "twice"]),
        (vec!["render", transform.to_str().unwrap(), "--out", "o"], vec!["transform", "lift_m"]),
        (vec!["run", twice.to_str().unwrap(), "--out", "o"], vec!["slice_3x3.csv", "given twice"]),
        (vec!["run", size.to_str().unwrap(), "--out", "o"], vec!["[render] size", "at least 1"]),
        (
            vec!["compare", "--photo", "p.exr", "--render", "r.exr", "--photo-repeat", "./p.exr", "--out", "o"],
            vec!["second photo"],
        ),
        // A board axis of length 100 was normalised without a word.
        (vec!["render", "u100.toml", "--out", "o"], vec!["u100.toml", "[board] u", "unit vector"]),
        // A diameter typed in metres; a yaw of 1e300°; an X3P written under a .csv name.
        (
            vec!["optics", "metres.toml", "--wavelength", "550", "--out", "o"],
            vec!["metres.toml", "diameter_um", "micrometres"],
        ),
        (vec!["env", "orient", "p.exr", "--yaw", "1e300", "--out", "t.exr"], vec!["--yaw", "3600"]),
        (vec!["surface", "synth", "--model", "tr", "--alpha", "0.1", "--size", "16", "--out", "s.csv"], vec!["X3P"]),
        // The wavelength grid says why it is refused.
        (vec!["optics", r, "--wavelengths", "550:450:10", "--out", "o"], vec!["end is below start"]),
    ] {
        let o = lucent_in(d, &args);
        refused(&o, &says, &args.join(" "));
    }
    // A file compared with itself is said, not refused (a sanity check of the tool).
    let o = lucent_in(d, &["compare", "--photo", "p.exr", "--render", "p.exr", "--out", "o"]);
    assert!(o.status.success() && stderr(&o).contains("compare a file with itself"), "{}", stderr(&o));
    std::fs::remove_dir_all(d.join("o")).unwrap();
    let left: Vec<_> = std::fs::read_dir(d).unwrap().flatten().map(|e| e.file_name()).collect();
    assert_eq!(left.len(), 4, "a refused run wrote something: {left:?}");
}
