//! A height map on a regular grid ([`HeightMap`]), what the readers make
//! and every later step reads.

use super::error::{show_metres, SurfaceError};

/// The largest height magnitude a height map may hold, in metres.
pub const MAX_HEIGHT_M: f64 = 1.0;

/// A height map on a regular grid: heights in metres, NaN where there is no
/// valid point.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightMap {
    /// Points along x (columns).
    pub nx: usize,
    /// Points along y (rows).
    pub ny: usize,
    /// Spacing of the columns in metres.
    pub pitch_x_m: f64,
    /// Spacing of the rows in metres.
    pub pitch_y_m: f64,
    /// Row-major heights in metres (row j is y = j·Δy), NaN = invalid.
    pub heights_m: Vec<f64>,
    /// Where the map came from (a file name, or "synthetic"), for messages.
    pub origin: String,
    /// Things worth saying about the reading (a pitch overridden, a layer
    /// skipped, …), reported in `fit.json`.
    pub notes: Vec<String>,
}

impl HeightMap {
    /// A map of `nx` × `ny` heights (metres, row-major, NaN or ±inf =
    /// invalid, stored as NaN). Errors: a size mismatch, a zero, negative or
    /// non-finite pitch, or no valid point.
    ///
    /// ```
    /// use lucent::surface::HeightMap;
    /// let m = HeightMap::new(2, 2, 1e-6, 1e-6, vec![0.0, 1e-9, f64::NAN, 2e-9], "doc").unwrap();
    /// assert_eq!(m.valid_count(), 3);
    /// assert!(HeightMap::new(2, 2, 0.0, 1e-6, vec![0.0; 4], "doc").is_err());
    /// ```
    pub fn new(
        nx: usize,
        ny: usize,
        pitch_x_m: f64,
        pitch_y_m: f64,
        mut heights_m: Vec<f64>,
        origin: impl Into<String>,
    ) -> Result<Self, SurfaceError> {
        let origin = origin.into();
        for (what, value) in [("x pitch", pitch_x_m), ("y pitch", pitch_y_m)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(SurfaceError::Pitch { origin, what: what.into(), value });
            }
        }
        if nx == 0 || ny == 0 || heights_m.len() != nx * ny {
            return Err(SurfaceError::Data {
                origin,
                reason: format!("{} heights for a {nx} × {ny} grid", heights_m.len()),
            });
        }
        for h in heights_m.iter_mut() {
            if !h.is_finite() {
                *h = f64::NAN;
            }
        }
        // A surface's heights span micrometres to millimetres: one beyond
        // MAX_HEIGHT_M is a wrong unit or a corrupt value (a 1e300 spike made
        // S_q infinite), not a height.
        if let Some(k) = heights_m.iter().position(|h| h.abs() > MAX_HEIGHT_M) {
            return Err(SurfaceError::Data {
                origin,
                reason: format!(
                    "height {} m at column {}, row {} is beyond ±{MAX_HEIGHT_M} m: not a surface height (wrong unit?)",
                    show_metres(heights_m[k]),
                    k % nx,
                    k / nx
                ),
            });
        }
        let map = HeightMap { nx, ny, pitch_x_m, pitch_y_m, heights_m, origin, notes: Vec::new() };
        if map.valid_count() == 0 {
            return Err(SurfaceError::AllInvalid { origin: map.origin, points: nx * ny });
        }
        Ok(map)
    }

    /// Number of valid (finite) heights.
    pub fn valid_count(&self) -> usize {
        self.heights_m.iter().filter(|h| h.is_finite()).count()
    }

    /// The height at column `i`, row `j` (NaN if invalid).
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.heights_m[j * self.nx + i]
    }
}
