//! The connection estimators four paths at a time (AVX2 + FMA, see
//! [`crate::simd`]).
//!
//! Each lane runs the random walk of `Kernel::trace` for one path: the same
//! random numbers from the path's own stream in the same order, the same
//! decisions and, apart from ln, exp, sin and cos (a few ulp), the same
//! arithmetic. So a batch gives the scalar kernel's result to rounding
//! (tested in `slab::tests`). What runs in vector instructions is the work of
//! every scattering event: the free path, the scattering angles and the new
//! direction, and the connection's geometry, pixel, phase function and
//! transmittance. What stays per lane is the random numbers, boundary hits
//! (rare), the splat into the image and the roulettes; the ring's and the
//! lobe's connections (many splats per event, see `Kernel::connect_ring`
//! and `Kernel::connect_lobe`) run per lane on the vector walk, each lane
//! with its own MIS history, chain and exit (through a rough top the
//! path's own ω₂₁, 1/cos θ₂₁ and splat constant), the chain's links four at a time
//! (`lobe_links_lanes`). A lane whose path
//! ends takes the batch's next path, so all four stay busy until the batch
//! runs out.

use super::boundary::{Crossing, Exit};
use super::kernel::{aux_stream, survives_roulette, Kernel, Strategy};
use super::lobe::{Chain, Junctions, Links, LobeEvent};
use super::tally::Batch;
use crate::phase::lanes::PhaseLanes;
use crate::rng::Rng;
use crate::simd::{to_i32, unit_f64, unit_pair, Lanes, F4};

/// The lanes' paths: position, direction and weight in vector layout, the
/// rest per lane.
struct Paths {
    p: [Lanes; 3],
    dir: [Lanes; 3],
    w: Lanes,
    /// Σ of the path's splats, per lane.
    total: [f64; 4],
    rng: [Rng; 4],
    /// Each lane's second stream (`aux_stream`).
    aux: [Rng; 4],
    /// Bit l set while lane l carries a path.
    live: u32,
    /// Bit l set while lane l's path has not scattered yet.
    unscattered: u32,
    /// Each lane's exit direction (rough top).
    exit: [Exit; 4],
    /// Each lane's MIS history and chain (lobe connection).
    junctions: [Junctions; 4],
    chains: Box<[Chain; 4]>,
    /// The next path of the batch, and the end of the batch.
    next: u64,
    end: u64,
    seed: u64,
}

impl Paths {
    /// Four idle lanes for the paths `first_path` … `first_path + count − 1`
    /// of `seed` (`Kernel::start_lane` puts a path in each).
    fn new(seed: u64, first_path: u64, count: u64) -> Self {
        Paths {
            p: [Lanes::default(); 3],
            dir: [Lanes::default(); 3],
            w: Lanes::default(),
            total: [0.0; 4],
            rng: std::array::from_fn(|_| Rng::new(seed, first_path)),
            aux: std::array::from_fn(|_| Rng::new(seed, first_path)),
            live: 0,
            unscattered: 0,
            exit: [Exit::LOST; 4],
            junctions: [Junctions::new(); 4],
            chains: Box::new(std::array::from_fn(|_| Chain::new())),
            next: first_path,
            end: first_path + count,
            seed,
        }
    }
}

/// The set bits of `bits`, lowest first.
fn lanes_of(mut bits: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (bits != 0).then(|| {
            let l = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            l
        })
    })
}

impl Kernel<'_> {
    /// Starts the batch's next path in lane `l`, or retires the lane when
    /// the batch is done.
    fn start_lane(&self, paths: &mut Paths, l: usize) {
        // A path lost at a rough entry adds nothing: the lane takes the next.
        let (rng, aux, (p, dir, w, exit)) = loop {
            if paths.next >= paths.end {
                paths.live &= !(1 << l);
                return;
            }
            let mut rng = Rng::new(paths.seed, paths.next);
            let aux = aux_stream(paths.seed, paths.next);
            paths.next += 1;
            if let Some(start) = self.launch(&mut rng) {
                break (rng, aux, start);
            }
        };
        for k in 0..3 {
            paths.p[k].0[l] = p[k];
            paths.dir[k].0[l] = dir[k];
        }
        paths.w.0[l] = w;
        paths.exit[l] = exit;
        paths.junctions[l] = Junctions::new();
        paths.chains[l].restart();
        paths.total[l] = 0.0;
        paths.rng[l] = rng;
        paths.aux[l] = aux;
        paths.live |= 1 << l;
        paths.unscattered |= 1 << l;
    }

    /// Ends lane `l`'s path (its tallies into `b`) and starts the next.
    fn end_lane(&self, paths: &mut Paths, b: &mut Batch, l: usize, reflected: f64, transmitted: f64) {
        let t = paths.total[l];
        b.path_sum += t;
        b.path_sq += t * t;
        b.reflected += reflected;
        b.transmitted += transmitted;
        self.start_lane(paths, l);
    }

    /// `Kernel::batch` for the connection estimators, four paths at a time:
    /// per round of the loop the free path and the scattering angles of
    /// every lane, the scattering events of the lanes that do not reach a
    /// boundary ([`connect_lanes`](Self::connect_lanes), the turn, the
    /// weight's roulette), then the boundary hits of the others
    /// ([`cross_lanes`](Self::cross_lanes)).
    #[target_feature(enable = "avx2,fma")]
    pub(super) fn batch_lanes(&self, seed: u64, first_path: u64, count: u64, image: Vec<f64>) -> Batch {
        let phase = PhaseLanes::new(&self.setup.slab.medium.phase);
        let mut b = Batch::new(image, self.setup.sensor.pixels);
        let mut paths = Paths::new(seed, first_path, count);
        for l in 0..4 {
            self.start_lane(&mut paths, l);
        }
        let (zero, one) = (F4::splat(0.0), F4::splat(1.0));
        while paths.live != 0 {
            let live = paths.live;
            // Random numbers: the free path's, then the angles' (as `trace`),
            // drawn in every lane (an idle lane's generator is discarded when
            // the lane takes a new path) and made uniform in the vector unit.
            let raw_s: [u64; 4] = std::array::from_fn(|l| paths.rng[l].next_u64());
            let raw_angles: [u64; 4] = std::array::from_fn(|l| paths.rng[l].next_u64());
            let s = -(one - unit_f64(raw_s)).ln() * F4::splat(self.inv_mu_t);
            let (u1, u2) = unit_pair(raw_angles);
            let angles = phase.sample_angles(u1, u2);

            // Which lanes reach a boundary before scattering (as `trace`).
            let pz = F4::load(&paths.p[2]);
            let dz = F4::load(&paths.dir[2]);
            let gap = dz.lt(zero).select(pz + F4::splat(self.d), -pz);
            let hit = (dz.ne(zero) & (s * dz.abs()).ge(gap)).bits() & live;
            // The scattering event runs in all four lanes, stored without
            // masks (a masked store is slow and spoils store forwarding); a
            // lane with a hit gets its state back below and crosses the
            // boundary instead, and idle lanes' values are never used. The
            // splats and roulettes are per lane, in the lanes of `ev` only.
            let before_hit = (hit != 0).then_some((paths.p, paths.dir, paths.w));
            let ev = live & !hit;
            let dir = paths.dir.each_ref().map(F4::load);
            let mut p = paths.p.each_ref().map(F4::load);
            for k in 0..3 {
                p[k] = p[k] + s * dir[k];
                p[k].store(&mut paths.p[k]);
            }
            let w = F4::load(&paths.w) * F4::splat(self.albedo);
            w.store(&mut paths.w);
            b.events += u64::from(ev.count_ones());
            paths.unscattered &= !ev;

            self.connect_lanes(&phase, &mut paths, &mut b.image, ev, (p, dir, w), angles.cos_theta);

            let turned = angles.turn(dir);
            for (t, d) in turned.iter().zip(paths.dir.iter_mut()) {
                t.store(d);
            }
            for l in lanes_of(w.lt(F4::splat(0.1)).bits() & ev) {
                if !survives_roulette(&mut paths.w.0[l], &mut paths.aux[l]) {
                    self.end_lane(&mut paths, &mut b, l, 0.0, 0.0);
                }
            }
            if let Some(before) = before_hit {
                self.cross_lanes(&mut paths, &mut b, hit, gap.lanes(), before);
            }
        }
        b
    }

    /// The connections of the scattering events in the lanes of `ev` (at
    /// `p`, incoming direction `dir`, weight `w` after albedo; `cos_theta`
    /// the cosine of each lane's next scattering angle, for the lobe
    /// connection's MIS history), splatted into `image`, each lane's value
    /// added to its path total: the lobe and ring connections and those of
    /// a thin slab or a rough top per lane, the thick slab's straight-up
    /// term of `connect` in vector instructions.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn connect_lanes(
        &self,
        phase: &PhaseLanes,
        paths: &mut Paths,
        image: &mut [f64],
        ev: u32,
        (p, dir, w): ([F4; 3], [F4; 3], F4),
        cos_theta: F4,
    ) {
        if let Strategy::Lobe { vertices, reuse } = self.strategy {
            // The lobe connection, per lane (as `trace`): the walk's
            // history, the connection and the lane's chain.
            let phase_value = phase.eval(cos_theta).lanes();
            for l in lanes_of(ev) {
                let (pl, dl) = (paths.p.map(|c| c.0[l]), paths.dir.map(|c| c.0[l]));
                paths.junctions[l].arrive();
                let chain = &mut paths.chains[l];
                paths.total[l] += match self.lobe_event(
                    (vertices, reuse),
                    pl,
                    dl,
                    paths.w.0[l],
                    &paths.exit[l],
                    &paths.junctions[l],
                    chain,
                    image,
                    &mut paths.aux[l],
                ) {
                    Ok(e) => e.total + self.lobe_links_lanes(phase, &e, pl, dl, chain, image),
                    Err(total) => total,
                };
                paths.junctions[l].scatter(phase_value.0[l]);
            }
        } else if let Strategy::Ring(ring) = &self.strategy {
            // The ring connection, per lane, where it can contribute
            // (τ ≤ 40 along the exit direction).
            let tau = -p[2] * F4::splat(self.inv_cos_t * self.mu_t);
            for l in lanes_of(tau.le(F4::splat(40.0 + 1e-9)).bits() & ev) {
                let (pl, dl) = (paths.p.map(|c| c.0[l]), paths.dir.map(|c| c.0[l]));
                paths.total[l] += self.connect_ring(ring, pl, dl, paths.w.0[l], image, &mut paths.aux[l]);
            }
        } else if self.image_terms || self.rough {
            // Thin slab (the image terms' loop) or a rough top (sampled
            // exit directions), per lane.
            for l in lanes_of(ev) {
                let (pl, dl) = (paths.p.map(|c| c.0[l]), paths.dir.map(|c| c.0[l]));
                let (w, exit) = (paths.w.0[l], paths.exit[l]);
                paths.total[l] += self.connect(pl, dl, w, exit, image, &mut paths.aux[l]);
            }
        } else {
            // Thick slab: `connect`'s straight-up term.
            let sensor = &self.setup.sensor;
            let npix = sensor.pixels;
            let zero = F4::splat(0.0);
            let w21 = self.w21.map(F4::splat);
            let half = 0.5 * npix as f64;
            let inv_pixel = 1.0 / sensor.pixel_m;
            let l = -p[2] * F4::splat(self.inv_cos_t);
            let tau = F4::splat(self.mu_t) * l;
            let c = (p[0] + l * w21[0]) * F4::splat(inv_pixel) + F4::splat(half);
            let r = F4::splat(half) - (p[1] + l * w21[1]) * F4::splat(inv_pixel);
            let n = F4::splat(npix as f64);
            let inside = tau.le(F4::splat(40.0)) & c.ge(zero) & r.ge(zero) & c.lt(n) & r.lt(n);
            let made = inside.bits() & ev;
            if made != 0 {
                let depth = F4::splat(self.roulette_depth);
                let e = tau.gt(depth).select(depth - tau, -tau).exp().lanes();
                let cos_up = dir[0] * w21[0] + dir[1] * w21[1] + dir[2] * w21[2];
                let phase_value = phase.eval(cos_up);
                let wp = (w * phase_value).lanes();
                let tau = tau.lanes();
                let pixel = to_i32(r.floor() * n + c.floor());
                for l in lanes_of(made) {
                    let t = self.connection_transmittance(tau.0[l], e.0[l], &mut paths.aux[l]);
                    if t != 0.0 {
                        let v = wp.0[l] * t * self.splat;
                        image[pixel[l] as usize] += v;
                        paths.total[l] += v;
                    }
                }
            }
        }
    }

    /// The boundary hits of the lanes of `hit`, per lane (as `trace`), from
    /// their state `before` the event (position, direction, weight; `gap`
    /// the vertical distance to the boundary ahead): the connection of
    /// unscattered light at a rough top, then the crossing; a path that
    /// leaves or is lost ends, and its lane takes the batch's next path.
    #[target_feature(enable = "avx2,fma")]
    #[inline]
    fn cross_lanes(
        &self,
        paths: &mut Paths,
        b: &mut Batch,
        hit: u32,
        gap: Lanes,
        (p_before, dir_before, w_before): ([Lanes; 3], [Lanes; 3], Lanes),
    ) {
        for l in lanes_of(hit) {
            let mut p = p_before.map(|c| c.0[l]);
            let mut dir = dir_before.map(|c| c.0[l]);
            let mut w = w_before.0[l];
            if self.rough && dir[2] > 0.0 && paths.unscattered & (1 << l) != 0 {
                paths.total[l] += self.connect_unscattered(p, dir, gap.0[l], w, &mut b.image);
            }
            let crossing = self.cross(&mut p, &mut dir, &mut w, gap.0[l], &mut paths.rng[l]);
            for k in 0..3 {
                paths.p[k].0[l] = p[k];
                paths.dir[k].0[l] = dir[k];
            }
            paths.w.0[l] = w;
            match crossing {
                Crossing::Reflected => paths.junctions[l].from_scatter = false,
                Crossing::Lost => self.end_lane(paths, b, l, 0.0, 0.0),
                Crossing::LeftTop(_) => self.end_lane(paths, b, l, w, 0.0),
                Crossing::LeftBottom => self.end_lane(paths, b, l, 0.0, w),
            }
        }
    }
}

impl Kernel<'_> {
    /// `Kernel::lobe_links` four links at a time: the same arithmetic in
    /// the same order (the phase function in its lane form), the splats in
    /// link order.
    #[inline(always)]
    fn lobe_links_lanes(
        &self,
        phase: &PhaseLanes,
        ev: &LobeEvent,
        p: [f64; 3],
        dir: [f64; 3],
        chain: &Chain,
        image: &mut [f64],
    ) -> f64 {
        let m = ev.m;
        let sensor = &self.setup.sensor;
        let npix = sensor.pixels as f64;
        let (zero, half, n) = (F4::splat(0.0), F4::splat(0.5 * npix), F4::splat(npix));
        let inv_pixel = F4::splat(1.0 / sensor.pixel_m);
        let depth = -p[2];
        let (depth4, floor4) = (F4::splat(depth), F4::splat(depth - self.d));
        let (p0, p1) = (F4::splat(p[0]), F4::splat(p[1]));
        let w21 = ev.w21.map(F4::splat);
        let d = dir.map(F4::splat);
        let inv_cos_t = F4::splat(ev.inv_cos);
        let tau_u = F4::splat(ev.tau_u);
        let load = |a: &Links, c: usize| {
            // SAFETY: `Links` is 32-byte aligned and c is a multiple of 4
            // below MAX_LOBE_VERTICES, so the four values are an aligned
            // `Lanes` inside the array.
            F4::load(unsafe { &*(a.0.as_ptr().add(c) as *const Lanes) })
        };
        let mut total = 0.0;
        for c in (0..m).step_by(4) {
            let valid = if m - c >= 4 { 0b1111 } else { (1u32 << (m - c)) - 1 };
            let inside = load(&chain.hi, c).lt(depth4) & load(&chain.lo, c).gt(floor4);
            let tau = tau_u + load(&chain.s_tau, c);
            let l = (depth4 - load(&chain.dz, c)) * inv_cos_t;
            let col = (p0 + load(&chain.x, c) + l * w21[0]) * inv_pixel + half;
            let row = half - (p1 + load(&chain.y, c) + l * w21[1]) * inv_pixel;
            let on = col.ge(zero) & row.ge(zero) & col.lt(n) & row.lt(n);
            let made = (inside & tau.le(F4::splat(40.0)) & on).bits() & valid;
            if made == 0 {
                continue;
            }
            let cos = d[0] * load(&chain.cx, c) + d[1] * load(&chain.cy, c) + d[2] * load(&chain.cz, c);
            let prefix = Lanes(std::array::from_fn(|k| ev.prefix[ev.light.min(m.saturating_sub(c + k + 1))]));
            let s = load(&chain.q, c) + F4::splat(1.0) / phase.eval(cos) + F4::load(&prefix);
            let attenuation =
                if ev.direct { load(&chain.albedo, c) * (-tau).exp() } else { F4::splat(ev.e) * load(&chain.atten, c) };
            let v = (F4::splat(ev.weight) * attenuation / s).lanes();
            let pixel = to_i32(row.floor() * n + col.floor());
            for k in lanes_of(made) {
                image[pixel[k] as usize] += v.0[k];
                total += v.0[k];
            }
        }
        total
    }
}
