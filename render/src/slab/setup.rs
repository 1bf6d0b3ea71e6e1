//! What a simulation is of: the slab ([`Slab`]: thickness [m], medium, top
//! interface), the camera's pixel grid on the surface ([`Sensor`]), the
//! incidence and observation directions ([`Directions`], degrees) and the
//! beam ([`Beam`]), gathered in a [`Setup`]. Coordinates as in the module
//! doc of [`slab`](super), "Geometry and units".

use super::beam::Beam;
use super::error::{check, SlabError};
use crate::interface::Interface;
use crate::medium::Medium;

/// The slab: thickness, medium, top interface (the bottom one is always
/// [`Interface::Smooth`]).
#[derive(Debug, Clone)]
pub struct Slab {
    pub thickness_m: f64,
    pub medium: Medium,
    pub top: Interface,
}

impl Slab {
    pub fn new(thickness_m: f64, medium: Medium) -> Result<Self, SlabError> {
        check("thickness_m", thickness_m, thickness_m > 0.0, "must be > 0")?;
        Ok(Self { thickness_m, medium, top: Interface::Smooth })
    }

    /// The slab with `top` as its top interface.
    pub fn with_top(self, top: Interface) -> Self {
        Self { top, ..self }
    }
}

/// The camera's pixel grid on the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    pub pixels: usize,
    pub pixel_m: f64,
}

impl Sensor {
    pub fn new(pixels: usize, pixel_m: f64) -> Result<Self, SlabError> {
        check("pixels", pixels as f64, (1..=8192).contains(&pixels), "must lie in 1 … 8192")?;
        check("pixel_m", pixel_m, pixel_m > 0.0, "must be > 0")?;
        // A slice wider than a metre is no measurement of a sample (and a
        // pixel of 1e305 m made the coordinates overflow, and paths loop).
        check(
            "pixel_m",
            pixel_m,
            pixel_m * pixels as f64 <= 1.0,
            "the slice (pixels × pixel size) must be at most 1 m wide",
        )?;
        Ok(Self { pixels, pixel_m })
    }

    /// Pixel index of surface point (x, y), if on the sensor.
    #[inline]
    pub(super) fn index(&self, x: f64, y: f64) -> Option<usize> {
        let half = 0.5 * self.pixels as f64;
        // 1/pixel_m is loop-invariant in the simulator's loops (hoisted).
        let inv = 1.0 / self.pixel_m;
        let c = x * inv + half;
        let r = half - y * inv;
        if c >= 0.0 && r >= 0.0 && c < self.pixels as f64 && r < self.pixels as f64 {
            Some(r as usize * self.pixels + c as usize)
        } else {
            None
        }
    }
}

/// Incidence and observation directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Directions {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
}

impl Directions {
    pub fn from_degrees(theta_i_deg: f64, phi_i_deg: f64, theta_o_deg: f64, phi_o_deg: f64) -> Result<Self, SlabError> {
        let polar = |v: f64| (0.0..90.0).contains(&v);
        check("theta_i_deg", theta_i_deg, polar(theta_i_deg), "must lie in [0°, 90°)")?;
        check("theta_o_deg", theta_o_deg, polar(theta_o_deg), "must lie in [0°, 90°)")?;
        check("phi_i_deg", phi_i_deg, true, "must be finite")?;
        check("phi_o_deg", phi_o_deg, true, "must be finite")?;
        Ok(Self { theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg })
    }

    /// The configuration with ω_i and ω_o exchanged.
    pub fn swapped(&self) -> Self {
        Self {
            theta_i_deg: self.theta_o_deg,
            phi_i_deg: self.phi_o_deg,
            theta_o_deg: self.theta_i_deg,
            phi_o_deg: self.phi_i_deg,
        }
    }
}

/// Unit vector of polar angle θ and azimuth φ (degrees).
pub fn direction(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// Everything a simulation needs.
#[derive(Debug, Clone)]
pub struct Setup {
    pub slab: Slab,
    pub beam: Beam,
    pub sensor: Sensor,
    pub directions: Directions,
}

impl Setup {
    pub fn new(slab: Slab, beam: Beam, sensor: Sensor, directions: Directions) -> Self {
        Self { slab, beam, sensor, directions }
    }

    /// Whether the slice is symmetric under y → −y: ω_i and ω_o in the
    /// x–z plane (φ a multiple of 180°) and the beam's footprint symmetric.
    /// The phase function depends on the scattering angle only, so the
    /// transport is mirror-symmetric then.
    pub fn mirror_symmetric(&self) -> bool {
        let in_plane = |phi_deg: f64| phi_deg.to_radians().sin().abs() < 1e-12;
        let d = &self.directions;
        in_plane(d.phi_i_deg)
            && in_plane(d.phi_o_deg)
            && self.beam.mirror_symmetric(d.phi_i_deg)
            && self.slab.top.mirror_symmetric()
    }
}
