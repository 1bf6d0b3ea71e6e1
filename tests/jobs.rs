//! Jobs (`lucent::job`): each job's command line parses back into the same
//! job, old flag spellings still parse, project values out of range are
//! named with their key before any stage runs, and the exit code says who
//! is at fault.

use lucent::ccm_file::ApplyTarget;
use lucent::cli::jobs::parse_job;
use lucent::job::*;
use std::path::PathBuf;
use std::process::Command;

fn lucent_in(dir: &std::path::Path, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).current_dir(dir).output().unwrap()
}

fn p(s: &str) -> PathBuf {
    PathBuf::from(s)
}

/// One job of every kind, every optional field set (with the canonical
/// spelling of each choice).
fn jobs() -> Vec<Job> {
    vec![
        Job::Optics(OpticsJob {
            recipes: vec![p("a.toml"), p("b.toml")],
            wavelengths: "400:700:5".parse().unwrap(),
            out: Some(p("{out}")),
            weight_percent: Some(0.4),
            wavelength_nm: None,
            json: true,
            phase_entries: 0,
            skip_invalid: true,
            uncertainty: Some(40),
            uncertainty_seed: 3,
            shard: Some(lucent::job::shard::ShardSpec { k: 1, n: 2 }),
        }),
        Job::Bssrdf(BssrdfJob {
            recipe: Some(p("r.toml")),
            wavelength_nm: 632.8,
            configs: Some("45/0,0/45".parse().unwrap()),
            pixels: 65,
            pixel_mm: 0.2,
            seed: 7,
            quiet: true,
            out: p("{out}/s"),
            weight_percent: Some(1.5),
            crop: Some(33),
            paths: Some(9000),
            rel_error: Some(0.02),
            time_s: Some(3.5),
            phase: Some(lucent::optics::PhaseModel::Hg),
            thickness_mm: Some(5.0),
            theta_i: 30.0,
            phi_i: 10.0,
            theta_o: -10.0,
            phi_o: 170.0,
            similarity_g: Some(0.9),
            beam_map: Some(p("beam.exr")),
            beam_map_pixel_mm: Some(0.01),
            pixel_rel_error: Some(0.05),
            estimator: lucent::job::EstimatorChoice::Lobe,
            lobe_vertices: 8,
            roughness: Some("tr:0.01".parse().unwrap()),
            no_fold: true,
            uncertainty: true,
            shard: Some(lucent::job::shard::ShardSpec { k: 1, n: 4 }),
            ..BssrdfJob::default()
        }),
        Job::BssrdfCompare(BssrdfCompareJob {
            measured: p("m.exr"),
            simulated: p("{out}/s"),
            out: p("{out}/s/compare"),
            measured_pixel_mm: Some(0.11),
            threshold: 0.02,
        }),
        Job::Fit(FitJob {
            recipe: p("r.toml"),
            measured: vec!["m1.exr:45/0".parse().unwrap(), "m2.exr:0/45".parse().unwrap()],
            measured_pixel_mm: Some(0.1),
            weight_percent: Some(0.5),
            free: vec!["weight_percent".parse().unwrap(), "diameter_um@1".parse().unwrap()],
            wavelength_nm: 550.0,
            seed: 3,
            quiet: true,
            objective: lucent::fit::Objective::Msre,
            rel_error: 0.01,
            paths: Some(20_000),
            measured_rel_sd: 0.1,
            bounds: Some("0.1:2,0.1:1".parse().unwrap()),
            threshold: 0.05,
            out: p("{out}/s"),
            beam_fwhm_um: 150.0,
            beam_map: None,
            beam_map_pixel_mm: None,
            pilot_time_s: 30.0,
            thickness_mm: Some(5.0),
        }),
        Job::Calibrate(CalibrateJob {
            images: vec!["photos/*.jpg".into()],
            board: "9x6".parse().unwrap(),
            square_mm: 25.0,
            out: p("{out}/camera.json"),
            model: lucent_calib::model::DistortionModel::Fisheye,
            detector: lucent_calib::cv::Detector::Classic,
            quiet: true,
        }),
        Job::ColourCalibrate(ColourCalibrateJob {
            image: p("chart.exr"),
            camera: Some("phone".into()),
            out: p("{out}/phone"),
            corners: Some("1,2,3,4,5,6,7,8".parse().expect("corners")),
            method: lucent_colour::ccm::CcmMethod::Finlayson2015,
            decode_srgb: true,
            clip_level: lucent::job::ClipLevel::None,
            gap_ratio: 0.2,
            inner_fraction: 0.25,
        }),
        Job::ColourApply(ColourApplyJob {
            ccm: p("ccm.json"),
            input: p("photo.dng"),
            output: p("{out}/s/photo.exr"),
            to: lucent::ccm_file::ApplyTarget::Xyz,
            variance_out: Some((p("{out}/s/photo_variance.exr"), 7)),
            bin: 4,
            adaptation: Some(lucent_colour::adaptation::Cat::VonKries),
            variance_realisations: 8,
        }),
        Job::RawClipped(RawClippedJob {
            input: p("photo.dng"),
            out: p("{out}/s/photo_valid.png"),
            bin: 2,
            level: 0.98,
            dilate: 3,
        }),
        Job::Pose(PoseJob {
            camera: p("camera.json"),
            image: p("pose.jpg"),
            board: "9x6".parse().unwrap(),
            square_mm: 20.0,
            out: p("{out}/scene.json"),
            sample: Some(("2,3".parse().unwrap(), "60,40,6".parse().unwrap())),
            keep_all: true,
        }),
        Job::EnvScale(EnvScaleJob {
            scene: p("{out}/s/input_scene.toml"),
            photo: p("empty.exr"),
            spp: Some(32),
            per_channel: true,
            mask: Some(p("valid.png")),
            size: Some("64x48".parse().unwrap()),
            seed: Some(9),
            out: p("{out}/s"),
            quiet: true,
            threads: Some(2),
        }),
        Job::Render(RenderJob {
            scene: p("{out}/s/input_scene.toml"),
            spp: Some(64),
            quiet: true,
            time_s: Some(2.5),
            size: Some("64x48".parse().unwrap()),
            seed: Some(9),
            uncertainty: true,
            out: p("{out}/s"),
            ..Default::default()
        }),
        Job::Compare(CompareJob {
            photo: p("photo.exr"),
            render: vec![p("a/render.exr"), p("b/render.exr")],
            out: p("{out}/s"),
            mask: Some(p("valid.png")),
            mask_object: Some(p("a/render.exr")),
            mask_board: None,
            photo_variance: Some(p("{out}/s/photo_variance.exr")),
            // (--photo-repeat is the other way to the photo's variance, not beside it.)
            photo_repeat: None,
            scene: Some(p("scene.json")),
            data_range: 2.0,
            luminance: lucent::compare::Luminance::Rec709,
            exposure: Some(0.5),
            refine: Some(lucent_calib::ecc::Motion::Affine),
            twin_names: Some(["recipe".into(), "fitted".into()]),
            band: vec![p("a/uncertainty.json"), p("b/uncertainty.json")],
        }),
        Job::SurfaceFit(SurfaceFitJob {
            heightmap: p("scan.tif"),
            pitch_um: Some(0.871),
            pitch_y_um: Some(0.9),
            height_unit: Some(lucent::surface::LengthUnit::Nm),
            window: 21,
            sigma_px: 1.5,
            min_weight: 0.8,
            keep_tilt: true,
            fit_tilt: true,
            out: p("{out}/surface"),
        }),
        Job::EnvMerge(EnvMergeJob {
            brackets: vec![p("b1.jpg"), p("b2.jpg"), p("b3.jpg")],
            exposures: Some("1/1000,1/250,0.016".parse().unwrap()),
            out: p("{out}/env.exr"),
            method: lucent_calib::hdr::ResponseMethod::Robertson,
            saturation: 0.9,
            noise_floor: 0.001,
            saturation_code: 240,
            floor_code: 10,
        }),
        Job::EnvOrient(EnvOrientJob {
            input: p("pano.exr"),
            yaw: None,
            board_view: Some("20,-90,100".parse().unwrap()),
            board: Some("9x6".parse().unwrap()),
            square_mm: Some(30.0),
            view_size: "1000x1000".parse().unwrap(),
            max_tilt_deg: 5.0,
            out: p("{out}/pano_oriented.exr"),
        }),
    ]
}

#[test]
fn every_job_round_trips_through_its_command_line() {
    let all = jobs();
    assert_eq!(all.len(), 15, "one job per command a stage runs, and surface fit, env merge, env orient");
    for job in all {
        job.validate().unwrap_or_else(|e| panic!("{job:?}: {e}"));
        let args = job.to_args();
        let back = parse_job(&args).unwrap_or_else(|e| panic!("lucent {}: {e}", args.join(" ")));
        assert_eq!(back, job, "lucent {}", args.join(" "));
    }
}

/// A job and its command line are one: with its optional fields set or
/// unset, the job's command line (`to_args`, what a stage's manifest and
/// the cluster's scripts hold) parses with clap into the command whose job
/// (`job_of`) is the same job, so running either does the same work.
#[test]
fn every_job_and_its_command_line_parse_into_the_same_job() {
    let mut all = jobs();
    // The same jobs with every optional field unset.
    all.extend(jobs().into_iter().map(|j| match j {
        Job::Optics(o) => Job::Optics(OpticsJob {
            weight_percent: None,
            json: false,
            phase_entries: lucent::job::DEFAULT_PHASE_ENTRIES,
            skip_invalid: false,
            uncertainty: None,
            uncertainty_seed: 1,
            shard: None,
            ..o
        }),
        Job::Bssrdf(b) => Job::Bssrdf(BssrdfJob {
            configs: None,
            weight_percent: None,
            crop: None,
            paths: None,
            rel_error: None,
            time_s: None,
            phase: None,
            quiet: false,
            ..b
        }),
        Job::Render(r) => Job::Render(RenderJob {
            spp: None,
            time_s: None,
            size: None,
            seed: None,
            quiet: false,
            uncertainty: false,
            ..r
        }),
        Job::Compare(c) => Job::Compare(CompareJob {
            mask: None,
            mask_object: None,
            photo_variance: None,
            photo_repeat: None,
            scene: None,
            luminance: Default::default(),
            exposure: None,
            refine: None,
            twin_names: None,
            band: vec![],
            ..c
        }),
        Job::ColourApply(c) => Job::ColourApply(ColourApplyJob {
            variance_out: None,
            bin: 1,
            adaptation: lucent::job::DEFAULT_ADAPTATION,
            variance_realisations: lucent::job::DEFAULT_VARIANCE_REALISATIONS,
            ..c
        }),
        Job::ColourCalibrate(c) => Job::ColourCalibrate(ColourCalibrateJob {
            clip_level: lucent::job::ClipLevel::default(),
            gap_ratio: lucent::job::DEFAULT_GAP_RATIO,
            inner_fraction: lucent::job::DEFAULT_INNER_FRACTION,
            ..c
        }),
        Job::Pose(p) => Job::Pose(PoseJob { sample: None, keep_all: false, ..p }),
        Job::Calibrate(c) => {
            Job::Calibrate(CalibrateJob { detector: lucent_calib::cv::Detector::Auto, quiet: false, ..c })
        }
        Job::RawClipped(r) => Job::RawClipped(RawClippedJob {
            level: lucent::job::DEFAULT_CLIPPED_LEVEL,
            dilate: lucent::job::DEFAULT_DILATE,
            ..r
        }),
        Job::EnvScale(e) => Job::EnvScale(EnvScaleJob {
            spp: None,
            per_channel: false,
            mask: None,
            size: None,
            seed: None,
            quiet: false,
            threads: None,
            ..e
        }),
        Job::SurfaceFit(f) => Job::SurfaceFit(SurfaceFitJob::new(f.heightmap, f.out)),
        Job::EnvMerge(m) => Job::EnvMerge(EnvMergeJob::new(m.brackets, m.out)),
        // (A yaw given instead of the board's view.)
        Job::EnvOrient(o) => Job::EnvOrient(EnvOrientJob::given_yaw(o.input, -117.5, o.out)),
        other => other,
    }));
    for job in all {
        let args = job.to_args();
        let parsed =
            lucent::cli::Cli::try_parse_args(std::iter::once("lucent".to_string()).chain(args.iter().cloned()))
                .unwrap_or_else(|e| panic!("lucent {}: {e}", args.join(" ")));
        let back = lucent::cli::jobs::job_of(&parsed.command)
            .unwrap_or_else(|| panic!("lucent {}: not a stage's job", args.join(" ")));
        assert_eq!(back, job, "lucent {}", args.join(" "));
    }
}

/// `lucent job run JOB.json` reads what serde writes: every job round-trips
/// through JSON, and the JSON names the command.
#[test]
fn every_job_round_trips_through_json() {
    for job in jobs() {
        let text = serde_json::to_string_pretty(&job).unwrap();
        let back: Job = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{text}: {e}"));
        assert_eq!(back, job, "{text}");
    }
    let text = r#"{"render": {"scene": "s.toml", "spp": 8, "quiet": true, "time_s": null, "size": null,
        "seed": null, "uncertainty": false, "out": "o"}}"#;
    assert!(matches!(serde_json::from_str::<Job>(text), Ok(Job::Render(RenderJob { spp: Some(8), .. }))));
    let typo = text.replace("\"spp\"", "\"sp\"");
    let e = serde_json::from_str::<Job>(&typo).unwrap_err().to_string();
    assert!(e.contains("sp"), "{e}");
    // The colour space is a type: written as the word the command line
    // takes, read in any of its spellings, a wrong one refused with its name.
    let apply = |to: &str| {
        format!(
            r#"{{"colour-apply": {{"ccm": "c.json", "input": "a.exr", "output": "b.exr", "to": "{to}", "variance_out": null, "bin": 1}}}}"#
        )
    };
    for (word, want) in [("cie-rgb", ApplyTarget::CieRgb), ("REC709", ApplyTarget::Srgb), ("xyz", ApplyTarget::Xyz)] {
        let job = serde_json::from_str::<Job>(&apply(word)).unwrap_or_else(|e| panic!("{word}: {e}"));
        let Job::ColourApply(j) = &job else { panic!("{word}") };
        assert_eq!(j.to, want, "{word}");
        assert!(serde_json::to_string(&job).unwrap().contains(&format!("\"to\":\"{}\"", <&str>::from(want))));
    }
    let e = serde_json::from_str::<Job>(&apply("lab")).unwrap_err().to_string();
    assert!(e.contains("\"lab\""), "{e}");
}

/// Shards of one run are one run however its command line is spelled: the
/// typed job's identity does not see the order of the flags, `--spp=8` for
/// `--spp 8`, a relative or an absolute path, or the output folder.
#[test]
fn a_jobs_identity_ignores_how_its_command_line_is_spelled() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, "").unwrap();
    let abs = scene.display().to_string();
    let here = std::env::current_dir().unwrap();
    let rel = pathdiff(&scene, &here);
    let id = |args: &[&str]| {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        parse_job(&args).unwrap_or_else(|e| panic!("{args:?}: {e}")).identity_sha256()
    };
    let a = id(&["render", &abs, "--spp", "8", "--seed", "3", "--out", "x"]);
    assert_eq!(a, id(&["render", &abs, "--spp=8", "--seed=3", "--out", "x"]));
    assert_eq!(a, id(&["render", "--seed", "3", &abs, "--out", "elsewhere", "--spp", "8", "--quiet"]));
    assert_eq!(a, id(&["render", &rel, "--spp", "8", "--seed", "3", "--out", "x"]));
    assert_ne!(a, id(&["render", &abs, "--spp", "9", "--seed", "3", "--out", "x"]));
    assert_ne!(a, id(&["render", &abs, "--spp", "8", "--seed", "4", "--out", "x"]));
}

#[test]
fn shard_and_clip_level_are_typed_in_job_files_and_command_lines() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, "").unwrap();
    let abs = scene.display().to_string();
    let job = |args: &[&str]| {
        let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
        parse_job(&args).unwrap_or_else(|e| panic!("{args:?}: {e}"))
    };
    // One shard, however spaced, is one job; its JSON spells it "K/N".
    let a = job(&["render", &abs, "--spp", "8", "--shard", "1/2", "--out", "x"]);
    assert_eq!(
        a.identity_sha256(),
        job(&["render", &abs, "--spp", "8", "--shard", " 1 / 2", "--out", "x"]).identity_sha256()
    );
    let text = serde_json::to_string(&a).unwrap();
    assert!(text.contains("\"shard\":\"1/2\""), "{text}");
    // A job file with a shard or a clip level its flag refuses is refused when read.
    let bad_shard = text.replace("\"1/2\"", "\"2/2\"");
    let e = serde_json::from_str::<Job>(&bad_shard).unwrap_err().to_string();
    assert!(e.contains("expected K/N"), "{e}");
    let Job::ColourCalibrate(c) = job(&["colour", "calibrate", "--image", &abs, "--clip-level", "none", "--out", "x"])
    else {
        panic!("not a colour calibrate job")
    };
    assert_eq!(c.clip_level, lucent::job::ClipLevel::None);
    let text = serde_json::to_string(&Job::ColourCalibrate(c)).unwrap();
    let e = serde_json::from_str::<Job>(&text.replace("\"none\"", "\"-1\"")).unwrap_err().to_string();
    assert!(e.contains("expected a positive number"), "{e}");
}

/// `path` relative to `base` ("../.." as needed).
fn pathdiff(path: &std::path::Path, base: &std::path::Path) -> String {
    let (p, b): (Vec<_>, Vec<_>) = (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &p[common..] {
        out.push(c);
    }
    out.display().to_string()
}

#[test]
fn jobs_refuse_what_their_flags_refuse() {
    let Job::Bssrdf(b) = jobs().swap_remove(1) else { unreachable!() };
    let e = BssrdfJob { pixel_mm: -0.5, ..b.clone() }.validate().unwrap_err();
    assert_eq!((e.field, e.to_string()), ("pixel_mm", "--pixel-mm -0.5: must be finite and > 0".to_string()));
    assert_eq!(BssrdfJob { pixels: 0, ..b.clone() }.validate().unwrap_err().field, "pixels");
    assert_eq!(BssrdfJob { crop: Some(66), ..b.clone() }.validate().unwrap_err().field, "crop");
    let Job::Fit(f) = jobs().swap_remove(3) else { unreachable!() };
    let e = FitJob { bounds: Some("0.1:2".parse().unwrap()), ..f }.validate().unwrap_err();
    assert_eq!((e.field, e.to_string().contains("1 entries for 2 free")), ("bounds", true), "{e}");
    // The command line refuses the same value with the same words, before any work.
    let tmp = tempfile::tempdir().unwrap();
    let recipe = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-09.toml");
    let o = lucent_in(
        tmp.path(),
        &["bssrdf", "--recipe", recipe.to_str().unwrap(), "--pixel-mm=-0.5", "--paths", "10", "--out", "o"],
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("--pixel-mm -0.5: must be finite and > 0"), "{e}");
    assert!(!tmp.path().join("o").exists(), "a refused command wrote its output folder");
}

#[test]
fn old_flag_spellings_still_parse() {
    use clap::Parser;
    use lucent::cli::{camera::EnvCommand, Cli, Command};
    let recipe = ["--recipe", "r.toml", "--out", "o"];
    for flag in ["--wavelength", "--wavelength-nm"] {
        let args: Vec<String> = ["bssrdf", flag, "600"].iter().chain(&recipe).map(|s| s.to_string()).collect();
        let Ok(Job::Bssrdf(j)) = parse_job(&args) else { panic!("{args:?}") };
        assert_eq!(j.wavelength_nm, 600.0, "{flag}");
        let args: Vec<String> = ["fit", "--measured", "m.exr:45/0", "--free", "weight_percent", flag, "610"]
            .iter()
            .chain(&recipe)
            .map(|s| s.to_string())
            .collect();
        let Ok(Job::Fit(j)) = parse_job(&args) else { panic!("{args:?}") };
        assert_eq!(j.wavelength_nm, 610.0, "{flag}");
        let cli = Cli::try_parse_from(["lucent", "optics", "r.toml", flag, "500"]).unwrap();
        let Command::Optics(a) = cli.command else { panic!() };
        assert_eq!(a.wavelength, Some(500.0), "{flag}");
    }
    for flag in ["--out", "--out-dir", "--output"] {
        let cli =
            Cli::try_parse_from(["lucent", "env", "brackets", "in.hdr", "--exposures", "1,4", flag, "b"]).unwrap();
        let Command::Env(EnvCommand::Brackets(a)) = cli.command else { panic!() };
        assert_eq!(a.out_dir, PathBuf::from("b"), "{flag}");
    }
}

#[test]
fn nonsense_project_values_are_named_before_any_stage_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let project = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bad/project/nonsense_values.toml");
    let o = lucent_in(tmp.path(), &["run", project.to_str().unwrap(), "--out", "o"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    for needle in
        ["nonsense_values.toml", "[bssrdf] pixel_mm: must be finite and > 0, got -0.5", "[compare] data_range"]
    {
        assert!(e.contains(needle), "{needle:?} missing from: {e}");
    }
    assert!(!e.contains("unexpected argument") && !e.contains("stage"), "{e}");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "a stage ran or a folder was made");
    // A value that is not one of its type is refused as the file is read:
    // its line, its key and why.
    let project = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bad/project/backwards_wavelengths.toml");
    let o = lucent_in(tmp.path(), &["run", project.to_str().unwrap(), "--out", "o"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    for needle in ["backwards_wavelengths.toml: line 7", "[optics] wavelengths", "\"780:380:10\"", "end is below start"]
    {
        assert!(e.contains(needle), "{needle:?} missing from: {e}");
    }
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0, "a stage ran or a folder was made");
}

#[test]
fn exit_codes_say_who_is_at_fault() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let help = lucent_in(d, &["--help"]);
    let h = String::from_utf8_lossy(&help.stdout);
    assert!(h.contains(lucent::fault::EXIT_CODES), "{h}");
    // User input: a file that is not there.
    let o = lucent_in(d, &["optics", "missing.toml", "--out", "o"]);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stderr));
    // Usage: a flag no command has.
    let o = lucent_in(d, &["optics", "--no-such-flag"]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    // Environment: Slurm is asked for but sbatch is not on PATH.
    let recipe = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-09.toml");
    let project = d.join("p.toml");
    std::fs::write(
        &project,
        format!(
            "[project]\nname = \"p\"\n[bssrdf]\npixels = 9\npaths = 200\nphase = \"hg\"\n[executor]\nkind = \"slurm\"\nshards = 2\n\
             [[sample]]\nname = \"s\"\nrecipe = {:?}\n",
            recipe.display().to_string()
        ),
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["run", project.to_str().unwrap(), "--out", "o", "--until", "bssrdf"])
        .current_dir(d)
        .env("PATH", d.join("no-bin"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{e}");
    assert!(e.contains("stage bssrdf failed (environment)") && e.contains("sbatch"), "{e}");
}

/// The names a stage's job takes from a closed set (`[calibration] model`,
/// `[[colour]] method`) are read by the library type's own parser when the
/// project loads: any spelling the flag takes works, a wrong one is named
/// with its key, its line and the valid names (exit 1), before any stage.
#[test]
fn project_choices_are_the_jobs_types_and_a_wrong_name_is_refused_at_load() {
    use lucent::pipeline::project::Project;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("chart.exr"), b"not read at load").unwrap();
    let text = |model: &str, method: &str| {
        format!(
            "[project]\nname = \"p\"\n[calibration]\nimages = \"photos/*.jpg\"\nboard = \"9x6\"\nsquare_mm = 25.0\n\
             model = \"{model}\"\n[[colour]]\ncamera = \"phone\"\nimage = \"chart.exr\"\nmethod = \"{method}\"\n"
        )
    };
    std::fs::write(d.join("ok.toml"), text("Kannala-Brandt", "finlayson 2015")).unwrap();
    let p = Project::load(&d.join("ok.toml")).unwrap_or_else(|e| panic!("{e}"));
    let c = p.file.calibration.as_ref().unwrap();
    assert_eq!(c.model, Some(lucent_calib::model::DistortionModel::Fisheye));
    assert_eq!(p.file.colour[0].method, Some(lucent_colour::ccm::CcmMethod::Finlayson2015));
    let job = lucent::pipeline::project::calibrate_job(c, p.path.clone());
    assert_eq!(parse_job(&job.to_args()).unwrap(), Job::Calibrate(job), "the job's line parses back");
    for (file, model, method, says) in [
        ("model.toml", "fisheye2", "Cheung 2004", ["model", "fisheye2", "pinhole-k3, rational, fisheye"]),
        ("method.toml", "rational", "Cheung 2005", ["method", "Cheung 2005", "Finlayson 2015"]),
    ] {
        std::fs::write(d.join(file), text(model, method)).unwrap();
        let e = Project::load(&d.join(file)).unwrap_err().to_string();
        assert!(e.contains(file) && says.iter().all(|s| e.contains(s)), "{e}");
        let o = lucent_in(d, &["run", file, "--out", "o"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains(says[1]) && !err.contains("stage"), "{err}");
        assert!(!d.join("o").exists(), "a project refused at load made its output folder");
    }
}

/// A stage's job that fails validation is refused with the project key,
/// whichever section it comes from, and the stage command's own flag name
/// never reaches the user.
#[test]
fn every_section_that_becomes_a_job_is_checked_with_its_key() {
    use lucent::pipeline::project::{Project, ProjectFile};
    let recipe = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-09.toml");
    let base =
        format!("[project]\nname = \"p\"\n[[sample]]\nname = \"s\"\nrecipe = {:?}\n", recipe.display().to_string());
    for (section, key) in [
        ("[bssrdf]\npaths = 10\nthreshold = 1.5\n", "[bssrdf] threshold"),
        ("[bssrdf]\npaths = 0\n", "[bssrdf] paths"),
        ("[fit]\nfree = [\"weight_percent\"]\nrel_error = 2.0\n", "[fit] rel_error"),
        ("[compare]\ndata_range = -1.0\n", "[compare] data_range"),
        ("[calibration]\nimages = \"x/*.jpg\"\nboard = \"9x6\"\nsquare_mm = -2.0\n", "[calibration] square_mm"),
    ] {
        let file: ProjectFile =
            toml::from_str(&format!("{base}{section}")).unwrap_or_else(|e| panic!("{section}: {e}"));
        let e = Project::build(file, std::path::Path::new("p.toml")).unwrap_err().to_string();
        assert!(e.starts_with("p.toml: ") && e.contains(key), "{key}: {e}");
        assert!(!e.contains("--"), "the stage's flag reached the user: {e}");
    }
}

#[test]
fn an_interrupted_child_is_classed_interrupted() {
    use lucent::fault::Fault;
    assert_eq!(Fault::from_exit_code(130), Some(Fault::Interrupted));
    assert_eq!(Fault::Interrupted.exit_code(), 130);
    assert!(lucent::fault::EXIT_CODES.contains("130  interrupted"));
}

/// `[bssrdf] phase` and `[fit] objective` (and the scene's `[material]
/// phase`) are the library's closed sets, read by their own parser: any
/// spelling the flags take loads, a wrong word is refused at load with its
/// key, its line and the valid names.
#[test]
fn phase_and_objective_are_typed_in_projects_and_scenes() {
    use lucent::pipeline::project::Project;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let text = |phase: &str, objective: &str| {
        format!(
            "[project]\nname = \"p\"\n[bssrdf]\nphase = \"{phase}\"\npaths = 10\n[fit]\nfree = [\"weight_percent\"]\n\
             objective = \"{objective}\"\n"
        )
    };
    std::fs::write(d.join("ok.toml"), text("HG", "MSRE")).unwrap();
    let p = Project::load(&d.join("ok.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(p.file.bssrdf.as_ref().unwrap().phase, Some(lucent::optics::PhaseModel::Hg));
    assert_eq!(p.file.fit.as_ref().unwrap().objective, Some(lucent::fit::Objective::Msre));
    for (file, phase, objective, says) in [
        ("phase.toml", "rayleigh", "sum", ["phase", "rayleigh", "mie, hg", "line 4"]),
        ("objective.toml", "mie", "chi2", ["objective", "chi2", "sum, msre", "line 8"]),
    ] {
        std::fs::write(d.join(file), text(phase, objective)).unwrap();
        let e = Project::load(&d.join(file)).unwrap_err().to_string();
        assert!(e.contains(file) && says.iter().all(|s| e.contains(s)), "{e}");
    }
    let scene = std::fs::read_to_string(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/render/demo.toml"))
        .unwrap()
        .replace("phase = \"mie\"", "phase = \"rayleigh\"");
    assert!(scene.contains("rayleigh"), "the demo scene names its phase function");
    std::fs::write(d.join("scene.toml"), scene).unwrap();
    let o = lucent_in(d, &["render", "scene.toml", "--out", "r"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("scene.toml") && e.contains("rayleigh") && e.contains("mie, hg"), "{e}");
    assert!(!d.join("r").exists());
}

/// `lucent job run JOB.json` runs a job as its command does: the same
/// files, byte for byte; a job file with a misspelt field, a value out of
/// range or the `{out}` placeholder is refused, naming the file.
#[test]
fn job_run_runs_a_json_job_as_its_command_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let recipe = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-09.toml");
    let job = Job::Optics(OpticsJob::new(vec![recipe.clone()], "450:650:100".parse().unwrap(), p("by-job")));
    std::fs::write(d.join("job.json"), serde_json::to_string_pretty(&job).unwrap()).unwrap();
    let o = lucent_in(d, &["job", "run", "job.json"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let r = recipe.display().to_string();
    let o = lucent_in(d, &["optics", &r, "--wavelengths", "450:650:100", "--out", "by-command"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let files = |sub: &str| {
        let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(d.join(sub))
            .unwrap()
            .map(|e| e.unwrap())
            .filter(|e| e.file_type().unwrap().is_file())
            .map(|e| (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap()))
            .collect();
        v.sort();
        v
    };
    let (a, b) = (files("by-job"), files("by-command"));
    assert!(!a.is_empty());
    assert_eq!(a.iter().map(|f| &f.0).collect::<Vec<_>>(), b.iter().map(|f| &f.0).collect::<Vec<_>>());
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        // The summary records the output folder it was written to; everything else is identical.
        if !name.ends_with(".json") {
            assert!(x == y, "{name} differs between `job run` and the command");
        }
    }
    let refused = |text: &str, expect: &str| {
        std::fs::write(d.join("bad.json"), text).unwrap();
        let o = lucent_in(d, &["job", "run", "bad.json"]);
        let e = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains("bad.json") && e.contains(expect), "{expect}: {e}");
    };
    let text = serde_json::to_string(&job).unwrap();
    refused(&text.replace("\"wavelengths\"", "\"wavelength\""), "wavelength");
    refused(&text.replace("450:650:100", "650:450:100"), "\"650:450:100\"");
    refused(&text.replace("by-job", "{out}/optics"), "{out}");
    refused("{\"optics\": ", "not a job");
}

/// The stages of `lucent run` run in its own process: with the binary
/// removed from the disk after it started (no second `lucent` can be
/// started from it), a stage still runs, its output in its log.txt and not
/// on the terminal, which shows the usual status lines.
#[cfg(unix)]
#[test]
fn stages_run_in_process_without_the_binary_on_disk() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let exe = d.join("lucent-copy");
    std::fs::copy(env!("CARGO_BIN_EXE_lucent"), &exe).unwrap();
    let recipe = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-09.toml");
    std::fs::write(
        d.join("p.toml"),
        format!(
            "[project]\nname = \"p\"\n[optics]\nwavelengths = \"450:650:100\"\n[[sample]]\nname = \"s\"\nrecipe = {:?}\n",
            recipe.display().to_string()
        ),
    )
    .unwrap();
    let child = Command::new(&exe)
        .args(["run", "p.toml", "--out", "o", "--until", "optics"])
        .current_dir(d)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::fs::remove_file(&exe).unwrap();
    let o = child.wait_with_output().unwrap();
    let (out, err) = (String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success(), "{out}\n{err}");
    assert!(out.contains("[1/12] optics     ran 1 task"), "{out}");
    assert!(err.contains("[1/12] optics …"), "{err}");
    let log = std::fs::read_to_string(d.join("o/optics/log.txt")).unwrap();
    assert!(log.starts_with("$ lucent optics "), "{log}");
    assert!(log.contains("μs [1/m]"), "the command's table goes to the log: {log}");
    assert!(!out.contains("μs [1/m]") && !err.contains("μs [1/m]"), "the command's output leaked: {out}\n{err}");
    assert!(d.join("o/optics/manifest.json").is_file());
}

/// Every structured job value is a type that reads its text in one place:
/// its canonical text reads and writes back unchanged (also through
/// serde), another spelling of it is written canonically, and a wrong
/// text is refused with a message naming that text.
#[test]
fn each_job_value_type_round_trips_through_its_text() {
    use lucent::bssrdf::{Configuration, Configurations};
    use lucent::fit::{FreeSpec, SearchBounds};
    use lucent_calib::board::BoardSize;
    use lucent_colour::WavelengthGrid;
    use std::fmt::Display;
    use std::str::FromStr;

    fn check<T>(what: &str, canonical: &[&str], other: &[(&str, &str)], wrong: &[&str])
    where
        T: FromStr + Display + std::fmt::Debug + PartialEq + serde::Serialize + serde::de::DeserializeOwned,
        T::Err: Display,
    {
        for text in canonical {
            let v: T = text.parse().unwrap_or_else(|e| panic!("{what} {text:?}: {e}"));
            assert_eq!(v.to_string(), *text, "{what}");
            let json = serde_json::to_string(&v).unwrap();
            assert_eq!(json, format!("{text:?}"), "{what}: serialised as its text");
            assert_eq!(serde_json::from_str::<T>(&json).unwrap(), v, "{what}");
        }
        for (text, written) in other {
            let v: T = text.parse().unwrap_or_else(|e| panic!("{what} {text:?}: {e}"));
            assert_eq!(v.to_string(), *written, "{what} {text:?}");
        }
        for text in wrong {
            let e = text.parse::<T>().map(|v| format!("{v:?}")).unwrap_err().to_string();
            assert!(e.contains(&format!("{text:?}")), "{what} {text:?}: the message does not name it: {e}");
            let e = serde_json::from_str::<T>(&format!("{text:?}")).unwrap_err().to_string();
            assert!(e.contains(&format!("{text:?}")), "{what} {text:?} (serde): the message does not name it: {e}");
        }
    }
    check::<WavelengthGrid>(
        "wavelengths",
        &["380:780:10", "400:700:5", "450:650:100", "550", "632.8"],
        &[("400.0:700:10", "400:700:10"), (" 550 ", "550")],
        &["780:380:10", "400:700", "nm"],
    );
    check::<Configuration>(
        "config",
        &["45/0", "0/45", "12.5/30"],
        &[(" 45 /0", "45/0")],
        &["45-0", "45/95", "45/0,0/45"],
    );
    check::<Configurations>("configs", &["45/0", "45/0,0/45"], &[("45/0, 0/45", "45/0,0/45")], &["x/0", "45/95"]);
    let e = "45/0,0/45,45/0".parse::<Configurations>().unwrap_err().to_string();
    assert!(e.contains("\"45/0\" is given twice"), "{e}");
    check::<ChartCorners>(
        "corners",
        &["10,20,300,20,300,200,10,200", "10.5,-2,300,20,300,200,10,200"],
        &[("10, 20,300,20 ,300,200,10,200.0", "10,20,300,20,300,200,10,200")],
        &["1,2,3", "1,2,3,4,5,6,7,x", "1,2,3,4,5,6,7,inf"],
    );
    check::<ImageSize>("size", &["640x480", "64x48"], &[("640X480", "640x480")], &["0x12", "640", "40000x2", "-1x2"]);
    check::<BoardSize>("board", &["9x6", "3x3"], &[("9X6", "9x6"), ("9×6", "9x6")], &["9", "2x6", "9x600"]);
    check::<MeasuredSlice>(
        "measured",
        &["m.exr:45/0", "dir/m.exr", "m.exr:45/10/0/190"],
        &[("m.exr:45.0/0", "m.exr:45/0")],
        &["m.exr:45/x", "m.exr:45/0/1", "m.exr:95/0"],
    );
    check::<FreeSpec>(
        "free",
        &["weight_percent", "diameter_um@1", "real_part_n@2"],
        &[(" weight_percent ", "weight_percent")],
        &["weight", "weight_percent@0", "diameter_um@x"],
    );
    check::<SearchBounds>(
        "bounds",
        &["0.1:2,0.1:1", "1.3:1.6"],
        &[("0.10:2", "0.1:2")],
        &["0.1-2", "0.1:x", "0.1:inf"],
    );
    check::<SampleCorner>("sample_corner", &["2,1", "0,0"], &[("2.0, 1", "2,1")], &["2", "-1,2", "1.5,2"]);
    check::<SampleSizeMm>(
        "sample_size_mm",
        &["100,60,6.35", "149.1,104.5,6.35"],
        &[],
        &["100,60", "0,60,6", "60x40x6"],
    );
}

/// A job's JSON (what the stage key and a shard's run identity hash) is the
/// text its typed fields held as strings before they were types: each
/// canonical job reads and writes back byte for byte, and its identity is
/// pinned (SHA-256 of the same JSON with `out` emptied and `quiet` false,
/// as the jobs of string fields hashed it).
#[test]
fn a_canonical_jobs_json_is_unchanged_by_its_typed_fields() {
    let texts = [
        (
            r#"{"optics":{"recipes":["/r/a.toml"],"wavelengths":"380:780:10","out":"{out}","weight_percent":null}}"#,
            "0dfffa5a24728d0d72da1c4aa61e22097020439e6bc7aae798920892512bf9c3",
        ),
        (
            r#"{"bssrdf":{"recipe":"/r/a.toml","wavelength_nm":550.0,"configs":"45/0,0/45","pixels":259,"pixel_mm":0.1029,"seed":1,"quiet":true,"out":"{out}/s","weight_percent":null,"crop":null,"paths":200000,"rel_error":null,"time_s":null,"phase":null}}"#,
            "7499edc8977ad560a96c675487cfec2f2926c28ec1f9c01c9e35a830c414443b",
        ),
        (
            r#"{"fit":{"recipe":"/r/a.toml","measured":["/r/m.exr:45/0","/r/n.exr:0/45"],"measured_pixel_mm":0.1,"weight_percent":null,"free":["weight_percent","diameter_um@1"],"wavelength_nm":550.0,"seed":1,"quiet":true,"objective":"sum","rel_error":0.005,"paths":null,"measured_rel_sd":0.05,"bounds":"0.1:2,0.5:5","threshold":0.01,"out":"{out}/s"}}"#,
            "7d3afe0d204beff9b5c322a1c68a05d0b0f3f87b2f2b767cab5d3dc37c403136",
        ),
        (
            r#"{"calibrate":{"images":["/r/photos/*.jpg"],"board":"9x6","square_mm":25.0,"out":"{out}/camera.json","model":"pinhole-k3"}}"#,
            "b2fac14d77727c6cb57342d1cb91714699451a527f82ea5f856929ab9c8f93a4",
        ),
        (
            r#"{"pose":{"camera":"/r/camera.json","image":"/r/pose.jpg","board":"9x6","square_mm":25.0,"out":"{out}/scene.json","sample":["2,1","100,60,6.35"]}}"#,
            "fa6c9fb34106c2a991e58d43491cd11b7bc2473df5c32385f89130a3f488da75",
        ),
        (
            r#"{"env-scale":{"scene":"/r/s.toml","photo":"/r/empty.exr","spp":16,"per_channel":false,"mask":null,"size":"320x240","seed":1,"out":"{out}/s"}}"#,
            "b24e54114d1f396d33e66cdf129995fdd97ddc0084bcdc3c7ca67cc8189304b3",
        ),
        (
            r#"{"render":{"scene":"/r/s.toml","spp":16,"quiet":true,"time_s":null,"size":"320x240","seed":1,"uncertainty":false,"out":"{out}/s"}}"#,
            "4dbcf8ceb8aa8458ff630598c83bbf68786abc3817ec88ad9b43502366110a00",
        ),
    ];
    for (text, identity) in texts {
        let job: Job = serde_json::from_str(text).unwrap_or_else(|e| panic!("{text}: {e}"));
        assert_eq!(serde_json::to_string(&job).unwrap(), text);
        assert_eq!(job.identity_sha256(), identity, "{text}");
        job.validate().unwrap_or_else(|e| panic!("{text}: {e}"));
        let back = parse_job(&job.to_args()).unwrap_or_else(|e| panic!("{text}: {e}"));
        assert_eq!(serde_json::to_string(&back).unwrap(), text, "through its command line");
    }
}
/// The compare job holds every flag of `lucent compare`; the ones a stage
/// of `lucent run` leaves at their defaults are not written, so its
/// job.json (and the stage's key, its hash) is what it was before the job
/// held them.
#[test]
fn a_compare_jobs_json_leaves_out_the_flags_at_their_defaults() {
    let job = CompareJob {
        photo: "p.exr".into(),
        render: vec!["r.exr".into()],
        out: "o".into(),
        mask: None,
        mask_object: None,
        mask_board: None,
        photo_variance: None,
        photo_repeat: None,
        scene: None,
        data_range: 1.0,
        luminance: Default::default(),
        exposure: None,
        refine: None,
        twin_names: None,
        band: vec![],
    };
    let text = serde_json::to_string(&Job::Compare(job.clone())).unwrap();
    assert_eq!(
        text,
        r#"{"compare":{"photo":"p.exr","render":["r.exr"],"out":"o","mask":null,"mask_object":null,"photo_variance":null,"data_range":1.0,"twin_names":null,"band":[]}}"#
    );
    let set = CompareJob {
        luminance: lucent::compare::Luminance::Rec709,
        refine: Some(lucent_calib::ecc::Motion::Homography),
        ..job
    };
    let text = serde_json::to_string(&Job::Compare(set.clone())).unwrap();
    assert!(text.contains(r#""luminance":"rec709""#) && text.contains(r#""refine":"homography""#), "{text}");
    assert_eq!(serde_json::from_str::<Job>(&text).unwrap(), Job::Compare(set.clone()));
    let args = set.to_args();
    let at = |flag: &str| args.iter().position(|a| a == flag).map(|i| args[i + 1].as_str());
    assert_eq!(
        (at("--luminance"), at("--refine"), at("--refine-motion")),
        (Some("rec709"), Some("ecc"), Some("homography"))
    );
}

/// The render job holds every flag of `lucent render`; the ones a stage of
/// `lucent run` leaves at their defaults are not written, so its job.json
/// (and the stage's key) is what it was before the job held them, and
/// those set go through its command line and its JSON.
#[test]
fn a_render_jobs_json_leaves_out_the_flags_at_their_defaults() {
    let job = RenderJob { scene: "s.toml".into(), out: "o".into(), ..Default::default() };
    let text = serde_json::to_string(&Job::Render(job.clone())).unwrap();
    assert_eq!(
        text,
        r#"{"render":{"scene":"s.toml","spp":null,"quiet":false,"time_s":null,"size":null,"seed":null,"uncertainty":false,"out":"o"}}"#
    );
    let set = RenderJob {
        exposure: 1.5,
        target_rel_error: Some(0.1),
        sampling: Some(lucent::scene::SamplingKey::ObjectWeighted),
        dispersion: Some(lucent::job::render::DispersionKey::SharedDirections),
        similarity_g: Some(0.0),
        split_entry: true,
        uncertainty: true,
        uncertainty_spp: Some(4),
        uncertainty_renders: true,
        threads: Some(2),
        ..job
    };
    let text = serde_json::to_string(&Job::Render(set.clone())).unwrap();
    assert!(text.contains(r#""sampling":"object-weighted""#) && text.contains(r#""dispersion":"shared-directions""#));
    assert_eq!(serde_json::from_str::<Job>(&text).unwrap(), Job::Render(set.clone()));
    let back = parse_job(&set.to_args()).unwrap_or_else(|e| panic!("lucent {}: {e}", set.to_args().join(" ")));
    assert_eq!(back, Job::Render(set.clone()), "through its command line");
    let sharded = RenderJob {
        scene: "s.toml".into(),
        out: "o".into(),
        shard: Some(lucent::job::shard::ShardSpec { k: 1, n: 4 }),
        spp: Some(8),
        ..Default::default()
    };
    assert_eq!(parse_job(&sharded.to_args()).unwrap(), Job::Render(sharded.clone()));
    assert_eq!(
        Job::Render(sharded.clone()).identity_sha256(),
        Job::Render(RenderJob { shard: None, threads: Some(3), ..sharded }).identity_sha256(),
        "a shard and the thread count are not the run's identity"
    );
}

/// A 48 × 36 view of a 10 × 8 board of 20 mm squares under a constant sky
/// (`sky` its RGB), `spp` samples per pixel.
fn board_scene(sky: [f64; 3], spp: u32) -> String {
    format!(
        "[camera]\nwidth = 48\nheight = 36\nposition_m = [0.0, -0.25, 0.30]\nlook_at_m = [0.0, 0.0, 0.0]\n\
         vertical_fov_deg = 34.0\n\n[board]\norigin_m = [-0.10, -0.08, 0.0]\nsquare_mm = 20.0\ncolumns = 10\n\
         rows = 8\neven = [0.05, 0.05, 0.05]\nodd = [0.8, 0.7, 0.6]\nmargin_mm = 40.0\n\n[environment]\n\
         constant = {sky:?}\n\n[render]\nspp = {spp}\nseed = 3\n"
    )
}

/// Every stage runs in the library: `Job::run` of a render job renders into
/// its output folder (marked as lucent's) and of an env-scale job fits the
/// sky's scale to that render, in this process, each with its typed run
/// and the summary its command prints.
#[test]
fn render_and_env_scale_jobs_run_in_process() {
    use lucent::job::run::JobRun;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("photo.toml"), board_scene([2.0, 2.0, 2.0], 8)).unwrap();
    std::fs::write(d.join("twin.toml"), board_scene([1.0, 1.0, 1.0], 8)).unwrap();
    let ctx = Context { quiet: true };
    let render =
        Job::Render(RenderJob { scene: d.join("photo.toml"), quiet: true, out: d.join("photo"), ..Default::default() });
    let done = render.run(&ctx).unwrap_or_else(|e| panic!("{e}"));
    let JobRun::Render(r) = &done else { panic!("a render job's run is a render's") };
    assert!(r.interrupted.is_none() && done.finished().is_ok());
    assert!(done.summary().iter().any(|l| l.starts_with("8 spp in ")), "{:?}", done.summary());
    assert!(d.join("photo/render.exr").is_file() && d.join("photo").join(lucent::io::OUTPUT_MARK).is_file());
    let fit = Job::EnvScale(EnvScaleJob {
        scene: d.join("twin.toml"),
        photo: d.join("photo/render.exr"),
        spp: Some(8),
        per_channel: false,
        mask: None,
        size: None,
        seed: Some(5),
        out: d.join("env"),
        quiet: true,
        threads: Some(1),
    });
    let done = fit.run(&ctx).unwrap_or_else(|e| panic!("{e}"));
    let JobRun::EnvScale(e) = &done else { panic!("an env-scale job's run is an env-scale's") };
    // The photo is the same board under a sky twice as bright (both renders noisy).
    assert!((e.report.fit.scale - 2.0).abs() < 0.1, "k = {}", e.report.fit.scale);
    assert!(e.files.toml.is_file() && e.files.exr.is_file() && e.files.json.is_file());
    assert!(done.summary()[0].starts_with("environment scale k = "), "{:?}", done.summary());
    // A bad job fails before any work and leaves no folder behind.
    let Job::EnvScale(good) = &fit else { unreachable!() };
    let missing = Job::EnvScale(EnvScaleJob { photo: d.join("missing.exr"), out: d.join("env2"), ..good.clone() });
    let e = missing.run(&ctx).err().expect("a missing photo fails");
    assert_eq!(e.fault(), lucent::fault::Fault::Input, "{e}");
    assert!(!d.join("env2").exists(), "the failed job's empty folder is removed");
}

/// `lucent job run` of a job that fails says what its command says, with
/// the same exit code, and leaves what its command leaves.
#[test]
fn job_run_of_a_bad_job_fails_as_its_command_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("twin.toml"), board_scene([1.0, 1.0, 1.0], 1)).unwrap();
    let cases: [(Job, &[&str]); 3] = [
        // User input (exit 1): the photo is not there.
        (
            Job::EnvScale(EnvScaleJob {
                scene: p("twin.toml"),
                photo: p("missing.exr"),
                spp: Some(1),
                per_channel: false,
                mask: None,
                size: None,
                seed: None,
                out: p("out"),
                quiet: true,
                threads: None,
            }),
            &["missing.exr"],
        ),
        // User input: the scene is not there.
        (
            Job::Render(RenderJob { scene: p("nowhere.toml"), spp: Some(1), out: p("out"), ..Default::default() }),
            &["nowhere.toml"],
        ),
        // User input: the output folder holds the user's files.
        (
            Job::Render(RenderJob { scene: p("twin.toml"), spp: Some(1), out: p("mine"), ..Default::default() }),
            &["mine", "lucent did not write"],
        ),
    ];
    std::fs::create_dir(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/thesis.tex"), "mine").unwrap();
    for (job, needles) in cases {
        std::fs::write(d.join("job.json"), serde_json::to_string(&job).unwrap()).unwrap();
        let by_job = lucent_in(d, &["job", "run", "job.json"]);
        let args = job.to_args();
        let by_command = lucent_in(d, &args.iter().map(String::as_str).collect::<Vec<_>>());
        let err = String::from_utf8_lossy(&by_job.stderr);
        assert_eq!(by_job.status.code(), Some(1), "{err}");
        assert_eq!(by_job.status.code(), by_command.status.code(), "{err}");
        assert_eq!(err, String::from_utf8_lossy(&by_command.stderr), "lucent {}", args.join(" "));
        assert!(needles.iter().all(|n| err.contains(n)), "{needles:?}: {err}");
        assert!(!d.join("out").exists(), "lucent {}: a folder was left behind", args.join(" "));
        assert_eq!(std::fs::read_dir(d.join("mine")).unwrap().count(), 1, "the user's folder is untouched");
    }
}

/// `lucent job run` of a render stopped by Ctrl-C ends as the command does:
/// the summary of the samples finished, an error saying so, exit code 130,
/// and the output folder kept (labelled, marked as lucent's).
#[cfg(unix)]
#[test]
fn job_run_of_an_interrupted_render_keeps_what_it_finished() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("twin.toml"), board_scene([1.0, 1.0, 1.0], 1)).unwrap();
    let out = d.join("out");
    let job = Job::Render(RenderJob {
        scene: d.join("twin.toml"),
        spp: Some(1 << 20),
        out: out.clone(),
        ..Default::default()
    });
    std::fs::write(d.join("job.json"), serde_json::to_string(&job).unwrap()).unwrap();
    let job_file = d.join("job.json").display().to_string();
    let (status, err) = crate::common::interrupt_n_after(&["job", "run", &job_file], "rendering", 1);
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("error: interrupted (Ctrl-C or SIGTERM): ") && err.contains("render.* hold the"), "{err}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("render.json")).unwrap()).unwrap();
    assert_eq!(report["interrupted"], true, "{report}");
    assert!(out.join(lucent::io::OUTPUT_MARK).is_file(), "the kept folder is lucent's");
}

/// The files under `dir` (relative name → bytes), the output mark left out.
fn files_under(dir: &std::path::Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut out = std::collections::BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display())) {
            let path = e.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else if path.file_name() != Some(std::ffi::OsStr::new(lucent::io::OUTPUT_MARK)) {
                out.insert(path.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&path).unwrap());
            }
        }
    }
    out
}

/// `lucent job run` of a `surface fit`, `env merge` or `env orient` job
/// writes what its command writes, byte for byte (`fit.json` but for its
/// wall time in seconds), and prints the same summary (the surface fit's
/// but for its time).
#[test]
fn job_run_of_surface_and_env_jobs_writes_what_their_commands_write() {
    use lucent::imageio::{write_exr, RgbImage};
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = |o: &std::process::Output, what: &str| {
        assert!(o.status.success(), "{what}: {}", String::from_utf8_lossy(&o.stderr));
    };
    // Linear brackets of a 2:1 radiance field (exposures 1/4, 1, 4, clipped
    // at 1) and 8-bit ones of it through the sRGB curve.
    let (w, h) = (64, 32);
    let radiance: Vec<f32> = (0..w * h * 3)
        .map(|k| {
            let (x, y, c) = ((k / 3) % w, (k / 3) / w, k % 3);
            0.02 * (5.0 * x as f32 / w as f32).exp() * (0.6 + 0.4 * (7.0 * y as f32 / h as f32 + c as f32).sin())
        })
        .collect();
    for (name, t) in [("l1.exr", 0.25f32), ("l2.exr", 1.0), ("l3.exr", 4.0)] {
        let img = RgbImage::new(w, h, radiance.iter().map(|v| (v * t).min(1.0)).collect()).unwrap();
        write_exr(&d.join(name), &img).unwrap();
    }
    write_exr(&d.join("map.exr"), &RgbImage::new(w, h, radiance).unwrap()).unwrap();
    ok(&lucent_in(d, &["env", "brackets", "map.exr", "--exposures", "1/4,1,4,16", "--out", "b8"]), "env brackets");
    // A panorama of a level 9x6 board (as tests/env_orient.rs makes one).
    write_exr(&d.join("grey.exr"), &RgbImage::new(512, 256, vec![0.3; 512 * 256 * 3]).unwrap()).unwrap();
    let paste = [
        "env",
        "paste",
        "grey.exr",
        "--chessboard",
        "9x6",
        "--yaw",
        "27",
        "--pitch=-90",
        "--fov",
        "70",
        "--width",
        "2048",
        "--out",
        "pano.exr",
    ];
    ok(&lucent_in(d, &paste), "env paste");
    let heightmap = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/surface/tr_0p0084.x3p");
    let jobs = [
        Job::SurfaceFit(SurfaceFitJob { fit_tilt: true, ..SurfaceFitJob::new(heightmap, p("{out}/surface")) }),
        Job::EnvMerge(EnvMergeJob {
            exposures: Some("1/4,1,4".parse().unwrap()),
            saturation: 0.95,
            ..EnvMergeJob::new(vec![p("l1.exr"), p("l2.exr"), p("l3.exr")], p("{out}/linear.exr"))
        }),
        Job::EnvMerge(EnvMergeJob {
            exposures: Some("1/4,1,4,16".parse().unwrap()),
            ..EnvMergeJob::new((1..=4).map(|k| p(&format!("b8/bracket_{k}.png"))).collect(), p("{out}/eight.exr"))
        }),
        Job::EnvOrient(EnvOrientJob::given_yaw(p("map.exr"), -37.5, p("{out}/turned.exr"))),
        Job::EnvOrient(EnvOrientJob {
            yaw: None,
            board_view: Some("0,-90,100".parse().unwrap()),
            board: Some("9x6".parse().unwrap()),
            square_mm: Some(30.0),
            view_size: "1000x1000".parse().unwrap(),
            ..EnvOrientJob::given_yaw(p("pano.exr"), 0.0, p("{out}/pano_oriented.exr"))
        }),
    ];
    for (k, job) in jobs.iter().enumerate() {
        let (by_job, by_command) = (format!("by-job/{k}"), format!("by-command/{k}"));
        let file = d.join(format!("job-{k}.json"));
        std::fs::write(&file, serde_json::to_string_pretty(&job.with_out(&p(&by_job)).unwrap()).unwrap()).unwrap();
        let o = lucent_in(d, &["job", "run", file.to_str().unwrap()]);
        ok(&o, &format!("lucent job run {}", file.display()));
        let args = job.with_out(&p(&by_command)).unwrap().to_args();
        let c = lucent_in(d, &args.iter().map(String::as_str).collect::<Vec<_>>());
        ok(&c, &format!("lucent {}", args.join(" ")));
        let (a, b) = (files_under(&d.join(&by_job)), files_under(&d.join(&by_command)));
        assert!(a.len() >= 2, "{k}: {:?}", a.keys());
        assert_eq!(a.keys().collect::<Vec<_>>(), b.keys().collect::<Vec<_>>(), "{k}: the same files");
        for ((name, x), (_, y)) in a.iter().zip(&b) {
            if name.ends_with("fit.json") {
                let without_time = |bytes: &[u8]| {
                    let mut v: serde_json::Value = serde_json::from_slice(bytes).unwrap();
                    v.as_object_mut().unwrap().remove("seconds").expect("fit.json has its wall time");
                    v
                };
                assert_eq!(without_time(x), without_time(y), "{k}: {}", name.display());
            } else {
                assert!(x == y, "{k}: {} differs between `job run` and the command", name.display());
            }
        }
        let printed = |o: &std::process::Output| {
            let text = String::from_utf8_lossy(&o.stdout).replace(&by_job, &by_command);
            let lines: Vec<String> = text.lines().map(String::from).collect();
            // The surface fit's last line starts with its wall time.
            if matches!(job, Job::SurfaceFit(_)) {
                lines[..lines.len() - 1].to_vec()
            } else {
                lines
            }
        };
        assert_eq!(printed(&o), printed(&c), "{k}: the same summary");
    }
    // The orientation from the board: the yaw the paste implies (−117°, tests/env_orient.rs).
    let orientation: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("by-job/4/pano_oriented.json")).unwrap()).unwrap();
    let yaw = orientation["source_yaw_deg"].as_f64().unwrap();
    assert!((yaw + 117.0).abs() < 0.05, "{orientation}");
}

/// tests/bad/job/: job files of the surface, env and report jobs that are
/// refused as the file is read, each naming the file and what is wrong
/// (exit 1, nothing written).
#[test]
fn bad_job_files_are_refused_naming_the_file() {
    let bad = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/bad/job");
    let cases = [
        ("env_merge_exposures.json", &["not a job of lucent", "\"-4\" is not a positive number or fraction"][..]),
        ("env_merge_count.json", &["--exposures 1,4,16: 3 values for 2 brackets"][..]),
        ("env_orient_yaw_and_view.json", &["--board-view 0,-90,100: give --yaw or --board-view, not both"][..]),
        ("env_orient_unknown_field.json", &["unknown field `yaw_deg`"][..]),
        ("surface_fit_window.json", &["--window 4: must be an odd number of pixels from 3 to 201"][..]),
        ("report_into_stage.json", &["would be written into the render stage's folder", "nothing was written"][..]),
        ("report_unknown_stage.json", &["not a job of lucent", "unknown variant `rendering`"][..]),
        (
            "bssrdf_roughness.json",
            &["not a job of lucent", "roughness \"tr:9\": α = 9 must be a number in [0, 4]", "measured:FIT.json"][..],
        ),
    ];
    let listed: Vec<String> = std::fs::read_dir(&bad)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".json"))
        .collect();
    assert_eq!(listed.len(), cases.len(), "every file of tests/bad/job has its case: {listed:?}");
    let dir = tempfile::tempdir().unwrap();
    for (name, needles) in cases {
        let o = lucent_in(dir.path(), &["job", "run", bad.join(name).to_str().unwrap()]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{name}: {e}");
        assert!(e.contains(name) && needles.iter().all(|n| e.contains(n)), "{name}: {needles:?}: {e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{name}: something was written");
    }
}
