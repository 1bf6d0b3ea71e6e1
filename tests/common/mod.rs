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

/// Starts `lucent ARGS…` in the repository root, waits until its stderr
/// shows `ready` (the Ctrl-C handler is in place), lets it work for 1.5 s,
/// sends it SIGINT and returns its exit status and everything it printed
/// on stderr.
pub fn interrupt_after(args: &[&str], ready: &str) -> (std::process::ExitStatus, String) {
    interrupt_n_after(args, ready, 1)
}

/// As [`interrupt_after`], with `count` SIGINTs; each one after the first
/// is sent once stderr shows that the previous one was seen ("Ctrl-C:",
/// printed by the handler's helper thread), so that none is merged into a
/// pending one (two: the second Ctrl-C that aborts the run).
pub fn interrupt_n_after(args: &[&str], ready: &str, count: usize) -> (std::process::ExitStatus, String) {
    signal_n_after(args, ready, count, libc::SIGINT)
}

/// As [`interrupt_n_after`] with another signal (SIGTERM: what a batch
/// system or `kill` sends).
pub fn signal_n_after(
    args: &[&str],
    ready: &str,
    count: usize,
    signal: libc::c_int,
) -> (std::process::ExitStatus, String) {
    use std::io::{BufRead, Read};
    let mut child = Command::new(env!("CARGO_BIN_EXE_lucent"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start lucent");
    let mut err = std::io::BufReader::new(child.stderr.take().expect("piped stderr"));
    let mut text = String::new();
    while !text.contains(ready) {
        assert!(err.read_line(&mut text).expect("read stderr") > 0, "lucent ended before {ready:?}: {text}");
    }
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let pid = i32::try_from(child.id()).expect("a pid");
    for i in 0..count {
        if i > 0 {
            while !text.contains("Ctrl-C:") {
                assert!(
                    err.read_line(&mut text).expect("read stderr") > 0,
                    "lucent ended before Ctrl-C was seen: {text}"
                );
            }
        }
        // SAFETY: sends a signal to our own child process.
        assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
    }
    err.read_to_string(&mut text).expect("read stderr");
    (child.wait().expect("wait for lucent"), text)
}
