//! All integration tests of this crate in one binary: one link instead of one per file, which
//! keeps `make test` short. Each file stays a module of its own; `every_test_file_is_included`
//! fails when a new file under tests/ is not listed here (cargo's autotests are off).

#[path = "calibration.rs"]
mod calibration;
#[path = "env_orient.rs"]
mod env_orient;
#[path = "fisheye.rs"]
mod fisheye;
#[path = "hdr_merge.rs"]
mod hdr_merge;
#[path = "raw_dng.rs"]
mod raw_dng;
#[path = "raw_dng_phone.rs"]
mod raw_dng_phone;
#[path = "raw_real.rs"]
mod raw_real;

#[test]
fn every_test_file_is_included() {
    let here = include_str!("it.rs");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests");
    for entry in std::fs::read_dir(&dir).expect("tests/ is readable") {
        let name = entry.expect("a directory entry").file_name().to_string_lossy().into_owned();
        if name.ends_with(".rs") && name != "it.rs" {
            let line = format!("#[path = \"{name}\"]");
            assert!(here.contains(&line), "tests/{name} is not included in tests/it.rs, so it would never run");
        }
    }
}
