//! Synthetic captures with a known truth (docs/method.md#pipeline): what a camera with a
//! known colour response and a Bayer sensor would record of a linear image,
//! written as a DNG that lucent's RAW decoding reads like any other.
//!
//! **Colour.** The truth is a 3 × 3 matrix `xyz_d50_to_camera` (CIE XYZ as
//! under D50, the ICC PCS that `lucent colour calibrate` fits against, Y of
//! the perfect white = 1 → linear camera RGB relative to the sensor's white
//! level at exposure 1). An input image in CIE 1931 RGB (white E, what the
//! renderer writes) is first taken to XYZ and adapted E → D50 with Bradford,
//! the exact inverse of `lucent colour apply --to cie-rgb`; an input already
//! in XYZ D50 (the chart of [`chart_image`]) is used as it is. So a
//! ColorChecker chart and a photo captured with the same exposure and then
//! developed with the CCM fitted on that chart come back as the input,
//! up to demosaicing, quantisation and noise.
//!
//! **Sensor.** Camera RGB `c` times `exposure` is the fraction of the full
//! well; the Bayer pattern keeps one channel per photosite. Shot noise is
//! Gaussian with the Poisson variance of the electron count (`full_well_e`
//! electrons at white; the normal approximation is within 1 % in variance for
//! counts above ≈ 10), read noise is Gaussian in digital numbers (DN); the
//! value is offset by the black level, rounded and clipped to
//! [0, white level]. Photosites at the white level are counted as clipped.
//!
//! ```
//! use lucent::imageio::RgbImage;
//! use lucent::synth::{capture_mosaic, InputSpace, Sensor};
//! let grey = RgbImage::new(4, 2, vec![0.18f32; 24]).unwrap();
//! let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let sensor = Sensor { read_noise_dn: 0.0, full_well_e: f64::INFINITY, ..Sensor::default() };
//! let m = lucent::synth::to_camera_matrix(InputSpace::XyzD50, &identity).unwrap();
//! let cap = capture_mosaic(&grey, &m, 0.5, &sensor, 1).unwrap();
//! // 0.18 × 0.5 of the 1024…16383 range above black.
//! assert_eq!(cap.data[0], (1024.0 + 0.09 * (16383.0 - 1024.0) as f64).round() as u16);
//! ```

pub mod dng;

use crate::imageio::RgbImage;
use lucent_colour::adaptation::Cat;
use lucent_colour::data::{colorchecker_2014, ICC_D50_XYZ};
use lucent_colour::spaces::{mat3_inverse, mat3_mul, mat3_vec, RgbSpace};
use lucent_colour::Mat3;
use lucent_render::rng::Rng;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};
use thiserror::Error;

/// What can go wrong making a synthetic capture.
#[derive(Debug, Error)]
pub enum SynthError {
    #[error("{}: {reason}", path.display())]
    Truth { path: PathBuf, reason: String },
    #[error("{what}: {reason}")]
    Invalid { what: String, reason: String },
    #[error(transparent)]
    Colour(#[from] lucent_colour::ColourError),
}

/// The colour space of the image a capture starts from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum InputSpace {
    /// CIE 1931 RGB, white E (the renderer's output).
    CieRgb,
    /// CIE XYZ as under D50 ([`chart_image`]'s output).
    #[strum(to_string = "xyz-d50", serialize = "xyz")]
    XyzD50,
}

impl InputSpace {
    /// Any spelling of a space (case ignored).
    pub fn from_name(name: &str) -> Result<Self, SynthError> {
        name.trim().parse().map_err(|_| SynthError::Invalid {
            what: format!("input space {name:?}"),
            reason: format!("valid: {}", <Self as strum::VariantNames>::VARIANTS.join(", ")),
        })
    }
}

/// `truth_colour.json`: the synthetic camera's colour response.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColourTruth {
    /// Name of the camera (as in the project's `[[colour]] camera`).
    pub camera: String,
    /// Linear camera RGB (fraction of white at exposure 1) = this · XYZ (D50, Y_white = 1).
    pub xyz_d50_to_camera: Mat3,
    /// Free text: where the matrix comes from.
    #[serde(default)]
    pub note: String,
}

impl ColourTruth {
    /// Reads and checks a `truth_colour.json` (finite, invertible matrix).
    pub fn load(path: &Path) -> Result<Self, SynthError> {
        let err = |reason: String| SynthError::Truth { path: path.to_path_buf(), reason };
        let text = crate::io::read_text(path).map_err(|e| err(e.kind().to_string()))?;
        let t: ColourTruth = serde_json::from_str(&text).map_err(|e| err(format!("not a colour truth file: {e}")))?;
        if t.xyz_d50_to_camera.iter().flatten().any(|v| !v.is_finite()) {
            return Err(err("xyz_d50_to_camera has a non-finite entry".into()));
        }
        mat3_inverse(&t.xyz_d50_to_camera).map_err(|e| err(format!("xyz_d50_to_camera: {e}")))?;
        Ok(t)
    }

    /// The CCM that `lucent colour calibrate` should find: camera RGB → XYZ D50.
    pub fn camera_to_xyz_d50(&self) -> Result<Mat3, SynthError> {
        Ok(mat3_inverse(&self.xyz_d50_to_camera)?)
    }
}

/// The matrix from the input space to camera RGB.
pub fn to_camera_matrix(space: InputSpace, xyz_d50_to_camera: &Mat3) -> Result<Mat3, SynthError> {
    Ok(match space {
        InputSpace::XyzD50 => *xyz_d50_to_camera,
        InputSpace::CieRgb => {
            // The inverse of `colour apply --to cie-rgb` (XYZ D50 → Bradford → E → CIE RGB).
            let from_xyz_d50 = RgbSpace::CieRgb.from_xyz_adapted_matrix(ICC_D50_XYZ, Some(Cat::Bradford))?;
            mat3_mul(xyz_d50_to_camera, &mat3_inverse(&from_xyz_d50)?)
        }
    })
}

/// A Bayer sensor.
#[derive(Debug, Clone, PartialEq)]
pub struct Sensor {
    /// Colour (0 R, 1 G, 2 B) at (row & 1, column & 1): `[top-left, top-right, bottom-left, bottom-right]`.
    pub cfa: [u8; 4],
    /// Black level, DN.
    pub black_dn: u16,
    /// White (saturation) level, DN.
    pub white_dn: u16,
    /// Electrons at the white level (shot noise); infinite = no shot noise.
    pub full_well_e: f64,
    /// Read noise, DN (standard deviation).
    pub read_noise_dn: f64,
}

impl Default for Sensor {
    /// RGGB, 14-bit with black 1024, 20 000 e⁻ full well, 2 DN read noise.
    fn default() -> Self {
        Self { cfa: [0, 1, 1, 2], black_dn: 1024, white_dn: 16383, full_well_e: 20_000.0, read_noise_dn: 2.0 }
    }
}

impl Sensor {
    /// The sensor's noise as a DNG NoiseProfile (S, O): variance = S·x + O
    /// of a value x in [0, 1] of the white level — S = 1 / full well (shot
    /// noise, 0 without), O = (read noise² + 1/12 of rounding) / (white −
    /// black)², both in DN before scaling. Exact but for the clipping at 0
    /// and at the white level.
    pub fn noise_profile(&self) -> [f64; 2] {
        let range = f64::from(self.white_dn) - f64::from(self.black_dn);
        let shot = if self.full_well_e.is_finite() { 1.0 / self.full_well_e } else { 0.0 };
        [shot, (self.read_noise_dn.powi(2) + 1.0 / 12.0) / (range * range)]
    }

    fn validate(&self) -> Result<(), SynthError> {
        let bad = |reason: String| Err(SynthError::Invalid { what: "sensor".into(), reason });
        if self.white_dn <= self.black_dn {
            return bad(format!("white level {} must exceed the black level {}", self.white_dn, self.black_dn));
        }
        if self.full_well_e.is_nan()
            || self.full_well_e <= 0.0
            || !(self.read_noise_dn >= 0.0 && self.read_noise_dn.is_finite())
        {
            return bad("full well must be > 0 and read noise finite and ≥ 0".into());
        }
        if self.cfa.iter().any(|&c| c > 2) || !(0..3u8).all(|c| self.cfa.contains(&c)) {
            return bad(format!("CFA {:?} must hold each of 0 (R), 1 (G), 2 (B)", self.cfa));
        }
        Ok(())
    }
}

/// A captured mosaic: one `u16` per photosite, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Capture {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u16>,
    /// Photosites at the white level.
    pub clipped: usize,
}

fn gaussian(rng: &mut Rng) -> f64 {
    let (u, v) = rng.next_f64_pair();
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Captures `img` (in the space `to_camera` starts from) on `sensor` at
/// `exposure` (camera RGB × exposure = fraction of the full well); `seed`
/// makes the noise reproducible.
pub fn capture_mosaic(
    img: &RgbImage,
    to_camera: &Mat3,
    exposure: f64,
    sensor: &Sensor,
    seed: u64,
) -> Result<Capture, SynthError> {
    sensor.validate()?;
    if !(exposure > 0.0 && exposure.is_finite()) {
        return Err(SynthError::Invalid { what: format!("exposure {exposure}"), reason: "must be > 0".into() });
    }
    let (black, white) = (f64::from(sensor.black_dn), f64::from(sensor.white_dn));
    let mut rng = Rng::new(seed, 0x5EED_CA97);
    let mut data = Vec::with_capacity(img.width * img.height);
    let mut clipped = 0;
    for y in 0..img.height {
        for x in 0..img.width {
            let p = img.pixel(x, y);
            let cam = mat3_vec(to_camera, [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]);
            let c = usize::from(sensor.cfa[2 * (y & 1) + (x & 1)]);
            let mut s = (cam[c] * exposure).max(0.0);
            if sensor.full_well_e.is_finite() {
                let e = s * sensor.full_well_e;
                s = (e + e.sqrt() * gaussian(&mut rng)).max(0.0) / sensor.full_well_e;
            }
            let mut dn = black + s * (white - black);
            if sensor.read_noise_dn > 0.0 {
                dn += sensor.read_noise_dn * gaussian(&mut rng);
            }
            let v = dn.round().clamp(0.0, white);
            clipped += usize::from(v >= white);
            data.push(v as u16);
        }
    }
    Ok(Capture { width: img.width, height: img.height, data, clipped })
}

/// A ColorChecker Classic in CIE XYZ (D50, the post-2014 references lucent
/// calibrates against) on a background of `background_y` times the D50
/// white, `width × height` pixels, the patch grid's outer corners at
/// `corners` (TL, TR, BR, BL) — a chart `lucent colour calibrate` samples.
pub fn chart_image(
    width: usize,
    height: usize,
    corners: [[f64; 2]; 4],
    background_y: f64,
) -> Result<RgbImage, SynthError> {
    let patches: Vec<[f64; 3]> = colorchecker_2014().iter().map(|p| p.xyz()).collect();
    let bg = ICC_D50_XYZ.map(|v| (v * background_y) as f32);
    let opts = lucent_colour::chart::SampleOptions::default();
    let data = lucent_colour::chart::draw_chart(width, height, corners, &patches, &opts, bg)?;
    RgbImage::new(width, height, data)
        .map_err(|e| SynthError::Invalid { what: "chart image".into(), reason: e.to_string() })
}

/// White balance multipliers the camera would record for a D50 white
/// (camera RGB of the white, normalised to green): the DNG's AsShotNeutral.
pub fn as_shot_neutral(xyz_d50_to_camera: &Mat3) -> [f64; 3] {
    let c = mat3_vec(xyz_d50_to_camera, ICC_D50_XYZ);
    [c[0] / c[1], 1.0, c[2] / c[1]]
}

/// How well a fitted camera RGB → XYZ (D50) matrix recovers the truth. A
/// CCM fitted on a chart captured at exposure e is the truth divided by e,
/// so the comparison first divides out the least-squares gain.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ColourRecovery {
    /// Least-squares s in recovered ≈ s · truth (1 / the chart's exposure).
    pub gain: f64,
    /// Largest |recovered / s − truth| over the 9 entries, relative to the largest |truth| entry.
    pub max_rel_matrix_error: f64,
    /// ΔE2000 between the truth's and the recovered matrix's (divided by s)
    /// XYZ of the 24 ColorChecker patches, camera RGB as the truth camera
    /// records them, noise free.
    pub de2000_mean: f64,
    pub de2000_max: f64,
}

/// Compares a fitted 3 × 3 CCM (camera RGB → XYZ D50) with the truth.
pub fn colour_recovery(truth: &ColourTruth, recovered: &Mat3) -> Result<ColourRecovery, SynthError> {
    use lucent_colour::difference::delta_e_2000;
    use lucent_colour::spaces::xyz_to_lab;
    let t = truth.camera_to_xyz_d50()?;
    let tf: Vec<f64> = t.iter().flatten().copied().collect();
    let rf: Vec<f64> = recovered.iter().flatten().copied().collect();
    let gain = tf.iter().zip(&rf).map(|(a, b)| a * b).sum::<f64>() / tf.iter().map(|a| a * a).sum::<f64>();
    if !(gain > 0.0 && gain.is_finite()) {
        return Err(SynthError::Invalid {
            what: "recovered colour matrix".into(),
            reason: format!("no positive gain relates it to the truth (gain {gain})"),
        });
    }
    let r = recovered.map(|row| row.map(|v| v / gain));
    let scale = tf.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let max_err = tf.iter().zip(r.iter().flatten()).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    let de: Vec<f64> = colorchecker_2014()
        .iter()
        .map(|p| {
            let cam = mat3_vec(&truth.xyz_d50_to_camera, p.xyz());
            let lab_t = xyz_to_lab(mat3_vec(&t, cam), ICC_D50_XYZ);
            let lab_r = xyz_to_lab(mat3_vec(&r, cam), ICC_D50_XYZ);
            delta_e_2000(lab_t, lab_r)
        })
        .collect();
    Ok(ColourRecovery {
        gain,
        max_rel_matrix_error: max_err / scale,
        de2000_mean: de.iter().sum::<f64>() / de.len() as f64,
        de2000_max: de.iter().fold(0.0, |m: f64, v| m.max(*v)),
    })
}
