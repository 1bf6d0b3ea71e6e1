//! `--shard K/N` and `lucent merge` through the CLI: a render and a BSSRDF
//! slice split into N = 1, 2 and 7 shards and merged equal the unsharded
//! run (bit-for-bit for N = 1, where the sums are taken in the same order;
//! else to the rounding bound of `lucent::shard`), an `optics
//! --uncertainty` run likewise bit for bit for every N (its draws are put
//! together, not summed), and shards of two runs, a missing or repeated
//! shard, a corrupt accumulator and the damaged shard folders of
//! tests/bad/shard/ are refused with the file named and nothing written.

use crate::common::{lucent, stderr};
use std::path::{Path, PathBuf};

const SCENE: &str = "fixtures/render/demo.toml";

fn render_args(out: &Path, seed: &str, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = ["render", SCENE, "--quiet", "--size", "12x9", "--spp", "7", "--seed", seed, "--out"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    v.push(out.display().to_string());
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

fn run(args: &[String]) {
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let o = lucent(&a);
    assert!(o.status.success(), "lucent {}: {}", args.join(" "), stderr(&o));
}

/// Runs N shards of `args_of(out, extra)` and merges them into `out`; returns the shard folders.
fn shards_and_merge(dir: &Path, n: u32, out: &Path, args_of: &dyn Fn(&Path, &[&str]) -> Vec<String>) -> Vec<PathBuf> {
    let mut dirs = Vec::new();
    for k in 0..n {
        let d = dir.join(format!("shard-{n}-{k}"));
        let spec = format!("{k}/{n}");
        run(&args_of(&d, &["--shard", &spec]));
        assert!(d.join("shard.json").is_file());
        dirs.push(d);
    }
    let mut merge = vec!["merge".to_string()];
    // In reverse order: the merge sorts them.
    merge.extend(dirs.iter().rev().map(|d| d.display().to_string()));
    merge.extend(["--out".to_string(), out.display().to_string()]);
    run(&merge);
    dirs
}

fn channels(path: &Path, names: &[&str]) -> Vec<Vec<f32>> {
    lucent::exr::read_channels(path, names).expect("read exr").2
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).expect("read json")).expect("parse json")
}

/// |a − b| ≤ rel·|a| for every value (f32 outputs of f64 sums that differ by ≲ 10⁻¹⁴: at most one f32 ulp).
fn assert_close(a: &[Vec<f32>], b: &[Vec<f32>], rel: f32, what: &str) {
    for (ca, cb) in a.iter().zip(b) {
        assert_eq!(ca.len(), cb.len());
        for (i, (x, y)) in ca.iter().zip(cb).enumerate() {
            assert!((x - y).abs() <= rel * x.abs().max(f32::MIN_POSITIVE), "{what}: value {i}: {x} vs {y}");
        }
    }
}

fn assert_rel(a: f64, b: f64, rel: f64, what: &str) {
    assert!((a - b).abs() <= rel * a.abs(), "{what}: {a} vs {b}");
}

#[test]
fn render_shards_merge_into_the_unsharded_render() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole");
    run(&render_args(&whole, "3", &[]));
    let names = ["R", "G", "B", "variance.R", "variance.G", "variance.B", "spp", "object", "board"];
    let reference = channels(&whole.join("render.exr"), &names);
    let ref_json = json(&whole.join("render.json"));
    for n in [1u32, 2, 7] {
        let out = dir.path().join(format!("merged-{n}"));
        shards_and_merge(dir.path(), n, &out, &|o, extra| render_args(o, "3", extra));
        let merged = channels(&out.join("render.exr"), &names);
        // Marked as lucent's, as the unsharded command marks its folder.
        assert!(out.join(".lucent-output").is_file(), "N = {n}: the merged folder is not marked");
        let m_json = json(&out.join("render.json"));
        // The merge reads the environment map's header only: the same
        // description, but for the paths of the scene and the files it
        // names, which the merge has from the run's job (absolute) rather
        // than as the command was given (relative to the repository here).
        let real = std::fs::canonicalize(SCENE).unwrap();
        assert_eq!(m_json["scene"]["scene_file"], real.display().to_string(), "N = {n}: the scene's path");
        let root = format!("{}/", std::fs::canonicalize(env!("CARGO_MANIFEST_DIR")).unwrap().display());
        let relative = m_json["scene"].to_string().replace(&root, "");
        assert_eq!(relative, ref_json["scene"].to_string(), "N = {n}: render.json's scene");
        assert_eq!(m_json["spp"], ref_json["spp"]);
        assert_eq!(m_json["samples"], ref_json["samples"]);
        assert_eq!(m_json["scattering_events"], ref_json["scattering_events"], "N = {n}: the same paths");
        for c in 0..3 {
            let (a, b) = (ref_json["mean_rgb"][c].as_f64().unwrap(), m_json["mean_rgb"][c].as_f64().unwrap());
            if n == 1 {
                assert_eq!(a.to_bits(), b.to_bits(), "N = 1: mean_rgb[{c}] bit-for-bit");
            } else {
                // 7 samples, 108 pixels: sums of ≤ 7 non-negative terms, bound 2·7·2⁻⁵³ per pixel.
                assert_rel(a, b, 1e-14, &format!("N = {n}: mean_rgb[{c}]"));
            }
        }
        if n == 1 {
            for f in ["render.exr", "render.png"] {
                assert_eq!(std::fs::read(whole.join(f)).unwrap(), std::fs::read(out.join(f)).unwrap(), "N = 1: {f}");
            }
        } else {
            assert_eq!(merged[6], reference[6], "N = {n}: sample counts");
            assert_close(&reference, &merged, 2.0 * f32::EPSILON, &format!("N = {n}: render.exr"));
        }
    }
    // Another seed is another image: the comparison above can fail.
    let other = dir.path().join("other");
    run(&render_args(&other, "4", &[]));
    assert_ne!(channels(&other.join("render.exr"), &["R"])[0], reference[0]);
}

#[test]
fn bad_shard_sets_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let shard = |seed: &str, k: u32, n: u32| {
        let d = dir.path().join(format!("s{seed}-{k}-{n}"));
        run(&render_args(&d, seed, &["--shard", &format!("{k}/{n}")]));
        d.display().to_string()
    };
    let (a0, a1, a2) = (shard("3", 0, 3), shard("3", 1, 3), shard("3", 2, 3));
    let b1 = shard("5", 1, 3);
    let merge = |dirs: &[&str], expect: &[&str]| refused_merge(&dir.path().join("out"), dirs, expect);
    merge(&[&a0, &b1, &a2], &["another run", "seed", "s5-1-3"]);
    merge(&[&a0, &a2], &["shard 1 of 3 missing"]);
    merge(&[&a0, &a1, &a1, &a2], &["both shard 1 of 3"]);
    merge(&[&a0, dir.path().to_str().unwrap()], &["not a shard folder"]);
    // A damaged accumulator: one byte changed.
    let acc = Path::new(&a1).join("render.acc");
    let mut bytes = std::fs::read(&acc).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(&acc, &bytes).unwrap();
    merge(&[&a0, &a1, &a2], &["render.acc", "corrupt accumulator", "checksum"]);
    std::fs::write(&acc, &bytes[..100]).unwrap();
    merge(&[&a0, &a1, &a2], &["render.acc", "corrupt accumulator"]);
    // Budgets that cannot be split, and more shards than samples.
    let out = dir.path().join("x");
    for (extra, expect) in [
        (vec!["--time-s", "5", "--shard", "0/2"], "time budget"),
        (vec!["--target-rel-error", "0.1", "--shard", "0/2"], "error target"),
        (vec!["--sampling", "object-weighted", "--shard", "0/2"], "object-weighted"),
        (vec!["--shard", "0/8"], "fewer than the 8 shards"),
        (vec!["--shard", "3/3"], "K/N"),
    ] {
        let args = render_args(&out, "3", &extra);
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = lucent(&a);
        assert!(!o.status.success() && stderr(&o).contains(expect), "{extra:?}: {}", stderr(&o));
        assert!(!out.join("shard.json").exists());
    }
}

const THIN: [&str; 16] = [
    "bssrdf",
    "--quiet",
    "--thickness-mm",
    "2",
    "--pixels",
    "21",
    "--pixel-mm",
    "0.2",
    "--mu-s",
    "3000",
    "--mu-a",
    "30",
    "--g",
    "0.8",
    "--n",
    "1.5",
];

fn slice_args(out: &Path, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = THIN.iter().map(|s| s.to_string()).collect();
    v.extend(["--paths", "9000", "--seed", "11", "--configs", "45/0,0/30"].map(String::from));
    v.extend(["--out".to_string(), out.display().to_string()]);
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

#[test]
fn slice_shards_merge_into_the_unsharded_slice() {
    let dir = tempfile::tempdir().unwrap();
    let whole = dir.path().join("whole");
    run(&slice_args(&whole, &[]));
    for n in [1u32, 2, 7] {
        let out = dir.path().join(format!("merged-{n}"));
        shards_and_merge(dir.path(), n, &out, &|o, extra| slice_args(o, extra));
        for sub in ["ti45_to0", "ti0_to30"] {
            let (w, m) = (whole.join(sub), out.join(sub));
            let (sw, sm) = (json(&w.join("summary.json")), json(&m.join("summary.json")));
            assert_eq!(sw["paths"], sm["paths"]);
            assert_eq!(sw["events"], sm["events"], "N = {n}, {sub}: the same paths");
            for k in ["sum", "sum_std_error", "diffuse_reflectance", "transmittance"] {
                let (a, b) = (sw[k].as_f64().unwrap(), sm[k].as_f64().unwrap());
                if n == 1 {
                    assert_eq!(a.to_bits(), b.to_bits(), "N = 1, {sub}: {k} bit-for-bit");
                } else {
                    // Sums over 9000 paths; the standard error subtracts two such sums (×100 margin).
                    assert_rel(a, b, if k == "sum_std_error" { 1e-9 } else { 1e-11 }, &format!("N = {n}, {sub}: {k}"));
                }
            }
            let (cw, cm) = (
                channels(&w.join("bssrdf.exr"), &["Y", "std_error"]),
                channels(&m.join("bssrdf.exr"), &["Y", "std_error"]),
            );
            if n == 1 {
                assert_eq!(std::fs::read(w.join("bssrdf.exr")).unwrap(), std::fs::read(m.join("bssrdf.exr")).unwrap());
            } else {
                assert_close(&cw[..1], &cm[..1], 2.0 * f32::EPSILON, &format!("N = {n}, {sub}: slice"));
                assert_close(&cw[1..], &cm[1..], 1e-5, &format!("N = {n}, {sub}: std_error"));
            }
            for f in ["profile.csv", "profile.png", "bssrdf.png"] {
                assert!(m.join(f).is_file(), "{f}");
            }
        }
        assert!(out.join("sweep.csv").is_file());
    }
    // A slice shard needs a path budget.
    let o = lucent(&THIN.iter().copied().chain(["--rel-error", "0.1", "--shard", "0/2"]).collect::<Vec<_>>());
    assert!(!o.status.success() && stderr(&o).contains("--paths"), "{}", stderr(&o));
}

/// A folder with two recipes that have uncertain inputs: IOL1068-09 with a
/// normal weight percentage, IOL1068-05 with a uniform diameter.
fn uncertain_recipes(dir: &Path) -> PathBuf {
    let folder = dir.join("recipes");
    std::fs::create_dir_all(&folder).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let a = std::fs::read_to_string(root.join("fixtures/samples/IOL1068-09.toml")).unwrap();
    let a = a.replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.02 }");
    let b = std::fs::read_to_string(root.join("fixtures/samples/IOL1068-05.toml")).unwrap();
    let b = b.replace("diameter_um = 0.3 }", "diameter_um = { min = 0.25, max = 0.35 } }");
    std::fs::write(folder.join("a.toml"), a).unwrap();
    std::fs::write(folder.join("b.toml"), b).unwrap();
    folder
}

fn optics_args(recipes: &Path, out: &Path, seed: &str, extra: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = vec!["optics".into(), recipes.display().to_string()];
    v.extend(["--wavelengths", "450:650:100", "--uncertainty", "40", "--uncertainty-seed", seed].map(String::from));
    v.extend(["--out".to_string(), out.display().to_string()]);
    v.extend(extra.iter().map(|s| s.to_string()));
    v
}

const UNCERTAINTY_FILES: [&str; 3] = ["uncertainty.csv", "uncertainty.json", "uncertainty.png"];

/// The draws of an uncertainty run are put together in draw order and
/// summarised by the unsharded code: every output equal byte for byte, for
/// any N.
#[test]
fn uncertainty_shards_merge_bit_for_bit_into_the_unsharded_run() {
    let dir = tempfile::tempdir().unwrap();
    let recipes = uncertain_recipes(dir.path());
    let whole = dir.path().join("whole");
    run(&optics_args(&recipes, &whole, "3", &[]));
    let samples = ["IOL1068-09", "IOL1068-05"];
    for n in [1u32, 2, 7] {
        let out = dir.path().join(format!("merged-{n}"));
        let dirs = shards_and_merge(dir.path(), n, &out, &|o, extra| optics_args(&recipes, o, "3", extra));
        for s in samples {
            assert!(dirs[0].join(s).join("uncertainty.acc").is_file(), "{s}");
            for f in UNCERTAINTY_FILES {
                let (a, b) =
                    (std::fs::read(whole.join(s).join(f)).unwrap(), std::fs::read(out.join(s).join(f)).unwrap());
                assert!(a == b, "N = {n}: {s}/{f} differs from the unsharded run's");
            }
        }
        let shard = json(&dirs[n as usize - 1].join("shard.json"));
        assert_eq!(shard["identity"]["command"], "optics");
        assert_eq!(shard["identity"]["budget"], "40 draws");
        assert_eq!(shard["identity"]["seed"], 3);
        assert_eq!(shard["range"][1], 40);
    }
    // Both samples' spreads are there, and another seed is another design.
    let u = json(&whole.join("IOL1068-05/uncertainty.json"));
    assert!(u["mu_s_per_m"]["sd"][0].as_f64().unwrap() > 0.0);
    let other = dir.path().join("other");
    run(&optics_args(&recipes, &other, "4", &[]));
    assert_ne!(
        std::fs::read(other.join("IOL1068-09/uncertainty.csv")).unwrap(),
        std::fs::read(whole.join("IOL1068-09/uncertainty.csv")).unwrap()
    );
}

/// Shards of two uncertainty runs, a missing, repeated or damaged shard, a
/// shard whose draws are not the run's design, a recipe changed since the
/// shards ran: refused, the file named, nothing written.
#[test]
fn bad_uncertainty_shard_sets_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let recipes = uncertain_recipes(dir.path());
    let shard = |seed: &str, k: u32, n: u32| {
        let d = dir.path().join(format!("u{seed}-{k}-{n}"));
        run(&optics_args(&recipes, &d, seed, &["--shard", &format!("{k}/{n}")]));
        d.display().to_string()
    };
    let (a0, a1, a2) = (shard("3", 0, 3), shard("3", 1, 3), shard("3", 2, 3));
    let b1 = shard("5", 1, 3);
    let r1 = dir.path().join("render-1-3");
    run(&render_args(&r1, "3", &["--shard", "1/3"]));
    let merge = |dirs: &[&str], expect: &[&str]| refused_merge(&dir.path().join("out"), dirs, expect);
    merge(&[&a0, &b1, &a2], &["another run", "seed", "u5-1-3"]);
    merge(&[&a0, r1.to_str().unwrap(), &a2], &["another run", "command", "render-1-3"]);
    merge(&[&a0, &a2], &["shard 1 of 3 missing"]);
    // A folder of the user's (files lucent did not write) is not merged into.
    let users = dir.path().join("mine");
    std::fs::create_dir(&users).unwrap();
    std::fs::write(users.join("notes.txt"), "mine").unwrap();
    let o = lucent(&["merge", &a0, &a1, &a2, "--out", users.to_str().unwrap()]);
    assert!(!o.status.success() && !stderr(&o).contains("panicked"), "{}", stderr(&o));
    assert_eq!(std::fs::read_dir(&users).unwrap().count(), 1, "merged into a folder of the user's");
    merge(&[&a0, &a1, &a2, &a1], &["both shard 1 of 3", "u3-1-3"]);
    // The draws of shard 1 replaced by other values under a valid checksum.
    let acc = Path::new(&a1).join("IOL1068-05/uncertainty.acc");
    let original = std::fs::read(&acc).unwrap();
    let mut arrays = lucent::shard::read_accumulator(&acc).unwrap();
    arrays.iter_mut().find(|(n, _)| n == "draws").unwrap().1[2] *= 1.01;
    let refs: Vec<(&str, &[f64])> = arrays.iter().map(|(n, v)| (n.as_str(), v.as_slice())).collect();
    // With the shard's own record inside (run, shard, range, counters), as the shard wrote it.
    let meta = lucent::shard::read_accumulator_meta(&acc).unwrap().expect("a shard's record");
    lucent::shard::write_shard_accumulator(&acc, &meta, &refs).unwrap();
    merge(&[&a0, &a1, &a2], &["IOL1068-05/uncertainty.acc", "Latin-hypercube design", "draw 16"]);
    // A flipped bit, a truncated file, a missing file.
    let mut bytes = original.clone();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x04;
    std::fs::write(&acc, &bytes).unwrap();
    merge(&[&a0, &a1, &a2], &["IOL1068-05/uncertainty.acc", "corrupt accumulator", "checksum"]);
    std::fs::write(&acc, &original[..original.len() - 40]).unwrap();
    merge(&[&a0, &a1, &a2], &["IOL1068-05/uncertainty.acc", "corrupt accumulator"]);
    std::fs::remove_file(&acc).unwrap();
    merge(&[&a0, &a1, &a2], &["IOL1068-05/uncertainty.acc", "cannot read"]);
    std::fs::write(&acc, &original).unwrap();
    // A recipe edited after the shards ran.
    let b = recipes.join("b.toml");
    let text = std::fs::read_to_string(&b).unwrap();
    std::fs::write(&b, text.replace("max = 0.35", "max = 0.36")).unwrap();
    merge(&[&a0, &a1, &a2], &["changed since the shards were made", "u3-0-3"]);
    std::fs::write(&b, &text).unwrap();
    // Flags: --shard needs --uncertainty; no more shards than draws.
    let out = dir.path().join("x");
    for (extra, expect) in [(vec!["--shard", "0/41"], "fewer than the 41 shards"), (vec!["--shard", "2/2"], "K/N")] {
        let args = optics_args(&recipes, &out, "3", &extra);
        let o = lucent(&args.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(!o.status.success() && stderr(&o).contains(expect), "{extra:?}: {}", stderr(&o));
        assert!(!out.join("shard.json").exists());
    }
    let r = recipes.display().to_string();
    let o = lucent(&["optics", &r, "--wavelength", "550", "--shard", "0/2", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success() && stderr(&o).contains("--uncertainty"), "{}", stderr(&o));
    // After all that, the three shards still merge.
    let good = dir.path().join("good");
    run(&["merge".into(), a0, a1, a2, "--out".into(), good.display().to_string()]);
    assert!(good.join("IOL1068-05/uncertainty.csv").is_file());
}

/// tests/bad/shard/: shard folders whose shard.json is damaged or foreign
/// (see its README): refused, the file named, nothing written.
#[test]
fn bad_shard_folders_of_the_corpus_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad/shard");
    let mut cases: Vec<PathBuf> =
        std::fs::read_dir(&corpus).unwrap().map(|e| e.unwrap().path()).filter(|p| p.is_dir()).collect();
    cases.sort();
    assert!(cases.len() >= 4, "corpus missing? {cases:?}");
    for case in cases {
        let out = dir.path().join("out");
        let (c, o_s) = (case.display().to_string(), out.display().to_string());
        let o = lucent(&["merge", &c, "--out", &o_s]);
        let e = stderr(&o);
        let name = case.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!o.status.success(), "{name}: merged");
        assert!(e.contains(&format!("shard/{name}")), "{name}: the folder not named: {e}");
        assert!(!e.contains("panicked"), "{name}: {e}");
        assert!(!out.exists(), "{name}: wrote {}", out.display());
    }
}

/// `lucent merge DIRS --out OUT` fails, its message holds every string of
/// `expect`, it does not panic and writes nothing.
fn refused_merge(out: &std::path::Path, dirs: &[&str], expect: &[&str]) {
    let mut args = vec!["merge"];
    args.extend_from_slice(dirs);
    let o_s = out.display().to_string();
    args.extend_from_slice(&["--out", &o_s]);
    let o = lucent(&args);
    let e = stderr(&o);
    assert!(!o.status.success(), "{dirs:?} merged");
    for x in expect {
        assert!(e.contains(x), "{dirs:?}: expected {x:?} in: {e}");
    }
    assert!(!e.contains("panicked"), "{e}");
    assert!(!out.exists(), "{dirs:?}: wrote {}", out.display());
}

/// A shard's identity is its typed job's: shards spelled differently (flag
/// order, `--spp=7`, the scene by a relative or an absolute path, run from
/// another folder) and a shard run through the library alone
/// (`RenderJob::run` with `shard` set, no command line) merge into the
/// same render; a shard of another job is refused, the folder and the
/// field that differs named.
#[test]
fn shards_of_one_job_merge_however_spelled_and_without_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (a0, a1) = (d.join("a0"), d.join("a1"));
    run(&render_args(&a0, "3", &["--shard", "0/2"]));
    // Another spelling, from another folder, the scene's path absolute.
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["render", "--shard=1/2", "--spp=7", "--seed", "3", "--size=12x9"])
        .arg(&scene)
        .args(["--out", "a1", "--quiet"])
        .current_dir(d)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let same = |a: &Path, b: &Path| {
        let id = |p: &Path| json(&p.join("shard.json"))["identity"].clone();
        assert_eq!(id(a), id(b), "{} and {} are shards of one run", a.display(), b.display());
    };
    same(&a0, &a1);
    let out = d.join("merged");
    run(&[
        "merge".into(),
        a0.display().to_string(),
        a1.display().to_string(),
        "--out".into(),
        out.display().to_string(),
    ]);
    // Shard 1 again, through the library in this process: no command line.
    let lib1 = d.join("lib1");
    let job = lucent::job::RenderJob {
        scene: SCENE.into(),
        spp: Some(7),
        seed: Some(3),
        size: Some("12x9".parse().unwrap()),
        quiet: true,
        out: lib1.clone(),
        shard: Some(lucent::job::shard::ShardSpec { k: 1, n: 2 }),
        ..Default::default()
    };
    let done = job.run(&lucent::job::Context { quiet: true }).expect("a shard run through the library");
    assert!(done.interrupted.is_none());
    same(&a0, &lib1);
    let out_lib = d.join("merged-lib");
    let dirs = [a0.clone(), lib1.clone()];
    let merged = lucent::job::merge(&lucent::job::Context { quiet: true }, &dirs, &out_lib, &mut ())
        .expect("the library merges the shards");
    assert!(matches!(merged, lucent::job::Merged::Render(_)));
    for f in ["render.exr", "render.png"] {
        assert_eq!(std::fs::read(out.join(f)).unwrap(), std::fs::read(out_lib.join(f)).unwrap(), "{f}");
    }
    // A shard of another job (another image size): refused, named.
    let other = d.join("other-size");
    let mut args = render_args(&other, "3", &["--shard", "1/2"]);
    let at = args.iter().position(|a| a == "12x9").unwrap();
    args[at] = "12x8".into();
    run(&args);
    refused_merge(
        &d.join("refused"),
        &[a0.to_str().unwrap(), other.to_str().unwrap()],
        &["other-size", "another run", "render.size is \"12x8\" here, \"12x9\" there"],
    );
}

/// A shard folder of an earlier version, whose run was named by its command
/// line (shard.json without the job), is refused with the format named,
/// never merged or a panic; so is one of a newer format.
#[test]
fn shards_of_the_older_command_line_format_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (a0, a1) = (d.join("a0"), d.join("a1"));
    run(&render_args(&a0, "3", &["--shard", "0/2"]));
    run(&render_args(&a1, "3", &["--shard", "1/2"]));
    let path = a1.join("shard.json");
    let mut v = json(&path);
    let id = v["identity"].as_object_mut().unwrap();
    for k in ["format", "job", "job_sha256"] {
        id.remove(k);
    }
    id.insert("args".into(), serde_json::json!(["render", SCENE, "--spp", "7"]));
    id.insert("normalized_args".into(), serde_json::json!([]));
    id.insert("cwd".into(), serde_json::json!(env!("CARGO_MANIFEST_DIR")));
    std::fs::write(&path, serde_json::to_string_pretty(&v).unwrap()).unwrap();
    let (s0, s1) = (a0.display().to_string(), a1.display().to_string());
    refused_merge(&d.join("out"), &[&s0, &s1], &["a1/shard.json", "older format", "command line", "rerun the shards"]);
    refused_merge(&d.join("out"), &[&s1], &["a1/shard.json", "older format"]);
    // A shard of a format this version does not know yet.
    let mut v = json(&a0.join("shard.json"));
    v["identity"]["format"] = serde_json::json!(99);
    std::fs::write(a0.join("shard.json"), serde_json::to_string_pretty(&v).unwrap()).unwrap();
    refused_merge(&d.join("out"), &[&s0], &["a0/shard.json", "format 99"]);
}
