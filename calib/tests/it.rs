//! All integration tests of this crate in one binary: one link instead of one per file, which
//! keeps `make test` short. Each file stays a module of its own; the root crate's
//! `every_test_file_is_included` (tests/it.rs) fails when a new file under tests/ is not listed here (cargo's autotests are off).

#[path = "calibration.rs"]
mod calibration;
#[path = "env_orient.rs"]
mod env_orient;
#[path = "fisheye.rs"]
mod fisheye;
#[path = "hdr_merge.rs"]
mod hdr_merge;
#[path = "noise.rs"]
mod noise;
#[path = "raw_dng.rs"]
mod raw_dng;
#[path = "raw_dng_phone.rs"]
mod raw_dng_phone;
#[path = "raw_real.rs"]
mod raw_real;
