//! Ctrl-C as a request to stop a long run early and keep its result.
//!
//! SIGTERM and SIGHUP (a closed terminal or ssh session) count as Ctrl-C. The first Ctrl-C (SIGINT) sets a flag the run polls; the second ends the
//! process (exit status 130) after removing the staging folders and files
//! registered with [`remove_on_abort`], so an aborted run leaves nothing
//! half-made behind. The signal handler itself only updates atomics and
//! writes one byte to a pipe (both async-signal-safe); a helper thread
//! blocked on that pipe says on stderr that the run will stop (first
//! Ctrl-C), or does the removal with ordinary file-system calls and then
//! calls `_exit(130)` (second). A third Ctrl-C, or a second one when the
//! helper could not be started, ends the process at once.
//!
//! The removal runs with the output frozen ([`crate::io::freeze_output`]):
//! a file or commit under way finishes first and no later write can
//! recreate a removed folder, so nothing of the run is left behind.
//! Commands without rounds to finish ([`Interrupt::abort_on_first`], e.g.
//! `calibrate`) clean up and end at the first Ctrl-C.
//!
//! Installs nest: a command that `lucent run` runs in its own process
//! installs its `Interrupt` inside the run's. The inner one keeps the
//! outer's request (a stop asked for before the command started stays
//! asked for) and its abort count (the first Ctrl-C never ends the whole
//! run: the stage under way is stopped and kept as `STAGE.failed/`), and
//! the helper thread says its message on the run's terminal
//! ([`set_console`]), not in the stage's log.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};
use std::sync::Mutex;

/// Ctrl-C (SIGINT) during a long run (`render`, `bssrdf`): the first one asks
/// the run to stop after the pass or round under way, so what is finished is
/// written as a valid, labelled partial result; a second one removes the
/// registered staging paths and ends the process (exit status 130). The
/// previous disposition is restored on drop.
pub struct Interrupt {
    #[cfg(unix)]
    previous: libc::sighandler_t,
    /// SIGTERM (`kill`, a batch system's stop) is handled like SIGINT.
    #[cfg(unix)]
    previous_term: libc::sighandler_t,
    /// SIGHUP (the terminal or ssh session closed) too.
    #[cfg(unix)]
    previous_hup: libc::sighandler_t,
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);
/// The last stop signal received (SIGINT, SIGTERM or SIGHUP), for the message.
static LAST_SIGNAL: AtomicI32 = AtomicI32::new(0);
/// SIGINTs received since [`Interrupt::install`].
static COUNT: AtomicUsize = AtomicUsize::new(0);
/// Write end of the pipe the cleanup thread waits on; -1 if there is none.
static ABORT_PIPE: AtomicI32 = AtomicI32::new(-1);
/// Paths removed on abort, with the id of their [`Registered`] guard.
static REGISTERED: Mutex<Vec<(usize, PathBuf)>> = Mutex::new(Vec::new());
static NEXT_ID: AtomicUsize = AtomicUsize::new(0);
/// The Ctrl-C that aborts: 2 for [`Interrupt::install`], 1 for [`Interrupt::abort_on_first`].
static ABORT_AT: AtomicUsize = AtomicUsize::new(2);
/// How many [`Interrupt`]s are installed (an inner one nests in an outer one).
static DEPTH: AtomicUsize = AtomicUsize::new(0);
/// The descriptor the helper thread writes its messages to; -1: standard error.
static CONSOLE: AtomicI32 = AtomicI32::new(-1);

/// Where the messages about a stop go while standard error is redirected
/// (`lucent run` sends a stage's output to its log): a duplicate of the
/// terminal's standard error, or -1 for standard error itself.
pub fn set_console(fd: i32) {
    CONSOLE.store(fd, Ordering::SeqCst);
}

/// Writes a message line to the console ([`set_console`]).
fn say(message: &str) {
    let fd = CONSOLE.load(Ordering::SeqCst);
    #[cfg(unix)]
    if fd >= 0 {
        let line = format!("{message}\n");
        // SAFETY: write(2) of a buffer we own to a descriptor lucent run keeps open.
        let _ = unsafe { libc::write(fd, line.as_ptr().cast(), line.len()) };
        return;
    }
    let _ = fd;
    eprintln!("{message}");
}

#[cfg(unix)]
extern "C" fn on_sigint(signal: libc::c_int) {
    // Only async-signal-safe work here: atomics, write and _exit.
    LAST_SIGNAL.store(signal, Ordering::SeqCst);
    INTERRUPTED.store(true, Ordering::SeqCst);
    let n = COUNT.fetch_add(1, Ordering::SeqCst) + 1;
    let fd = ABORT_PIPE.load(Ordering::SeqCst);
    // SAFETY: write(2) on a pipe we own is async-signal-safe; the byte (the
    // count) wakes the helper thread.
    let abort_at = ABORT_AT.load(Ordering::SeqCst);
    let told = n <= abort_at && fd >= 0 && unsafe { libc::write(fd, [n as u8].as_ptr().cast(), 1) } == 1;
    if n >= abort_at && !told {
        // SAFETY: _exit is async-signal-safe.
        unsafe { libc::_exit(130) };
    }
}

/// Removes every registered path (a folder with all it holds, or a file).
/// The run may still be writing into a folder while it is removed, so each
/// removal is retried until the path is gone (a few times at most).
fn remove_registered() {
    let paths: Vec<PathBuf> = match REGISTERED.lock() {
        Ok(list) => list.iter().map(|(_, p)| p.clone()).collect(),
        Err(poisoned) => poisoned.into_inner().iter().map(|(_, p)| p.clone()).collect(),
    };
    for p in paths {
        for _ in 0..20 {
            if std::fs::symlink_metadata(&p).is_err() {
                break;
            }
            let _ = if p.is_dir() { std::fs::remove_dir_all(&p) } else { std::fs::remove_file(&p) };
        }
    }
}

/// Starts (once per process) the thread that cleans up and exits on the
/// second Ctrl-C.
#[cfg(unix)]
fn start_cleanup_thread() {
    static STARTED: std::sync::Once = std::sync::Once::new();
    STARTED.call_once(|| {
        let mut fds = [0 as libc::c_int; 2];
        // SAFETY: pipe(2) fills the two descriptors of a new pipe.
        if unsafe { libc::pipe(fds.as_mut_ptr()) } != 0 {
            return;
        }
        let read_fd = fds[0];
        let spawned = std::thread::Builder::new().name("ctrl-c cleanup".into()).spawn(move || {
            let mut byte = 0u8;
            loop {
                // SAFETY: reads one byte from the pipe's read end, owned by this thread.
                let n = unsafe { libc::read(read_fd, (&mut byte as *mut u8).cast(), 1) };
                if n == 0 {
                    return;
                }
                let abort_at = ABORT_AT.load(Ordering::SeqCst);
                if n == 1 && usize::from(byte) >= abort_at {
                    break;
                }
                if n == 1 {
                    let by = match LAST_SIGNAL.load(Ordering::SeqCst) {
                        libc::SIGHUP => "SIGHUP (the terminal closed)",
                        libc::SIGTERM => "SIGTERM",
                        _ => "Ctrl-C",
                    };
                    say(&format!("\n{by}: stopping after the round under way (press Ctrl-C again to abort)"));
                }
            }
            // Held until _exit: no write of the run starts after the removal.
            let _frozen = crate::io::freeze_output();
            remove_registered();
            if ABORT_AT.load(Ordering::SeqCst) >= 2 {
                say("interrupted twice: stopped at once; the unfinished output was removed");
            } else {
                say("\ninterrupted: stopped; the unfinished output was removed");
            }
            // SAFETY: ends the process without running destructors on other threads' data.
            unsafe { libc::_exit(130) };
        });
        if spawned.is_ok() {
            ABORT_PIPE.store(fds[1], Ordering::SeqCst);
        }
    });
}

impl Interrupt {
    /// The first Ctrl-C asks the run to stop (see [`Interrupt::requested`]),
    /// the second aborts.
    pub fn install() -> Self {
        Self::install_aborting_at(2)
    }

    /// Ctrl-C aborts at once: removes the registered paths and ends the
    /// process (exit status 130). For commands with no partial result to keep.
    pub fn abort_on_first() -> Self {
        Self::install_aborting_at(1)
    }

    fn install_aborting_at(abort_at: usize) -> Self {
        // Inside an outer Interrupt (a command `lucent run` runs in its
        // process) the outer's request and abort count stand.
        if DEPTH.fetch_add(1, Ordering::SeqCst) == 0 {
            ABORT_AT.store(abort_at, Ordering::SeqCst);
            INTERRUPTED.store(false, Ordering::SeqCst);
            COUNT.store(0, Ordering::SeqCst);
        }
        #[cfg(unix)]
        {
            start_cleanup_thread();
            let handler = on_sigint as extern "C" fn(libc::c_int) as libc::sighandler_t;
            // SAFETY: installs a handler that only touches atomics, writes to a pipe and calls _exit.
            let previous = unsafe { libc::signal(libc::SIGINT, handler) };
            // SAFETY: the same handler for SIGTERM.
            let previous_term = unsafe { libc::signal(libc::SIGTERM, handler) };
            // SAFETY: the same handler for SIGHUP.
            let previous_hup = unsafe { libc::signal(libc::SIGHUP, handler) };
            Self { previous, previous_term, previous_hup }
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
        DEPTH.fetch_sub(1, Ordering::SeqCst);
        #[cfg(unix)]
        // SAFETY: restores the disposition found by `install`.
        unsafe {
            libc::signal(libc::SIGINT, self.previous);
            libc::signal(libc::SIGTERM, self.previous_term);
            libc::signal(libc::SIGHUP, self.previous_hup);
        }
    }
}

/// A path removed if the run is aborted (second Ctrl-C) while this guard
/// lives; dropping the guard unregisters it (the path itself stays).
#[derive(Debug)]
pub struct Registered(usize);

/// Registers `path` (a staging folder or temporary file of the run under
/// way) for removal on abort. Keep the guard for as long as the path is
/// unfinished output.
pub fn remove_on_abort(path: &Path) -> Registered {
    let id = NEXT_ID.fetch_add(1, Ordering::SeqCst);
    let path = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut list = REGISTERED.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    list.push((id, path));
    Registered(id)
}

/// The guards of a command that writes through a [`crate::io::StagedDir`]
/// into `out`: its staging folder, and `out` itself when this run creates
/// it. Taken before either exists, so an abort the moment they appear still
/// removes them.
pub fn remove_staged_on_abort(out: &Path) -> (Registered, Option<Registered>) {
    (remove_on_abort(&crate::io::StagedDir::staging_path(out)), (!out.exists()).then(|| remove_on_abort(out)))
}

impl Drop for Registered {
    fn drop(&mut self) {
        let mut list = REGISTERED.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        list.retain(|(id, _)| *id != self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn registered_paths_are_removed_and_guards_unregister() {
        let dir = tempfile::tempdir().unwrap();
        let stage = dir.path().join(".out.staging-1");
        std::fs::create_dir_all(stage.join("ti45_to0")).unwrap();
        std::fs::write(stage.join("ti45_to0/bssrdf.exr"), b"x").unwrap();
        let kept = dir.path().join("kept.txt");
        std::fs::write(&kept, b"y").unwrap();
        let guard = remove_on_abort(&stage);
        let unregistered = remove_on_abort(&kept);
        drop(unregistered);
        remove_registered();
        assert!(!stage.exists(), "the registered staging folder must be removed");
        assert!(kept.exists(), "an unregistered path must stay");
        drop(guard);
        assert!(REGISTERED.lock().unwrap().iter().all(|(_, p)| !p.starts_with(dir.path())));
    }
}
