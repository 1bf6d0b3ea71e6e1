//! The `lucent` binary: parses arguments, runs, prints the whole error chain
//! once and exits non-zero on failure.

use lucent::fault::Fault;

fn main() -> std::process::ExitCode {
    // Behave like other Unix tools when the reader goes away (`lucent … | head`):
    // end quietly on SIGPIPE instead of panicking on a failed write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread
    // starts touches no Rust state.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // A full or closed standard output (`lucent … > /dev/full`): `println!`
    // panics on the failed write; say so as an error of the environment
    // (exit 3) instead of printing a panic. Every other panic keeps the default report.
    let default_hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        // Inside a stage of `lucent run` the stage catches the panic and says it.
        if let Some(reason) = message.strip_prefix("failed printing to stdout: ")
            && !lucent::cli::jobs::in_stage()
        {
            // A full device is the machine's fault, not the input's.
            eprintln!("error (environment): cannot write to standard output: {reason}");
            std::process::exit(i32::from(Fault::Environment.exit_code()));
        }
        default_hook(info);
    }));
    // Ctrl-C while a file is being written removes its temporary file.
    lucent::io::remove_temporaries_on_interrupt();
    let cli = lucent::cli::Cli::parse_args();
    // The exit code says who is at fault (`lucent --help` lists them); a
    // panic is a bug: its report, then the internal class's code.
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| lucent::cli::run(cli))) {
        Ok(Ok(())) => std::process::ExitCode::SUCCESS,
        Ok(Err(e)) => {
            let fault = lucent::pipeline::fault_of(e.as_ref());
            match fault {
                Fault::Input | Fault::Interrupted => eprintln!("error: {}", error_chain(&e)),
                _ => eprintln!("error ({fault}): {}", error_chain(&e)),
            }
            std::process::ExitCode::from(fault.exit_code())
        }
        Err(_) => {
            eprintln!("error (internal): lucent panicked (a bug; please report it with the command line)");
            std::process::ExitCode::from(Fault::Internal.exit_code())
        }
    }
}

/// The error and its causes as one line "a: b: c", leaving out a cause whose
/// text the line already holds (a message that prints its source and also
/// returns it from `source()` would otherwise say it twice:
/// "No such file or directory (os error 2): No such file or directory (os error 2)").
fn error_chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if text.is_empty() || line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    // A write that failed inside a staging folder is said at the output's own path.
    lucent::io::user_visible_paths(&line)
}
