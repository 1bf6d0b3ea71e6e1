use super::{Phase, PhaseTable, HG_SMALL_G, INV_4PI, ONE_MINUS_EPSILON, TURN_TABLE, TURN_TABLE_LEN};
use crate::simd::{gather, to_i32, Lanes, F4};

/// A [`Phase`] prepared for lanes: HG with its factors hoisted, a table,
/// or (HG with |g| < 10⁻³) the scalar forms per lane.
#[derive(Debug, Clone, Copy)]
pub(crate) enum PhaseLanes<'a> {
    Hg(Hg),
    Table(&'a PhaseTable),
    PerLane(&'a Phase),
}

impl<'a> PhaseLanes<'a> {
    pub(crate) fn new(phase: &'a Phase) -> Self {
        match phase {
            Phase::HenyeyGreenstein { g } => Hg::new(*g).map_or(PhaseLanes::PerLane(phase), PhaseLanes::Hg),
            Phase::Tabulated(t) => PhaseLanes::Table(t),
        }
    }

    /// `Phase::sample_angles` in lanes.
    #[inline(always)]
    pub(crate) fn sample_angles(&self, u1: F4, u2: F4) -> Angles {
        let cos_theta = match self {
            PhaseLanes::Hg(hg) => hg.sample_cos_theta(u1),
            PhaseLanes::Table(t) => t.sample_cos_theta_lanes(u1),
            PhaseLanes::PerLane(phase) => F4::load(&Lanes(u1.lanes().0.map(|u| phase.sample_cos_theta(u)))),
        };
        Angles::new(cos_theta, u2)
    }

    /// `Phase::eval` in lanes.
    #[inline(always)]
    pub(crate) fn eval(&self, cos_theta: F4) -> F4 {
        match self {
            PhaseLanes::Hg(hg) => hg.eval(cos_theta),
            PhaseLanes::Table(t) => t.eval_lanes(cos_theta),
            PhaseLanes::PerLane(phase) => F4::load(&Lanes(cos_theta.lanes().0.map(|c| phase.eval(c)))),
        }
    }
}

/// Henyey–Greenstein with g fixed, its loop-invariant factors hoisted.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Hg {
    /// 1 − g², 1 − g, 2g, 0.5/g, 1 + g² (sampling).
    one_minus_g2: f64,
    one_minus_g: f64,
    two_g: f64,
    half_inv_g: f64,
    one_plus_g2: f64,
    /// p = num / (d √d), d = a + b·(1 + s μ) (evaluation, see `hg_eval`).
    num: f64,
    a: f64,
    b: f64,
    s: f64,
}

impl Hg {
    /// `None` for |g| < 10⁻³, where the scalar sampler switches to the
    /// division-free form (the lane kernel then samples per lane).
    pub(crate) fn new(g: f64) -> Option<Self> {
        if g.abs() < HG_SMALL_G {
            return None;
        }
        let (a, b, s) =
            if g >= 0.0 { ((1.0 - g) * (1.0 - g), 2.0 * g, -1.0) } else { ((1.0 + g) * (1.0 + g), -2.0 * g, 1.0) };
        Some(Self {
            one_minus_g2: 1.0 - g * g,
            one_minus_g: 1.0 - g,
            two_g: 2.0 * g,
            half_inv_g: 0.5 / g,
            one_plus_g2: 1.0 + g * g,
            num: INV_4PI * (1.0 - g) * (1.0 + g),
            a,
            b,
            s,
        })
    }

    /// `hg_sample_cos_theta` in lanes.
    #[inline(always)]
    pub(crate) fn sample_cos_theta(&self, u: F4) -> F4 {
        let (zero, one) = (F4::splat(0.0), F4::splat(1.0));
        let u = u.max(zero).min(one);
        let s = F4::splat(self.one_minus_g2) / (F4::splat(self.one_minus_g) + F4::splat(self.two_g) * u);
        let mu = (F4::splat(self.one_plus_g2) - s * s) * F4::splat(self.half_inv_g);
        mu.max(-one).min(one)
    }

    /// `hg_eval` in lanes.
    #[inline(always)]
    pub(crate) fn eval(&self, cos_theta: F4) -> F4 {
        let one = F4::splat(1.0);
        let mu = cos_theta.max(-one).min(one);
        let d = F4::splat(self.a) + F4::splat(self.b) * (one + F4::splat(self.s) * mu);
        F4::splat(self.num) / (d * d.sqrt())
    }
}

/// `PhaseTable::sample_cos_theta` and `eval` in lanes: the bins are
/// found per lane, the arithmetic (the same as the scalar forms') runs
/// on gathered node data.
impl PhaseTable {
    /// `sample_cos_theta` for u ∈ [0, 1) in every lane.
    #[inline(always)]
    pub(crate) fn sample_cos_theta_lanes(&self, u: F4) -> F4 {
        let (zero, one) = (F4::splat(0.0), F4::splat(1.0));
        let u = u.max(zero).min(F4::splat(ONE_MINUS_EPSILON));
        let ul = u.lanes();
        let i: [i32; 4] = std::array::from_fn(|l| self.bin_of_cdf(ul.0[l]) as i32);
        let next = i.map(|i| i + 1);
        let (c_lo, c_hi) = (gather(&self.cdf, next), gather(&self.cdf, i));
        let up = ((u - c_lo) / (c_hi - c_lo)).max(zero).min(one);
        let (a, b) = (gather(&self.values, next), gather(&self.values, i));
        let denom = a + (a * a * (one - up) + b * b * up).sqrt();
        let s = denom.gt(zero).select((up * (a + b) / denom).min(one), zero);
        let (lo, hi) = (gather(&self.mu, next), gather(&self.mu, i));
        (lo + s * (hi - lo)).min(hi)
    }

    /// `eval` in lanes.
    #[inline(always)]
    pub(crate) fn eval_lanes(&self, cos_theta: F4) -> F4 {
        let one = F4::splat(1.0);
        let mu = cos_theta.max(-one).min(one);
        let ml = mu.lanes();
        let i: [i32; 4] = std::array::from_fn(|l| self.bin_of_cos(ml.0[l]) as i32);
        let next = i.map(|i| i + 1);
        let (hi, lo) = (gather(&self.mu, i), gather(&self.mu, next));
        let width = hi - lo;
        let zero = F4::splat(0.0);
        let s = width.gt(zero).select((mu - lo) / width, F4::splat(0.5));
        (one - s) * gather(&self.values, next) + s * gather(&self.values, i)
    }
}

/// `super::sin_cos_turns` in lanes: table entries by gather, the rotation
/// by the residual with the constant divisions as products.
#[inline(always)]
pub(crate) fn sin_cos_turns(u: F4) -> (F4, F4) {
    let len = TURN_TABLE_LEN as f64;
    let t = u.max(F4::splat(0.0)).min(F4::splat(1.0)) * F4::splat(len);
    let k = t.floor().min(F4::splat(len - 1.0));
    let d = (t - k) * F4::splat(std::f64::consts::TAU / len);
    let d2 = d * d;
    let one = F4::splat(1.0);
    let sd = d * (one - d2 * F4::splat(1.0 / 6.0) * (one - d2 * F4::splat(1.0 / 20.0)));
    let cd = one - d2 * F4::splat(0.5) * (one - d2 * F4::splat(1.0 / 12.0) * (one - d2 * F4::splat(1.0 / 30.0)));
    let ki = to_i32(k + k);
    let table = TURN_TABLE.as_flattened();
    let sk = gather(table, ki);
    let ck = gather(table, ki.map(|i| i + 1));
    (sk * cd + ck * sd, ck * cd - sk * sd)
}

/// `super::ScatteringAngles` in lanes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Angles {
    pub cos_theta: F4,
    pub sin_theta: F4,
    pub cos_phi: F4,
    pub sin_phi: F4,
}

impl Angles {
    /// The rest of `Phase::sample_angles` in lanes, from cos θ (however
    /// sampled) and the azimuth's uniform `u2`.
    #[inline(always)]
    pub(crate) fn new(cos_theta: F4, u2: F4) -> Angles {
        let one = F4::splat(1.0);
        let sin_theta = ((one - cos_theta) * (one + cos_theta)).max(F4::splat(0.0)).sqrt();
        let (sin_phi, cos_phi) = sin_cos_turns(u2);
        Angles { cos_theta, sin_theta, cos_phi, sin_phi }
    }

    /// `ScatteringAngles::turn` in lanes (frame of `orthonormal_basis`).
    #[inline(always)]
    pub(crate) fn turn(&self, n: [F4; 3]) -> [F4; 3] {
        let sign = n[2].sign_one();
        let a = -(F4::splat(1.0) / (sign + n[2]));
        let b = n[0] * n[1] * a;
        let t = [F4::splat(1.0) + sign * n[0] * n[0] * a, sign * b, -(sign * n[0])];
        let bb = [b, sign + n[1] * n[1] * a, -n[1]];
        let (x, y) = (self.sin_theta * self.cos_phi, self.sin_theta * self.sin_phi);
        let c = self.cos_theta;
        [x * t[0] + y * bb[0] + c * n[0], x * t[1] + y * bb[1] + c * n[1], x * t[2] + y * bb[2] + c * n[2]]
    }
}
