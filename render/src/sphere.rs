//! Sphere jumps: where a path scatters deep inside an isotropically
//! scattering medium, one draw from the tabulated exit distribution of a
//! sphere centred on the scattering point replaces the whole walk inside
//! it ("shell transport": Moon, Walter & Marschner, "Rendering discrete
//! random media using precomputed scattering solutions", EGSR 2007; the
//! walk-on-spheres idea of Muller, Ann. Math. Stat. 27, 1956).
//!
//! For isotropic scattering in an unbounded homogeneous medium, a path that
//! starts at a sphere's centre in an isotropic direction leaves the sphere
//! at a point ω uniform over it (by symmetry), in a direction whose angle to
//! the outward normal at ω has cosine μ ∈ (0, 1] and whose azimuth about
//! that normal is uniform. What depends on the medium is the distribution of
//! μ and the albedo weight a^n of the n scattering events inside, both
//! functions of the optical radius R = μ_t r (mean free paths) and the
//! single-scattering albedo a = μ_s/μ_t only. [`SphereExits`] tabulates
//! them per band on a geometric grid of radii in metres:
//!
//! - the unscattered exit (μ = 1 exactly), probability e^{−R}, weight 1;
//! - the scattered exits in [`BINS`] bins of μ: the density q(μ) of the
//!   unweighted walk (it always leaves; ∫ q dμ = 1 − e^{−R}) and the weighted
//!   density w(μ) = E[a^n | μ] q(μ) (∫ w dμ is the probability that light
//!   which scatters inside leaves it unabsorbed).
//!
//! A draw for band h picks the unscattered exit with probability e^{−R_h},
//! else a bin by q_h and μ uniform in it. Band c's contribution and density
//! of that draw are (e^{−R_c}, e^{−R_c}) or (w_c(μ), q_c(μ)), the pair the
//! tracer's spectral MIS needs; the common factors (ω, the azimuth) cancel.
//!
//! The tables are Monte Carlo estimates (fixed seed, [`PATHS`] paths per
//! radius and band), made smallest radius first: a table's walk itself
//! jumps through the smaller spheres that fit, so a radius of R mean free
//! paths costs O(log R) jumps rather than R² events. Their noise is a fixed
//! error of a few % per bin in the exit angle; the tracer's test of the
//! jumps against the plain walk bounds its effect on the image.

use glam::DVec3;
use rayon::prelude::*;

use crate::phase::ScatteringAngles;
use crate::rng::Rng;

/// Bins of the exit cosine μ ∈ [0, 1], equal width.
pub const BINS: usize = 24;
/// Paths per table (one radius, one band).
pub const PATHS: u32 = 1 << 15;
/// Ratio between neighbouring radii of the grid.
pub const RADIUS_RATIO: f64 = 1.25;
/// The smallest radius, in mean free paths of the band with the largest
/// mean free path.
pub const SMALLEST_RADIUS_MFP: f64 = 1.0;
/// At most this many radii.
const MAX_RADII: usize = 48;
/// Paths per work item of the tabulation (the unit of parallelism; fixed,
/// so the tables do not depend on the thread count).
const CHUNK: u32 = 2048;

/// One band's exit distribution at one radius.
#[derive(Debug, Clone, PartialEq)]
struct ExitTable {
    /// e^{−R}: the probability of leaving unscattered (μ = 1).
    unscattered: f64,
    /// q per bin, per unit μ (∫ q dμ = 1 − e^{−R}).
    density: [f64; BINS],
    /// w per bin, per unit μ.
    weight: [f64; BINS],
    /// The bins' cumulative probabilities of q/(1 − e^{−R}), cdf[0] = 0,
    /// cdf[BINS] = 1.
    cdf: [f64; BINS + 1],
}

impl ExitTable {
    /// An exit from the uniforms `u` (which kind and bin) and `v` (μ within
    /// the bin): unscattered with probability e^{−R}, else a bin by q.
    #[inline]
    fn sample(&self, u: f64, v: f64) -> SphereExit {
        if u < self.unscattered {
            return SphereExit { cos_theta: 1.0, bin: None };
        }
        let u = ((u - self.unscattered) / (1.0 - self.unscattered)).min(1.0);
        // A bin the cdf picks has q > 0 (the fallback is for rounding).
        let k = (self.cdf.partition_point(|&c| c <= u).max(1) - 1).min(BINS - 1);
        let k = if self.density[k] > 0.0 { k } else { (0..BINS).rev().find(|&i| self.density[i] > 0.0).unwrap_or(k) };
        SphereExit { cos_theta: ((k as f64 + v) / BINS as f64).min(1.0), bin: Some(k) }
    }
}

/// Where a sphere jump leaves: unscattered, or scattered into bin `bin`
/// with exit cosine `cos_theta` to the outward normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SphereExit {
    /// cos θ between the exit direction and the sphere's outward normal at the exit point.
    pub cos_theta: f64,
    /// The bin of a scattered exit; `None` for the unscattered one.
    pub bin: Option<usize>,
}

/// Exit distributions of spheres of radii r_j (metres) in the three bands'
/// media; see the module documentation.
#[derive(Debug, Clone, PartialEq)]
pub struct SphereExits {
    radii_m: Vec<f64>,
    tables: [Vec<ExitTable>; 3],
}

impl SphereExits {
    /// Tables for the media with extinction `sigma_t_per_m` (μ_t > 0, 1/m)
    /// and albedo `albedo` (μ_s/μ_t ∈ [0, 1]) per band, for radii from
    /// [`SMALLEST_RADIUS_MFP`] mean free paths of the least extinct band up
    /// to `max_radius_m` in steps of [`RADIUS_RATIO`] (none when that is
    /// below the smallest). Deterministic: the same arguments give the
    /// same tables on every machine and thread count.
    ///
    /// ```
    /// use lucent_render::sphere::SphereExits;
    /// let s = SphereExits::new([1e4; 3], [0.999; 3], 1e-3);
    /// let j = s.largest_within(5e-4).unwrap();
    /// assert!(s.radius_m(j) <= 5e-4 && s.radius_m(j) * 1.25 > 5e-4);
    /// ```
    pub fn new(sigma_t_per_m: [f64; 3], albedo: [f64; 3], max_radius_m: f64) -> SphereExits {
        let sigma_min = sigma_t_per_m.iter().copied().fold(f64::INFINITY, f64::min);
        let r0 = SMALLEST_RADIUS_MFP / sigma_min;
        let radii_m: Vec<f64> =
            (0..MAX_RADII).map(|j| r0 * RADIUS_RATIO.powi(j as i32)).take_while(|&r| r <= max_radius_m).collect();
        let tables = std::array::from_fn(|band| {
            let radii: Vec<f64> = radii_m.iter().map(|r| r * sigma_t_per_m[band]).collect();
            let mut done: Vec<ExitTable> = Vec::with_capacity(radii.len());
            for (j, &radius) in radii.iter().enumerate() {
                let table = tabulate(radius, albedo[band], &radii[..j], &done, (band * MAX_RADII + j) as u64);
                done.push(table);
            }
            done
        });
        SphereExits { radii_m, tables }
    }

    /// The radius r_j, metres.
    #[inline]
    pub fn radius_m(&self, j: usize) -> f64 {
        self.radii_m[j]
    }

    /// The largest tabulated radius at most `r_m` metres, if any.
    #[inline]
    pub fn largest_within(&self, r_m: f64) -> Option<usize> {
        self.radii_m.partition_point(|&r| r <= r_m).checked_sub(1)
    }

    /// An exit of band `band`'s sphere j from the uniforms `u` (which kind
    /// and bin) and `v` (μ within the bin).
    #[inline]
    pub fn sample(&self, band: usize, j: usize, u: f64, v: f64) -> SphereExit {
        self.tables[band][j].sample(u, v)
    }

    /// Each band's contribution and density of `exit` at radius j (the
    /// factors common to all bands left out).
    #[inline]
    pub fn factors(&self, j: usize, exit: SphereExit) -> ([f64; 3], [f64; 3]) {
        self.bin_factors(j, exit.bin)
    }

    /// Each band's probability 1 − e^{−R_c} that a jump through sphere j
    /// scatters inside.
    #[inline]
    pub fn scattered_probability(&self, j: usize) -> [f64; 3] {
        std::array::from_fn(|c| 1.0 - self.tables[c][j].unscattered)
    }

    /// Given that a jump through sphere j scattered inside, each band's
    /// contribution w_c(μ) and density q_c(μ)/(1 − e^{−R_c}) per unit μ of
    /// leaving at cosine μ to the outward normal; (0, 0) for μ ≤ 0 (no path
    /// leaves inwards). Per steradian they are these over 2π (the azimuth is
    /// uniform): the exit point's "phase function" for a connection from it,
    /// whose sampling of the scattered branch itself is
    /// [`SphereExits::scattered_probability`].
    #[inline]
    pub fn given_scattered(&self, j: usize, mu: f64) -> ([f64; 3], [f64; 3]) {
        if mu.is_nan() || mu <= 0.0 {
            return ([0.0; 3], [0.0; 3]);
        }
        let (w, q) = self.bin_factors(j, Some(((mu * BINS as f64) as usize).min(BINS - 1)));
        let s = self.scattered_probability(j);
        (w, std::array::from_fn(|c| if s[c] > 0.0 { q[c] / s[c] } else { 0.0 }))
    }

    #[inline]
    fn bin_factors(&self, j: usize, bin: Option<usize>) -> ([f64; 3], [f64; 3]) {
        match bin {
            None => {
                let e = std::array::from_fn(|c| self.tables[c][j].unscattered);
                (e, e)
            }
            Some(k) => (
                std::array::from_fn(|c| self.tables[c][j].weight[k]),
                std::array::from_fn(|c| self.tables[c][j].density[k]),
            ),
        }
    }
}

/// A unit vector uniform over the sphere.
#[inline]
pub(crate) fn isotropic(rng: &mut Rng) -> DVec3 {
    let (u1, u2) = rng.next_f64_pair();
    leave(DVec3::Z, 1.0 - 2.0 * u1, u2)
}

/// The direction at cos θ = `mu` to the unit `normal`, azimuth 2π`u`.
#[inline]
pub fn leave(normal: DVec3, mu: f64, u: f64) -> DVec3 {
    DVec3::from_array(ScatteringAngles::at(mu, u).turn(normal.to_array()))
}

/// The table of a sphere of optical radius `radius` (mean free paths) for
/// albedo `albedo`, by walks that jump through the `inner` spheres (their
/// optical radii, ascending, and tables).
fn tabulate(radius: f64, albedo: f64, inner_radii: &[f64], inner: &[ExitTable], stream: u64) -> ExitTable {
    let unscattered = (-radius).exp();
    let chunks: Vec<([f64; BINS], [f64; BINS])> = (0..PATHS.div_ceil(CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let mut rng = Rng::new(0x5fe7e_u64 ^ stream, u64::from(chunk));
            let (mut count, mut weight) = ([0.0; BINS], [0.0; BINS]);
            for _ in 0..CHUNK.min(PATHS - chunk * CHUNK) {
                let (mu, w) = walk(radius, albedo, unscattered, inner_radii, inner, &mut rng);
                let k = ((mu * BINS as f64) as usize).min(BINS - 1);
                count[k] += 1.0;
                weight[k] += w;
            }
            (count, weight)
        })
        .collect();
    let (mut count, mut weight) = ([0.0; BINS], [0.0; BINS]);
    for (c, w) in &chunks {
        for k in 0..BINS {
            count[k] += c[k];
            weight[k] += w[k];
        }
    }
    // Per unit μ, the scattered part's mass 1 − e^{−R} (the walks are
    // conditioned on scattering inside).
    let scale = (1.0 - unscattered) * BINS as f64 / f64::from(PATHS);
    let density = count.map(|c| c * scale);
    let weight = weight.map(|w| w * scale);
    let mut cdf = [0.0; BINS + 1];
    for k in 0..BINS {
        cdf[k + 1] = cdf[k] + count[k] / f64::from(PATHS);
    }
    cdf[BINS] = 1.0;
    ExitTable { unscattered, density, weight, cdf }
}

/// One walk from the centre of the sphere of optical radius `radius`,
/// conditioned on scattering inside: the exit cosine and the albedo weight.
fn walk(
    radius: f64,
    albedo: f64,
    unscattered: f64,
    inner_radii: &[f64],
    inner: &[ExitTable],
    rng: &mut Rng,
) -> (f64, f64) {
    // The first flight, conditioned on ending inside: s < R.
    let s = -(1.0 - rng.next_f64() * (1.0 - unscattered)).ln();
    let mut x = s * isotropic(rng);
    let mut w = albedo;
    loop {
        // At a scattering point: jump through the largest inner sphere that
        // fits, else turn isotropically.
        let room = radius - x.length();
        let d = match inner_radii.partition_point(|&r| r <= room).checked_sub(1) {
            Some(i) => {
                let omega = isotropic(rng);
                x += inner_radii[i] * omega;
                let t = &inner[i];
                let (u, v) = rng.next_f64_pair();
                let exit = t.sample(u, v);
                match exit.bin {
                    None => omega,
                    Some(k) => {
                        w *= t.weight[k] / t.density[k];
                        let (a, _) = rng.next_f64_pair();
                        leave(omega, exit.cos_theta, a)
                    }
                }
            }
            None => isotropic(rng),
        };
        // The flight: out of the sphere, or to the next scattering point.
        let s = -(1.0 - rng.next_f64()).ln();
        let b = x.dot(d);
        let t_out = -b + (b * b - (x.length_squared() - radius * radius)).max(0.0).sqrt();
        if s >= t_out {
            let e = x + t_out * d;
            return ((d.dot(e) / radius).clamp(0.0, 1.0), w);
        }
        x += s * d;
        w *= albedo;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The jumping tables against plain walks of the same spheres (no
    /// inner jumps): the exit-cosine histograms by a two-sample χ² test
    /// and the probability of leaving unabsorbed by a z-test (4σ), at the
    /// smallest radius (no inner sphere fits), a middle and the largest.
    #[test]
    fn jumping_tables_agree_with_plain_walks() {
        let albedo = 0.995;
        let s = SphereExits::new([1.0; 3], [albedo; 3], 12.0);
        assert!(s.radii_m.len() >= 8, "{:?}", s.radii_m);
        for j in [0, 4, s.radii_m.len() - 1] {
            let radius = s.radii_m[j];
            let t = &s.tables[0][j];
            let scattered = 1.0 - t.unscattered;
            let paths = 20_000;
            let (mut plain, mut sw, mut sw2) = ([0.0; BINS], 0.0, 0.0);
            let mut rng = Rng::new(99, j as u64);
            for _ in 0..paths {
                let (mu, w) = walk(radius, albedo, t.unscattered, &[], &[], &mut rng);
                plain[((mu * BINS as f64) as usize).min(BINS - 1)] += 1.0;
                sw += w;
                sw2 += w * w;
            }
            let n = f64::from(paths);
            let (mw, se_w) = (sw / n, ((sw2 / n - (sw / n).powi(2)) / n).sqrt());
            // The table's counts and mean weight, back from its densities.
            let counts = t.density.map(|q| q / scattered / BINS as f64 * f64::from(PATHS));
            let table_w = t.weight.iter().sum::<f64>() / BINS as f64 / scattered;
            let (na, nb) = (f64::from(PATHS), n);
            let (chi2, used) =
                counts.iter().zip(&plain).filter(|(a, b)| **a + **b > 0.0).fold((0.0, 0usize), |(x, k), (&a, &b)| {
                    let d = (nb / na).sqrt() * a - (na / nb).sqrt() * b;
                    (x + d * d / (a + b), k + 1)
                });
            let limit = chi2_limit(used - 1);
            assert!(chi2 < limit, "r {radius}: χ² {chi2} over {} dof (limit {limit})", used - 1);
            // The table's own noise is of the plain estimate's order.
            let se = se_w * (1.0 + n / na).sqrt();
            assert!((table_w - mw).abs() < 4.0 * se, "r {radius}: w {table_w} vs {mw} ± {se_w}");
            assert!(table_w < 1.0 && table_w > 0.0);
        }
    }

    /// Sampling follows the table: χ² of the drawn bins against q, and the
    /// unscattered fraction against e^{−R}.
    #[test]
    fn draws_follow_the_tabulated_density() {
        let s = SphereExits::new([2.0, 1.0, 1.5], [0.99, 0.999, 0.9], 8.0);
        let j = 2;
        let r = s.radius_m(j);
        let mut rng = Rng::new(3, 0);
        let n = 200_000;
        let mut counts = [0.0; BINS + 1];
        for _ in 0..n {
            let e = s.sample(1, j, rng.next_f64(), rng.next_f64());
            match e.bin {
                None => counts[BINS] += 1.0,
                Some(k) => {
                    assert!(e.cos_theta >= k as f64 / BINS as f64 && e.cos_theta <= (k + 1) as f64 / BINS as f64);
                    counts[k] += 1.0
                }
            }
        }
        let t = &s.tables[1][j];
        let mut expected: Vec<f64> = t.density.iter().map(|q| q / BINS as f64 * n as f64).collect();
        expected.push((-r).exp() * n as f64);
        let chi2: f64 =
            counts.iter().zip(&expected).filter(|&(_, &e)| e > 0.0).map(|(&o, &e)| (o - e) * (o - e) / e).sum();
        let dof = expected.iter().filter(|&&e| e > 0.0).count() - 1;
        let limit = chi2_limit(dof);
        assert!(chi2 < limit, "χ² {chi2} over {dof} dof (limit {limit})");
        // The factors: unscattered exits have equal contribution and
        // density e^{−R_c}; scattered ones w ≤ q per band.
        let (f, p) = s.factors(j, SphereExit { cos_theta: 1.0, bin: None });
        assert_eq!(f, p);
        assert!((f[0] - (-2.0 * s.radius_m(j)).exp()).abs() < 1e-15);
        for k in 0..BINS {
            let (f, p) = s.factors(j, SphereExit { cos_theta: 0.5, bin: Some(k) });
            for c in 0..3 {
                assert!(f[c] <= p[c] * (1.0 + 1e-12), "band {c} bin {k}: {f:?} {p:?}");
            }
        }
    }

    /// The χ² quantile at p = 1e-4.
    fn chi2_limit(dof: usize) -> f64 {
        use statrs::distribution::{ChiSquared, ContinuousCDF};
        ChiSquared::new(dof as f64).expect("dof > 0").inverse_cdf(1.0 - 1e-4)
    }
}
