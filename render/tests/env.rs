//! Tests of the HDR environment (docs/method.md#render, `lucent_render::env`): the map seen
//! from the centre pixel by pixel, the yaw convention, the finite sphere seen
//! off-centre against closed forms and an independent quadratic, χ²
//! goodness-of-fit of `sample` against `pdf`, normalisation of `pdf`,
//! consistency of `sample` with `radiance`/`pdf`, an unbiased Monte Carlo
//! estimate of ∫L dω, and bad input. Fixed seeds; the conventions are
//! re-derived here from the module documentation, not taken from the module.

use glam::DVec3;
use lucent_render::env::{EnvError, Environment, Projection, BELOW_WEIGHT};
use lucent_render::rng::Rng;
use std::f64::consts::{PI, TAU};

const CENTRE: DVec3 = DVec3::new(0.1, -0.2, 0.3);
const R: f64 = 0.6;

fn sphere() -> Projection {
    Projection::FiniteSphere { centre: CENTRE, radius_m: R }
}

// ------------------------------------------------------------ conventions

/// The documented map direction of (u, v): θ = πv, φ = −2πu.
fn map_dir(u: f64, v: f64) -> DVec3 {
    let (th, ph) = (PI * v, TAU * u);
    DVec3::new(th.sin() * ph.cos(), -th.sin() * ph.sin(), th.cos())
}

/// R_z(deg) · d, counter-clockwise seen from +z.
fn rot_z(deg: f64, d: DVec3) -> DVec3 {
    let (s, c) = deg.to_radians().sin_cos();
    DVec3::new(c * d.x - s * d.y, s * d.x + c * d.y, d.z)
}

/// (u, v) of a map direction, by acos and atan2 (not the module's forms).
fn map_uv(m: DVec3) -> (f64, f64) {
    let m = m.normalize();
    let v = m.z.clamp(-1.0, 1.0).acos() / PI;
    let u = (-m.y.atan2(m.x) / TAU).rem_euclid(1.0);
    (u, v)
}

/// World direction with polar angle θ and azimuth φ (from +x towards +y).
fn spherical(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

fn scaled(scale: f64, c: [f32; 3]) -> [f64; 3] {
    c.map(|v| scale * f64::from(v))
}

/// A 32×16 map with a horizontal (R) and vertical (G) gradient, so every
/// pixel has its own value; a two-pixel spot ~50× brighter than the rest
/// (≈ 30 % of the power); a black block where the density must be 0; and a
/// pure-blue pixel.
fn test_map() -> (usize, usize, Vec<f32>) {
    let (w, h) = (32, 16);
    let mut rgb = Vec::with_capacity(3 * w * h);
    for y in 0..h {
        for x in 0..w {
            let mut c = [0.2 + 0.8 * x as f32 / 31.0, 0.3 + 0.7 * y as f32 / 15.0, 0.5];
            if y == 6 && (x == 5 || x == 6) {
                c = [40.0 + x as f32, 30.0, 20.0];
            }
            if (11..13).contains(&y) && (20..28).contains(&x) {
                c = [0.0; 3];
            }
            if (x, y) == (10, 14) {
                c = [0.0, 0.0, 0.3];
            }
            rgb.extend_from_slice(&c);
        }
    }
    (w, h, rgb)
}

fn test_env(yaw_deg: f64, scale: f64, projection: Projection) -> Environment {
    let (w, h, rgb) = test_map();
    Environment::new(w, h, rgb, yaw_deg, scale, projection).unwrap()
}

fn off_centre() -> DVec3 {
    CENTRE + DVec3::new(0.2 * R, -0.1 * R, 0.3 * R)
}

fn random_unit(rng: &mut Rng) -> DVec3 {
    let z = 2.0 * rng.next_f64() - 1.0;
    let phi = TAU * rng.next_f64();
    let s = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(s * phi.cos(), s * phi.sin(), z)
}

// -------------------------------------------------------------- quadrature

/// ∫∫ f(θ, φ) sin θ dθ dφ over [θa, θb] × [φa, φb] (θ, φ of the world frame
/// at the shading point). An `n × n` grid of cells, each integrated by the
/// 3×3 product Simpson rule; a cell whose nine values of f spread by more than
/// 2 % (a pixel edge of the piecewise-constant map, or the 1/sin θ of the map
/// pole) is split in four, down to `depth` levels, so steps are located to
/// 2^−depth of a cell instead of being smeared by a fixed grid. The error left
/// is O(2^−depth · cell) along the pixel edges.
#[allow(clippy::too_many_arguments)]
fn integrate(f: &dyn Fn(f64, f64) -> f64, ta: f64, tb: f64, pa: f64, pb: f64, n: usize, depth: u32) -> f64 {
    fn cell(f: &dyn Fn(f64, f64) -> f64, ta: f64, tb: f64, pa: f64, pb: f64, depth: u32) -> f64 {
        let ts = [ta, 0.5 * (ta + tb), tb];
        let ps = [pa, 0.5 * (pa + pb), pb];
        let mut v = [[0.0; 3]; 3];
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for i in 0..3 {
            for j in 0..3 {
                v[i][j] = f(ts[i], ps[j]);
                lo = lo.min(v[i][j]);
                hi = hi.max(v[i][j]);
            }
        }
        if depth == 0 || hi - lo <= 0.02 * hi.abs() {
            let wt = [1.0, 4.0, 1.0];
            let mut s = 0.0;
            for i in 0..3 {
                for j in 0..3 {
                    s += wt[i] * wt[j] * v[i][j] * ts[i].sin();
                }
            }
            return s * (tb - ta) * (pb - pa) / 36.0;
        }
        let (tm, pm) = (ts[1], ps[1]);
        cell(f, ta, tm, pa, pm, depth - 1)
            + cell(f, ta, tm, pm, pb, depth - 1)
            + cell(f, tm, tb, pa, pm, depth - 1)
            + cell(f, tm, tb, pm, pb, depth - 1)
    }
    let (dt, dp) = ((tb - ta) / n as f64, (pb - pa) / n as f64);
    let mut s = 0.0;
    for i in 0..n {
        for j in 0..n {
            let (t0, p0) = (ta + i as f64 * dt, pa + j as f64 * dp);
            s += cell(f, t0, t0 + dt, p0, p0 + dp, depth);
        }
    }
    s
}

/// ∫ f dω over the whole sphere of directions at the shading point.
fn integrate_sphere(f: &dyn Fn(DVec3) -> f64, n: usize, depth: u32) -> f64 {
    let g = |t: f64, p: f64| f(spherical(t, p));
    // Four φ quarters so the base grid is not too coarse in φ.
    (0..4)
        .map(|k| {
            let (pa, pb) = (k as f64 * PI / 2.0, (k + 1) as f64 * PI / 2.0);
            integrate(&g, 0.0, PI, pa, pb, n, depth)
        })
        .sum()
}

/// ∫ L(p, ω) dω_p over the sphere at `p` inside the finite sphere, by a change
/// of variables to the map: a patch dA at q = c + R d subtends dω_c = dA/R² at
/// c and dω_p = dA (d·ω)/|q − p|² at p, so with s = d − (p − c)/R,
/// dω_p = (d·s)/|s|³ dω_c, and dω_c = 2π² sin θ du dv. Each pixel's value
/// times the integral of that smooth factor over the pixel (composite Simpson,
/// 16 × 16 intervals): exact up to the smooth-integrand error (~1e-10), with
/// the pixel layout and the yaw taken from the documented conventions.
fn radiance_integral_via_map(w: usize, h: usize, rgb: &[f32], yaw: f64, scale: f64, p: DVec3) -> [f64; 3] {
    const M: usize = 16;
    let o = (p - CENTRE) / R;
    let simpson = |k: usize| {
        if k == 0 || k == M {
            1.0
        } else if k % 2 == 1 {
            4.0
        } else {
            2.0
        }
    };
    let mut total = [0.0; 3];
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for i in 0..=M {
                for j in 0..=M {
                    let u = (x as f64 + j as f64 / M as f64) / w as f64;
                    let v = (y as f64 + i as f64 / M as f64) / h as f64;
                    let d = rot_z(yaw, map_dir(u, v));
                    let s = d - o;
                    let factor = d.dot(s) / s.length().powi(3);
                    acc += simpson(i) * simpson(j) * factor * 2.0 * PI * PI * (PI * v).sin();
                }
            }
            let area = 1.0 / (w * h * 9 * M * M) as f64;
            for k in 0..3 {
                total[k] += scale * f64::from(rgb[3 * (y * w + x) + k]) * acc * area;
            }
        }
    }
    total
}

// ----------------------------------------------------------------- 1. centre

#[test]
fn centre_sees_every_pixel_exactly() {
    let (w, h, rgb) = test_map();
    for yaw in [0.0, 37.0, -110.0] {
        for projection in [sphere(), Projection::Infinite] {
            let env = Environment::new(w, h, rgb.clone(), yaw, 2.5, projection).unwrap();
            for y in 0..h {
                for x in 0..w {
                    let (u, v) = ((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
                    let dir = rot_z(yaw, map_dir(u, v));
                    let i = 3 * (y * w + x);
                    let want = scaled(2.5, [rgb[i], rgb[i + 1], rgb[i + 2]]);
                    assert_eq!(env.radiance(CENTRE, dir), want, "yaw {yaw} pixel ({x}, {y})");
                    assert_eq!(env.pixel(x, y), [rgb[i], rgb[i + 1], rgb[i + 2]]);
                    // The module's own coordinate helpers agree with the doc.
                    assert!((env.world_direction(u, v) - dir).length() < 1e-14);
                    let [mu, mv] = env.map_coordinates(dir);
                    assert!((mu - u).abs() < 1e-14 && (mv - v).abs() < 1e-14, "{mu} {mv} vs {u} {v}");
                }
            }
        }
    }
}

#[test]
fn yaw_turns_the_map_counter_clockwise() {
    // One bright pixel (3, 5) on a dark 32×16 map; pixel width 11.25°.
    let (w, h, x0, y0) = (32, 16, 3, 5);
    let mut rgb = vec![0.0_f32; 3 * w * h];
    rgb[3 * (y0 * w + x0)..3 * (y0 * w + x0) + 3].copy_from_slice(&[1.0, 2.0, 3.0]);
    let env = Environment::new(w, h, rgb, 37.0, 1.0, Projection::Infinite).unwrap();
    let theta = PI * (y0 as f64 + 0.5) / h as f64;
    // Map azimuth −2πu of the pixel centre, then +37° counter-clockwise.
    let phi_map = -TAU * (x0 as f64 + 0.5) / w as f64;
    let seen = |phi: f64| env.radiance(DVec3::ZERO, spherical(theta, phi));
    assert_eq!(seen(phi_map + 37f64.to_radians()), [1.0, 2.0, 3.0]);
    assert_eq!(seen(phi_map), [0.0; 3], "yaw ignored");
    assert_eq!(seen(phi_map - 37f64.to_radians()), [0.0; 3], "yaw turned clockwise");
    assert_eq!(seen(-phi_map + 37f64.to_radians()), [0.0; 3], "map mirrored");
    // Sampling finds the same pixel: every sample is along the rotated centre
    // direction to within the pixel's extent.
    let mut rng = Rng::new(5, 0);
    for _ in 0..1000 {
        let s = env.sample(DVec3::ZERO, [rng.next_f64(), rng.next_f64()]).unwrap();
        let phi = s.dir.y.atan2(s.dir.x);
        let dphi = (phi - phi_map - 37f64.to_radians() + PI).rem_euclid(TAU) - PI;
        assert!(dphi.abs() <= PI / w as f64 + 1e-12, "{dphi}");
        assert!((s.dir.z.acos() - theta).abs() <= PI / (2 * h) as f64 + 1e-12);
        assert_eq!(s.radiance, [1.0, 2.0, 3.0]);
    }
}

// --------------------------------------------------------------- 2. infinite

#[test]
fn infinite_radiance_is_independent_of_the_point() {
    let env = test_env(23.0, 1.7, Projection::Infinite);
    let (w, h, rgb) = test_map();
    let mut rng = Rng::new(2, 0);
    for _ in 0..20_000 {
        let dir = random_unit(&mut rng);
        let p = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 200.0 - 100.0;
        let l = env.radiance(p, dir);
        assert_eq!(l, env.radiance(DVec3::ZERO, dir));
        assert_eq!(env.pdf(p, dir), env.pdf(DVec3::ZERO, dir));
        let (u, v) = map_uv(rot_z(-23.0, dir));
        let (fx, fy) = (u * w as f64, v * h as f64);
        if near_edge(fx) || near_edge(fy) {
            continue;
        }
        let i = 3 * (fy as usize * w + fx as usize);
        assert_eq!(l, scaled(1.7, [rgb[i], rgb[i + 1], rgb[i + 2]]));
    }
}

fn near_edge(f: f64) -> bool {
    (f - f.round()).abs() < 1e-7
}

// ------------------------------------------------------ 3. finite sphere, p ≠ c

#[test]
fn polar_cap_boundary_seen_off_centre_matches_closed_form() {
    // Rows 0..4 of 16 lit: the cap θ < θ0 = π/4 (z > cos θ0) of the sphere.
    let (w, h, k) = (24, 16, 4);
    let theta0 = PI * k as f64 / h as f64;
    let mut rgb = vec![0.0_f32; 3 * w * h];
    rgb[..3 * w * k].fill(1.0);
    let env = Environment::new(w, h, rgb, 37.0, 1.0, sphere()).unwrap();
    for eta in [0.0, 0.5, -0.7, 0.93] {
        let p = CENTRE + DVec3::Z * (eta * R);
        // The cap's rim, at R(sin θ0 cos φ, sin θ0 sin φ, cos θ0) from c, is
        // seen from p = c + ηR ẑ at polar angle α = atan2(sin θ0, cos θ0 − η).
        let alpha = theta0.sin().atan2(theta0.cos() - eta);
        for j in 0..36 {
            let phi = TAU * (j as f64 + 0.3) / 36.0;
            let inside = env.radiance(p, spherical(alpha - 1e-3, phi));
            let outside = env.radiance(p, spherical(alpha + 1e-3, phi));
            assert_eq!(inside, [1.0; 3], "η {eta} φ {phi}: α = {alpha}");
            assert_eq!(outside, [0.0; 3], "η {eta} φ {phi}: α = {alpha}");
        }
    }
}

#[test]
fn sideways_displacement_matches_an_independent_quadratic() {
    let (yaw, scale) = (-64.0, 0.8);
    let env = test_env(yaw, scale, sphere());
    let (w, h, rgb) = test_map();
    let p = CENTRE + DVec3::new(0.3 * R, -0.2 * R, 0.1 * R);
    let mut rng = Rng::new(3, 0);
    let mut checked = 0;
    for _ in 0..20_000 {
        let dir = random_unit(&mut rng);
        // |p + tω − c|² = R²: A t² + B t + C = 0, larger root.
        let o = p - CENTRE;
        let (a, b, c) = (dir.dot(dir), 2.0 * dir.dot(o), o.dot(o) - R * R);
        let t = (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * a);
        let q = p + t * dir;
        assert!(((q - CENTRE).length() - R).abs() < 1e-12);
        let (u, v) = map_uv(rot_z(-yaw, (q - CENTRE) / R));
        let (fx, fy) = (u * w as f64, v * h as f64);
        if near_edge(fx) || near_edge(fy) {
            continue;
        }
        let i = 3 * (fy as usize * w + fx as usize);
        assert_eq!(env.radiance(p, dir), scaled(scale, [rgb[i], rgb[i + 1], rgb[i + 2]]), "ω {dir}");
        checked += 1;
    }
    assert!(checked > 19_900);

    // One by hand: from c + (R/2, 0, 0) looking along +y the ray meets the
    // sphere at c + R(½, √¾, 0): azimuth +60°, so u = 5/6 (x = 26), v = ½
    // (y = 8) with yaw 0.
    let env = test_env(0.0, 1.0, sphere());
    let i = 3 * (8 * w + 26);
    assert_eq!(env.radiance(CENTRE + DVec3::X * (R / 2.0), DVec3::Y), scaled(1.0, [rgb[i], rgb[i + 1], rgb[i + 2]]));
}

// ------------------------------------------------------------ 4. χ² and norm

/// χ² goodness-of-fit of `env.sample` at `p` against `env.pdf`: `n` samples
/// from a fixed seed binned in (cos θ, φ) of the world frame on 20 × 40
/// equal-solid-angle bins; expected counts n × ∫_bin pdf dω by adaptive
/// quadrature; bins expecting < 5 pooled. Returns the p-value.
fn chi2_pvalue(env: &Environment, p: DVec3, n: usize, seed: u64) -> f64 {
    const NMU: usize = 20;
    const NPHI: usize = 40;
    let mut observed = vec![0.0_f64; NMU * NPHI];
    let mut rng = Rng::new(seed, 0);
    for _ in 0..n {
        let s = env.sample(p, [rng.next_f64(), rng.next_f64()]).expect("a sample inside the sphere");
        assert!((s.dir.length() - 1.0).abs() < 1e-12 && s.pdf > 0.0 && s.pdf.is_finite());
        let mu = s.dir.z.clamp(-1.0, 1.0);
        let phi = s.dir.y.atan2(s.dir.x).rem_euclid(TAU);
        let i = (((mu + 1.0) / 2.0 * NMU as f64) as usize).min(NMU - 1);
        let j = ((phi / TAU * NPHI as f64) as usize).min(NPHI - 1);
        observed[i * NPHI + j] += 1.0;
    }
    let f = |t: f64, ph: f64| env.pdf(p, spherical(t, ph));
    let mut expected = vec![0.0_f64; NMU * NPHI];
    for i in 0..NMU {
        let mu_lo = -1.0 + 2.0 * i as f64 / NMU as f64;
        let mu_hi = -1.0 + 2.0 * (i + 1) as f64 / NMU as f64;
        let (ta, tb) = (mu_hi.acos(), mu_lo.acos());
        for j in 0..NPHI {
            let (pa, pb) = (TAU * j as f64 / NPHI as f64, TAU * (j + 1) as f64 / NPHI as f64);
            expected[i * NPHI + j] = n as f64 * integrate(&f, ta, tb, pa, pb, 3, 5);
        }
    }
    let total: f64 = expected.iter().sum();
    assert!((total / n as f64 - 1.0).abs() < 1e-3, "∫pdf = {}", total / n as f64);

    let fit = lucent_testkit::chi2::goodness_of_fit(&observed, &expected);
    eprintln!("χ² = {:.1} on {} dof, p = {:.3}", fit.chi2, fit.dof, fit.p_value);
    fit.p_value
}

#[test]
fn chi2_sample_matches_pdf_off_centre() {
    let env = test_env(25.0, 1.3, sphere());
    let pv = chi2_pvalue(&env, off_centre(), 500_000, 11);
    assert!(pv > 1e-4, "p-value {pv}");
}

#[test]
fn chi2_sample_matches_pdf_at_centre() {
    let env = test_env(25.0, 1.3, sphere());
    let pv = chi2_pvalue(&env, CENTRE, 500_000, 12);
    assert!(pv > 1e-4, "p-value {pv}");
}

#[test]
fn chi2_sample_matches_pdf_infinite() {
    let env = test_env(-140.0, 1.0, Projection::Infinite);
    let pv = chi2_pvalue(&env, DVec3::new(3.0, -4.0, 5.0), 500_000, 13);
    assert!(pv > 1e-4, "p-value {pv}");
}

#[test]
fn a_forgotten_jacobian_is_caught() {
    // The harness must be able to fail: the density at the centre of the
    // direction d(ω) that the ray from p hits, without the Jacobian
    // |q − p|²/(R² d·ω), is not a density at p and disagrees with the samples.
    let env = test_env(25.0, 1.3, sphere());
    let inf = test_env(25.0, 1.3, Projection::Infinite);
    let p = off_centre();
    let hit = |dir: DVec3| {
        let o = p - CENTRE;
        let (b, c) = (2.0 * dir.dot(o), o.dot(o) - R * R);
        let t = (-b + (b * b - 4.0 * c).sqrt()) / 2.0;
        (p + t * dir - CENTRE) / R
    };
    let wrong = |t: f64, ph: f64| inf.pdf(DVec3::ZERO, hit(spherical(t, ph)));
    let right = |t: f64, ph: f64| env.pdf(p, spherical(t, ph));
    let total_wrong = integrate(&wrong, 0.0, PI, 0.0, TAU, 24, 5);
    assert!((total_wrong - 1.0).abs() > 0.02, "{total_wrong}");
    // The fraction of samples in the cap θ < 60° at p.
    let mut rng = Rng::new(14, 0);
    let (mut inside, n) = (0usize, 200_000);
    for _ in 0..n {
        let s = env.sample(p, [rng.next_f64(), rng.next_f64()]).unwrap();
        inside += (s.dir.z > 0.5) as usize;
    }
    let want_right = integrate(&right, 0.0, PI / 3.0, 0.0, TAU, 24, 5);
    let want_wrong = integrate(&wrong, 0.0, PI / 3.0, 0.0, TAU, 24, 5);
    let got = inside as f64 / n as f64;
    let se = (got * (1.0 - got) / n as f64).sqrt();
    assert!((got - want_right).abs() < 4.0 * se, "{got} vs {want_right}");
    assert!((got - want_wrong).abs() > 20.0 * se, "{got} vs {want_wrong}");
}

#[test]
fn pdf_integrates_to_one() {
    for (name, env, p) in [
        ("off-centre", test_env(25.0, 1.3, sphere()), off_centre()),
        ("near the wall", test_env(-10.0, 1.0, sphere()), CENTRE + DVec3::new(-0.55, 0.2, -0.1) * R),
        ("centre", test_env(25.0, 1.3, sphere()), CENTRE),
        ("infinite", test_env(25.0, 1.3, Projection::Infinite), off_centre()),
    ] {
        let total = integrate_sphere(&|d| env.pdf(p, d), 8, 6);
        assert!((total - 1.0).abs() < 1e-3, "{name}: ∫pdf dω = {total}");
    }
}

// ----------------------------------------------------------- 5. consistency

#[test]
fn sample_agrees_with_radiance_and_pdf() {
    for (env, p) in [
        (test_env(25.0, 1.3, sphere()), off_centre()),
        (test_env(25.0, 1.3, sphere()), CENTRE),
        (test_env(0.0, 1.0, sphere()), CENTRE + DVec3::new(0.0, 0.0, 0.999 * R)),
        (test_env(-140.0, 2.0, Projection::Infinite), DVec3::new(7.0, 8.0, 9.0)),
    ] {
        let mut rng = Rng::new(21, 0);
        for _ in 0..50_000 {
            let u = [rng.next_f64(), rng.next_f64()];
            let s = env.sample(p, u).unwrap();
            assert!((s.dir.length() - 1.0).abs() < 1e-12);
            assert_eq!(s.radiance, env.radiance(p, s.dir), "u {u:?}");
            let pdf = env.pdf(p, s.dir);
            assert!((pdf - s.pdf).abs() <= 1e-9 * s.pdf, "u {u:?}: {pdf} vs {}", s.pdf);
        }
    }
}

// ----------------------------------------------------------- 6. unbiasedness

#[test]
fn estimator_of_the_radiance_integral_is_unbiased() {
    // ∫ L(p, ω) dω at an off-centre p, estimated by the mean of L/pdf over
    // `sample`, against the integral over the map's pixels (a different
    // parametrisation: it does not use the module's pdf or lookup).
    let (w, h, rgb) = test_map();
    let (yaw, scale) = (25.0, 1.3);
    let env = test_env(yaw, scale, sphere());
    let p = off_centre();
    let n = 400_000;
    let mut rng = Rng::new(31, 0);
    let (mut sum, mut sum2) = ([0.0; 3], [0.0; 3]);
    for _ in 0..n {
        let s = env.sample(p, [rng.next_f64(), rng.next_f64()]).unwrap();
        for k in 0..3 {
            let x = s.radiance[k] / s.pdf;
            sum[k] += x;
            sum2[k] += x * x;
        }
    }
    let want = radiance_integral_via_map(w, h, &rgb, yaw, scale, p);
    let at_centre = radiance_integral_via_map(w, h, &rgb, yaw, scale, CENTRE);
    for k in 0..3 {
        let mean = sum[k] / n as f64;
        let se = ((sum2[k] / n as f64 - mean * mean) / (n - 1) as f64).sqrt();
        assert!((mean - want[k]).abs() < 4.0 * se, "channel {k}: {mean} ± {se} vs {}", want[k]);
        // The test can tell: the centre sees a different integral.
        assert!((at_centre[k] - want[k]).abs() > 10.0 * se, "channel {k}: {} vs {}", at_centre[k], want[k]);
        // From the centre the integral is 4π × the mean radiance.
        let mean_rad = env.mean_radiance()[k];
        assert!(
            (at_centre[k] / (4.0 * PI * mean_rad) - 1.0).abs() < 1e-9,
            "channel {k}: {} vs 4π × {mean_rad}",
            at_centre[k]
        );
    }
    // And the same through the module's lookup, integrated at p in p's own
    // frame (adaptive quadrature; agreement to its accuracy).
    let direct = integrate_sphere(&|d| env.radiance(p, d)[1], 8, 7);
    assert!((direct / want[1] - 1.0).abs() < 1e-3, "{direct} vs {}", want[1]);
}

/// The test map weighted towards a tilted normal (as a scene's board does).
fn facing_env() -> Environment {
    let mut env = test_env(25.0, 1.3, sphere());
    env.set_sampling_normal(Some(DVec3::new(0.3, -0.2, 0.9).normalize()));
    env
}

#[test]
fn weighting_towards_a_normal_keeps_sample_pdf_and_integral_consistent() {
    let env = facing_env();
    let p = off_centre();
    let pv = chi2_pvalue(&env, p, 500_000, 15);
    assert!(pv > 1e-4, "p-value {pv}");
    let total = integrate_sphere(&|d| env.pdf(p, d), 8, 6);
    assert!((total - 1.0).abs() < 1e-3, "∫pdf dω = {total}");
    let mut rng = Rng::new(22, 0);
    let (mut sum, mut sum2, n) = (0.0, 0.0, 400_000);
    for _ in 0..n {
        let s = env.sample(p, [rng.next_f64(), rng.next_f64()]).unwrap();
        assert!((env.pdf(p, s.dir) - s.pdf).abs() <= 1e-9 * s.pdf);
        let x = s.radiance[1] / s.pdf;
        sum += x;
        sum2 += x * x;
    }
    let (w, h, rgb) = test_map();
    let want = radiance_integral_via_map(w, h, &rgb, 25.0, 1.3, p)[1];
    let mean = sum / n as f64;
    let se = ((sum2 / n as f64 - mean * mean) / (n - 1) as f64).sqrt();
    assert!((mean - want).abs() < 4.0 * se, "{mean} ± {se} vs {want}");
}

#[test]
fn weighting_towards_a_normal_follows_kappa_plus_cosine() {
    // At the centre of an infinite map the density of pixel (x, y) is its
    // weight over the total: weighted / plain = (κ + max(0, n·d)) / Z for
    // every pixel centre d, one constant Z. The test map's spot and black
    // block make the weights uneven; the floor is part of both.
    let (w, h, rgb) = test_map();
    let plain = Environment::new(w, h, rgb.clone(), 25.0, 1.3, Projection::Infinite).unwrap();
    let mut weighted = Environment::new(w, h, rgb, 25.0, 1.3, Projection::Infinite).unwrap();
    let n = DVec3::new(0.3, -0.2, 0.9).normalize();
    weighted.set_sampling_normal(Some(n));
    assert!(weighted.sampling_normal().is_some_and(|m| (m - n).length() < 1e-15));
    let mut ratios = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let d = plain.world_direction((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
            let (a, b) = (plain.pdf(DVec3::ZERO, d), weighted.pdf(DVec3::ZERO, d));
            if a > 0.0 {
                ratios.push(b / a / (BELOW_WEIGHT + n.dot(d).max(0.0)));
            } else {
                assert_eq!(b, 0.0, "pixel ({x}, {y})");
            }
        }
    }
    let z = ratios[0];
    assert!(ratios.iter().all(|r| (r / z - 1.0).abs() < 1e-9), "{ratios:?}");
    // Along n against −n: (κ + 1)/κ = 11 times more likely than plain
    // (the test can tell the weighting from none).
    let gain = |d: DVec3| weighted.pdf(DVec3::ZERO, d) / plain.pdf(DVec3::ZERO, d);
    assert!(gain(n) / gain(-n) > 9.0, "{}", gain(n) / gain(-n));
    // None restores the plain tables exactly.
    weighted.set_sampling_normal(None);
    let d = DVec3::new(0.1, 0.7, -0.3).normalize();
    assert_eq!(weighted.pdf(DVec3::ZERO, d), plain.pdf(DVec3::ZERO, d));
}

#[test]
fn constant_environment_is_uniform() {
    let env = Environment::constant([0.25, 0.5, 2.0], sphere());
    let mut rng = Rng::new(41, 0);
    let n = 200_000;
    let (mut sum, mut sum2) = (0.0, 0.0);
    for _ in 0..n {
        let p = CENTRE + random_unit(&mut rng) * (0.9 * R * rng.next_f64());
        let dir = random_unit(&mut rng);
        assert_eq!(env.radiance(p, dir), [0.25, 0.5, 2.0]);
        let s = env.sample(p, [rng.next_f64(), rng.next_f64()]).unwrap();
        let x = s.radiance[1] / s.pdf;
        sum += x;
        sum2 += x * x;
    }
    // E[L/pdf] = 4π L at every p inside the sphere.
    let mean = sum / n as f64;
    let se = ((sum2 / n as f64 - mean * mean) / (n - 1) as f64).sqrt();
    assert!((mean - 4.0 * PI * 0.5).abs() < 4.0 * se, "{mean} ± {se}");
    assert_eq!(env.mean_radiance(), [0.25, 0.5, 2.0]);
}

// ------------------------------------------------------------- 7. bad input

#[test]
fn bad_input_is_rejected_with_a_reason() {
    let ok = || vec![0.5_f32; 3 * 4 * 2];
    let err = |w, h, rgb, yaw, scale, proj| Environment::new(w, h, rgb, yaw, scale, proj).unwrap_err();
    let msg = |e: EnvError| e.to_string();

    let e = err(4, 2, vec![0.5; 23], 0.0, 1.0, Projection::Infinite);
    assert!(matches!(e, EnvError::DataLength { expected: 24, got: 23, .. }));
    assert!(msg(e).contains("24 RGB values, got 23"));

    let e = err(0, 2, vec![], 0.0, 1.0, Projection::Infinite);
    assert!(msg(e).contains("at least 1"));

    let mut nan = ok();
    nan[3 * (4 + 2) + 1] = f32::NAN; // pixel (2, 1), G
    let e = msg(err(4, 2, nan, 0.0, 1.0, Projection::Infinite));
    assert!(e.contains("(x = 2, y = 1)") && e.contains("channel G") && e.contains("NaN"), "{e}");

    let mut neg = ok();
    neg[3 * 3 + 2] = -0.5; // pixel (3, 0), B
    let e = msg(err(4, 2, neg, 0.0, 1.0, Projection::Infinite));
    assert!(e.contains("(x = 3, y = 0)") && e.contains("channel B") && e.contains("-0.5"), "{e}");

    let mut inf = ok();
    inf[0] = f32::INFINITY;
    assert!(msg(err(4, 2, inf, 0.0, 1.0, Projection::Infinite)).contains("(x = 0, y = 0)"));

    let e = msg(err(4, 2, ok(), 0.0, f64::NAN, Projection::Infinite));
    assert!(e.contains("scale NaN"), "{e}");
    assert!(msg(err(4, 2, ok(), 0.0, -1.0, Projection::Infinite)).contains("scale -1"));
    let mut big = ok();
    big[5] = f32::MAX;
    assert!(msg(err(4, 2, big, 0.0, 1e300, Projection::Infinite)).contains("overflows"));
    assert!(msg(err(4, 2, ok(), f64::INFINITY, 1.0, Projection::Infinite)).contains("yaw"));

    let zero_r = Projection::FiniteSphere { centre: CENTRE, radius_m: 0.0 };
    let e = msg(err(4, 2, ok(), 0.0, 1.0, zero_r));
    assert!(e.contains("radius 0 m"), "{e}");
    let nan_r = Projection::FiniteSphere { centre: CENTRE, radius_m: f64::NAN };
    assert!(msg(err(4, 2, ok(), 0.0, 1.0, nan_r)).contains("radius NaN"));
    let bad_c = Projection::FiniteSphere { centre: DVec3::new(0.0, f64::NAN, 0.0), radius_m: 0.6 };
    assert!(msg(err(4, 2, ok(), 0.0, 1.0, bad_c)).contains("centre"));

    // Overflowing sizes are an error, not a panic.
    assert!(matches!(err(usize::MAX, 2, vec![], 0.0, 1.0, Projection::Infinite), EnvError::TooLarge { .. }));
    // An all-zero map is valid.
    assert!(Environment::new(4, 2, vec![0.0; 24], 0.0, 1.0, Projection::Infinite).is_ok());
}
