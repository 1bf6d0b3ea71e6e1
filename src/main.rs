//! The `lucent` binary: parses arguments, runs, prints the whole error chain
//! once and exits non-zero on failure.

use clap::Parser;

fn main() -> std::process::ExitCode {
    // Behave like other Unix tools when the reader goes away (`lucent … | head`):
    // end quietly on SIGPIPE instead of panicking on a failed write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread
    // starts touches no Rust state.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = lucent::cli::Cli::parse();
    match lucent::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
