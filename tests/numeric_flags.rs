//! A property pass over numeric parameters through the real binary: every
//! numeric flag of the commands below gets 0, −1, NaN, +inf, −inf, 1e300 and
//! the largest u64 and f64, one at a time on an otherwise valid, small
//! command line. Each run must end within a time limit (no hang), print no
//! panic, either succeed or say `error:`, and leave nothing in its working
//! folder but its own output folder `out/` (no write outside it, no staging
//! folder left behind).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const VALUES: [&str; 8] = ["0", "-1", "NaN", "inf", "-inf", "1e300", "18446744073709551615", "1.7976931348623157e308"];
/// Far above what any of these small runs needs when the value is refused
/// or bounded.
const LIMIT: Duration = Duration::from_secs(20);

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn write_exr(path: &Path, w: usize, h: usize, value: f32) {
    let plane = vec![value; w * h];
    lucent::exr::write_channels(path, w, h, &[("R", &plane), ("G", &plane), ("B", &plane)]).unwrap();
}

/// The small valid inputs the command lines name.
fn inputs(dir: &Path) {
    let scene = "[camera]\nwidth = 8\nheight = 6\nposition_m = [0.0, -0.14, 0.16]\nlook_at_m = [0.0, 0.0, 0.004]\n\
                 up = [0.0, 0.0, 1.0]\nvertical_fov_deg = 36.0\n\n[object]\nsize_mm = [60.0, 40.0, 6.35]\n\
                 lift_m = 0.001\n\n[material]\nsigma_s_per_m = [1200.0, 1500.0, 1800.0]\n\
                 sigma_a_per_m = [30.0, 15.0, 8.0]\ng = [0.8, 0.8, 0.8]\nn = [1.5, 1.5, 1.5]\nphase = \"hg\"\n\n\
                 [board]\norigin_m = [-0.1, -0.1, 0.0]\nu = [1.0, 0.0, 0.0]\nv = [0.0, 1.0, 0.0]\nsquare_mm = 20.0\n\
                 columns = 10\nrows = 10\neven = [0.8, 0.75, 0.7]\nodd = [0.05, 0.08, 0.12]\n\n[environment]\n\
                 constant = [1.0, 0.9, 0.8]\nprojection = \"infinite\"\n\n[render]\nspp = 1\nseed = 1\n";
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    write_exr(&dir.join("photo.exr"), 8, 6, 0.5);
    write_exr(&dir.join("render.exr"), 8, 6, 0.4);
    write_exr(&dir.join("map.exr"), 16, 8, 1.0);
    let mut csv = String::new();
    for j in 0..24 {
        let row: Vec<String> = (0..24).map(|i| format!("{:e}", 1e-7 * ((i * 7 + j * 3) % 11) as f64)).collect();
        csv += &row.join(",");
        csv += "\n";
    }
    std::fs::write(dir.join("heights.csv"), csv).unwrap();
    std::fs::write(dir.join("slice.csv"), "1,2,1\n2,4,2\n1,2,1\n").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(["bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "3", "--paths"])
        .args(["200", "--quiet", "--out"])
        .arg(dir.join("sim"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// (command line with `{in}` for the inputs folder, numeric flags). The
/// flag under test is appended as `--flag=VALUE` (a value like -1 is then
/// never taken for a flag), replacing a same-named flag of the line.
fn cases() -> Vec<(Vec<&'static str>, Vec<&'static str>)> {
    let bssrdf = vec![
        "bssrdf", "--mu-s", "1000", "--mu-a", "1", "--g", "0.8", "--n", "1.5", "--pixels", "9", "--paths", "50",
        "--time-s", "1", "--quiet", "--out", "out",
    ];
    vec![
        (
            vec!["optics", "{root}/fixtures/samples/IOL1068-09.toml", "--wavelength", "550", "--out", "out"],
            vec!["--wavelength", "--phase-entries", "--uncertainty", "--uncertainty-seed"],
        ),
        (
            vec!["optics", "{root}/fixtures/samples/IOL1068-15.toml", "--wavelength", "550", "--out", "out"],
            vec!["--weight-percent"],
        ),
        (vec!["mie", "--size-parameter", "1", "--relative-index", "1.2"], vec!["--size-parameter"]),
        (
            vec!["mie", "--radius-um", "0.2", "--wavelength-nm", "550", "--particle-index", "1.5"],
            vec!["--radius-um", "--wavelength-nm"],
        ),
        (
            bssrdf,
            vec![
                "--mu-s",
                "--mu-a",
                "--g",
                "--n",
                "--thickness-mm",
                "--theta-i",
                "--phi-i",
                "--theta-o",
                "--phi-o",
                "--beam-fwhm-um",
                "--pixels",
                "--pixel-mm",
                "--crop",
                "--rel-error",
                "--pixel-rel-error",
                "--paths",
                "--time-s",
                "--seed",
                "--lobe-vertices",
                "--similarity-g",
            ],
        ),
        (
            vec![
                "bssrdf",
                "compare",
                "--measured",
                "{in}/slice.csv",
                "--measured-pixel-mm",
                "0.1",
                "--simulated",
                "{in}/sim",
                "--out",
                "out",
            ],
            vec!["--measured-pixel-mm", "--threshold"],
        ),
        (
            vec!["render", "{in}/scene.toml", "--spp", "1", "--time-s", "5", "--quiet", "--out", "out"],
            vec!["--spp", "--time-s", "--seed", "--exposure", "--target-rel-error", "--threads", "--similarity-g"],
        ),
        (
            vec!["compare", "--photo", "{in}/photo.exr", "--render", "{in}/render.exr", "--out", "out"],
            vec!["--data-range", "--exposure"],
        ),
        (
            vec!["env", "fit-scale", "{in}/scene.toml", "--photo", "{in}/photo.exr", "--spp", "1", "--out", "out"],
            vec!["--spp", "--seed", "--threads"],
        ),
        (
            vec!["env", "view", "{in}/map.exr", "--fov", "60", "--size", "8x6", "--out", "out/v.exr"],
            vec!["--yaw", "--pitch", "--fov"],
        ),
        (
            vec![
                "env",
                "merge",
                "{root}/tests/bad/env/bracket_16x8_a.png",
                "{root}/tests/bad/env/bracket_16x8_b.png",
                "--exposures",
                "1,4",
                "--out",
                "out/m.exr",
            ],
            vec!["--saturation", "--noise-floor", "--saturation-code", "--floor-code"],
        ),
        (
            vec!["surface", "fit", "{in}/heights.csv", "--pitch-um", "1", "--out", "out"],
            vec!["--pitch-um", "--pitch-y-um", "--window", "--sigma-px", "--min-weight"],
        ),
        (
            vec!["surface", "synth", "--size", "16x16", "--out", "out/s.x3p"],
            vec![
                "--alpha",
                "--pitch-um",
                "--correlation-px",
                "--amplitude-correlation-px",
                "--seed",
                "--tilt-deg",
                "--tilt-azimuth-deg",
                "--invalid-fraction",
            ],
        ),
        (vec!["synth", "chart", "--size", "64x48", "--out", "out/c.exr"], vec!["--background"]),
    ]
}

struct Outcome {
    line: String,
    problem: Option<String>,
}

fn run_one(args: Vec<String>, work: &Path) -> Outcome {
    let line = args.join(" ");
    let mut child = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(&args)
        .current_dir(work)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stderr, &mut s).ok();
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed() > LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let err = reader.join().unwrap();
    let mut problems = Vec::new();
    match status {
        None => problems.push(format!("still running after {} s", LIMIT.as_secs())),
        Some(s) if !s.success() && !err.contains("error:") => problems.push(format!("{s} without 'error:'")),
        _ => {}
    }
    if err.contains("panicked") || err.contains("RUST_BACKTRACE") {
        problems.push("panic".into());
    }
    let extra: Vec<String> = std::fs::read_dir(work)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "out")
        .collect();
    if !extra.is_empty() {
        problems.push(format!("wrote outside out/: {extra:?}"));
    }
    let problem = (!problems.is_empty()).then(|| format!("{}\n    stderr: {}", problems.join(", "), err.trim()));
    Outcome { line, problem }
}

#[test]
fn every_numeric_flag_survives_extreme_values() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    std::fs::create_dir_all(&input).unwrap();
    inputs(&input);
    let mut lines = Vec::new();
    for (base, flags) in cases() {
        for flag in flags {
            for value in VALUES {
                let mut args: Vec<String> = Vec::new();
                let mut skip = false;
                for a in &base {
                    if skip {
                        skip = false;
                        continue;
                    }
                    if *a == flag {
                        skip = true;
                        continue;
                    }
                    args.push(a.replace("{in}", input.to_str().unwrap()).replace("{root}", root().to_str().unwrap()));
                }
                args.push(format!("{flag}={value}"));
                lines.push(args);
            }
        }
    }
    let total = lines.len();
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let start = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::SeqCst);
                let Some(args) = lines.get(k) else { break };
                let work = tmp.path().join(format!("w{k}"));
                std::fs::create_dir_all(&work).unwrap();
                let o = run_one(args.clone(), &work);
                if let Some(p) = o.problem {
                    failures.lock().unwrap().push(format!("lucent {}: {p}", o.line));
                }
                let _ = std::fs::remove_dir_all(&work);
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    eprintln!("{total} runs in {:.1} s, {} failed", start.elapsed().as_secs_f64(), failures.len());
    assert!(total >= 400, "only {total} runs");
    assert!(failures.is_empty(), "{} of {total} runs:\n{}", failures.len(), failures.join("\n"));
}
