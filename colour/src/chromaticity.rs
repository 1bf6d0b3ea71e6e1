//! Chromaticity coordinates: XYZ ↔ xyY and the XYZ (Y = 1) of a
//! chromaticity x, y (CIE 15:2004 §7.3: x = X / (X + Y + Z),
//! y = Y / (X + Y + Z)). Plain arithmetic, no dependency on the rest of the
//! crate, so the data tables and colour spaces can both use it.
//!
//! ```
//! use lucent_colour::chromaticity::{xy_to_xyz, xyz_to_xyy};
//! // D65 white point (CIE 15:2004, 4-digit xy): X = 0.3127 / 0.3290.
//! let xyz = xy_to_xyz([0.3127, 0.3290]);
//! assert!((xyz[0] - 0.950456).abs() < 1e-6 && xyz[1] == 1.0);
//! let xyy = xyz_to_xyy(xyz);
//! assert!((xyy[0] - 0.3127).abs() < 1e-12 && (xyy[1] - 0.3290).abs() < 1e-12);
//! ```

/// XYZ (Y = 1) of a chromaticity x, y; y = 0 gives NaN.
pub fn xy_to_xyz(xy: [f64; 2]) -> [f64; 3] {
    let [x, y] = xy;
    [x / y, 1.0, (1.0 - x - y) / y]
}

/// x, y, Y of XYZ; black (X + Y + Z = 0) gives (0, 0, 0) as in colour-science.
pub fn xyz_to_xyy(xyz: [f64; 3]) -> [f64; 3] {
    let s = xyz[0] + xyz[1] + xyz[2];
    if s == 0.0 {
        return [0.0, 0.0, 0.0];
    }
    [xyz[0] / s, xyz[1] / s, xyz[1]]
}

/// XYZ of x, y, Y; y = 0 gives (0, 0, 0) as in colour-science.
pub fn xyy_to_xyz(xyy: [f64; 3]) -> [f64; 3] {
    let [x, y, big_y] = xyy;
    if y == 0.0 {
        return [0.0, 0.0, 0.0];
    }
    [x * big_y / y, big_y, (1.0 - x - y) * big_y / y]
}
