//! Ctrl-C as a request to stop a long run early and keep its result.

use std::sync::atomic::{AtomicBool, Ordering};

/// Ctrl-C (SIGINT) during a long run (`render`, `bssrdf`): the first one asks
/// the run to stop after the pass or round under way, so what is finished is
/// written as a valid, labelled partial result; a second one ends the process at once
/// (exit status 130). The previous disposition is restored on drop.
pub struct Interrupt {
    #[cfg(unix)]
    previous: libc::sighandler_t,
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

#[cfg(unix)]
extern "C" fn on_sigint(_: libc::c_int) {
    // Only async-signal-safe work here: an atomic swap and _exit.
    if INTERRUPTED.swap(true, Ordering::SeqCst) {
        unsafe { libc::_exit(130) };
    }
}

impl Interrupt {
    pub fn install() -> Self {
        INTERRUPTED.store(false, Ordering::SeqCst);
        #[cfg(unix)]
        {
            let handler = on_sigint as extern "C" fn(libc::c_int) as libc::sighandler_t;
            // SAFETY: installs a handler that only touches an atomic and calls _exit.
            let previous = unsafe { libc::signal(libc::SIGINT, handler) };
            Self { previous }
        }
        #[cfg(not(unix))]
        Self {}
    }
    pub fn flag(&self) -> &'static AtomicBool {
        &INTERRUPTED
    }
    pub fn requested(&self) -> bool {
        INTERRUPTED.load(Ordering::SeqCst)
    }
}

impl Drop for Interrupt {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: restores the disposition found by `install`.
        unsafe {
            libc::signal(libc::SIGINT, self.previous);
        }
    }
}
