//! Smooth dielectric interfaces: unpolarised Fresnel reflectance and Snell
//! refraction (Born & Wolf, Principles of Optics, §1.5; pbrt-v4 §9.3).
//!
//! Directions are unit vectors; the interface normal is ±z. Indices are real
//! (the rough interface built on these is [`crate::interface`]).
//!
//! ```
//! // Normal incidence from air onto n = 1.5: ((n − 1)/(n + 1))² = 0.04.
//! let f = lucent_render::fresnel::reflectance(1.0, 1.5);
//! assert!((f - 0.04).abs() < 1e-15);
//! ```

use glam::DVec3;

/// The bulk refractive indices a medium may have, relative to the air
/// around it: the one range the slab simulator and the path tracer accept.
pub const INDEX_RANGE: std::ops::RangeInclusive<f64> = 1.0..=10.0;

/// True when `n` lies in [`INDEX_RANGE`] (NaN: false).
pub fn valid_index(n: f64) -> bool {
    INDEX_RANGE.contains(&n)
}

/// Unpolarised Fresnel reflectance for light arriving with cosine `cos_i`
/// (0 < cos_i ≤ 1, measured from the normal on the incident side) at an
/// interface with relative index `eta` = n_transmitted / n_incident. Returns
/// 1 under total internal reflection.
#[inline]
pub fn reflectance(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin_t2 >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t2).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Refracts the unit direction of travel `d` through an interface with unit
/// normal `n` (either orientation) and relative index `eta` =
/// n_transmitted / n_incident: t = (d − (d·n) n)/η + cos θ_t sgn(d·n) n
/// (Snell's law in vector form; pbrt-v4 §9.3.2). The result goes on through
/// the interface (t·n has the sign of d·n) and is a unit vector to rounding;
/// for n = ±z its tangential part is exactly d's over η. `None` under total
/// internal reflection.
#[inline]
pub fn refract(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let cos_i = d.dot(n);
    let sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin_t2 >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin_t2).sqrt();
    Some((d - cos_i * n) / eta + cos_t.copysign(cos_i) * n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reciprocity_and_limits() {
        // Reflectance is the same from both sides for paired angles.
        let n = 1.589;
        for k in 1..90 {
            let cos_i = (k as f64).to_radians().cos();
            let d = DVec3::new((1.0 - cos_i * cos_i).sqrt(), 0.0, -cos_i);
            let t = refract(d, DVec3::Z, n).unwrap();
            let back = reflectance(t.z.abs(), 1.0 / n);
            assert!((reflectance(cos_i, n) - back).abs() < 1e-12, "{k}°");
            // Snell: n_i sin θ_i = n_t sin θ_t, the same result about −z.
            assert!((d.x - n * t.x).abs() < 1e-12 && t.z < 0.0);
            assert!((t.length() - 1.0).abs() < 1e-12);
            assert_eq!(refract(d, -DVec3::Z, n), Some(t));
            // A tilted normal: the tangential parts obey Snell, and back again.
            let m = DVec3::new(0.3, -0.2, 0.9).normalize();
            let t = refract(d, m, n).unwrap();
            let (si, st) = (d.cross(m).length(), t.cross(m).length());
            assert!((si - n * st).abs() < 1e-12 && (t.dot(m) < 0.0) == (d.dot(m) < 0.0));
            assert!((refract(t, m, 1.0 / n).unwrap() - d).length() < 1e-12);
        }
        assert_eq!(reflectance(0.0, 1.5), 1.0);
        // Critical angle from inside n = 1.5: sin θ_c = 1/1.5.
        let cos_c = (1.0f64 - 1.0 / 2.25).sqrt();
        assert_eq!(reflectance(cos_c - 1e-9, 1.0 / 1.5), 1.0);
        assert!(reflectance(cos_c + 1e-6, 1.0 / 1.5) < 1.0);
        assert!(refract(DVec3::new(0.9, 0.0, (1.0f64 - 0.81).sqrt()), DVec3::Z, 1.0 / 1.5).is_none());
        // Brewster angle: p-polarised reflectance vanishes, so F = rs²/2.
        let tb = 1.5f64.atan();
        let f = reflectance(tb.cos(), 1.5);
        let tt = (tb.sin() / 1.5).asin();
        let rs = (tb - tt).sin() / (tb + tt).sin();
        assert!((f - 0.5 * rs * rs).abs() < 1e-12);
    }
}
