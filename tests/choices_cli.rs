//! Flags that take one of a fixed set of words (`src/cli/choices.rs`): a bad
//! word is refused by clap with exit status 2 and the list of valid ones, the
//! spellings users typed before (aliases, other case) are still accepted, and
//! `--help` lists the choices.

use crate::common::{lucent, stderr, stdout};

/// Runs `lucent ARGS` with `FLAG nope` appended and checks clap's refusal.
fn refused(args: &[&str], flag: &str, choices: &str) {
    let mut all: Vec<&str> = args.to_vec();
    all.extend_from_slice(&[flag, "nope"]);
    let o = lucent(&all);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{all:?}: {e}");
    assert!(e.contains(&format!("invalid value 'nope' for '{flag}")), "{all:?}: {e}");
    assert!(e.contains(&format!("[possible values: {choices}]")), "{all:?}: {e}");
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn bad_words_get_the_list_of_choices_and_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out = out.to_str().unwrap();
    let calibrate = ["calibrate", "--images", "x", "--board", "9x6", "--square-mm", "10", "--out", out];
    refused(&calibrate, "--detector", "auto, sector-based, classic");
    refused(&calibrate, "--model", "pinhole-k3, rational, fisheye");
    refused(&["raw", "decode", "a.dng", "b.exr"], "--demosaic", "malvar, bilinear");
    refused(&["raw", "decode", "a.dng", "b.exr"], "--white-balance", "none, camera");
    refused(&["undistort", "--camera", "c.json", "a.png", "b.png"], "--to", "pinhole, equirect");
    let compare = ["compare", "--photo", "p.exr", "--render", "r.exr", "--out", out];
    refused(&compare, "--luminance", "cie-rgb, rec709");
    refused(&compare, "--refine", "ecc");
    refused(
        &[&compare[..], &["--refine", "ecc"]].concat(),
        "--refine-motion",
        "translation, euclidean, affine, homography",
    );
    refused(&["env", "merge", "a.jpg", "b.jpg", "--out", "m.exr"], "--method", "debevec, robertson");
    refused(
        &["colour", "calibrate", "--image", "c.exr", "--out", out],
        "--method",
        "\"Cheung 2004\", \"Finlayson 2015\", \"Finlayson 1997\"",
    );
    refused(&["colour", "apply", "--ccm", "c.json", "a.exr", "b.exr"], "--to", "cie-rgb, xyz, srgb");
    refused(
        &["colour", "apply", "--ccm", "c.json", "a.exr", "b.exr"],
        "--adaptation",
        "bradford, von-kries, cat02, none",
    );
    refused(&["surface", "fit", "h.tif", "--out", out], "--height-unit", "m, mm, um, nm");
    refused(&["surface", "synth", "--alpha", "0.1", "--out", "s.x3p"], "--model", "tr, beckmann");
    refused(&["surface", "synth", "--model", "tr", "--alpha", "0.1", "--out", "s.x3p"], "--point-type", "I, L, F, D");
    refused(&["synth", "raw", "a.exr", "b.dng", "--truth", "t.json"], "--space", "cie-rgb, xyz-d50");
    let stages = "optics, surface, bssrdf, fit, calibrate, colour, develop, pose, env-scale, render, compare, report";
    refused(&["run", "p.toml"], "--until", stages);
    refused(&["run", "p.toml"], "--force", &format!("all, {stages}"));
}

#[test]
fn earlier_spellings_still_parse() {
    // Each run gets past the command line (the choice is accepted) and
    // stops at the missing input: exit status 1, not clap's 2.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let out = out.to_str().unwrap();
    let missing = dir.path().join("missing");
    let missing = missing.to_str().unwrap();
    let runs: Vec<Vec<&str>> = vec![
        vec!["calibrate", "--images", missing, "--board", "9x6", "--square-mm", "10", "--out", out, "--detector", "SB"],
        vec!["calibrate", "--images", missing, "--board", "9x6", "--square-mm", "10", "--out", out, "--model", "k3"],
        vec!["colour", "apply", "--ccm", missing, "a.exr", "b.exr", "--adaptation", "von Kries", "--to", "rec709"],
        vec!["colour", "calibrate", "--image", missing, "--out", out, "--method", "finlayson-2015"],
        vec!["surface", "synth", "--model", "GGX", "--alpha", "0.1", "--size", "x", "--point-type", "f", "--out", out],
        vec!["undistort", "--camera", missing, "a.png", "b.exr", "--to", "equirectangular"],
        vec!["run", missing, "--force", "env-scale", "--until", "render"],
    ];
    for args in runs {
        let o = lucent(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(!e.contains("invalid value") && !e.contains("panicked"), "{args:?}: {e}");
    }
}

#[test]
fn help_lists_the_choices() {
    let o = lucent(&["calibrate", "--help"]);
    let h = stdout(&o);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(h.contains("sector-based") && h.contains("classic"), "{h}");
    assert!(h.contains("pinhole-k3") && h.contains("fisheye"), "{h}");
}
