//! The HDR environment of the 3D renderer (docs/method.md §5): radiance arriving from
//! outside the scene, looked up in an equirectangular image, and importance
//! sampling of directions proportionally to it.
//!
//! # What is computed
//!
//! The map holds **linear RGB radiance** (W·m⁻²·sr⁻¹ up to the calibration
//! factor `scale`, which the environment fit (docs/method.md §7) sets so that the rendered checkerboard matches
//! the photograph) as `width × height` pixels of `f32` triples, row-major,
//! row 0 at the top. [`Environment::radiance`] returns `scale × pixel` for the
//! pixel that the ray hits (**nearest pixel, piecewise constant**, no
//! filtering). [`Environment::sample`] draws a direction with a density
//! proportional to that radiance's luminance, and [`Environment::pdf`] returns
//! the density of the same distribution, **per steradian at the shading point
//! p**, so the two can be combined by multiple importance sampling.
//!
//! # Conventions
//!
//! * World: right-handed, metres, **z up**.
//! * Map coordinates: pixel (x, y) covers u ∈ [x/W, (x+1)/W),
//!   v ∈ [y/H, (y+1)/H). The polar angle from +z is θ = πv (row 0 is the
//!   zenith, row H−1 the nadir); the map direction is
//!   d = (sin θ cos 2πu, −sin θ sin 2πu, cos θ), i.e. azimuth φ = −2πu:
//!   u = 0 looks along +x and increasing u turns **clockwise seen from above**,
//!   so a panorama seen from inside the sphere is not mirrored.
//! * Yaw (degrees, about +z, positive = counter-clockwise seen from above)
//!   turns the map in the world: world direction = R_z(yaw) · map direction.
//! * Directions are unit [`DVec3`]s and always point **away from p**, along
//!   the ray that leaves the scene (the radiance travels the other way).
//!
//! # Projections
//!
//! * [`Projection::Infinite`]: the map is at infinity; the radiance arriving at
//!   any p from direction ω is map(ω), independent of p.
//! * [`Projection::FiniteSphere`]: the map is painted on a sphere of radius R
//!   about a centre c (docs/method.md §5: R = 0.60 m about the top of the sample). The
//!   ray p + tω, t > 0, leaves the sphere at q = p + tω with t the larger root
//!   of |p + tω − c|² = R², and the radiance is map(d), d = (q − c)/R. The root
//!   is computed in the cancellation-free forms of pbrt-v4 §6.2.2 (discriminant
//!   1 − |o − (o·ω)ω|² with o = (p − c)/R). The renderer keeps p strictly inside
//!   the sphere; for p on or outside it, the lookup is clamped: t = max(root, 0)
//!   (and the point of closest approach, t = max(−o·ω, 0), for rays that miss),
//!   i.e. q = p when the sphere is behind the ray. There `pdf` is 0 for such
//!   directions, `sample` may return `None`, and sample/pdf describe a
//!   sub-probability distribution over the directions that do see the sphere.
//!
//! # Sampling and its densities
//!
//! Each pixel gets the weight w = Y·Ω, with Y = 0.2126 R + 0.7152 G + 0.0722 B
//! (the Rec. 709 luminance of the non-negative stored values) and
//! Ω = (2π/W)(cos θ_y − cos θ_{y+1}) = (4π/W) sin θ_mid sin(π/2H) its solid
//! angle seen from the centre. Every pixel with a channel > 0 then gets a
//! floor of 10⁻³ × the mean weight added: the floor holds at most 0.1 % of the
//! total mass, and guarantees that no pixel with radiance has probability 0
//! (its cumulative-sum step stays above the rounding of the total). With
//! `scale = 0` or an all-zero map, `sample` returns `None` and `pdf` is 0.
//! [`Environment::set_sampling_normal`] multiplies every weight by
//! κ + max(0, n·d) (d the pixel centre's world direction): light that
//! arrives on a surface facing n is then drawn in proportion to
//! L cos θ, as its irradiance integrand asks, rather than to L alone.
//!
//! A pixel is drawn from the piecewise-constant 2-D distribution (pbrt-v4
//! Appendix A.5, "Sampling Multidimensional Functions", piecewise-constant
//! 2-D distributions): the row from the marginal cumulative sum of row
//! weights with `u[1]`, then the column from that row's conditional cumulative
//! sum with `u[0]` (binary searches, no allocation), and the point is uniform
//! in (u, v) inside the pixel (the unused fraction of each random number is
//! reused). With P_xy the pixel's probability, the density in (u, v) is
//! P_xy·W·H. Since θ = πv and φ = −2πu,
//!
//! dω = sin θ dθ dφ = 2π² sin θ du dv,
//!
//! so the density in solid angle **at the centre** is
//!
//! pdf_c(d) = P_xy · W·H / (2π² sin θ)
//!
//! (0 where sin θ = 0), as in pbrt-v4 §12.5.2 "Image Infinite Lights"
//! (pbrt-v3 §14.2.4). For `Infinite` this is the density at every p.
//!
//! For `FiniteSphere` the same point q = c + R d is seen from p. A patch dA of
//! the sphere at q subtends dω_c = dA/R² at the centre (the sphere normal is
//! d, radial) and dω_p = dA (d·ω)/|q − p|² at p, so
//!
//! pdf_p(ω) = pdf_c(d) · dω_c/dω_p = pdf_c(d) · |q − p|² / (R² (d·ω)),
//!
//! with d·ω > 0 for the exit point of a ray from inside. In units of R, with
//! s = d − o, this is pdf_c · |s|³/(d·s) in `sample` and pdf_c · t²/(d·ω) in
//! `pdf` (t the exit distance in units of R).
//!
//! `sample` returns the radiance and density of the pixel it drew; `pdf` and
//! `radiance` locate the pixel from the direction. The two agree to rounding
//! (≈1e-15 relative) except when a sample lies within rounding of a pixel edge
//! (probability ~1e-15 per sample), where the lookup may pick the neighbour.
//!
//! # Example
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::env::{Environment, Projection};
//! use std::f64::consts::PI;
//!
//! // A uniform grey sky on a 0.6 m sphere about the origin.
//! let sphere = Projection::FiniteSphere { centre: DVec3::ZERO, radius_m: 0.6 };
//! let env = Environment::constant([0.5, 0.5, 0.5], sphere);
//! assert_eq!(env.radiance(DVec3::new(0.1, 0.0, 0.2), DVec3::X), [0.5, 0.5, 0.5]);
//! assert_eq!(env.mean_radiance()[1], 0.5);
//! // One pixel, uniform in (u, v): the density at the centre on the horizon
//! // is 1 / (2π²) ≈ 0.0507 sr⁻¹.
//! let pdf = env.pdf(DVec3::ZERO, DVec3::Y);
//! assert!((pdf - 1.0 / (2.0 * PI * PI)).abs() < 1e-15);
//! ```

use std::f64::consts::{FRAC_1_PI, PI, TAU};
use std::fmt;

use glam::DVec3;
use thiserror::Error;

/// Rec. 709 / sRGB luminance weights (ITU-R BT.709-6, Y row of the RGB→XYZ
/// matrix), used only for the sampling weights.
const LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];
/// Floor added to every pixel with radiance, as a fraction of the mean weight.
const FLOOR_FRACTION: f64 = 1e-3;
const INV_TAU: f64 = 1.0 / TAU;
const CHANNELS: [char; 3] = ['R', 'G', 'B'];

/// Invalid environment input. The caller (configuration or image loading) is
/// at fault in every case; pixel errors name the pixel.
/// The largest radiance an environment may have (scale × pixel value): far
/// below the 32-bit float maximum (3.4e38) that rendered images are stored
/// in, so that sums of samples and variances stay finite.
pub const MAX_RADIANCE: f64 = 1e30;

/// κ of [`Environment::set_sampling_normal`]: the weight, relative to a
/// direction along the normal, left to the directions below the plane
/// (0.1 took the demo board's median relative error from 17 % to 9 % at
/// equal samples, and the plaques' by 4–10 %; 0.03 and 0.3 did less).
pub const BELOW_WEIGHT: f64 = 0.1;

/// The largest |yaw| of a map, degrees (ten turns: a larger value is a typo,
/// and reduces mod 360° inexactly).
pub const MAX_YAW_DEG: f64 = 3600.0;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum EnvError {
    /// Width or height is 0.
    #[error("environment map is {width}×{height} pixels: width and height must both be at least 1")]
    EmptyMap { width: usize, height: usize },
    /// 3·W·H overflows `usize`.
    #[error("environment map {width}×{height} is too large (3·W·H overflows)")]
    TooLarge { width: usize, height: usize },
    /// The data do not hold exactly 3·W·H values.
    #[error("environment map {width}×{height} needs 3·W·H = {expected} RGB values, got {got}")]
    DataLength { width: usize, height: usize, expected: usize, got: usize },
    /// A pixel value is NaN, infinite or negative.
    #[error("environment map pixel (x = {x}, y = {y}) channel {channel} is {value}: radiance must be finite and ≥ 0")]
    BadPixel { x: usize, y: usize, channel: char, value: f32 },
    /// The radiance scale is NaN, infinite or negative.
    #[error("environment radiance scale {0} must be finite and ≥ 0")]
    BadScale(f64),
    /// scale × the largest pixel value exceeds [`MAX_RADIANCE`].
    #[error(
        "environment radiance overflows: scale {scale} × largest pixel value {max} exceeds {MAX_RADIANCE:e} \
         (renders are stored as 32-bit floats)"
    )]
    Overflow { scale: f64, max: f32 },
    /// The yaw is NaN, infinite or beyond [`MAX_YAW_DEG`].
    #[error("environment yaw {0}° must be finite and within ±{MAX_YAW_DEG}°")]
    BadYaw(f64),
    /// The sphere radius is NaN, infinite, zero or negative.
    #[error("environment sphere radius {0} m must be finite and > 0")]
    BadRadius(f64),
    /// The sphere centre has a NaN or infinite coordinate.
    #[error("environment sphere centre ({}, {}, {}) m must be finite", .0.x, .0.y, .0.z)]
    BadCentre(DVec3),
}

/// Where the map is: at infinity, or painted on a sphere about the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Directions only: radiance independent of the point.
    Infinite,
    /// On a sphere of radius `radius_m` (m) about `centre` (world, m).
    FiniteSphere { centre: DVec3, radius_m: f64 },
}

/// A direction drawn by [`Environment::sample`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnvSample {
    /// Unit direction of the ray leaving p (world).
    pub dir: DVec3,
    /// Radiance arriving at p along `dir` (scaled linear RGB).
    pub radiance: [f64; 3],
    /// Density of `dir`, per steradian at p; > 0.
    pub pdf: f64,
}

/// An equirectangular HDR environment with its sampling tables. Immutable
/// after construction; share it between threads by reference.
#[derive(Clone)]
pub struct Environment {
    width: usize,
    height: usize,
    /// 3·W·H linear RGB values, row-major, row 0 at the zenith.
    rgb: Vec<f32>,
    scale: f64,
    yaw_deg: f64,
    cos_yaw: f64,
    sin_yaw: f64,
    projection: Projection,
    /// 1/R for `FiniteSphere`, 0 for `Infinite`.
    inv_radius: f64,
    /// Per row, W + 1 unnormalised cumulative pixel weights (starting at 0).
    col_cdf: Vec<f64>,
    /// H + 1 cumulative row weights (starting at 0); the last is the total.
    row_cdf: Vec<f64>,
    /// [`guide`] tables of `row_cdf` and of each row's `col_cdf`
    /// (GUIDE_CELLS + 1 entries per row): where [`pick`]'s search starts.
    row_guide: Vec<u32>,
    col_guide: Vec<u32>,
    /// W·H / (2π²).
    pdf_norm: f64,
    /// Mean radiance over the sphere seen from the centre (scaled).
    mean: [f64; 3],
    /// Every pixel has the same radiance.
    uniform: bool,
    /// The weight added to every pixel with radiance (module documentation).
    floor: f64,
    /// The normal the sampling weights are turned towards, if any
    /// ([`Environment::set_sampling_normal`]).
    facing: Option<DVec3>,
}

/// The solid angle of one pixel of each of `height` rows, seen from the
/// centre: (4π/W) sin θ_mid sin(π/2H).
fn row_solid_angles(width: usize, height: usize) -> Vec<f64> {
    let half_row = (PI / (2.0 * height as f64)).sin();
    (0..height)
        .map(|y| {
            let theta_mid = PI * (y as f64 + 0.5) / height as f64;
            4.0 * PI / width as f64 * theta_mid.sin() * half_row
        })
        .collect()
}

/// The stored (unscaled) value of the pixel with row-major index `i` of
/// row-major RGB data.
#[inline]
fn stored(rgb: &[f32], i: usize) -> [f64; 3] {
    [f64::from(rgb[3 * i]), f64::from(rgb[3 * i + 1]), f64::from(rgb[3 * i + 2])]
}

/// Rec. 709 luminance of linear RGB.
fn luminance(c: [f64; 3]) -> f64 {
    LUMINANCE[0] * c[0] + LUMINANCE[1] * c[1] + LUMINANCE[2] * c[2]
}

impl fmt::Debug for Environment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Environment")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("scale", &self.scale)
            .field("yaw_deg", &self.yaw_deg)
            .field("projection", &self.projection)
            .field("mean_radiance", &self.mean)
            .finish_non_exhaustive()
    }
}

impl Environment {
    /// An environment from `width × height` RGB pixels (`rgb.len() = 3·W·H`,
    /// row-major, row 0 at the zenith, linear radiance ≥ 0), turned by
    /// `yaw_deg` about +z and multiplied by `scale` (≥ 0). Any W, H ≥ 1 is
    /// accepted (W = 2H gives square pixels at the equator). Builds the
    /// sampling tables: O(W·H) time, 8·(W+1)·H bytes besides the pixels.
    pub fn new(
        width: usize,
        height: usize,
        rgb: Vec<f32>,
        yaw_deg: f64,
        scale: f64,
        projection: Projection,
    ) -> Result<Self, EnvError> {
        if width == 0 || height == 0 {
            return Err(EnvError::EmptyMap { width, height });
        }
        let expected =
            width.checked_mul(height).and_then(|n| n.checked_mul(3)).ok_or(EnvError::TooLarge { width, height })?;
        if rgb.len() != expected {
            return Err(EnvError::DataLength { width, height, expected, got: rgb.len() });
        }
        let mut max = 0.0_f32;
        for (i, &value) in rgb.iter().enumerate() {
            if !(value.is_finite() && value >= 0.0) {
                let pixel = i / 3;
                return Err(EnvError::BadPixel { x: pixel % width, y: pixel / width, channel: CHANNELS[i % 3], value });
            }
            max = max.max(value);
        }
        if !(scale.is_finite() && scale >= 0.0) {
            return Err(EnvError::BadScale(scale));
        }
        if scale * f64::from(max) > MAX_RADIANCE {
            return Err(EnvError::Overflow { scale, max });
        }
        if !(yaw_deg.is_finite() && yaw_deg.abs() <= MAX_YAW_DEG) {
            return Err(EnvError::BadYaw(yaw_deg));
        }
        let inv_radius = match projection {
            Projection::Infinite => 0.0,
            Projection::FiniteSphere { centre, radius_m } => {
                if !centre.is_finite() {
                    return Err(EnvError::BadCentre(centre));
                }
                if !(radius_m.is_finite() && radius_m > 0.0) {
                    return Err(EnvError::BadRadius(radius_m));
                }
                1.0 / radius_m
            }
        };

        let omega = row_solid_angles(width, height);
        // Mean radiance and mean weight (weights are scale-free; a zero scale
        // makes the whole map dark and the sampler empty).
        let mut sum = [0.0; 3];
        let mut sum_omega = 0.0;
        let mut sum_weight = 0.0;
        for (y, &om) in omega.iter().enumerate() {
            for x in 0..width {
                let c = stored(&rgb, y * width + x);
                for k in 0..3 {
                    sum[k] += c[k] * om;
                }
                sum_weight += luminance(c) * om;
            }
            sum_omega += om * width as f64;
        }
        let (sin_yaw, cos_yaw) = yaw_deg.to_radians().sin_cos();
        let mut env = Self {
            width,
            height,
            rgb,
            scale,
            yaw_deg,
            cos_yaw,
            sin_yaw,
            projection,
            inv_radius,
            col_cdf: Vec::new(),
            row_cdf: Vec::new(),
            row_guide: Vec::new(),
            col_guide: Vec::new(),
            pdf_norm: (width * height) as f64 / (2.0 * PI * PI),
            mean: sum.map(|s| scale * s / sum_omega),
            uniform: false,
            floor: FLOOR_FRACTION * sum_weight / (width * height) as f64,
            facing: None,
        };
        env.uniform = env.rgb.chunks_exact(3).all(|p| p == &env.rgb[..3]);
        env.build_tables(&omega);
        Ok(env)
    }

    /// Weights the sampling towards the hemisphere around `normal` (unit,
    /// world): each pixel's weight Y·Ω becomes Y·Ω·(κ + max(0, n·d)), with d
    /// its centre's world direction and κ = [`BELOW_WEIGHT`]; `None` restores
    /// the plain weights. For a scene on a board with normal n the board's
    /// direct light, ρ/π ∫ L cos θ dω, is then drawn in proportion to its
    /// integrand (up to the board's shadows), and so are the refractions into
    /// faces that look up; the directions below the board, which it hides
    /// from everything on it, keep a weight κ so that none with radiance gets
    /// probability 0. [`Environment::sample`] and [`Environment::pdf`] follow.
    pub fn set_sampling_normal(&mut self, normal: Option<DVec3>) {
        if normal == self.facing {
            return;
        }
        self.facing = normal.filter(|n| n.is_finite() && n.length_squared() > 0.0).map(DVec3::normalize);
        let omega = row_solid_angles(self.width, self.height);
        self.build_tables(&omega);
    }

    /// The normal the sampling is weighted towards ([`Environment::set_sampling_normal`]).
    pub fn sampling_normal(&self) -> Option<DVec3> {
        self.facing
    }

    /// The cumulative sums and guides of the pixel weights (module documentation).
    fn build_tables(&mut self, omega: &[f64]) {
        let (width, height) = (self.width, self.height);
        let mut col_cdf = Vec::with_capacity((width + 1) * height);
        let mut row_cdf = Vec::with_capacity(height + 1);
        row_cdf.push(0.0);
        for (y, &om) in omega.iter().enumerate() {
            let mut acc = 0.0;
            col_cdf.push(acc);
            let v = (y as f64 + 0.5) / height as f64;
            for x in 0..width {
                let c = stored(&self.rgb, y * width + x);
                if self.scale > 0.0 && c.iter().any(|&v| v > 0.0) {
                    let facing = self.facing.map_or(1.0, |n| {
                        BELOW_WEIGHT + n.dot(self.world_direction((x as f64 + 0.5) / width as f64, v)).max(0.0)
                    });
                    acc += (luminance(c) * om + self.floor) * facing;
                }
                col_cdf.push(acc);
            }
            let last = *row_cdf.last().unwrap_or(&0.0);
            row_cdf.push(last + acc);
        }
        self.row_guide = guide(&row_cdf);
        self.col_guide = col_cdf.chunks_exact(width + 1).flat_map(guide).collect();
        self.row_cdf = row_cdf;
        self.col_cdf = col_cdf;
    }

    /// A uniform environment: a 1×1 map of `rgb` (stored as `f32`, like any
    /// map), scale 1, yaw 0.
    ///
    /// # Panics
    ///
    /// If `rgb` has a negative or non-finite value or `projection` is invalid
    /// (the message is the [`EnvError`]); use [`Environment::new`] for input
    /// that is not known to be valid.
    pub fn constant(rgb: [f64; 3], projection: Projection) -> Self {
        let data = rgb.iter().map(|&c| c as f32).collect();
        Self::new(1, 1, data, 0.0, 1.0, projection).unwrap_or_else(|e| panic!("Environment::constant: {e}"))
    }

    /// True when every pixel has the same radiance: then sampling the map
    /// cannot beat sampling a BSDF or phase function, and a renderer may
    /// skip connections to it where they are costly.
    pub fn is_uniform(&self) -> bool {
        self.uniform
    }

    /// Map width W in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Map height H in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The radiance scale factor.
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The yaw of the map about +z, degrees (counter-clockwise from above).
    pub fn yaw_deg(&self) -> f64 {
        self.yaw_deg
    }

    /// Where the map is.
    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// The stored (unscaled) value of pixel (x, y). Panics if out of range.
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        assert!(x < self.width && y < self.height, "pixel ({x}, {y}) outside {}×{}", self.width, self.height);
        let i = 3 * (y * self.width + x);
        [self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]]
    }

    /// The world direction (unit, from the centre, yaw applied) of map
    /// coordinates (u, v).
    pub fn world_direction(&self, u: f64, v: f64) -> DVec3 {
        let (sin_t, cos_t) = polar_sin_cos(v);
        let (sin_p, cos_p) = (TAU * u).sin_cos();
        self.map_to_world(DVec3::new(sin_t * cos_p, -sin_t * sin_p, cos_t))
    }

    /// The map coordinates [u, v] ∈ [0, 1]² of a world direction seen from
    /// the centre (need not be unit); the inverse of
    /// [`Environment::world_direction`].
    pub fn map_coordinates(&self, dir: DVec3) -> [f64; 2] {
        let m = self.world_to_map(dir);
        let rho = (m.x * m.x + m.y * m.y).sqrt();
        [azimuth_u(m), rho.atan2(m.z) * FRAC_1_PI]
    }

    /// Radiance arriving at `p` (world, m) from the scene's outside along a
    /// ray leaving p in unit direction `dir`: `scale × pixel` of the pixel hit
    /// (see the module documentation for the projections and the clamping
    /// when p is not inside the sphere).
    #[inline]
    pub fn radiance(&self, p: DVec3, dir: DVec3) -> [f64; 3] {
        let d = match self.projection {
            Projection::Infinite => dir,
            Projection::FiniteSphere { centre, .. } => {
                let o = (p - centre) * self.inv_radius;
                exit_point(o, dir).0
            }
        };
        let (i, _) = self.locate(d);
        self.pixel_radiance(i)
    }

    /// A direction at `p` drawn proportionally to the map's luminance (times
    /// the weight of [`Environment::set_sampling_normal`], if set)
    /// (u ∈ [0, 1)²; `u[1]` picks the row, `u[0]` the column), with the
    /// radiance along it and its density per steradian at p.
    ///
    /// `None` if the map is all zero (or `scale` is 0), and with probability
    /// ~2⁻⁵³ when the point falls exactly on the zenith (sin θ = 0). For p
    /// outside or on the sphere, also for points of the sphere that p cannot
    /// see as exit points (see the module documentation).
    #[inline]
    pub fn sample(&self, p: DVec3, u: [f64; 2]) -> Option<EnvSample> {
        let total = self.row_cdf[self.height];
        if !positive(total) {
            return None;
        }
        let w = self.width;
        let (y, fy) = pick(&self.row_cdf, &self.row_guide, u[1]);
        let row = &self.col_cdf[y * (w + 1)..(y + 1) * (w + 1)];
        let (x, fx) = pick(row, &self.col_guide[y * (GUIDE_CELLS + 1)..(y + 1) * (GUIDE_CELLS + 1)], u[0]);
        let prob = (self.row_cdf[y + 1] - self.row_cdf[y]) / total * ((row[x + 1] - row[x]) / row[w]);

        let v = (y as f64 + fy) / self.height as f64;
        let um = (x as f64 + fx) / w as f64;
        let (sin_t, cos_t) = polar_sin_cos(v);
        if !positive(sin_t) {
            return None;
        }
        let (sin_p, cos_p) = (TAU * um).sin_cos();
        let d = self.map_to_world(DVec3::new(sin_t * cos_p, -sin_t * sin_p, cos_t));
        let pdf_c = prob * self.pdf_norm / sin_t;
        let radiance = self.pixel_radiance(y * w + x);
        match self.projection {
            Projection::Infinite => Some(EnvSample { dir: d, radiance, pdf: pdf_c }),
            Projection::FiniteSphere { centre, .. } => {
                let o = (p - centre) * self.inv_radius;
                let s = d - o;
                let ds = d.dot(s);
                if !positive(ds) {
                    return None;
                }
                let len = s.length();
                Some(EnvSample { dir: s / len, radiance, pdf: pdf_c * len * len * len / ds })
            }
        }
    }

    /// The density (per steradian at `p`) with which [`Environment::sample`]
    /// returns the unit direction `dir` at p: the same piecewise-constant
    /// distribution, for multiple importance sampling. 0 for directions
    /// `sample` never returns.
    #[inline]
    pub fn pdf(&self, p: DVec3, dir: DVec3) -> f64 {
        if !positive(self.row_cdf[self.height]) {
            return 0.0;
        }
        match self.projection {
            Projection::Infinite => self.pdf_centre(dir),
            Projection::FiniteSphere { centre, .. } => {
                let o = (p - centre) * self.inv_radius;
                let (d, t, hit) = exit_point(o, dir);
                let cos = d.dot(dir);
                if !(hit && t > 0.0 && cos > 0.0) {
                    return 0.0;
                }
                self.pdf_centre(d) * t * t / cos
            }
        }
    }

    /// Mean radiance over the sphere of directions seen from the centre,
    /// Σ scale·L·Ω / Σ Ω over the pixels (scaled linear RGB).
    pub fn mean_radiance(&self) -> [f64; 3] {
        self.mean
    }

    /// Density per steradian at the centre of direction `d` (need not be
    /// unit).
    #[inline]
    fn pdf_centre(&self, d: DVec3) -> f64 {
        let (i, sin_t) = self.locate(d);
        if !positive(sin_t) {
            return 0.0;
        }
        let (x, y) = (i % self.width, i / self.width);
        let w = self.width;
        let row = &self.col_cdf[y * (w + 1)..(y + 1) * (w + 1)];
        if !positive(row[w]) {
            return 0.0;
        }
        let prob =
            (self.row_cdf[y + 1] - self.row_cdf[y]) / self.row_cdf[self.height] * ((row[x + 1] - row[x]) / row[w]);
        prob * self.pdf_norm / sin_t
    }

    /// Index y·W + x of the pixel seen in world direction `d` from the centre
    /// (need not be unit), and sin θ of that direction.
    #[inline]
    fn locate(&self, d: DVec3) -> (usize, f64) {
        let m = self.world_to_map(d);
        let rho2 = m.x * m.x + m.y * m.y;
        let rho = rho2.sqrt();
        let theta = rho.atan2(m.z);
        let u = azimuth_u(m);
        // `as usize` saturates (NaN → 0), `min` keeps u = 1, θ = π in range.
        let x = ((u * self.width as f64) as usize).min(self.width - 1);
        let y = ((theta * FRAC_1_PI * self.height as f64) as usize).min(self.height - 1);
        let norm = (rho2 + m.z * m.z).sqrt();
        (y * self.width + x, rho / norm)
    }

    #[inline]
    fn pixel_radiance(&self, i: usize) -> [f64; 3] {
        let c = &self.rgb[3 * i..3 * i + 3];
        [self.scale * f64::from(c[0]), self.scale * f64::from(c[1]), self.scale * f64::from(c[2])]
    }

    /// R_z(yaw) · m.
    #[inline]
    fn map_to_world(&self, m: DVec3) -> DVec3 {
        DVec3::new(self.cos_yaw * m.x - self.sin_yaw * m.y, self.sin_yaw * m.x + self.cos_yaw * m.y, m.z)
    }

    /// R_z(−yaw) · d.
    #[inline]
    fn world_to_map(&self, d: DVec3) -> DVec3 {
        DVec3::new(self.cos_yaw * d.x + self.sin_yaw * d.y, -self.sin_yaw * d.x + self.cos_yaw * d.y, d.z)
    }
}

/// x > 0, false for NaN (the guards below must reject NaN too).
#[inline]
fn positive(x: f64) -> bool {
    x > 0.0
}

/// u ∈ [0, 1] of a map-space direction: φ = −2πu.
#[inline]
fn azimuth_u(m: DVec3) -> f64 {
    let u = (-m.y).atan2(m.x) * INV_TAU;
    if u < 0.0 {
        u + 1.0
    } else {
        u
    }
}

/// (sin πv, cos πv), accurate near both poles (v ≥ ½ uses π(1 − v), exact
/// by Sterbenz).
#[inline]
fn polar_sin_cos(v: f64) -> (f64, f64) {
    if v <= 0.5 {
        (PI * v).sin_cos()
    } else {
        let (s, c) = (PI * (1.0 - v)).sin_cos();
        (s, -c)
    }
}

/// Where the ray o + tω (units of R, centre at the origin, unit ω) leaves the
/// unit sphere: (o + tω, t, hit) with t = max(larger root, 0); for a ray that
/// misses (only from outside), t = max(−o·ω, 0), the closest approach, and
/// hit = false. Discriminant and root in cancellation-free forms (as in
/// pbrt-v4's sphere intersection).
#[inline]
fn exit_point(o: DVec3, w: DVec3) -> (DVec3, f64, bool) {
    let b = o.dot(w);
    let perp = o - b * w;
    let disc = 1.0 - perp.length_squared();
    let (t, hit) = if disc >= 0.0 {
        let sq = disc.sqrt();
        // Larger root of t² + 2bt + (|o|² − 1) = 0, i.e. −b + √disc.
        let t = if b <= 0.0 { sq - b } else { (1.0 - o.length_squared()) / (b + sq) };
        (t.max(0.0), true)
    } else {
        ((-b).max(0.0), false)
    };
    (o + t * w, t, hit)
}

/// Cells of the guide tables that start [`pick`]'s search.
const GUIDE_CELLS: usize = 64;

/// For each of the GUIDE_CELLS + 1 fractions f = j / GUIDE_CELLS of the
/// total of the cumulative weights `cdf`, the first i with
/// cdf[i + 1] > f · total (capped at the last bin).
fn guide(cdf: &[f64]) -> Vec<u32> {
    let n = cdf.len() - 1;
    let total = cdf[n];
    (0..=GUIDE_CELLS)
        .map(|j| {
            let t = j as f64 / GUIDE_CELLS as f64 * total;
            let i = cdf[1..].partition_point(|&c| c <= t).min(n.saturating_sub(1));
            u32::try_from(i).unwrap_or(u32::MAX)
        })
        .collect()
}

/// Cell i of a non-decreasing cumulative sum `cdf` (cdf[0] = 0, total =
/// cdf[n] > 0) with cdf[i] ≤ u·total < cdf[i+1], and the fraction of the way
/// through it; `guide`: its [`guide`] table. Never returns a cell of zero mass: u·total rounding up to the
/// total (or NaN) gives the last cell with mass.
#[inline]
fn pick(cdf: &[f64], guide: &[u32], u: f64) -> (usize, f64) {
    let n = cdf.len() - 1;
    let total = cdf[n];
    let t = u * total;
    // The first i with cdf[i + 1] > t, searched between the guide's bounds
    // for u's cell (widened by one for rounding) and checked, else over all.
    let j = ((u * GUIDE_CELLS as f64) as usize).min(GUIDE_CELLS - 1);
    let lo = (guide[j] as usize).saturating_sub(1);
    let hi = (guide[j + 1] as usize + 1).min(n);
    let mut i = lo + cdf[lo + 1..=hi].partition_point(|&c| c <= t);
    let found = i < n && cdf[i + 1] > t && (i == 0 || cdf[i] <= t);
    if !found {
        i = cdf[1..].partition_point(|&c| c <= t);
    }
    if i >= n || !positive(cdf[i + 1] - cdf[i]) {
        i = cdf[1..].partition_point(|&c| c < total);
    }
    let (lo, hi) = (cdf[i], cdf[i + 1]);
    (i, ((t - lo) / (hi - lo)).clamp(0.0, 1.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere() -> Projection {
        Projection::FiniteSphere { centre: DVec3::new(0.1, -0.2, 0.3), radius_m: 0.6 }
    }

    #[test]
    fn pick_skips_zero_cells_and_handles_the_top() {
        let cdf = [0.0, 0.0, 1.0, 1.0, 3.0, 3.0];
        assert_eq!(pick(&cdf, &guide(&cdf), 0.0), (1, 0.0));
        assert_eq!(pick(&cdf, &guide(&cdf), 0.25), (1, 0.75));
        assert_eq!(pick(&cdf, &guide(&cdf), 1.0 / 3.0), (3, 0.0));
        assert_eq!(pick(&cdf, &guide(&cdf), 0.5), (3, 0.25));
        // u = 1 (out of contract) and the largest u below 1: last cell with mass.
        assert_eq!(pick(&cdf, &guide(&cdf), 1.0), (3, 1.0));
        let (i, f) = pick(&cdf, &guide(&cdf), 1.0 - f64::EPSILON / 2.0);
        assert_eq!(i, 3);
        assert!((0.0..=1.0).contains(&f));
        // NaN does not panic and stays on a cell with mass.
        let (i, _) = pick(&cdf, &guide(&cdf), f64::NAN);
        assert!(i == 1 || i == 3);
    }

    #[test]
    fn exit_point_from_inside_is_on_the_sphere_and_ahead() {
        let o = DVec3::new(0.3, -0.4, 0.5);
        for w in [DVec3::X, -DVec3::X, DVec3::Z, DVec3::new(1.0, 2.0, -2.0) / 3.0] {
            let (d, t, hit) = exit_point(o, w);
            assert!(hit && t > 0.0);
            assert!((d.length() - 1.0).abs() < 1e-15, "{d}");
            assert!(d.dot(w) > 0.0);
        }
        // From the centre: exactly the direction.
        let w = DVec3::new(0.6, 0.0, 0.8);
        assert_eq!(exit_point(DVec3::ZERO, w), (w, 1.0, true));
        // Near the surface going out: no cancellation (t ≈ 1e-12).
        let o = DVec3::new(0.0, 0.0, 1.0 - 1e-12);
        let (_, t, _) = exit_point(o, DVec3::Z);
        assert!((t - 1e-12).abs() < 1e-15, "{t}");
    }

    #[test]
    fn outside_the_sphere_the_lookup_clamps() {
        // 2×1 map: u < ½ (x = 0) is red, u ≥ ½ (x = 1) green; θ ∈ [0, π).
        let env = Environment::new(
            2,
            1,
            vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            0.0,
            1.0,
            Projection::FiniteSphere { centre: DVec3::ZERO, radius_m: 1.0 },
        )
        .unwrap();
        // u ∈ [0, ½) is φ ∈ (−π, 0]: y ≤ 0.
        let p = DVec3::new(0.0, -2.0, 0.0);
        // Looking away from the sphere: q = p, direction of p from c (y < 0).
        assert_eq!(env.radiance(p, -DVec3::Y), [1.0, 0.0, 0.0]);
        assert_eq!(env.pdf(p, -DVec3::Y), 0.0);
        // Looking through the sphere: the far side (y > 0).
        assert_eq!(env.radiance(p, DVec3::Y), [0.0, 1.0, 0.0]);
        assert!(env.pdf(p, DVec3::Y) > 0.0);
        // Missing it: closest approach, no density.
        assert_eq!(env.pdf(p, DVec3::X), 0.0);
        // Samples are finite and consistent where they exist.
        for k in 0..100 {
            let u = [(k as f64 + 0.5) / 100.0, ((k * 37) % 100) as f64 / 100.0];
            if let Some(s) = env.sample(p, u) {
                assert!(s.dir.y > 0.0 && s.pdf.is_finite() && s.pdf > 0.0);
                let q = env.pdf(p, s.dir);
                assert!((q - s.pdf).abs() <= 1e-9 * s.pdf, "{q} {}", s.pdf);
            }
        }
    }

    #[test]
    fn zero_map_or_zero_scale_has_no_samples() {
        let zero = Environment::new(4, 2, vec![0.0; 24], 0.0, 1.0, sphere()).unwrap();
        let scaled = Environment::new(4, 2, vec![1.0; 24], 0.0, 0.0, sphere()).unwrap();
        for env in [zero, scaled] {
            assert_eq!(env.sample(DVec3::ZERO, [0.3, 0.6]), None);
            assert_eq!(env.pdf(DVec3::ZERO, DVec3::X), 0.0);
            assert_eq!(env.radiance(DVec3::ZERO, DVec3::X), [0.0; 3]);
            assert_eq!(env.mean_radiance(), [0.0; 3]);
        }
    }

    #[test]
    fn floor_gives_dim_pixels_a_density() {
        // One very bright pixel and one pixel 1e-12 as bright: both sampled.
        let mut rgb = vec![0.0_f32; 3 * 8 * 4];
        rgb[3 * 9] = 1e6;
        rgb[3 * 30 + 2] = 1e-6;
        let env = Environment::new(8, 4, rgb, 0.0, 1.0, Projection::Infinite).unwrap();
        let dim = env.world_direction((6.0 + 0.5) / 8.0, (3.0 + 0.5) / 4.0);
        let bright = env.world_direction((1.0 + 0.5) / 8.0, (1.0 + 0.5) / 4.0);
        let (pd, pb) = (env.pdf(DVec3::ZERO, dim), env.pdf(DVec3::ZERO, bright));
        assert!(pd > 0.0 && pb > 0.0);
        // Floor mass: 1e-3 × mean weight of 32 pixels per floored pixel.
        assert!(pd / pb > 1e-5 && pd / pb < 1e-4, "{}", pd / pb);
        // Zero pixels stay at 0.
        assert_eq!(env.pdf(DVec3::ZERO, env.world_direction(0.05, 0.1)), 0.0);
    }

    #[test]
    fn mean_radiance_weights_rows_by_solid_angle() {
        // 1×2 map: upper hemisphere 1, lower 3 → mean 2.
        let env = Environment::new(1, 2, vec![1.0, 1.0, 1.0, 3.0, 3.0, 3.0], 0.0, 2.0, Projection::Infinite).unwrap();
        for c in env.mean_radiance() {
            assert!((c - 4.0).abs() < 1e-15, "{c}");
        }
        // 1×3 map: bands of 60°; the middle one has solid angle 2π.
        let env =
            Environment::new(1, 3, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0], 0.0, 1.0, Projection::Infinite)
                .unwrap();
        assert!((env.mean_radiance()[0] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn debug_is_short() {
        let env = Environment::new(64, 32, vec![1.0; 3 * 64 * 32], 10.0, 1.0, sphere()).unwrap();
        let s = format!("{env:?}");
        assert!(s.len() < 300 && s.contains("64") && s.contains("FiniteSphere"), "{s}");
    }

    #[test]
    #[should_panic(expected = "channel R")]
    fn constant_panics_on_bad_value() {
        let _ = Environment::constant([-1.0, 0.0, 0.0], Projection::Infinite);
    }
}
