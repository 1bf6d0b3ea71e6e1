//! The parameters of [`super::fit_surface`] ([`FitOptions`]): the window and
//! weights of the per-pixel plane fits, levelling and the tilt fit.

use super::error::SurfaceError;
use serde::{Deserialize, Serialize};

/// Parameters of [`fit_surface`](super::fit_surface).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FitOptions {
    /// Side k of the k × k window of the per-pixel plane fits (odd, ≥ 3).
    pub window_px: usize,
    /// σ of the Gaussian weights of the plane fits, in pixels.
    pub sigma_px: f64,
    /// A pixel gets a normal only if it is valid and the valid points of its
    /// window carry at least this fraction of the full window's weight
    /// (pixels next to the map edge or to invalid points are left out).
    pub min_weight_fraction: f64,
    /// Remove the global least-squares plane first (docs/method.md#surface).
    pub remove_tilt: bool,
    /// Fit a tilt τ of the distribution's axis as a third parameter.
    pub fit_tilt: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions { window_px: 15, sigma_px: 1.0, min_weight_fraction: 0.9, remove_tilt: true, fit_tilt: false }
    }
}

impl FitOptions {
    /// Checks the parameters; the error names the offending one.
    pub fn validate(&self) -> Result<(), SurfaceError> {
        if self.window_px < 3 || self.window_px.is_multiple_of(2) || self.window_px > 201 {
            return Err(SurfaceError::parameter(
                "window",
                self.window_px,
                "must be an odd number of pixels from 3 to 201",
            ));
        }
        if !(self.sigma_px.is_finite() && self.sigma_px > 0.0) {
            return Err(SurfaceError::parameter(
                "sigma-px",
                self.sigma_px,
                "must be a positive finite number of pixels",
            ));
        }
        if !(self.min_weight_fraction > 0.0 && self.min_weight_fraction <= 1.0) {
            return Err(SurfaceError::parameter("min-weight", self.min_weight_fraction, "must lie in (0, 1]"));
        }
        Ok(())
    }
}
