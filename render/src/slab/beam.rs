//! The incident light: a beam ([`Beam`]: Gaussian by the full width at half
//! maximum of its cross section, or a measured irradiance map [`BeamMap`])
//! and what it lays on the surface z = 0 for one incidence direction
//! ([`Footprint`]: the sampler of entry points (x, y) [m] and the
//! irradiance per unit incident flux [1/m²], which integrates to 1).

use super::error::{check, SlabError};
use crate::rng::Rng;
use std::f64::consts::PI;

/// Incident irradiance on the surface, normalised to unit flux: the closed
/// set of beams. Where a beam lands depends on the incidence direction, so
/// its sampling and evaluation go through [`Beam::footprint`].
#[derive(Debug, Clone)]
pub enum Beam {
    /// Gaussian beam; `fwhm_m` is the full width at half maximum of its cross
    /// section perpendicular to the beam (the footprint on the surface is
    /// longer by 1/cos θ_i in the plane of incidence).
    Gaussian { fwhm_m: f64 },
    /// A measured map of irradiance on the surface.
    Map(BeamMap),
}

/// σ of a Gaussian of full width at half maximum `fwhm`: FWHM = 2√(2 ln 2) σ
/// ≈ 2.3548 σ. The one place this conversion is written.
pub fn fwhm_to_sigma(fwhm: f64) -> f64 {
    fwhm / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt())
}

impl Beam {
    pub fn gaussian(fwhm_m: f64) -> Result<Self, SlabError> {
        check("beam_fwhm_m", fwhm_m, fwhm_m > 0.0, "must be > 0")?;
        Ok(Beam::Gaussian { fwhm_m })
    }

    /// The irradiance this beam lays on the surface when it arrives from
    /// (θ_i, φ_i) (degrees): the sampler and the density the simulator and
    /// the plots share.
    pub fn footprint(&self, theta_i_deg: f64, phi_i_deg: f64) -> Footprint<'_> {
        match self {
            Beam::Gaussian { fwhm_m } => {
                let (sin_phi, cos_phi) = phi_i_deg.to_radians().sin_cos();
                Footprint::Gaussian {
                    sigma_m: fwhm_to_sigma(*fwhm_m),
                    cos_theta_i: theta_i_deg.to_radians().cos(),
                    cos_phi,
                    sin_phi,
                }
            }
            Beam::Map(map) => Footprint::Map(map),
        }
    }

    /// Whether the irradiance is unchanged by the mirror y → −y for light
    /// arriving from azimuth `phi_i_deg` (a Gaussian arriving in the x–z
    /// plane; a map whose rows read the same from both ends).
    pub fn mirror_symmetric(&self, phi_i_deg: f64) -> bool {
        match self {
            Beam::Gaussian { .. } => (phi_i_deg.to_radians().sin()).abs() < 1e-12,
            Beam::Map(map) => (0..map.height / 2).all(|r| {
                let a = &map.values[r * map.width..(r + 1) * map.width];
                let b = &map.values[(map.height - 1 - r) * map.width..(map.height - r) * map.width];
                a == b
            }),
        }
    }
}

/// A beam's irradiance on the surface z = 0 for one incidence direction,
/// normalised to unit flux ([`Beam::footprint`]).
#[derive(Debug, Clone, Copy)]
pub enum Footprint<'a> {
    /// A Gaussian of standard deviation σ across the beam; on the surface
    /// σ/cos θ_i along the plane of incidence (azimuth φ_i), σ across it.
    Gaussian {
        sigma_m: f64,
        cos_theta_i: f64,
        cos_phi: f64,
        sin_phi: f64,
    },
    Map(&'a BeamMap),
}

impl Footprint<'_> {
    /// A point (x, y) \[m\] drawn with density [`irradiance`](Self::irradiance)
    /// from two uniform numbers (Gaussian: Box–Muller in the beam's cross
    /// section, stretched onto the surface) or three (map: a pixel by its
    /// CDF, then uniform inside it).
    #[inline]
    pub fn sample(&self, rng: &mut Rng) -> (f64, f64) {
        match self {
            Footprint::Gaussian { sigma_m, cos_theta_i, cos_phi, sin_phi } => {
                let r = sigma_m * (-2.0 * (1.0 - rng.next_f64()).ln()).sqrt();
                let (sin_a, cos_a) = crate::phase::sin_cos_turns(rng.next_f64());
                let (u, v) = (r * cos_a / cos_theta_i, r * sin_a);
                (u * cos_phi - v * sin_phi, u * sin_phi + v * cos_phi)
            }
            Footprint::Map(map) => map.sample(rng.next_f64(), rng.next_f64(), rng.next_f64()),
        }
    }

    /// Irradiance per unit incident flux at (x, y) [1/m²]; integrates to 1
    /// over the plane.
    pub fn irradiance(&self, x: f64, y: f64) -> f64 {
        match self {
            Footprint::Gaussian { sigma_m, cos_theta_i, cos_phi, sin_phi } => {
                // Coordinates along and across the plane of incidence.
                let u = x * cos_phi + y * sin_phi;
                let v = -x * sin_phi + y * cos_phi;
                let su = sigma_m / cos_theta_i;
                (-0.5 * ((u / su).powi(2) + (v / sigma_m).powi(2))).exp() / (2.0 * PI * su * sigma_m)
            }
            Footprint::Map(map) => {
                let c = (x / map.pixel_m + 0.5 * map.width as f64).floor();
                let r = (0.5 * map.height as f64 - y / map.pixel_m).floor();
                if c >= 0.0 && r >= 0.0 && (c as usize) < map.width && (r as usize) < map.height {
                    let total: f64 = map.values.iter().sum();
                    map.values[r as usize * map.width + c as usize] / (total * map.pixel_m * map.pixel_m)
                } else {
                    0.0
                }
            }
        }
    }
}

/// Irradiance map on the surface: `width` × `height` pixels of side
/// `pixel_m`, row-major from +y (top) down, centred at the origin.
#[derive(Debug, Clone)]
pub struct BeamMap {
    pub width: usize,
    pub height: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
    cdf: Vec<f64>,
}

impl BeamMap {
    /// Validates the map: finite, non-negative, not all zero.
    pub fn new(width: usize, height: usize, pixel_m: f64, values: Vec<f64>) -> Result<Self, SlabError> {
        check("beam_map_pixel_m", pixel_m, pixel_m > 0.0, "must be > 0")?;
        if width == 0 || height == 0 || values.len() != width * height {
            return Err(SlabError::BeamMapSize { values: values.len(), width, height });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(SlabError::BeamMapNotFinite { column: i % width, row: i / width });
        }
        if let Some(i) = values.iter().position(|v| *v < 0.0) {
            return Err(SlabError::BeamMapNegative { column: i % width, row: i / width });
        }
        let mut cdf = Vec::with_capacity(values.len());
        let mut acc = 0.0;
        for v in &values {
            acc += v;
            cdf.push(acc);
        }
        if acc <= 0.0 {
            return Err(SlabError::BeamMapAllZero);
        }
        for c in &mut cdf {
            *c /= acc;
        }
        Ok(Self { width, height, pixel_m, values, cdf })
    }

    fn sample(&self, u: f64, v: f64, w: f64) -> (f64, f64) {
        let i = self.cdf.partition_point(|c| *c <= u).min(self.cdf.len() - 1);
        let (col, row) = (i % self.width, i / self.width);
        let x = (col as f64 + v - 0.5 * self.width as f64) * self.pixel_m;
        let y = (0.5 * self.height as f64 - row as f64 - w) * self.pixel_m;
        (x, y)
    }
}
