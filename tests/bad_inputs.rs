//! The bad-input corpus (tests/bad/<reader>/, made by tests/bad/make_corpus.py):
//! every file goes through the CLI binary as a user would give it, and the run
//! must exit non-zero, name the file in its message, not panic, and leave the
//! output folder exactly as it was. (tests/bad/{compare,env,mesh,render,surface,bssrdf}
//! have their own tests next to their commands.)

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every file under `dir` (relative name → bytes).
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// `lucent bssrdf compare` reading FILE as the measured slice.
fn compare_measured() -> Vec<&'static str> {
    vec![
        "bssrdf",
        "compare",
        "--measured",
        "FILE",
        "--measured-pixel-mm",
        "0.1",
        "--simulated",
        "GOOD_SLICE",
        "--out",
        "OUT",
    ]
}

/// The commands that read each corpus folder; FILE is the bad file, OUT the output folder.
fn commands(reader: &str) -> Vec<Vec<&'static str>> {
    match reader {
        "recipe" | "index" => vec![vec!["optics", "FILE", "--wavelength", "550", "--out", "OUT"]],
        "slice" => vec![compare_measured()],
        "beam" => vec![vec![
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
            "10",
            "--quiet",
            "--beam-map",
            "FILE",
            "--beam-map-pixel-mm",
            "0.01",
            "--out",
            "OUT",
        ]],
        "camera" => vec![vec!["undistort", "--camera", "FILE", "fixtures/camera/chessboard/left01.jpg", "OUT/u.png"]],
        "scene" => vec![vec!["render", "FILE", "--out", "OUT"]],
        "raw" => vec![vec!["raw", "decode", "FILE", "OUT/x.exr"]],
        "jpeg" => vec![
            vec!["undistort", "--camera", "fixtures/demo/truth_camera.json", "FILE", "OUT/u.png"],
            vec!["calibrate", "--images", "FILE", "--board", "9x6", "--square-mm", "20", "--out", "OUT/camera.json"],
        ],
        "png" => vec![vec!["undistort", "--camera", "fixtures/demo/truth_camera.json", "FILE", "OUT/u.png"]],
        "hdr" => vec![vec!["env", "info", "FILE"], vec!["env", "convert", "FILE", "OUT/env.exr"]],
        "project" => vec![vec!["run", "FILE", "--out", "OUT"]],
        "job" => vec![vec!["job", "run", "FILE"]],
        // Every reader of lucent::exr: an image (read_rgb), a compare input and a
        // slice and a height map (read_layer), a render's object layer (read_channels).
        "exr" => vec![
            vec!["env", "info", "FILE"],
            vec!["compare", "--photo", "FILE", "--render", "fixtures/reference/compare/base.exr", "--out", "OUT"],
            vec![
                "compare",
                "--photo",
                "fixtures/reference/compare/base.exr",
                "--render",
                "fixtures/reference/compare/shifted.exr",
                "--mask-object",
                "FILE",
                "--out",
                "OUT",
            ],
            compare_measured(),
            vec!["surface", "fit", "FILE", "--out", "OUT"],
            // (Read even though this render has no variance layers to use it with.)
            vec![
                "compare",
                "--photo",
                "fixtures/reference/compare/base.exr",
                "--render",
                "fixtures/reference/compare/shifted.exr",
                "--photo-variance",
                "FILE",
                "--out",
                "OUT",
            ],
        ],
        other => panic!("no command for tests/bad/{other}"),
    }
}

#[test]
fn every_bad_file_is_refused_by_name_without_panic_or_output() {
    let tmp = tempfile::tempdir().unwrap();
    let good_slice = tmp.path().join("good_slice.csv");
    std::fs::write(&good_slice, "1,2,1\n2,4,2\n1,2,1\n").unwrap();
    let mut runs = 0;
    let mut failures = Vec::new();
    for reader in
        ["recipe", "index", "slice", "beam", "camera", "scene", "raw", "jpeg", "png", "hdr", "project", "job", "exr"]
    {
        let dir = root().join("tests/bad").join(reader);
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().path()).collect();
        files.sort();
        for file in files {
            let ext = file.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
            // The index cases go through their recipe; the scene cases through their render file.
            if (reader == "index" && ext == "toml") || (reader == "scene" && ext == "json") || ext == "md" {
                continue;
            }
            let named = if reader == "index" { file.with_extension("yml") } else { file.clone() };
            let named = if reader == "scene" { file.with_extension("json") } else { named };
            let file = if reader == "index" { file.with_extension("toml") } else { file };
            for args in commands(reader) {
                let out = tmp.path().join(format!("out-{runs}"));
                std::fs::create_dir_all(&out).unwrap();
                // An output folder of an earlier run (marked as lucent's) with a file of the user's in it.
                lucent::io::mark_output_folder(&out).unwrap();
                std::fs::write(out.join("keep.txt"), "a file of the user's").unwrap();
                let before = snapshot(&out);
                let args: Vec<String> = args
                    .iter()
                    .map(|a| {
                        a.replace("FILE", file.to_str().unwrap())
                            .replace("GOOD_SLICE", good_slice.to_str().unwrap())
                            .replace("OUT", out.to_str().unwrap())
                    })
                    .collect();
                let o = Command::new(env!("CARGO_BIN_EXE_lucent")).args(&args).current_dir(root()).output().unwrap();
                runs += 1;
                let stderr = String::from_utf8_lossy(&o.stderr);
                let name = named.file_name().unwrap().to_string_lossy();
                let mut problems = Vec::new();
                if o.status.success() {
                    problems.push("exit 0".to_string());
                }
                if !stderr.contains(name.as_ref()) {
                    problems.push(format!("message does not name {name}"));
                }
                if stderr.contains("panicked") {
                    problems.push("panic".into());
                }
                if snapshot(&out) != before {
                    problems.push("output folder changed".into());
                }
                if !problems.is_empty() {
                    failures.push(format!("{args:?}: {}\n    stderr: {}", problems.join(", "), stderr.trim()));
                }
            }
        }
    }
    assert!(runs >= 40, "only {runs} runs: corpus missing?");
    assert!(failures.is_empty(), "{} of {runs} runs:\n{}", failures.len(), failures.join("\n"));
}

/// The classes of the issue that are flags, not files: each must be refused
/// (or, for a duplicate recipe, computed once) with a plain message.
#[test]
fn bad_flags_are_refused_plainly() {
    let tmp = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).current_dir(root()).output().unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let recipe = "fixtures/samples/IOL1068-09.toml";
    let out = tmp.path().join("o");
    let out = out.to_str().unwrap();
    // Far outside every index file's data: refused, not clamped.
    let (ok, _, err) = run(&["optics", recipe, "--wavelength", "1e9", "--out", out]);
    assert!(!ok && err.contains("too far outside") && err.contains("PC_Zhang2020"), "{err}");
    let (ok, _, err) = run(&["optics", recipe, "--wavelength", "-5", "--out", out]);
    assert!(!ok && err.contains("--wavelength -5: must be a positive") && !err.contains("tip"), "{err}");
    // The same recipe twice (two spellings): one row.
    let (ok, stdout, err) =
        run(&["optics", recipe, "./fixtures/samples/IOL1068-09.toml", "--wavelength", "550", "--out", out]);
    assert!(ok && err.contains("more than once"), "{err}");
    assert_eq!(stdout.lines().filter(|l| l.starts_with("IOL1068-09")).count(), 1, "{stdout}");
    // A missing file is said once, not "os error 2: … os error 2".
    let (ok, _, err) = run(&["undistort", "--camera", "/nope/camera.json", "x.jpg", "y.png"]);
    assert!(!ok && err.matches("os error 2").count() == 1, "{err}");
    // --out that is a file.
    let file = tmp.path().join("a_file");
    std::fs::write(&file, "x").unwrap();
    let (ok, _, err) = run(&["optics", recipe, "--wavelength", "550", "--out", file.to_str().unwrap()]);
    assert!(!ok && err.contains("is not a folder"), "{err}");
    // bssrdf: validated before any work, nothing written.
    let out = tmp.path().join("b");
    let out = out.to_str().unwrap();
    let base = ["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--quiet"];
    for (extra, says) in [
        (&["--paths", "0"][..], "--paths 0"),
        (&["--paths", "10", "--configs", "45/0,45/95"][..], "95"),
        (&["--paths", "10", "--beam-fwhm-um", "100000"][..], "wider than the slice"),
    ] {
        let (ok, _, err) = run(&[&base[..], extra, &["--out", out]].concat());
        assert!(!ok && err.contains(says), "{extra:?}: {err}");
        assert!(!Path::new(out).exists(), "{extra:?} wrote {out}");
    }
    // A beam map without a pixel size names the flag that gives it.
    let map = tmp.path().join("beam.csv");
    std::fs::write(&map, "0,1\n1,0\n").unwrap();
    let (ok, _, err) =
        run(&[&base[..], &["--paths", "10", "--beam-map", map.to_str().unwrap(), "--out", out]].concat());
    assert!(!ok && err.contains("--beam-map-pixel-mm"), "{err}");
}

/// A reused output folder keeps the user's files but no stale output: a
/// 2-configuration sweep followed by a single run leaves no sweep.csv nor
/// per-configuration folders.
#[test]
fn reused_bssrdf_folder_has_no_stale_output() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let out_s = out.to_str().unwrap();
    let base = ["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--quiet"];
    let run = |extra: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_lucent"))
            .args([&base[..], extra, &["--out", out_s]].concat())
            .current_dir(root())
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&["--paths", "2000", "--configs", "45/0,0/45"]);
    assert!(out.join("sweep.csv").exists() && out.join("ti45_to0").is_dir());
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    run(&["--paths", "2000"]);
    let mut names: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != lucent::io::OUTPUT_MARK)
        .collect();
    names.sort();
    assert_eq!(names, ["bssrdf.exr", "bssrdf.png", "notes.txt", "profile.csv", "profile.png", "summary.json"]);
    // No staging folder left beside it.
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1);
}
