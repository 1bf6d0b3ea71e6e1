//! Helpers the commands share: flag checks (`--size`, `--time-s`,
//! `--threads`, `--board`/`--square-mm`) and the wording of a time. This
//! module imports no command module, so the commands that use it
//! (render, bssrdf, camera, groups, shard, synth, …) do not import each
//! other for them.

use anyhow::{anyhow, bail, Result};
use lucent_calib::scene::BoardSpec;

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
