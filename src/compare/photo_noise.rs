//! The photo's per-pixel variance, var P of the model RMSE ([`super::noise`]),
//! from its RAW capture: the RAW's noise model (shot + read noise,
//! var = a·x + b per channel; the DNG's NoiseProfile or estimated from the
//! photo, [`lucent_calib::noise`]) carried through development as
//! `lucent colour apply` develops the photo (white balance none,
//! Malvar–He–Cutler demosaicing, orientation, then the colour correction and
//! the target space).
//!
//! **How.** Demosaicing mixes neighbouring photosites and the colour matrix
//! mixes channels, so the developed noise is correlated and its variance is
//! not the model's at one photosite. [`photo_variance`] draws `realisations`
//! independent noise mosaics (Gaussian, the model's variance at each
//! photosite's recorded value), develops each like the photo (all steps up
//! to the colour correction are linear), maps it through the colour
//! correction's Jacobian at the photo's own pixel (central differences;
//! exact for the 3 × 3 methods) and averages the squares: an unbiased
//! estimate of each pixel's variance, per pixel within √(2/K) (K = 16: ±35 %),
//! and of a mean over n pixels far better (what the model RMSE and its
//! noise floor use). Seeded: the same photo gives the same variance image.
//!
//! ```no_run
//! use lucent::compare::photo_noise::photo_variance;
//! let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let (var, file) = photo_variance(std::path::Path::new("photo.dng"), &|rgb| rgb, 16, 1, 1).unwrap();
//! println!("{} variances, noise model {:?}", var.len(), file.noise_model.a);
//! ```

use lucent_calib::noise::{self, NoiseModel};
use lucent_calib::raw::{self, RawOptions};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The sidecar JSON of a photo-variance EXR (`<variance>.noise.json`), which
/// `lucent compare --photo-variance` copies into metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PhotoVarianceFile {
    pub definition: String,
    /// The RAW photo the variance belongs to.
    pub photo: String,
    pub noise_model: NoiseModel,
    /// Where the model is the DNG's NoiseProfile: the estimate from the photo
    /// itself beside it, as a check (it also counts texture as noise).
    #[serde(default)]
    pub estimated_from_image: Option<NoiseModel>,
    /// Noise realisations averaged per pixel, and the seed of the first.
    pub realisations: usize,
    pub seed: u64,
    /// The photo's binning (bin × bin photo pixels per pixel; 1: none).
    #[serde(default = "one")]
    pub bin: usize,
    /// What the variance's units are.
    pub units: String,
}

/// The default of a count that older files lack (a factor of 1: none);
/// also the noise report's ([`super::noise`]).
pub(super) fn one() -> usize {
    1
}

/// Why the photo's variance cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum PhotoNoiseError {
    #[error(transparent)]
    Raw(#[from] raw::RawError),
    #[error("{}: {source}", path.display())]
    Noise { path: PathBuf, source: noise::NoiseError },
    #[error("realisations must be at least 2, got {0}")]
    Realisations(usize),
    #[error("{}: {source}", path.display())]
    Bin { path: PathBuf, source: crate::imageio::ImageIoError },
}

/// The per-pixel variance (interleaved RGB, the developed photo's layout)
/// of the RAW photo at `path` developed with `develop_colour` (camera RGB →
/// output RGB, applied after [`raw::decode_raw`] with default options),
/// binned `bin` × `bin` as [`crate::imageio::RgbImage::binned`] bins the
/// developed photo (1: not binned), and the description of how it was made.
pub fn photo_variance(
    path: &Path,
    develop_colour: &(dyn Fn([f64; 3]) -> [f64; 3] + Sync),
    realisations: usize,
    seed: u64,
    bin: usize,
) -> Result<(Vec<f32>, PhotoVarianceFile), PhotoNoiseError> {
    if realisations < 2 {
        return Err(PhotoNoiseError::Realisations(realisations));
    }
    let opts = RawOptions::default();
    let frame = raw::read_raw(path, opts.white_level)?;
    let model =
        noise::model_of(&frame).map_err(|source| PhotoNoiseError::Noise { path: path.to_path_buf(), source })?;
    let (photo, _) = raw::develop(&frame, &opts)?;
    crate::imageio::check_bin(photo.width, photo.height, bin.max(1))
        .map_err(|source| PhotoNoiseError::Bin { path: path.to_path_buf(), source })?;
    // The colour step's Jacobian at each pixel, columns d out / d camera channel.
    let jac: Vec<[[f64; 3]; 3]> = photo
        .data
        .chunks_exact(3)
        .map(|p| {
            let x = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
            std::array::from_fn(|j| {
                let h = 1e-4 + 1e-3 * x[j].abs();
                let (mut up, mut down) = (x, x);
                up[j] += h;
                down[j] -= h;
                let (fu, fd) = (develop_colour(up), develop_colour(down));
                std::array::from_fn(|i| (fu[i] - fd[i]) / (2.0 * h))
            })
        })
        .collect();
    // Each realisation through the colour Jacobian, binned, then squared:
    // the binned pixel's variance with the demosaicing's correlations.
    let (w, h) = (photo.width, photo.height);
    let mut developed = vec![0f32; photo.data.len()];
    let mut sum = vec![0f64; photo.data.len() / (bin * bin).max(1)];
    for k in 0..realisations {
        let n = noise::developed_noise(&frame, &model, &opts, seed.wrapping_add(k as u64))?;
        for ((o, px), j) in developed.chunks_exact_mut(3).zip(n.data.chunks_exact(3)).zip(&jac) {
            let v = [f64::from(px[0]), f64::from(px[1]), f64::from(px[2])];
            for (i, oi) in o.iter_mut().enumerate() {
                *oi = (0..3).map(|c| j[c][i] * v[c]).sum::<f64>() as f32;
            }
        }
        let binned = if bin > 1 {
            std::borrow::Cow::Owned(
                crate::imageio::bin_interleaved(&developed, w, h, 3, bin)
                    .map_err(|source| PhotoNoiseError::Bin { path: path.to_path_buf(), source })?,
            )
        } else {
            std::borrow::Cow::Borrowed(&developed)
        };
        for (si, o) in sum.iter_mut().zip(binned.iter()) {
            *si += f64::from(*o) * f64::from(*o);
        }
    }
    let estimated_from_image = match model.source {
        noise::NoiseSource::DngNoiseProfile => noise::estimate(&frame.data).ok(),
        noise::NoiseSource::EstimatedFromImage => None,
    };
    let var = sum.iter().map(|s| (s / realisations as f64) as f32).collect();
    let file = PhotoVarianceFile {
        definition: "per-pixel variance of the developed photo: the RAW's noise model (variance = a x + b per \
                     photosite, x its recorded value) drawn as Gaussian noise, developed like the photo \
                     (demosaicing, orientation, colour correction's Jacobian at the photo's pixel), binned as the \
                     photo (bin), squared and averaged over the realisations"
            .into(),
        photo: path.display().to_string(),
        noise_model: model,
        estimated_from_image,
        realisations,
        seed,
        bin: bin.max(1),
        units: "the developed photo's units, squared".into(),
    };
    Ok((var, file))
}

/// The sidecar JSON path of a variance image: `v.exr` → `v.noise.json` (not
/// `v.json`, which is e.g. a render's render.json beside its EXR).
pub fn sidecar(variance: &Path) -> PathBuf {
    variance.with_extension("noise.json")
}
