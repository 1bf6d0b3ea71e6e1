//! Helpers shared by the CLI integration tests: run the `lucent` binary
//! from the repository root and read what it printed.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Runs `lucent ARGS…` in the repository root.
pub fn lucent(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run lucent")
}

pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}
