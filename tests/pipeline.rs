//! `lucent run`: a tiny project over the shipped fixtures (one sample, a
//! synthetic photo and empty board rendered with a known environment scale,
//! four chessboard photos and the pose photo (the truth's camera), the ColorChecker photo, a 33 × 33 BSSRDF slice
//! scored against a "measured" slice): every stage runs, a second run skips
//! them all, a changed input reruns only what depends on it, `--force`
//! reruns, a failing stage stops the run and leaves earlier results; the
//! report opens in headless Chromium without console messages, every image
//! it references exists, and its screenshot is kept in
//! target/test-output/report.png. Bad project files are refused.

use lucent::exr::read_channels;
use lucent::imageio::{write_exr, RgbImage};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn lucent(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).output().expect("run lucent")
}

fn ok(o: &std::process::Output) -> String {
    assert!(
        o.status.success(),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The stage's word in the status lines of a run ("ran", "up", "skipped").
fn status_of(stdout: &str, stage: &str) -> String {
    stdout
        .lines()
        .find(|l| l.split_whitespace().nth(1) == Some(stage))
        .and_then(|l| l.split_whitespace().nth(2))
        .unwrap_or("missing")
        .to_string()
}

const SIZE: &str = "48x36";

/// Writes the fixtures' demo scene (the twin's template) at a small size into
/// `dir`, and renders the truth in the frame the run's pose stage will find:
/// `lucent calibrate` and `lucent pose` on the project's photos (as the run
/// will), then a "photo" (64 spp, environment scale 1.6) with the camera,
/// board and sample placement of that scene.json and the calibrated
/// distortion, and an "empty board" photo with the sphere centred where the
/// photo's is. The run must take its camera from its pose stage (the
/// template's own camera looks elsewhere), and env-scale should find 1.6.
fn synthetic_inputs(dir: &Path) {
    let demo = root().join("fixtures/render/demo.toml");
    let text = std::fs::read_to_string(&demo).unwrap();
    let fixtures = root().join("fixtures");
    let text = text
        .replace("\"../samples/", &format!("\"{}/samples/", fixtures.display()))
        .replace("\"../env/", &format!("\"{}/env/", fixtures.display()));
    std::fs::write(dir.join("scene.toml"), &text).unwrap();
    let cal = dir.join("cal");
    let (camera_json, scene_json) = (cal.join("camera.json"), cal.join("scene.json"));
    let chess = fixtures.join("camera/chessboard");
    let images = format!("{}/left0{{1,2,3,4}}.jpg", chess.display());
    ok(&lucent(&[
        "calibrate",
        "--images",
        &images,
        "--board",
        "9x6",
        "--square-mm",
        "25",
        "--out",
        camera_json.to_str().unwrap(),
    ]));
    ok(&lucent(&[
        "pose",
        "--camera",
        camera_json.to_str().unwrap(),
        "--image",
        chess.join("left12.jpg").to_str().unwrap(),
        "--board",
        "9x6",
        "--square-mm",
        "25",
        "--sample-corner",
        "2,1",
        "--sample-size-mm",
        "100,60,6.35",
        "--out",
        scene_json.to_str().unwrap(),
    ]));
    let mut truth = lucent::scene::parse(&text, &demo).unwrap();
    truth.camera = lucent::scene::CameraSection {
        scene_json: Some(scene_json.clone()),
        camera_json: Some(camera_json.clone()),
        distortion: Some("calibrated".into()),
        ..Default::default()
    };
    let b = truth.board.as_mut().unwrap();
    (b.origin_m, b.u, b.v, b.columns, b.rows, b.square_mm) = (None, None, None, None, None, None);
    let o = truth.object.as_mut().unwrap();
    (o.transform, o.placement) = (None, Some("scene".into()));
    truth.environment.scale = Some(1.6);
    std::fs::write(dir.join("truth.toml"), toml::to_string_pretty(&truth).unwrap()).unwrap();
    let render = |scene: &str, out: &str| {
        ok(&lucent(&[
            "render",
            dir.join(scene).to_str().unwrap(),
            "--size",
            SIZE,
            "--spp",
            "64",
            "--seed",
            "99",
            "--quiet",
            "--out",
            dir.join(out).to_str().unwrap(),
        ]))
    };
    render("truth.toml", "photo");
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("photo/render.json")).unwrap()).unwrap();
    let centre: Vec<f64> =
        info["scene"]["environment_centre_m"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    // The sphere on the sample's top, in the pose's frame (not the template's origin).
    assert!(centre[2] > 0.006 && (centre[0].abs() + centre[1].abs()) > 0.01, "{centre:?}");
    let mut empty = truth.clone();
    (empty.object, empty.material) = (None, None);
    empty.environment.centre_m = Some([centre[0], centre[1], centre[2]]);
    std::fs::write(dir.join("truth_empty.toml"), toml::to_string_pretty(&empty).unwrap()).unwrap();
    render("truth_empty.toml", "empty");
}

fn project_text(dir: &Path, measured: &str) -> String {
    let f = root().join("fixtures");
    format!(
        r#"[project]
name = "tiny"
seed = 7

[optics]
wavelengths = "400:700:20"

[bssrdf]
wavelength_nm = 550
configs = "45/0"
pixels = 33
pixel_mm = 0.2
paths = 3000
phase = "hg"

[calibration]
images = "{f}/camera/chessboard/left0{{1,2,3,4}}.jpg"
board = "9x6"
square_mm = 25

[[colour]]
camera = "phone"
image = "{f}/colour/colorchecker.png"
corners = "5,6.5,196,6,195.5,133.5,3.5,133"

[pose]
image = "{f}/camera/chessboard/left12.jpg"
sample_corner = "2,1"
sample_size_mm = "100,60,6.35"

[render]
scene = "{d}/scene.toml"
spp = 8
env_spp = 16
size = "{SIZE}"

[[sample]]
name = "IOL1068-09"
recipe = "{f}/samples/IOL1068-09.toml"
photo = "{d}/photo/render.exr"
empty_board = "{d}/empty/render.exr"

[[sample.measured]]
config = "45/0"
file = "{measured}"
pixel_mm = 0.2
"#,
        f = f.display(),
        d = dir.display()
    )
}

/// Headless Chromium on a page: (stderr console lines, DOM, screenshot written).
fn chromium(page: &Path, screenshot: &Path) -> (Vec<String>, String) {
    chromium_at(page, screenshot, "1280,2400")
}

/// [`chromium`] with the window size "WIDTH,HEIGHT" of the screenshot.
fn chromium_at(page: &Path, screenshot: &Path, window: &str) -> (Vec<String>, String) {
    let bin = ["chromium", "chromium-browser"]
        .into_iter()
        .find(|b| Command::new("sh").args(["-c", &format!("command -v {b}")]).output().is_ok_and(|o| o.status.success()))
        .expect("headless Chromium is required for the report test: install Debian's `chromium` (make deps / scripts/install-deps.sh)");
    let url = format!("file://{}", page.display());
    let common =
        ["--headless", "--disable-gpu", "--no-sandbox", "--enable-logging=stderr", "--v=0", "--hide-scrollbars"];
    let shot = Command::new(bin)
        .args(common)
        .arg(format!("--screenshot={}", screenshot.display()))
        .arg(format!("--window-size={window}"))
        .arg(&url)
        .output()
        .expect("run chromium");
    assert!(shot.status.success(), "chromium failed: {}", String::from_utf8_lossy(&shot.stderr));
    let dom = Command::new(bin).args(common).arg("--dump-dom").arg(&url).output().expect("run chromium");
    assert!(dom.status.success(), "chromium failed: {}", String::from_utf8_lossy(&dom.stderr));
    let console: Vec<String> = [shot.stderr, dom.stderr.clone()]
        .iter()
        .flat_map(|e| String::from_utf8_lossy(e).lines().map(str::to_string).collect::<Vec<_>>())
        .filter(|l| l.contains("CONSOLE"))
        .collect();
    (console, String::from_utf8_lossy(&dom.stdout).into_owned())
}

fn img_sources(dom: &str) -> Vec<String> {
    dom.match_indices("<img ")
        .filter_map(|(i, _)| {
            let rest = &dom[i..];
            let end = rest.find('>')?;
            let tag = &rest[..end];
            let s = tag.find("src=\"")? + 5;
            let e = tag[s..].find('"')?;
            Some(tag[s..s + e].to_string())
        })
        .collect()
}

#[test]
fn chromium_check_catches_console_errors() {
    // The detector itself: a page that logs an error must be caught.
    let tmp = tempfile::tempdir().unwrap();
    let page = tmp.path().join("bad.html");
    std::fs::write(&page, "<!DOCTYPE html><html><body><img src=\"img/nothing.png\"><script>console.error('bad-page')</script></body></html>").unwrap();
    let (console, dom) = chromium(&page, &tmp.path().join("bad.png"));
    assert!(console.iter().any(|l| l.contains("bad-page")), "{console:?}");
    assert_eq!(img_sources(&dom), ["img/nothing.png"]);
}

#[test]
fn project_runs_skips_reruns_fails_and_reports() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    synthetic_inputs(d);
    // A "measured" slice: a simulated one of the same slab with another seed.
    let m = d.join("measured");
    ok(&lucent(&[
        "bssrdf",
        "--recipe",
        root().join("fixtures/samples/IOL1068-09.toml").to_str().unwrap(),
        "--pixels",
        "33",
        "--pixel-mm",
        "0.2",
        "--paths",
        "3000",
        "--phase",
        "hg",
        "--seed",
        "3",
        "--quiet",
        "--out",
        m.to_str().unwrap(),
    ]));
    let measured = m.join("bssrdf.exr");
    let project = d.join("tiny.toml");
    std::fs::write(&project, project_text(d, &measured.display().to_string())).unwrap();
    let out = d.join("out");
    let run = |extra: &[&str]| {
        let mut a = vec!["run", project.to_str().unwrap(), "--out", out.to_str().unwrap()];
        a.extend_from_slice(extra);
        lucent(&a)
    };

    // 1. Everything runs; each stage says on stderr when it starts (no time yet: no earlier run).
    let o = run(&[]);
    let first = ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    for s in ["optics", "bssrdf", "render", "report"] {
        assert!(err.lines().any(|l| l.starts_with('[') && l.ends_with(&format!("] {s} …"))), "{s}:\n{err}");
    }
    for s in ["optics", "bssrdf", "calibrate", "colour", "pose", "env-scale", "render", "compare", "report"] {
        assert_eq!(status_of(&first, s), "ran", "{s}:\n{first}");
        let man: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(s).join("manifest.json")).unwrap()).unwrap();
        assert_eq!(man["seed"], 7);
        assert!(man["wall_s"].as_f64().unwrap() >= 0.0);
    }
    assert!(first.contains("report: "), "{first}");
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report/metrics.json")).unwrap()).unwrap();
    let smp = &metrics["samples"]["IOL1068-09"];
    // The synthetic truth: env-scale finds the photo's 1.6 (noisy renders at 16 and 64 spp).
    let k = smp["env_scale"]["fit"]["scale"].as_f64().unwrap();
    assert!((k - 1.6).abs() < 0.1, "k = {k}");
    // The render with the fitted scale matches the photo: SSIM high, RMSE small against the photo's level.
    let ssim = smp["compare"]["as_calibrated"]["ssim"]["Y"].as_f64().unwrap();
    assert!(ssim > 0.3 && ssim <= 1.0, "SSIM {ssim}");
    assert!(smp["compare"]["as_calibrated"]["rmse"].as_f64().unwrap() > 0.0);
    assert!(smp["optics"]["mu_s_per_m"][0].as_f64().unwrap() > 1e3);
    assert!(smp["bssrdf"][0]["comparison"]["mean_squared_relative_error"].as_f64().unwrap() >= 0.0);
    assert!(metrics["calibration"]["rms_px"].as_f64().unwrap() < 1.0);
    assert!(metrics["colour"]["phone"]["de2000_mean"].as_f64().unwrap() > 0.0);
    assert!(metrics["manifests"]["render"]["inputs"].as_array().unwrap().len() >= 3);
    // The run's render took the pose stage's camera, board and placement, not the template's.
    let scene = std::fs::read_to_string(out.join("render/IOL1068-09/input_scene.toml")).unwrap();
    let pose_json = out.join("pose/scene.json");
    assert!(scene.contains(&format!("scene_json = {:?}", pose_json.display().to_string())), "{scene}");
    assert!(scene.contains("distortion = \"calibrated\"") && scene.contains("placement = \"scene\""), "{scene}");
    assert!(!scene.contains("position_m") && !scene.contains("origin_m"), "{scene}");
    let (w, h, _) = read_channels(&out.join("render/IOL1068-09/render.exr"), &["R"]).unwrap();
    assert_eq!((w, h), (48, 36));

    report_again_by_command_and_job(d, &project, &out);

    // 2. Nothing changed: every stage is skipped.
    let second = ok(&run(&[]));
    for s in ["optics", "bssrdf", "calibrate", "colour", "pose", "env-scale", "render", "compare", "report"] {
        assert_eq!(status_of(&second, s), "up", "{s}:\n{second}");
    }

    // 3. A changed photo reruns compare and the report only; --force reruns a stage.
    let photo = d.join("photo/render.exr");
    let (pw, ph, ch) = read_channels(&photo, &["R", "G", "B"]).unwrap();
    let data: Vec<f32> = (0..pw * ph).flat_map(|i| [ch[0][i] * 1.01, ch[1][i], ch[2][i]]).collect();
    write_exr(&photo, &RgbImage::new(pw, ph, data).unwrap()).unwrap();
    let o = run(&["--force", "colour"]);
    let third = ok(&o);
    // A stage that ran before says how long it took then; an up-to-date one does not start.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.lines().any(|l| l.contains("] colour … (≈ ") && l.ends_with(" s, as last time)")), "{err}");
    assert!(!err.contains("] optics …"), "{err}");
    for (s, want) in [("optics", "up"), ("colour", "ran"), ("render", "up"), ("compare", "ran"), ("report", "ran")] {
        assert_eq!(status_of(&third, s), want, "{s}:\n{third}");
    }

    // 4. A failing stage stops the run with its name and log; earlier results stay.
    std::fs::write(&measured, b"not an EXR").unwrap();
    let o = run(&[]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("stage bssrdf failed") && err.contains("bssrdf.failed"), "{err}");
    assert!(out.join("bssrdf.failed/log.txt").is_file());
    assert!(out.join("bssrdf/manifest.json").is_file(), "the previous bssrdf result is put back");
    assert!(out.join("optics/manifest.json").is_file());
    assert_eq!(status_of(&String::from_utf8_lossy(&o.stdout), "calibrate"), "missing", "the run stopped");

    // 5. The report in a browser: no console messages, every image there.
    let index = out.join("report/index.html");
    let shots = root().join("target/test-output");
    std::fs::create_dir_all(&shots).unwrap();
    let (console, dom) = chromium(&index, &shots.join("report.png"));
    assert!(console.is_empty(), "console messages: {console:?}");
    let imgs = img_sources(&dom);
    assert!(imgs.len() >= 8, "{imgs:?}");
    for src in &imgs {
        assert!(!src.contains("://"), "{src}: the report must not load from the network");
        assert!(out.join("report").join(src).is_file(), "{src} missing");
    }
    assert!(dom.contains("Photo | render | difference") && dom.contains("Manifest"));
    // The render's noise per region and the model RMSE beside the plain one.
    assert!(
        dom.contains("the object's") && dom.contains("Model RMSE with the render's and the photo's noise removed"),
        "{dom}"
    );
    assert!(shots.join("report.png").metadata().unwrap().len() > 10_000);
    // The answer comes first: the verdict sentence before the stage table and
    // before the first per-stage section.
    let verdict = dom.find("class=\"verdict\"").expect("a verdict sentence");
    assert!(verdict < dom.find("<h2>Stages</h2>").unwrap(), "{dom}");
    assert!(verdict < dom.find("details per stage</h2>").unwrap(), "{dom}");
    assert!(verdict < dom.find("Optical properties").unwrap(), "{dom}");
    // Figures that may alarm carry a line saying what they are.
    assert!(dom.contains("What the ") && dom.contains("not an error of k"), "the env-scale residual is explained");

    // 6. Two twins (the run's render as A, a render of the same scene with
    // another seed as B): one difference scale for both, each row named.
    twins_share_one_scale_and_lead_the_report(d, &project, &out, &shots);
}

/// The arguments of the stage's recorded command whose `--out` ends with `out_end`.
fn recorded_command(out: &Path, stage: &str, out_end: &str) -> Vec<String> {
    let man: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(stage).join("manifest.json")).unwrap()).unwrap();
    man["commands"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_array().unwrap().iter().map(|a| a.as_str().unwrap().to_string()).collect::<Vec<_>>())
        .find(|c| c.windows(2).any(|w| w[0] == "--out" && w[1].ends_with(out_end)))
        .unwrap_or_else(|| panic!("no {stage} command writing …{out_end}: {man}"))
}

/// `args` with the value of `flag` replaced.
fn with_flag(mut args: Vec<String>, flag: &str, value: &str) -> Vec<String> {
    match args.iter().position(|a| a == flag) {
        Some(i) => args[i + 1] = value.to_string(),
        None => args.extend([flag.to_string(), value.to_string()]),
    }
    args
}

fn twins_share_one_scale_and_lead_the_report(d: &Path, project: &Path, out: &Path, shots: &Path) {
    let run = |args: &[String]| ok(&lucent(&args.iter().map(String::as_str).collect::<Vec<_>>()));
    let twin_b = d.join("twin-b");
    let render = recorded_command(out, "render", "/IOL1068-09");
    run(&with_flag(with_flag(render, "--seed", "99"), "--out", twin_b.to_str().unwrap()));
    let b_exr = twin_b.join("render.exr");
    let compare = recorded_command(out, "compare", "/IOL1068-09");
    let (alone_b, twins) = (d.join("compare-b"), d.join("compare-twins"));
    let b_only: Vec<String> = {
        let i = compare.iter().position(|a| a == "--render").unwrap();
        let mut v = compare.clone();
        v[i + 1] = b_exr.display().to_string();
        v
    };
    run(&with_flag(b_only, "--out", alone_b.to_str().unwrap()));
    let mut both = with_flag(compare.clone(), "--out", twins.to_str().unwrap());
    both.extend(["--render".into(), b_exr.display().to_string(), "--twin-names".into(), "recipe,fitted".into()]);
    run(&both);
    let range = |dir: &Path| -> f64 {
        let m: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
        m["display"]["difference_range"].as_f64().unwrap()
    };
    let a_dir = out.join("compare/IOL1068-09");
    let (ra, rb, rt) = (range(&a_dir), range(&alone_b), range(&twins));
    assert_eq!(rt, ra.max(rb), "one scale for both twins: the larger of their own ({ra}, {rb})");
    // Both twins side by side in one picture (photo, A, A − photo, B, B − photo), under one colour bar.
    let (w_one, _) = lucent::imageio::image_size(&alone_b.join("triplet.png")).unwrap();
    let (w_two, _) = lucent::imageio::image_size(&twins.join("triplet.png")).unwrap();
    assert!(3 * w_two > 4 * w_one, "five panels side by side: {w_two} px vs three {w_one} px");
    // The report with the twins' comparison: the verdict names both twins with
    // their numbers and significance, before any per-stage section.
    for f in ["metrics.json", "triplet.png"] {
        std::fs::copy(twins.join(f), a_dir.join(f)).unwrap();
    }
    let report = d.join("report-twins");
    let job = lucent::pipeline::report::ReportJob {
        project: project.to_path_buf(),
        run: out.to_path_buf(),
        out: report.clone(),
        stages: Default::default(),
    };
    job.run().unwrap();
    let index = report.join("index.html");
    let (console, dom) = chromium_at(&index, &shots.join("report-twins-1440.png"), "1440,900");
    assert!(console.is_empty(), "console messages: {console:?}");
    let (_, _) = chromium_at(&index, &shots.join("report-twins-1280x800.png"), "1280,800");
    let start = dom.find("class=\"verdict\"").expect("a verdict");
    let sentence = &dom[start..start + dom[start..].find("</p>").unwrap()];
    for needle in ["recipe's twin (A)", "fitted twin (B)", "model RMSE with the noise removed", "paired test p = "] {
        assert!(sentence.contains(needle), "{needle:?} not in {sentence}");
    }
    assert!(start < dom.find("<h2>Stages</h2>").unwrap() && start < dom.find("details per stage</h2>").unwrap());
    // The twins' picture follows the verdict, before the details; one scale said in words.
    let img = dom[start..].find("<img ").map(|i| i + start).unwrap();
    assert!(img < dom.find("details per stage</h2>").unwrap());
    assert!(dom[start..img].contains("one colour scale") && dom[start..img].contains("for both twins"), "{dom}");
}

#[test]
fn bad_projects_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let cases: [(&str, &[&str]); 13] = [
        (
            "[calibration]\nimages = \"b*.png\"\nboard = \"9x6\"\nsquare_mm = 25\ntruth = \"x.toml\"\n",
            &["[calibration] truth", "x.toml", "camera.json"],
        ),
        ("[render]\nscene = \"x.toml\"\ncamera = \"pose\"\n", &["[render] camera", "[pose]"]),
        ("[project]\nname = \"x\"\ncolour_space = 1\n", &["unknown field"]),
        ("[[sample]]\nname = \"a\"\nrecipe = \"nope.toml\"\n", &["recipe", "nope.toml", "no such file"]),
        ("[[sample]]\nname = \"a b\"\nrecipe = \"x.toml\"\n", &["name", "folder name"]),
        ("[bssrdf]\nconfigs = \"45-0\"\npaths = 10\n", &["configs", "45-0"]),
        ("[bssrdf]\nconfigs = \"45/0\"\n", &["stop rule"]),
        ("[bssrdf]\nconfigs = \"45/0\"\npaths = -10\n", &["line 3", "[bssrdf] paths", "whole number ≥ 0"]),
        ("[bssrdf]\nconfigs = \"45-0\"\npaths = -10\n", &["line 2", "[bssrdf] configs", "\"45-0\""]),
        (
            "[[sample]] # one sample\nname = \"a\"\nrecipe = \"x.toml\"\nweight_percent = \"x\"\n",
            &["line 4", "[[sample]] weight_percent", "expected a number"],
        ),
        (
            "[[sample]]\nname = \"a\"\nrecipe = \"x.toml\"\nsurface = \"nope.x3p\"\n",
            &["[[sample]] #1 (a) surface", "nope.x3p", "no such file"],
        ),
        ("[surface]\nwindow = 4\n", &["[surface] window", "odd number of pixels", "got 4"]),
        ("[surface]\nwindow_px = 5\n", &["line 2", "window_px", "unknown field"]),
    ];
    std::fs::write(tmp.path().join("x.toml"), "").unwrap();
    for (k, (text, needles)) in cases.iter().enumerate() {
        let p = tmp.path().join(format!("p{k}.toml"));
        std::fs::write(&p, text).unwrap();
        let out = tmp.path().join(format!("out{k}"));
        let o = lucent(&["run", p.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "case {k} succeeded");
        assert!(err.contains(&format!("p{k}.toml")), "case {k}: {err}");
        for n in *needles {
            assert!(err.contains(n), "case {k}: {err:?} lacks {n:?}");
        }
        assert!(!out.exists(), "case {k} wrote output");
    }
    let p = tmp.path().join("ok.toml");
    std::fs::write(&p, "[project]\nname = \"empty\"\n").unwrap();
    let o = lucent(&["run", p.to_str().unwrap(), "--force", "rendr", "--out", tmp.path().join("o").to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("render"), "the valid names are listed");
}

/// A project file that is not TOML: the error gives the line and column
/// (as scene files do), and a caller can match on them.
#[test]
fn project_syntax_errors_give_line_and_column() {
    use lucent::pipeline::project::{Project, ProjectError};
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("p.toml");
    std::fs::write(&p, "[project]\nname = \"x\"\nseed = = 3\n").unwrap();
    let e = Project::load(&p).unwrap_err();
    let ProjectError::Toml { path, line, column, .. } = &e else { panic!("{e:?}") };
    assert_eq!((path, *line, *column), (&p, Some(3), Some(8)), "{e}");
    let text = e.to_string();
    assert!(text.starts_with(&format!("{}: line 3, column 8: ", p.display())), "{text}");
    assert_eq!(text.lines().count(), 1, "one line, no snippet of the file: {text}");
    std::fs::write(&p, "[project]\nname = \"x\"\n\n[optics]\nwavelenghts = \"380:780:10\"\n").unwrap();
    let e = Project::load(&p).unwrap_err();
    assert!(matches!(e, ProjectError::Toml { line: Some(5), column: Some(1), .. }), "{e:?}");
    assert!(e.to_string().contains("unknown field `wavelenghts`"), "{e}");
}

/// A project with one sample and a [bssrdf] stage, and its output folder
/// The report stage's job run again from the command line (`lucent report`)
/// and from a job file (`lucent job run`) writes the stage's report: the
/// same page and numbers but for the table of how each stage ended, which
/// only the run knows (the command reports the folders as they are; a job
/// file may say it). The stage's manifest records the job's command.
fn report_again_by_command_and_job(d: &Path, project: &Path, out: &Path) {
    let man: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report/manifest.json")).unwrap()).unwrap();
    let command: Vec<&str> = man["commands"][0].as_array().unwrap().iter().map(|w| w.as_str().unwrap()).collect();
    let (p, o, r) = (project.to_str().unwrap(), out.to_str().unwrap(), out.join("report"));
    assert_eq!(command, ["report", p, "--run", o, "--out", r.to_str().unwrap()], "{man}");
    // Without the stages' table (and its numbers), one page.
    let page = |dir: &Path| {
        let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
        let start = html.find("<h2>Stages</h2>").expect("a table of stages");
        let end = start + html[start..].find("</table>").unwrap();
        let mut metrics: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("metrics.json")).unwrap()).unwrap();
        let stages = metrics.as_object_mut().unwrap().remove("stages").unwrap();
        (format!("{}{}", &html[..start], &html[end..]), metrics, stages, html[start..end].to_string())
    };
    let (html, metrics, _, _) = page(&r);
    let again = d.join("report-again");
    let o_cmd = ok(&lucent(&["report", p, "--run", o, "--out", again.to_str().unwrap()]));
    assert!(o_cmd.contains("report: ") && o_cmd.contains("index.html"), "{o_cmd}");
    let (html_cmd, metrics_cmd, stages_cmd, _) = page(&again);
    assert!(html_cmd == html, "lucent report wrote another page");
    assert_eq!(metrics_cmd, metrics);
    assert_eq!(stages_cmd["optics"]["status"], "as in the run's folder (its manifest)", "{stages_cmd}");
    assert_eq!(stages_cmd["fit"]["status"], "not run", "{stages_cmd}");
    // A job file that says how the stages ended, as the run's table has them: the run's page and numbers.
    let (_, _, run_stages, _) = page(&r);
    let outcomes: serde_json::Map<String, serde_json::Value> = run_stages
        .as_object()
        .unwrap()
        .iter()
        .filter_map(|(stage, v)| {
            let status = v["status"].as_str().unwrap();
            let outcome = match status.strip_prefix("skipped: ") {
                Some(reason) => serde_json::json!({ "skipped": reason }),
                None if status == "ran" => serde_json::json!("ran"),
                None if status.starts_with("up to date") => serde_json::json!("up-to-date"),
                None => return None,
            };
            Some((stage.clone(), outcome))
        })
        .collect();
    assert!(outcomes.len() >= 10, "{run_stages}");
    let job = d.join("report-job.json");
    let by_job = d.join("report-by-job");
    let text = serde_json::json!({"report": {"project": p, "run": o, "out": by_job, "stages": outcomes}});
    std::fs::write(&job, text.to_string()).unwrap();
    ok(&lucent(&["job", "run", job.to_str().unwrap()]));
    for f in ["index.html", "metrics.json"] {
        let (a, b) = (std::fs::read(r.join(f)).unwrap(), std::fs::read(by_job.join(f)).unwrap());
        assert!(a == b, "lucent job run of the report's job wrote another {f}");
    }
    // Outside a run's plan a stage's folder is not read: bssrdf "skipped" leaves its section out.
    let skipped = d.join("report-skipped");
    let text = serde_json::json!({"report": {"project": p, "run": o, "out": skipped,
        "stages": {"optics": "ran", "bssrdf": {"skipped": "said so"}}}});
    std::fs::write(&job, text.to_string()).unwrap();
    ok(&lucent(&["job", "run", job.to_str().unwrap()]));
    let (html_skipped, _, _, _) = page(&skipped);
    assert!(html.contains("BSSRDF slices") && !html_skipped.contains("BSSRDF slices"), "the skipped stage is left out");
}

/// holding `summary` as the sample's BSSRDF summary.json.
fn report_with_summary(dir: &Path, summary: &str) -> Result<String, lucent::pipeline::report::ReportJobError> {
    let recipe = root().join("fixtures/samples/IOL1068-09.toml");
    let text = format!("[bssrdf]\nconfigs = \"45/0\"\npaths = 10\n\n[[sample]]\nname = \"s\"\nrecipe = {recipe:?}\n");
    let p = dir.join("p.toml");
    std::fs::write(&p, text).unwrap();
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("bssrdf/s")).unwrap();
    std::fs::write(out.join("bssrdf/s/summary.json"), summary).unwrap();
    let report = out.join("report");
    lucent::pipeline::report::ReportJob { project: p, run: out, out: report.clone(), stages: Default::default() }
        .run()?;
    Ok(std::fs::read_to_string(report.join("index.html")).unwrap())
}

/// summary.json as `lucent bssrdf` wrote it on 23 Nov 2026 (c3456eb), before
/// the per-pixel errors, kernel, estimator, folding, reciprocity,
/// interruption and roughness fields existed.
const OLD_SUMMARY: &str = r#"{
  "config": {"recipe": null, "wavelength_nm": null, "theta_i_deg": 45.0, "phi_i_deg": 0.0, "theta_o_deg": 0.0,
             "phi_o_deg": 180.0, "phase": "hg", "beam": "gaussian", "pixels": 33, "pixel_mm": 0.2, "crop_of": null,
             "seed": 1, "thickness_mm": 6.35},
  "optical_properties": {"mu_s_per_m": 30000.0, "mu_a_per_m": 5.0, "g": 0.7, "n": 1.49},
  "sum": 123.456, "sum_std_error": 1.5, "relative_std_error": 0.012, "paths": 10000, "events": 2000000,
  "events_per_s": null, "wall_s": 0.5, "specular_reflectance": 0.04, "diffuse_reflectance": 0.5,
  "transmittance": 0.1, "pixel_mm": 0.2
}"#;

/// The report reads each stage's file into the type its writer uses: an old
/// summary.json still loads (its newer fields defaulted, a `null` shown as
/// "—"); one missing a field fails with an error naming the file and field.
#[test]
fn report_reads_summaries_typed_and_names_a_missing_field() {
    use lucent::pipeline::report::{ReportError, ReportJobError};
    let tmp = tempfile::tempdir().unwrap();
    let html = report_with_summary(tmp.path(), OLD_SUMMARY).unwrap();
    assert!(html.contains("1.2346e2 ± 1.5000e0") && html.contains("<td>10000</td>"), "{html}");
    let summary: lucent::bssrdf::Summary = serde_json::from_str(OLD_SUMMARY).unwrap();
    assert!(summary.events_per_s.is_nan() && summary.pixel_rel_error_median.is_nan());
    assert_eq!((summary.config.roughness.as_str(), summary.interrupted), ("smooth", false));

    let tmp = tempfile::tempdir().unwrap();
    let broken = OLD_SUMMARY.replace("\"sum\": 123.456, ", "");
    let e = report_with_summary(tmp.path(), &broken).unwrap_err();
    let ReportJobError::Report(ReportError::Format { path, source, .. }) = &e else { panic!("{e:?}") };
    assert!(path.ends_with("bssrdf/s/summary.json"), "{}", path.display());
    assert!(source.is_data(), "{source}");
    let text = e.to_string();
    assert!(text.contains("summary.json") && text.contains("missing field `sum`"), "{text}");
    assert!(!tmp.path().join("out/report/index.html").exists(), "no report from a broken file");

    let tmp = tempfile::tempdir().unwrap();
    let e =
        report_with_summary(tmp.path(), &OLD_SUMMARY.replace("\"paths\": 10000", "\"paths\": \"many\"")).unwrap_err();
    assert!(e.to_string().contains("invalid type: string \"many\", expected u64"), "{e}");
}

/// Planning errors are typed: a render whose camera comes from the pose
/// stage names the missing pose output.
#[test]
fn missing_pose_output_is_a_typed_stage_error() {
    use lucent::pipeline::{PipelineError, Stage, StageProblem};
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("photo.png"), b"").unwrap();
    let p = tmp.path().join("p.toml");
    std::fs::write(&p, "[pose]\nimage = \"photo.png\"\nboard = \"9x6\"\n").unwrap();
    let project = lucent::pipeline::project::Project::load(&p).unwrap();
    let out = tmp.path().join("out");
    let e = lucent::pipeline::pose_frame(&project, &out).unwrap_err();
    let PipelineError::Stage { stage: Stage::Render, problem } = &e else { panic!("{e:?}") };
    let StageProblem::PoseOutputMissing { missing } = problem else { panic!("{problem:?}") };
    assert_eq!(missing, &out.join("pose/scene.json"));
    assert!(e.to_string().contains("pose/scene.json") && e.to_string().contains("camera = \"template\""), "{e}");
}

/// Every stage file the report reads, as lucent writes it
/// (fixtures/formats/), reads into its writer's type and serialises back to
/// the same JSON: the type holds every field, none is dropped or renamed.
#[test]
fn stage_files_round_trip_through_their_writers_types() {
    use lucent::pipeline::report::read_json;
    use serde::{de::DeserializeOwned, Serialize};
    fn round_trip<T: DeserializeOwned + Serialize>(name: &str) {
        let p = root().join("fixtures/formats").join(name);
        let typed: T = read_json(&p, "a fixture").unwrap().unwrap_or_else(|| panic!("{name} missing"));
        let original: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
        assert_eq!(serde_json::to_value(&typed).unwrap(), original, "{name}");
    }
    round_trip::<lucent::bssrdf::Summary>("bssrdf_summary.json");
    round_trip::<lucent::bssrdf::Comparison>("bssrdf_comparison.json");
    round_trip::<lucent::scene::RenderReport>("render.json");
    round_trip::<lucent::compare::Report>("compare_metrics.json");
    round_trip::<lucent::envfit::FitReport>("env_scale.json");
    // An absent file is "stage not run", not an error.
    assert!(read_json::<lucent::bssrdf::Summary>(&root().join("fixtures/formats/none.json"), "x").unwrap().is_none());
}

/// The paper's loop in one run: slices "measured" at a hidden 0.425 wt-%
/// (simulated from fixtures/fit's truth recipe), a photo rendered at it;
/// stage fit recovers the weight percentage from the slices, render makes
/// both twins, compare scores both and says which is closer, and the report
/// tabulates truth vs fitted and shows both triplets.
#[test]
fn fit_stage_closes_the_loop_slices_fit_rerender_compare() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let f = root().join("fixtures");
    let truth_recipe = f.join("fit/IOL1068-09_truth_0425.toml");
    let m = d.join("measured");
    ok(&lucent(&[
        "bssrdf",
        "--recipe",
        truth_recipe.to_str().unwrap(),
        "--wavelength",
        "550",
        "--configs",
        "45/0,30/0",
        "--crop",
        "--paths",
        "30000",
        "--seed",
        "101",
        "--quiet",
        "--out",
        m.to_str().unwrap(),
    ]));
    let text = std::fs::read_to_string(f.join("render/demo.toml"))
        .unwrap()
        .replace("\"../samples/", &format!("\"{}/samples/", f.display()))
        .replace("\"../env/", &format!("\"{}/env/", f.display()));
    std::fs::write(d.join("scene.toml"), &text).unwrap();
    let truth_scene = text.replace(
        &format!("\"{}/samples/IOL1068-09.toml\"", f.display()),
        &format!("{:?}", truth_recipe.display().to_string()),
    );
    assert_ne!(truth_scene, text);
    std::fs::write(d.join("truth.toml"), &truth_scene).unwrap();
    let photo = d.join("photo");
    ok(&lucent(&[
        "render",
        d.join("truth.toml").to_str().unwrap(),
        "--size",
        "64x48",
        "--spp",
        "64",
        "--seed",
        "99",
        "--quiet",
        "--out",
        photo.to_str().unwrap(),
    ]));
    let project = d.join("loop.toml");
    std::fs::write(
        &project,
        format!(
            r#"[project]
name = "loop"
seed = 7

[render]
scene = "{d}/scene.toml"
spp = 32
size = "64x48"

[fit]
free = ["weight_percent"]
paths = 8000

[[sample]]
name = "IOL1068-09"
recipe = "{f}/samples/IOL1068-09.toml"
photo = "{d}/photo/render.exr"
truth_recipe = "{truth}"

[[sample.measured]]
config = "45/0"
file = "{d}/measured/ti45_to0/bssrdf.exr"

[[sample.measured]]
config = "30/0"
file = "{d}/measured/ti30_to0/bssrdf.exr"
"#,
            d = d.display(),
            f = f.display(),
            truth = truth_recipe.display()
        ),
    )
    .unwrap();
    let out = d.join("out");
    let text = ok(&lucent(&["run", project.to_str().unwrap(), "--out", out.to_str().unwrap()]));
    for s in ["fit", "render", "compare", "report"] {
        assert_eq!(status_of(&text, s), "ran", "{s}:\n{text}");
    }
    // The fitted recipe and the fitted twin.
    assert!(out.join("fit/IOL1068-09/IOL1068-09_fitted.toml").is_file());
    assert!(out.join("render/IOL1068-09/fitted/render.exr").is_file());
    let scene = std::fs::read_to_string(out.join("render/IOL1068-09/input_scene_fitted.toml")).unwrap();
    assert!(scene.contains("IOL1068-09_fitted.toml"), "{scene}");
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report/metrics.json")).unwrap()).unwrap();
    let smp = &metrics["samples"]["IOL1068-09"];
    let p = &smp["fit"]["parameters"][0];
    assert_eq!(p["truth"].as_f64(), Some(0.425), "{p}");
    let (lo, hi) = (p["interval_95"][0].as_f64().unwrap(), p["interval_95"][1].as_f64().unwrap());
    assert!(lo <= 0.425 && 0.425 <= hi, "fitted {p}");
    // Both twins scored; the recipe's (0.65 wt-%) is not found closer than the fitted one.
    let twins = &smp["compare"]["twins"];
    assert!(twins["paired"]["verdict"].is_string(), "{twins}");
    assert_ne!(twins["paired"]["verdict"], "A is closer", "{twins}");
    assert!(out.join("compare/IOL1068-09/fitted/triplet.png").is_file());
    let html = std::fs::read_to_string(out.join("report/index.html")).unwrap();
    assert!(html.contains("Recipe fitted to the measured slices") && html.contains("Which twin is closer"), "report");
    // The answer first: the verdict names both twins with their numbers and
    // significance, then one picture of both under one difference scale.
    let verdict = html.find("<p class=\"verdict\">").expect("a verdict");
    let sentence = &html[verdict..verdict + html[verdict..].find("</p>").unwrap()];
    for needle in ["Over the object's pixels", "fitted twin (B)", "recipe's twin (A)", "paired test p = "] {
        assert!(sentence.contains(needle), "{needle:?} not in {sentence}");
    }
    assert!(verdict < html.find("details per stage</h2>").unwrap() && verdict < html.find("<h2>Stages</h2>").unwrap());
    assert!(html.contains("A (recipe) render, difference | B (fitted) render, difference, one difference scale"));
    // demo.toml walks the similar medium: its measured bias on the object's
    // interior stands beside the answer, and in the render's details.
    let approximate = html.find("<b>The renders approximate</b>").expect("the approximations beside the answer");
    assert!(approximate < html.find("details per stage</h2>").unwrap(), "beside the answer");
    assert!(html[approximate..].contains("+2.64 / +2.29 / +2.55 %"), "the measured bias");
    let paragraph = &html[approximate..approximate + html[approximate..].find("</p>").unwrap()];
    assert!(paragraph.contains("A (recipe): similar medium") && !paragraph.contains("/render.exr"), "{paragraph}");
    assert!(html.contains("<p class=\"why approximation\">Approximation: similar medium"), "in the render's section");
    let display = &smp["compare"]["display"];
    assert!(display["difference_range_source"].as_str().unwrap().contains("one scale for both twins"), "{display}");
    let alone: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("compare/IOL1068-09/fitted/metrics.json")).unwrap())
            .unwrap();
    assert!(display["difference_range"].as_f64() >= alone["display"]["difference_range"].as_f64(), "{display}");
    let shots = root().join("target/test-output");
    std::fs::create_dir_all(&shots).unwrap();
    for (name, window) in [("report-loop-1440.png", "1440,900"), ("report-loop-1280x800.png", "1280,800")] {
        let (console, _) = chromium_at(&out.join("report/index.html"), &shots.join(name), window);
        assert!(console.is_empty(), "console messages: {console:?}");
    }
    // The slices measured vs simulated at the recipe and at the fit (sums, MSRE).
    assert!(html.contains("simulated/measured sum: recipe") && html.contains("MSRE: recipe"), "report");
    // … and their profiles: measured, at the recipe and at the fit, one plot per configuration.
    assert!(html.contains("measured profile vs simulated at the recipe and at the fit"), "report");
    assert!(out
        .join("fit/IOL1068-09")
        .read_dir()
        .unwrap()
        .flatten()
        .any(|e| e.file_name().to_string_lossy().starts_with("profiles_ti")));
    // Also scored over the plaque's pixels alone, as the render's object layer marks them.
    let object = &smp["compare_object"];
    assert_eq!(object["mask"]["source"], "object", "{}", object["mask"]);
    assert!(
        object["mask"]["included_pixels"].as_u64().unwrap()
            < smp["compare"]["mask"]["included_pixels"].as_u64().unwrap()
    );
    assert!(object["twins"]["paired"]["verdict"].is_string(), "{object}");
    // The loop against its truth, stated once: truth, recovered, the object's verdict and its p.
    let lp = &smp["loop"];
    assert_eq!(lp["parameters"][0]["truth"].as_f64(), Some(0.425), "{lp}");
    assert_eq!(lp["parameters"][0]["recovered"], p["value"], "{lp}");
    assert_eq!(lp["region"], "the object's pixels", "{lp}");
    assert_eq!(lp["verdict"], object["twins"]["paired"]["verdict"], "{lp}");
    assert_eq!(lp["p_value"], object["twins"]["paired"]["p_value"], "{lp}");
    assert!(html.contains("The loop against its known truth"), "report");
    // A second run skips every stage.
    let again = ok(&lucent(&["run", project.to_str().unwrap(), "--out", out.to_str().unwrap()]));
    for s in ["fit", "render", "compare"] {
        assert_eq!(status_of(&again, s), "up", "{s}:\n{again}");
    }
}

/// The worked example's project names no `spp`: its render job carries
/// none, so the render stops at the default 5 % on the object (a project
/// render used to fall back to 16 samples, a noisy preview).
#[test]
fn a_project_without_spp_renders_to_the_default_error_target() {
    use lucent::job::Job;
    use lucent::pipeline::{plan, project::Project, Stage, Task};
    let tmp = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for f in ["part.obj", "tio2_pmma.toml", "scene.toml", "project.toml"] {
        std::fs::copy(root.join("fixtures/example").join(f), tmp.path().join(f)).unwrap();
    }
    std::fs::copy(root.join("fixtures/env/studio.exr"), tmp.path().join("studio.exr")).unwrap();
    let project = Project::load(&tmp.path().join("project.toml")).unwrap();
    let planned = plan(Stage::Render, &project, &tmp.path().join("out")).unwrap().unwrap();
    let renders: Vec<_> = planned
        .tasks
        .iter()
        .filter_map(|t| match t {
            Task::Lucent { job: Job::Render(r), .. } => Some(r),
            _ => None,
        })
        .collect();
    assert_eq!(renders.len(), 1);
    assert_eq!(renders[0].spp, None);
    let stop = renders[0].stop();
    assert_eq!((stop.samples, stop.time_s), (None, None), "{stop:?}");
    // With spp the project's budget is the job's.
    let text = std::fs::read_to_string(tmp.path().join("project.toml")).unwrap();
    std::fs::write(tmp.path().join("project.toml"), text.replace("[render]\n", "[render]\nspp = 8\n")).unwrap();
    let project = Project::load(&tmp.path().join("project.toml")).unwrap();
    let planned = plan(Stage::Render, &project, &tmp.path().join("out")).unwrap().unwrap();
    assert!(planned.tasks.iter().any(|t| matches!(t, Task::Lucent { job: Job::Render(r), .. } if r.spp == Some(8))));
}

/// A sample with a measured height map (`surface`, relative to the project
/// file): stage surface fits it, the bssrdf stage's job takes its normals as
/// the top boundary (`--roughness measured:…/fit.json`), the report shows
/// the fit, and a second run finds every stage up to date. `[bssrdf]
/// roughness` wins over the fitted surface.
#[test]
fn a_sample_surface_is_fitted_and_is_the_slices_top_boundary() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::copy(root().join("fixtures/surface/tr_0p0084.x3p"), d.join("heights.x3p")).unwrap();
    let text = |roughness: &str| {
        format!(
            "[project]\nname = \"rough\"\n\n[surface]\nwindow = 9\n\n[bssrdf]\nconfigs = \"45/0\"\npixels = 33\n\
             pixel_mm = 0.2\npaths = 3000\nphase = \"hg\"\n{roughness}\n[[sample]]\nname = \"s1\"\n\
             recipe = \"{}\"\nsurface = \"heights.x3p\"\n",
            root().join("fixtures/samples/IOL1068-09.toml").display()
        )
    };
    let project = d.join("project.toml");
    std::fs::write(&project, text("")).unwrap();
    let out = d.join("out");
    let run = || ok(&lucent(&["run", project.to_str().unwrap(), "--out", out.to_str().unwrap()]));
    let first = run();
    assert_eq!(status_of(&first, "surface"), "ran", "{first}");
    assert_eq!(status_of(&first, "bssrdf"), "ran", "{first}");

    // The fit: fit.json as `surface fit` writes it, with the project's window.
    let fit_json = out.join("surface/s1/fit.json");
    let fit: lucent::surface::FitReport =
        serde_json::from_str(&std::fs::read_to_string(&fit_json).unwrap()).expect("surface/s1/fit.json");
    assert_eq!(fit.schema, lucent::surface::FIT_SCHEMA);
    assert_eq!(fit.options.window_px, 9);
    let tr = fit.fits.trowbridge_reitz.alpha;
    assert!((0.007..0.0095).contains(&tr), "TR α {tr} of a TR α = 0.0084 surface");
    assert!(out.join("surface/s1/normals.exr").is_file() && out.join("surface/s1/distribution.png").is_file());

    // The bssrdf stage's job carries the measured top boundary, and the slice used it.
    let roughness = |out: &Path| {
        let args = recorded_command(out, "bssrdf", "/s1");
        let k = args.iter().position(|a| a == "--roughness").map(|k| k + 1);
        k.map(|k| args[k].clone())
    };
    assert_eq!(roughness(&out), Some(format!("measured:{}", fit_json.display())));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bssrdf/s1/summary.json")).unwrap()).unwrap();
    let boundary = summary["config"]["roughness"].as_str().unwrap();
    assert!(boundary.contains("measured normals") && boundary.contains("normals.exr"), "{boundary}");

    // The report's section, and its numbers in metrics.json.
    let html = std::fs::read_to_string(out.join("report/index.html")).unwrap();
    assert!(html.contains("<h3>Surface</h3>") && html.contains("Trowbridge–Reitz (better)"), "no surface section");
    assert!(html.contains(&format!("{tr:.5}")), "the fitted α in the report");
    let metrics: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report/metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics["samples"]["s1"]["surface"]["fits"]["trowbridge-reitz"]["alpha"].as_f64(), Some(tr));

    // A second run: nothing to do.
    let second = run();
    for s in ["optics", "surface", "bssrdf", "report"] {
        assert_eq!(status_of(&second, s), "up", "{s}: {second}");
    }

    // [bssrdf] roughness wins over the fitted surface.
    std::fs::write(&project, text("roughness = \"smooth\"\n")).unwrap();
    let third = run();
    assert_eq!((status_of(&third, "surface"), status_of(&third, "bssrdf")), ("up".into(), "ran".into()), "{third}");
    assert_eq!(roughness(&out).as_deref(), Some("smooth"));
}
