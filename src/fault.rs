//! Who is at fault when a command fails, as image-rs sorts its
//! `ImageError` (a bad parameter or undecodable input, a limit or I/O of
//! the machine, an unsupported case): the **user input** (a flag, a project
//! key, a file the user named), the **environment** (a missing tool, a full
//! or read-only disk, the network, Slurm), or lucent itself (**internal**:
//! a bug). Each class has its exit code, so a script or a cluster knows
//! whether to fix the input, retry elsewhere, or report a bug. A run
//! stopped by Ctrl-C or SIGTERM is nobody's fault and has its own code
//! (130, as shells report a process ended by SIGINT).

use std::error::Error;
use thiserror::Error;

/// The class of a failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// A value, file or key the user gave is wrong.
    Input,
    /// The machine or a service it needs failed (missing tool, disk, network, Slurm).
    Environment,
    /// A bug in lucent.
    Internal,
    /// Stopped by Ctrl-C or SIGTERM (what it finished may be kept, labelled).
    Interrupted,
}

/// The class of the errors of one module (`None`: not one of its), for
/// [`Fault::of_with`].
pub type Classifier = fn(&(dyn Error + 'static)) -> Option<Fault>;

/// The exit codes, as `lucent --help` lists them.
pub const EXIT_CODES: &str = "Exit codes:
  0    success
  1    user input: a flag value, a project key or a file given is wrong (the message names it)
  2    usage: the command line does not parse (unknown flag, missing argument)
  3    environment: a missing tool, a full or read-only disk, the network or Slurm failed; the input may be fine
  4    internal: a bug in lucent (please report it with the command line)
  130  interrupted (Ctrl-C or SIGTERM)";

impl Fault {
    /// The process exit code of the class.
    pub fn exit_code(self) -> u8 {
        match self {
            Fault::Input => 1,
            Fault::Environment => 3,
            Fault::Internal => 4,
            Fault::Interrupted => 130,
        }
    }

    /// The class of a child `lucent`'s exit code (`None` for success, usage
    /// errors count as input).
    pub fn from_exit_code(code: i32) -> Option<Fault> {
        match code {
            0 => None,
            3 => Some(Fault::Environment),
            4 | 101 => Some(Fault::Internal),
            130 => Some(Fault::Interrupted),
            _ => Some(Fault::Input),
        }
    }

    /// How a status line names the class.
    pub fn name(self) -> &'static str {
        match self {
            Fault::Input => "user input",
            Fault::Environment => "environment",
            Fault::Internal => "internal",
            Fault::Interrupted => "interrupted",
        }
    }

    /// The class of an error: the first cause in its chain that says (a
    /// [`Faulted`] or [`Internal`], an I/O error of the machine such as a
    /// full disk or a refused permission), else the user input. Errors of
    /// the modules above this one (the pipeline's, Slurm's) are classed by
    /// [`Fault::of_with`] with their classifiers
    /// (`lucent::pipeline::fault_of`).
    pub fn of(error: &(dyn Error + 'static)) -> Fault {
        Self::of_with(error, &[])
    }

    /// [`Fault::of`], asking `classifiers` too at every cause of the chain
    /// (after [`Faulted`]): each names the class of the errors it knows.
    pub fn of_with(error: &(dyn Error + 'static), classifiers: &[Classifier]) -> Fault {
        let mut cause: Option<&(dyn Error + 'static)> = Some(error);
        while let Some(e) = cause {
            if let Some(f) = e.downcast_ref::<Faulted>() {
                return f.fault;
            }
            if let Some(f) = classifiers.iter().find_map(|c| c(e)) {
                return f;
            }
            if e.is::<Internal>() {
                return Fault::Internal;
            }
            if e.is::<Interrupted>() || matches!(e.downcast_ref(), Some(crate::fit::FitError::Interrupted { .. })) {
                return Fault::Interrupted;
            }
            if let Some(io) = e.downcast_ref::<std::io::Error>()
                && environment_io(io.kind())
            {
                return Fault::Environment;
            }
            cause = e.source();
        }
        Fault::Input
    }
}

impl std::fmt::Display for Fault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// I/O failures of the machine rather than of the path the user named.
fn environment_io(kind: std::io::ErrorKind) -> bool {
    use std::io::ErrorKind as K;
    matches!(
        kind,
        K::PermissionDenied
            | K::StorageFull
            | K::ReadOnlyFilesystem
            | K::QuotaExceeded
            | K::OutOfMemory
            | K::WriteZero
            | K::BrokenPipe
            | K::TimedOut
            | K::ConnectionRefused
            | K::ConnectionReset
            | K::ConnectionAborted
            | K::NetworkUnreachable
            | K::HostUnreachable
            | K::NetworkDown
            | K::ResourceBusy
            | K::StaleNetworkFileHandle
    )
}

/// A failure whose class is known where it happens (e.g. a child `lucent`
/// that exited with a class's code).
#[derive(Debug, Error)]
#[error("{message}")]
pub struct Faulted {
    pub fault: Fault,
    pub message: String,
}

/// A run stopped by Ctrl-C or SIGTERM: the message says what was kept.
#[derive(Debug, Error)]
#[error("interrupted (Ctrl-C or SIGTERM): {0}")]
pub struct Interrupted(pub String);

/// A state lucent's own logic should never reach: a bug.
#[derive(Debug, Error)]
#[error("internal error (a bug in lucent; please report it): {0}")]
pub struct Internal(pub String);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_class_has_its_code_and_is_found_in_the_chain() {
        let user = anyhow::anyhow!("--pixel-mm -1: must be finite and > 0");
        assert_eq!(Fault::of(user.as_ref()), Fault::Input);
        let disk = anyhow::Error::from(std::io::Error::from(std::io::ErrorKind::StorageFull)).context("out/x.exr");
        assert_eq!(Fault::of(disk.as_ref()), Fault::Environment);
        let missing = anyhow::Error::from(std::io::Error::from(std::io::ErrorKind::NotFound)).context("recipe.toml");
        assert_eq!(Fault::of(missing.as_ref()), Fault::Input);
        let bug = anyhow::Error::from(Internal("tile index out of range".into())).context("render");
        assert_eq!(Fault::of(bug.as_ref()), Fault::Internal);
        let stopped = anyhow::Error::from(Interrupted("render.* hold 3 spp".into())).context("render");
        assert_eq!(Fault::of(stopped.as_ref()), Fault::Interrupted);
        let fit = anyhow::Error::from(crate::fit::FitError::Interrupted { evaluations: 2 });
        assert_eq!(Fault::of(fit.as_ref()), Fault::Interrupted);
        let all = [Fault::Input, Fault::Environment, Fault::Internal, Fault::Interrupted];
        assert_eq!(all.map(Fault::exit_code), [1, 3, 4, 130]);
        for f in all {
            assert_eq!(Fault::from_exit_code(i32::from(f.exit_code())), Some(f));
            assert!(EXIT_CODES.contains(&format!("  {:<5}{}", f.exit_code(), f.name())), "{f}");
        }
    }
}
