//! `lucent raw clipped`: which pixels of a RAW photo carry a valid value,
//! as a PNG mask (white = valid, black = clipped). Argument handling and
//! printing only: the flags become a [`RawClippedJob`], which does the work.

use crate::job::RawClippedJob;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct ClippedArgs {
    /// The RAW photo.
    pub input: PathBuf,
    /// Output mask (.png): white = valid, black = clipped.
    #[arg(long)]
    pub out: PathBuf,
    /// Clipped at or above this fraction of the white level.
    #[arg(long, default_value_t = crate::job::DEFAULT_CLIPPED_LEVEL)]
    pub level: f32,
    /// Also mark pixels within this many pixels of a clipped photosite (demosaicing spreads it; at most 100).
    #[arg(long, default_value_t = crate::job::DEFAULT_DILATE, value_parser = super::common::count_in::<0, 100>)]
    pub dilate: usize,
    /// The mask of the photo binned K × K (`lucent colour apply --bin K`): a binned pixel is valid
    /// when all its K × K pixels are.
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = super::common::count_in::<1, 64>)]
    pub bin: usize,
}

/// Runs `lucent raw clipped`: the job of the flags ([`RawClippedJob::run`]),
/// then its summary on stdout.
pub fn run(a: ClippedArgs) -> Result<()> {
    let done = RawClippedJob::from(&a).run(&crate::job::Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}
