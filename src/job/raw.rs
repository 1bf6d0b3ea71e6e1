//! The clipping mask of a RAW photo: [`RawClippedJob::run`] marks which
//! pixels carry a valid value. A photosite at the white (saturation) level
//! records only a lower bound of its light, and demosaicing spreads that
//! into its neighbours (the Malvar–He–Cutler kernel is 5 × 5), so a photo
//! pixel is invalid when any photosite within `dilate` pixels of it
//! (default 2, the kernel's radius) is at or above `level` × white. The
//! mask is a PNG of the decoded photo's size and orientation (optionally
//! binned: a binned pixel is valid when all its pixels are): white = valid,
//! black = clipped — the `--mask` of `lucent compare` and `lucent env
//! fit-scale`. `lucent raw clipped` and the pipeline's develop stage run it.

use super::context::Context;
use super::spec::RawClippedJob;
use crate::imageio::{self, ImageIoError, RgbImage};
use lucent_calib::raw::{self, RawData, RawError};
use lucent_calib::RgbBuffer;
use std::path::PathBuf;

/// Why a clipping mask cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum RawClippedError {
    #[error("--level {0}: must lie in (0, 1] (a fraction of the white level)")]
    Level(f32),
    #[error("{}: the mask must be a .png file", .0.display())]
    NotPng(PathBuf),
    #[error(transparent)]
    Raw(#[from] RawError),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error("--bin {bin}: {}: {source}", input.display())]
    Bin { bin: usize, input: PathBuf, source: ImageIoError },
    #[error("{}: {source}", path.display())]
    Write { path: PathBuf, source: ImageIoError },
}

/// What a clipping mask holds.
pub struct RawClippedRun {
    /// Pixels clipped or within `dilate` of a clipped photosite, of `pixels`.
    pub clipped: usize,
    pub pixels: usize,
    /// The mask's size (binned, when the job bins).
    pub size: (usize, usize),
    input: PathBuf,
    out: PathBuf,
    dilate: usize,
    bin: usize,
}

impl RawClippedJob {
    /// Reads the RAW photo and writes its mask.
    pub fn run(&self, _ctx: &Context) -> Result<RawClippedRun, RawClippedError> {
        if !(self.level > 0.0 && self.level <= 1.0) {
            return Err(RawClippedError::Level(self.level));
        }
        if imageio::extension(&self.out) != "png" {
            return Err(RawClippedError::NotPng(self.out.clone()));
        }
        let frame = raw::read_raw(&self.input, None)?;
        let level = self.level;
        let (w, h, clipped): (usize, usize, Vec<bool>) = match &frame.data {
            RawData::Bayer(m) => (m.width, m.height, m.data.iter().map(|&v| v >= level).collect()),
            RawData::Rgb(b) => {
                (b.width, b.height, b.data.chunks_exact(3).map(|p| p.iter().any(|&v| v >= level)).collect())
            }
        };
        let (valid, bad) = dilated_validity(w, h, &clipped, self.dilate);
        let oriented = raw::orient(&RgbBuffer { width: w, height: h, data: valid }, frame.meta.orientation);
        let mut img = RgbImage::new(oriented.width, oriented.height, oriented.data)?;
        if self.bin > 1 {
            // Valid only where every pixel of the square is: the mean is then 1.
            img = img.binned(self.bin).map_err(|source| RawClippedError::Bin {
                bin: self.bin,
                input: self.input.clone(),
                source,
            })?;
            for v in &mut img.data {
                *v = if *v >= 1.0 { 1.0 } else { 0.0 };
            }
        }
        imageio::write_png(&self.out, &img)
            .map_err(|source| RawClippedError::Write { path: self.out.clone(), source })?;
        Ok(RawClippedRun {
            clipped: bad,
            pixels: w * h,
            size: (img.width, img.height),
            input: self.input.clone(),
            out: self.out.clone(),
            dilate: self.dilate,
            bin: self.bin,
        })
    }
}

/// The validity of every pixel of a `w` × `h` photo (1 valid, 0 not; three
/// channels each) whose photosites `clipped` marks, each clipped photosite
/// spoiling the pixels within `dilate` of it; with how many are spoiled.
fn dilated_validity(w: usize, h: usize, clipped: &[bool], dilate: usize) -> (Vec<f32>, usize) {
    let d = dilate as isize;
    let mut valid = vec![1.0f32; 3 * w * h];
    let mut bad = 0usize;
    for y in 0..h as isize {
        for x in 0..w as isize {
            let hit = (-d..=d).any(|dy| {
                (-d..=d).any(|dx| {
                    let (xx, yy) = (x + dx, y + dy);
                    xx >= 0 && yy >= 0 && xx < w as isize && yy < h as isize && clipped[(yy as usize) * w + xx as usize]
                })
            });
            if hit {
                bad += 1;
                let i = 3 * (y as usize * w + x as usize);
                valid[i..i + 3].fill(0.0);
            }
        }
    }
    (valid, bad)
}

impl RawClippedRun {
    /// What `lucent raw clipped` prints: how many pixels are invalid and where the mask went.
    pub fn summary(&self) -> Vec<String> {
        vec![format!(
            "{}: {} of {} pixels ({:.2} %) clipped or within {} px of a clipped photosite; mask {}{}",
            self.input.display(),
            self.clipped,
            self.pixels,
            100.0 * self.clipped as f64 / self.pixels as f64,
            self.dilate,
            self.out.display(),
            if self.bin > 1 {
                format!(" (binned {0} × {0}: {1} × {2})", self.bin, self.size.0, self.size.1)
            } else {
                String::new()
            }
        )]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clipped_photosite_spoils_its_neighbours_within_the_dilation() {
        let mut clipped = vec![false; 25];
        clipped[12] = true; // the centre of 5 × 5
        let (valid, bad) = dilated_validity(5, 5, &clipped, 1);
        assert_eq!(bad, 9);
        assert_eq!(valid[0], 1.0);
        assert_eq!(valid[3 * 6], 0.0);
        assert_eq!(dilated_validity(5, 5, &clipped, 0).1, 1);
    }
}
