//! `lucent raw clipped`: which pixels of a RAW photo carry a valid value. A
//! photosite at the white (saturation) level records only a lower bound of
//! its light, and demosaicing spreads that into its neighbours (the
//! Malvar–He–Cutler kernel is 5 × 5), so a photo pixel is invalid when any
//! photosite within `dilate` pixels of it (default 2, the kernel's radius)
//! is at or above `level` × white. Writes a PNG of the decoded photo's size
//! and orientation: white = valid, black = clipped — the `--mask` of
//! `lucent compare` and `lucent env fit-scale`.

use crate::imageio::{self, RgbImage};
use anyhow::{bail, Context, Result};
use clap::Args;
use lucent_calib::raw::{self, RawData};
use lucent_calib::RgbBuffer;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct ClippedArgs {
    /// The RAW photo.
    pub input: PathBuf,
    /// Output mask (.png): white = valid, black = clipped.
    #[arg(long)]
    pub out: PathBuf,
    /// Clipped at or above this fraction of the white level.
    #[arg(long, default_value_t = 0.999)]
    pub level: f32,
    /// Also mark pixels within this many pixels of a clipped photosite (demosaicing spreads it; at most 100).
    #[arg(long, default_value_t = 2, value_parser = super::count_in::<0, 100>)]
    pub dilate: usize,
    /// The mask of the photo binned K × K (`lucent colour apply --bin K`): a binned pixel is valid
    /// when all its K × K pixels are.
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = super::count_in::<1, 64>)]
    pub bin: usize,
}

/// Runs `lucent raw clipped`.
pub fn run(a: ClippedArgs) -> Result<()> {
    if !(a.level > 0.0 && a.level <= 1.0) {
        bail!("--level {}: must lie in (0, 1] (a fraction of the white level)", a.level);
    }
    if imageio::extension(&a.out) != "png" {
        bail!("{}: the mask must be a .png file", a.out.display());
    }
    let frame = raw::read_raw(&a.input, None)?;
    let (w, h, clipped): (usize, usize, Vec<bool>) = match &frame.data {
        RawData::Bayer(m) => (m.width, m.height, m.data.iter().map(|&v| v >= a.level).collect()),
        RawData::Rgb(b) => {
            (b.width, b.height, b.data.chunks_exact(3).map(|p| p.iter().any(|&v| v >= a.level)).collect())
        }
    };
    let d = a.dilate as isize;
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
    let oriented = raw::orient(&RgbBuffer { width: w, height: h, data: valid }, frame.meta.orientation);
    let mut img = RgbImage::new(oriented.width, oriented.height, oriented.data)?;
    if a.bin > 1 {
        // Valid only where every pixel of the square is: the mean is then 1.
        img = img.binned(a.bin).with_context(|| format!("--bin {}: {}", a.bin, a.input.display()))?;
        for v in &mut img.data {
            *v = if *v >= 1.0 { 1.0 } else { 0.0 };
        }
    }
    imageio::write_png(&a.out, &img).with_context(|| format!("{}", a.out.display()))?;
    println!(
        "{}: {} of {} pixels ({:.2} %) clipped or within {} px of a clipped photosite; mask {}{}",
        a.input.display(),
        bad,
        w * h,
        100.0 * bad as f64 / (w * h) as f64,
        a.dilate,
        a.out.display(),
        if a.bin > 1 {
            format!(" (binned {0} × {0}: {1} × {2})", a.bin, img.width, img.height)
        } else {
            String::new()
        }
    );
    Ok(())
}
