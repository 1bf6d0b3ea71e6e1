//! All integration tests of this crate in one binary: one link instead of one per file, which
//! keeps `make test` short. Each file stays a module of its own; `every_test_file_is_included`
//! fails when a new file under tests/ is not listed here (cargo's autotests are off).

mod common;

#[path = "bad_inputs.rs"]
mod bad_inputs;
#[path = "bssrdf_cli.rs"]
mod bssrdf_cli;
#[path = "camera_cli.rs"]
mod camera_cli;
#[path = "chart_detect.rs"]
mod chart_detect;
#[path = "choices_cli.rs"]
mod choices_cli;
#[path = "cli.rs"]
mod cli;
#[path = "colour_cli.rs"]
mod colour_cli;
#[path = "compare.rs"]
mod compare;
#[path = "env_fit.rs"]
mod env_fit;
#[path = "env_merge.rs"]
mod env_merge;
#[path = "env_orient.rs"]
mod env_orient;
#[path = "fisheye_cli.rs"]
mod fisheye_cli;
#[path = "fit.rs"]
mod fit;
#[path = "formats_doc.rs"]
mod formats_doc;
#[path = "hardening.rs"]
mod hardening;
#[path = "hardening3.rs"]
mod hardening3;
#[path = "jobs.rs"]
mod jobs;
#[path = "mesh.rs"]
mod mesh;
#[path = "mie_reference.rs"]
mod mie_reference;
#[path = "modules.rs"]
mod modules;
#[path = "newcomer.rs"]
mod newcomer;
#[path = "numeric_flags.rs"]
mod numeric_flags;
#[path = "optics_bulk.rs"]
mod optics_bulk;
#[path = "optics_cli.rs"]
mod optics_cli;
#[path = "photo_noise.rs"]
mod photo_noise;
#[path = "pipeline.rs"]
mod pipeline;
#[path = "plots.rs"]
mod plots;
#[path = "render.rs"]
mod render;
#[path = "shard.rs"]
mod shard;
#[path = "slurm.rs"]
mod slurm;
#[path = "surface.rs"]
mod surface;
#[path = "synth.rs"]
mod synth;
#[path = "uncertainty.rs"]
mod uncertainty;

/// Cargo's autotests are off in the three crates with integration tests
/// (root, calib, render): a file under their tests/ runs only if their
/// tests/it.rs includes it.
#[test]
fn every_test_file_is_included() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    for crate_dir in [root.to_path_buf(), root.join("calib"), root.join("render")] {
        let dir = crate_dir.join("tests");
        let listed = std::fs::read_to_string(dir.join("it.rs")).expect("tests/it.rs is readable");
        for entry in std::fs::read_dir(&dir).expect("tests/ is readable") {
            let name = entry.expect("a directory entry").file_name().to_string_lossy().into_owned();
            if name.ends_with(".rs") && name != "it.rs" {
                let line = format!("#[path = \"{name}\"]");
                assert!(
                    listed.contains(&line),
                    "{}/{name} is not included in its it.rs, so it would never run",
                    dir.display()
                );
            }
        }
    }
}
