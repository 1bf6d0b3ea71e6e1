//! Helpers the commands share: flag checks (`--size`, `--time-s`,
//! `--threads`, `--board`/`--square-mm`, a count's range, a wavelength
//! grid), the wording of a time, an optics job's error, and running a
//! command into its output folder ([`writing_into`]). This
//! module imports no command module, so the commands that use it
//! (render, bssrdf, camera, groups, shard, synth, …) do not import each
//! other for them.

use anyhow::{anyhow, bail, Result};
use lucent_calib::scene::BoardSpec;
use lucent_colour::WavelengthGrid;
use std::path::PathBuf;

/// The most worker threads `--threads` starts.
pub use crate::job::MAX_THREADS;

/// `--size WxH` in pixels of a command whose flag is not an
/// [`ImageSize`](crate::job::ImageSize) itself, read as that type reads it.
pub fn parse_size(text: &str) -> Result<(usize, usize)> {
    let size: crate::job::ImageSize = text.parse().map_err(|e| anyhow!("--size {e}"))?;
    Ok((size.width, size.height))
}

/// Checks a wall-time budget in seconds.
pub fn check_time_s(t: f64) -> Result<f64> {
    if !(t > 0.0 && t.is_finite()) {
        bail!("--time-s {t}: must be a positive number of seconds");
    }
    Ok(t)
}

/// Checks `--threads` against [`MAX_THREADS`] (rayon would try to start them all).
pub fn check_threads(threads: Option<usize>) -> Result<()> {
    Ok(crate::job::check_threads(threads)?)
}

pub use crate::text::duration;

/// The chessboard of `--board COLSxROWS` (inner corners) and `--square-mm`.
pub fn board_spec(board: &str, square_mm: f64) -> Result<BoardSpec> {
    BoardSpec::parse(board, square_mm).map_err(|e| anyhow!("--board/--square-mm: {e}"))
}

/// A count flag's value, refused outside `LO ..= HI` (every flag that sets a
/// size or a count states its limit).
pub fn count_in<const LO: usize, const HI: usize>(text: &str) -> Result<usize, String> {
    let n: usize = text.trim().parse().map_err(|_| format!("{text:?} is not a whole number"))?;
    if (LO..=HI).contains(&n) {
        Ok(n)
    } else {
        Err(format!("{n} is outside {LO} … {HI}"))
    }
}

/// Parses "START:END:STEP" or one wavelength "W" (nm) of `--wavelengths`.
pub fn parse_grid(text: &str) -> Result<WavelengthGrid> {
    text.parse().map_err(|e| anyhow!("--wavelengths {e}"))
}

/// An optics job's error for the command: a study stopped by Ctrl-C as the
/// [`crate::fault::Interrupted`] it is (its exit code), others as they are.
pub fn optics_error(e: crate::job::OpticsJobError) -> anyhow::Error {
    match e.into_parts() {
        Ok(e) => e.into(),
        Err(interrupted) => interrupted.into(),
    }
}

/// Rayon's global pool sized to the allocation ([`crate::job::allocated_threads`]),
/// unless `RAYON_NUM_THREADS` says otherwise: a shard on a cluster node
/// uses the CPUs its job was given, not every core of the node.
fn size_threads_to_allocation() {
    if std::env::var_os("RAYON_NUM_THREADS").is_some() {
        return;
    }
    if let Some((n, _)) = crate::job::allocated_threads(|k| std::env::var(k).ok()) {
        // Fails only when the pool already exists; it then keeps its size.
        let _ = rayon::ThreadPoolBuilder::new().num_threads(n).build_global();
    }
}

/// Runs `work`, a command that writes into the output folder
/// `folder` (if it has one), as [`super::run`] runs a command: rayon's pool sized
/// to the allocation (`size_threads_to_allocation`), the folder opened
/// ([`OutputFolder::open`](crate::job::guard::OutputFolder::open): a folder
/// of the user's is refused before any work) and closed
/// ([`close`](crate::job::guard::OutputFolder::close): marked as lucent's
/// when the work succeeds, removed again when it fails and leaves it empty).
pub fn writing_into(folder: Option<PathBuf>, work: impl FnOnce() -> Result<()>) -> Result<()> {
    size_threads_to_allocation();
    let guard = crate::job::guard::OutputFolder::open(folder.as_deref())?;
    let result = work();
    let interrupted =
        result.as_ref().is_err_and(|e| crate::pipeline::fault_of(e.as_ref()) == crate::fault::Fault::Interrupted);
    guard.close(result.is_ok(), interrupted)?;
    result
}
