//! Crossing the object's surface, from inside (`leave_medium`) and from
//! outside (`enter_object`), both through one routine (`cross`) that asks
//! the interface for the crossing, smooth and rough alike
//! ([`Interface::cross`](crate::interface::Interface::cross)): a smooth
//! boundary chooses reflection with the Fresnel reflectance F of the
//! driving band (unpolarised Fresnel and Snell, [`crate::fresnel`]; per
//! band under shared directions) and refraction otherwise, so the factors
//! cancel; a rough one is sampled (Walter et al. 2007, weight f|cos|/pdf,
//! radiance transport). Entering, a path picks its band (or branches into
//! three) and may split into reflection and refraction. Also the geometry
//! the connections share: Snell's law backwards (`unrefract`), the face
//! search of a mesh that is not a convex polyhedron (`mesh_exit`). Angles
//! are given by their cosines to the face normal.

use super::accumulate::Estimate;
use super::board_nee::BoardVertex;
use super::image::Stats;
use super::scene::Object;
use super::throughput::roulette;
use super::walk::{sphere_tables, trace_path, Path, Walk};
use crate::accel::{Accel, Hit};
use crate::fresnel;
use crate::interface::Crossing;
use crate::rng::Rng;
use glam::DVec3;
use std::f64::consts::TAU;
use std::ops::ControlFlow;

/// The Fresnel reflectance per band at a smooth boundary under
/// [`Dispersion::SharedDirections`]: each band's own index at the angle of
/// incidence `cos_i` > 0; `from_inside`: the path is in the medium (relative
/// index 1/n_c), and `f_mean`, the mean index's reflectance there, = 1 marks
/// total internal reflection, which then holds in every band.
#[inline]
pub(super) fn band_reflectance(obj: &Object, cos_i: f64, f_mean: f64, from_inside: bool) -> [f64; 3] {
    if from_inside && f_mean >= 1.0 {
        return [1.0; 3];
    }
    std::array::from_fn(|c| {
        let eta = obj.eta(c);
        fresnel::reflectance(cos_i, if from_inside { 1.0 / eta } else { eta })
    })
}

/// The Fresnel reflectance at a smooth boundary at the angle of incidence
/// cos_i > 0 with the path's index `eta` (its band's, or the bands' mean
/// under `shared`), from inside the medium (relative index 1/η) or from
/// outside: that value, and per band the same or, under `shared`, each
/// band's own ([`band_reflectance`]).
#[inline]
pub(super) fn reflectances(obj: &Object, cos_i: f64, eta: f64, shared: bool, from_inside: bool) -> (f64, [f64; 3]) {
    let f = fresnel::reflectance(cos_i, if from_inside { 1.0 / eta } else { eta });
    (f, if shared { band_reflectance(obj, cos_i, f, from_inside) } else { [f; 3] })
}

/// Snell's law backwards at a flat face with unit normal `n`: the direction
/// v on the far side (relative index `eta` = n_far / n_near) that refracts
/// into the unit direction `w` leaving the face on n's side (n·w > 0), and
/// cos θ_v = n·v; `None` where no v does (w beyond the critical angle).
/// Both travel along +n: v = (w − (n·w) n)/η + cos θ_v n.
#[inline]
pub(super) fn unrefract(w: DVec3, n: DVec3, eta: f64) -> Option<(DVec3, f64)> {
    let cos_w = n.dot(w);
    let cos_v = (1.0 - (1.0 - cos_w * cos_w) / (eta * eta)).max(0.0).sqrt();
    (cos_v > 0.0).then(|| (((w - cos_w * n) / eta + cos_v * n).normalize(), cos_v))
}

/// Refraction of unit `d` through an interface with unit normal `n`,
/// relative index `eta` = n_t/n_i ([`fresnel::refract`]). The caller has
/// already chosen refraction, so total internal reflection cannot occur
/// (F = 1 there); it falls back to the mirror direction defensively.
#[inline]
pub(super) fn refract_or_mirror(d: DVec3, n: DVec3, eta: f64) -> DVec3 {
    fresnel::refract(d, n, eta).unwrap_or_else(|| d - 2.0 * d.dot(n) * n)
}

/// Steps of [`mesh_exit`]'s search.
pub(super) const MESH_EXIT_STEPS: usize = 4;

/// Where the inside ray from `x` that refracts into the outside direction
/// `wo` leaves a mesh: the face is searched by fixed-point steps, starting
/// from the face the ray x + t·ω_o meets: the inside direction ω_i that
/// refracts into ω_o at that face's plane (Snell backwards, relative index
/// `eta`) is traced from x, and the face it meets is taken next, until a
/// face is met by its own ω_i (found) or [`MESH_EXIT_STEPS`] steps pass
/// (none). The search is deterministic in (x, ω_o), so the path's own escape
/// asks it whether a connection would have made the same path
/// (multiple-importance weights), and a face it does not find is left to the
/// path's escape and the phase connection.
pub(super) fn mesh_exit(accel: &Accel, x: DVec3, wo: DVec3, eta: f64) -> Option<MeshExit> {
    let mut hit = accel.exit(x, wo)?;
    let mut dir = wo;
    for _ in 0..MESH_EXIT_STEPS {
        let n = if hit.normal.dot(dir) >= 0.0 { hit.normal } else { -hit.normal };
        if n.dot(wo) <= 0.0 {
            return None;
        }
        let (wi, cos_i) = unrefract(wo, n, eta)?;
        let next = accel.exit_from(x, wi, hit.triangle)?;
        if next.triangle == hit.triangle {
            return Some(MeshExit { hit: next, n, wi, cos_i });
        }
        (hit, dir) = (next, wi);
    }
    None
}

/// True when [`mesh_exit`] finds `triangle` for (x, ω_o): the environment
/// connection makes a path that left through it (the path's own escape and
/// the phase connection ask this for their weights).
pub(super) fn mesh_exit_through(accel: &Accel, x: DVec3, wo: DVec3, eta: f64, triangle: u32) -> bool {
    mesh_exit(accel, x, wo, eta).is_some_and(|e| e.hit.triangle == triangle)
}

/// A face found by [`mesh_exit`]: the hit, the outward normal n, the inside
/// direction ω_i and cos θ_i = n·ω_i.
pub(super) struct MeshExit {
    pub(super) hit: crate::accel::Hit,
    pub(super) n: DVec3,
    pub(super) wi: DVec3,
    pub(super) cos_i: f64,
}

impl Walk<'_> {
    /// One crossing of the object's boundary at `p` (unit outward normal
    /// `outward`) by the path, from inside or from outside, in driving band
    /// `h`, for smooth and rough boundaries alike: the interface's crossing
    /// ([`Interface::cross`](crate::interface::Interface::cross); `reflect`:
    /// a smooth boundary's probability of reflection, `None` to take the
    /// refraction), its sampled weight on the throughput, and the path
    /// moved to the side it goes to (offset ε along the normal). `None`:
    /// the sample was lost (the path ends).
    #[allow(clippy::too_many_arguments)]
    fn cross(
        &self,
        obj: &Object,
        h: usize,
        outward: DVec3,
        p: DVec3,
        from_inside: bool,
        reflect: Option<f64>,
        path: &mut Path,
        rng: &mut Rng,
    ) -> Option<Crossing> {
        let eta = if self.shared { obj.eta_mean } else { obj.eta(h) };
        let crossing = obj.interface.cross(path.d, outward, eta, from_inside, reflect, rng)?;
        if crossing.weighted {
            for beta in path.tp.beta.iter_mut() {
                *beta *= crossing.weight;
            }
        }
        let eps = self.scene.epsilon_m;
        path.inside = from_inside != crossing.transmitted;
        path.d = crossing.dir;
        path.o = if path.inside { p - eps * outward } else { p + eps * outward };
        Some(crossing)
    }

    /// The flight from the path's point in `obj`'s medium reaches the
    /// boundary at `hit` (probability e^{−μ_t,h t} in driving band `h`) and
    /// crosses it (`cross`; a smooth boundary reflects with probability F_h):
    /// after a reflection the stretch stays one the connections make (one
    /// reflection, with the chains); after a refraction out its density in
    /// outside solid angle (for the weights of its escape) takes the
    /// refraction's dω_i/dω_o = cos θ_o / (n² cos θ_i). A rough boundary's
    /// sampled weight is followed by the roulette.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn leave_medium(
        &self,
        obj: &Object,
        h: usize,
        hit: &Hit,
        path: &mut Path,
        est: &mut Estimate,
        rng: &mut Rng,
        st: &mut Stats,
    ) -> ControlFlow<()> {
        let (settings, shared) = (self.settings, self.shared);
        let bc = &obj.bands;
        let sigma_t = bc.sigma_t[h];
        // The flight reaches the boundary: probability e^{−μ_t,h t}.
        if !bc.same_sigma_t && !path.tp.single_band() {
            let tp = &path.tp;
            let decay: [f64; 3] =
                std::array::from_fn(|c| if tp.active(c) { (-(bc.sigma_t[c] - sigma_t) * hit.t).exp() } else { 0.0 });
            path.tp.scale(decay, decay, h);
        }
        st.surface_hits += 1;
        est.flight(obj, hit.t);
        let p = path.o + hit.t * path.d;
        let n_out = if hit.normal.dot(path.d) >= 0.0 { hit.normal } else { -hit.normal };
        path.stretch.t += hit.t;
        if let Some(c) = path.chain.as_mut() {
            c.pdf *= (-sigma_t * hit.t).exp();
        }
        let eta = if shared { obj.eta_mean } else { obj.eta(h) };
        let cos_i = path.d.dot(n_out);
        let (_, fr) = reflectances(obj, cos_i, eta, shared, true);
        let Some(crossing) = self.cross(obj, h, n_out, p, true, Some(fr[h]), path, rng) else {
            return ControlFlow::Break(());
        };
        if !crossing.transmitted {
            if shared {
                path.tp.scale(fr, fr, h);
            }
            // One reflection on the way out keeps the stretch one that
            // the connections make (with the chains).
            if self.chains && self.planes.is_some() && path.vertex.is_some() && path.stretch.refl.is_none() {
                path.stretch.refl = Some(fr[h]);
            } else {
                path.vertex = None;
            }
            path.chain = None;
            path.safe = 0.0;
        } else {
            let f = fr[h];
            if shared {
                let t = fr.map(|x| 1.0 - x);
                path.tp.scale(t, t, h);
            }
            if path.vertex.is_some() {
                let stretch = &mut path.stretch;
                stretch.triangle = hit.triangle;
                // Phase sampling, the flights, a reflection, refraction; in outside
                // solid angle: dω_i/dω_o = cos θ_o / (n² cos θ_i).
                stretch.jacobian = path.d.dot(n_out) / (eta * eta * cos_i);
                let density = match (path.vertex.and_then(|v| v.sphere), sphere_tables(obj, settings)) {
                    (Some(j), Some(t)) => t.given_scattered(j, stretch.mu).1[h] / TAU,
                    _ => obj.medium[h].phase.eval(stretch.mu),
                };
                stretch.pdf =
                    density * (-sigma_t * stretch.t).exp() * stretch.refl.unwrap_or(1.0) * (1.0 - f) * stretch.jacobian;
            }
            if let Some(c) = path.chain.as_mut() {
                // Out: 1 − F and the second refraction's cos θ_o / cos θ_i.
                c.pdf *= (1.0 - f) * path.d.dot(n_out) / cos_i;
                c.out = true;
            }
        }
        path.last_diffuse_pdf = None;
        if crossing.weighted && !roulette(&mut path.tp, settings, rng) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }

    /// The path meets the object's boundary from outside at `hit`: with
    /// band branches, one branch per band from here; else (after the
    /// split's reflection branch, if any) the driving band is picked and
    /// the path crosses (`cross`): a smooth boundary refracts in with
    /// probability 1 − F_h (or weight 1 − F_c when split) or reflects; a
    /// rough one's sampled weight is followed by the roulette.
    pub(super) fn enter_object(
        &self,
        hit: &Hit,
        path: &mut Path,
        est: &mut Estimate,
        rng: &mut Rng,
        st: &mut Stats,
    ) -> ControlFlow<()> {
        let (scene, settings, shared) = (self.scene, self.settings, self.shared);
        path.vertex = None;
        if path.chain.is_some_and(|c| c.out) {
            path.chain = None;
        }
        let obj = scene.object.as_ref().expect("object hit without an object");
        let p = path.o + hit.t * path.d;
        let n_in = if hit.normal.dot(path.d) < 0.0 { hit.normal } else { -hit.normal };
        let one_band = !(settings.spectral_mis && (obj.bands.achromatic || shared));
        if path.hero.is_none() && one_band && settings.band_branches {
            // One branch per band from here, each in its band alone
            // (each makes its own split of the entry, if any).
            let score = est.score;
            for b in 0..3 {
                let branch = path.tp.keep_band(b, 1.0);
                trace_path(scene, settings, path.o, path.d, branch, Some(b), path.events, self.split, est, rng, st);
                est.score = score;
            }
            return ControlFlow::Break(());
        }
        // (Counted here, after the branches, which count their own.)
        st.surface_hits += 1;
        // Splitting: the reflection, weighted by F_c, as a branch of its own.
        let entry_f = (self.split && obj.interface.is_specular())
            .then(|| self.reflect_at_entry(obj, p, n_in, path, est, rng, st));
        let tp = &mut path.tp;
        let h = *path.hero.get_or_insert_with(|| {
            let b = ((rng.next_f64() * 3.0) as usize).min(2);
            if one_band {
                // One band per path (docs/method.md §5): weight 3 in band b.
                *tp = tp.keep_band(b, 3.0);
            }
            b
        });
        let eta = if shared { obj.eta_mean } else { obj.eta(h) };
        let cos_b = -path.d.dot(n_in);
        let (_, fr) = reflectances(obj, cos_b, eta, shared, false);
        // Split: the refraction is taken (its reflection was traced above).
        let reflect = if entry_f.is_some() { None } else { Some(fr[h]) };
        let Some(crossing) = self.cross(obj, h, n_in, p, false, reflect, path, rng) else {
            return ControlFlow::Break(());
        };
        // The probability of refracting in (and of reflecting, when the path does).
        let mut p_reflect = 0.0;
        let p_in = if let Some(f) = entry_f {
            // The reflection was traced above; the refraction carries 1 − F_c.
            for (b, fc) in path.tp.beta.iter_mut().zip(f) {
                *b *= 1.0 - fc;
            }
            Some(1.0)
        } else {
            if shared {
                let w = if crossing.transmitted { fr.map(|x| 1.0 - x) } else { fr };
                path.tp.scale(w, w, h);
            }
            p_reflect = fr[h];
            crossing.transmitted.then(|| 1.0 - fr[h])
        };
        if let Some(p_in) = p_in {
            path.safe = 0.0;
            if let Some(c) = path.chain.as_mut() {
                // In: the first refraction's cos θ_i / cos θ_o (dω_b/dω_i = n² cos θ_i / cos θ_b).
                c.pdf *= p_in * (-path.d.dot(n_in)) / cos_b;
            }
        } else {
            // Straight from the board: a chain that the board's
            // connection by reflection makes.
            path.chain = path.chain.filter(|c| !c.out).map(|c| BoardVertex {
                pdf: c.pdf * p_reflect,
                out: true,
                mirror: true,
                ..c
            });
        }
        path.last_diffuse_pdf = None;
        if crossing.weighted && !roulette(&mut path.tp, settings, rng) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }

    /// Splitting at the entry ([`Settings::split_entry`]): the reflection at
    /// `p` (inward normal `n_in`), weighted by F_c per band, traced as a
    /// branch of its own (its score goes on from the path's, and the
    /// path's from here). Returns F_c.
    #[allow(clippy::too_many_arguments)]
    fn reflect_at_entry(
        &self,
        obj: &Object,
        p: DVec3,
        n_in: DVec3,
        path: &Path,
        est: &mut Estimate,
        rng: &mut Rng,
        st: &mut Stats,
    ) -> [f64; 3] {
        let d = path.d;
        let cos_i = -d.dot(n_in);
        let f: [f64; 3] = std::array::from_fn(|c| fresnel::reflectance(cos_i, obj.eta(c)));
        let mut branch = path.tp;
        for (b, fc) in branch.beta.iter_mut().zip(f) {
            *b *= fc;
        }
        let d_refl = d - 2.0 * d.dot(n_in) * n_in;
        let score = est.score;
        let o = p + self.scene.epsilon_m * n_in;
        trace_path(self.scene, self.settings, o, d_refl, branch, path.hero, path.events, false, est, rng, st);
        est.score = score;
        f
    }
}
