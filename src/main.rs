//! The `lucent` binary: parses arguments, runs, prints the whole error chain
//! once and exits non-zero on failure.

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = lucent::cli::Cli::parse();
    match lucent::cli::run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
