//! Four f64 lanes on AVX2 + FMA for the slab simulator's lane kernel
//! (`slab::lanes`): a thin wrapper [`F4`] over `__m256d`, and the lane forms
//! of the few functions the random walk needs — natural logarithm and
//! exponential (a few ulp), and the phase-function pieces in `phase`.
//!
//! Every function here may run only on a CPU with AVX2 and FMA. The lane
//! kernel checks [`available`] once per run and otherwise uses the scalar
//! kernel; both consume the random streams identically, so they agree to
//! rounding (tested in `slab`).
//!
//! The operators are `#[inline(always)]` wrappers of the intrinsics; they are
//! only called from functions compiled with `#[target_feature(enable =
//! "avx2,fma")]`, into which they inline (checked: the lane kernel's
//! disassembly has no calls to them).

use std::arch::x86_64::*;
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Sub};

/// ln 2 split as in fdlibm: LN2_HI has 32 significant bits, so k·LN2_HI is
/// exact for |k| < 2²⁰; LN2_HI + LN2_LO = ln 2 to 1e-26.
const LN2_HI: f64 = f64::from_bits(0x3FE6_2E42_FEE0_0000);
const LN2_LO: f64 = f64::from_bits(0x3DEA_39EF_3579_3C76);

/// Whether this CPU runs the lane kernel (AVX2 and FMA).
pub fn available() -> bool {
    is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma")
}

/// For tests of lane code: whether it cannot run here (then says so).
#[cfg(test)]
pub(crate) fn lanes_unavailable() -> bool {
    let missing = !available();
    if missing {
        eprintln!("no AVX2/FMA on this CPU: the lane kernel is not used, nothing to check");
    }
    missing
}

/// Four f64 lanes.
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct F4(pub __m256d);

/// Four lanes aligned for a vector load or store, for per-lane scalar work.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct Lanes(pub [f64; 4]);

/// A lane mask: all bits set where true (the result of a comparison).
#[derive(Clone, Copy, Debug)]
#[repr(transparent)]
pub struct M4(__m256d);

impl F4 {
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        // SAFETY (all intrinsics in this module): callers run on AVX2 + FMA
        // (module doc); the intrinsics have no other precondition.
        unsafe { F4(_mm256_set1_pd(x)) }
    }

    #[inline(always)]
    pub fn load(l: &Lanes) -> Self {
        unsafe { F4(_mm256_load_pd(l.0.as_ptr())) }
    }

    #[inline(always)]
    pub fn store(self, l: &mut Lanes) {
        unsafe { _mm256_store_pd(l.0.as_mut_ptr(), self.0) }
    }

    #[inline(always)]
    pub fn lanes(self) -> Lanes {
        let mut l = Lanes::default();
        self.store(&mut l);
        l
    }

    /// self · a + b with one rounding.
    #[inline(always)]
    pub fn mul_add(self, a: F4, b: F4) -> F4 {
        unsafe { F4(_mm256_fmadd_pd(self.0, a.0, b.0)) }
    }

    #[inline(always)]
    pub fn sqrt(self) -> F4 {
        unsafe { F4(_mm256_sqrt_pd(self.0)) }
    }

    #[inline(always)]
    pub fn floor(self) -> F4 {
        unsafe { F4(_mm256_floor_pd(self.0)) }
    }

    #[inline(always)]
    pub fn abs(self) -> F4 {
        unsafe { F4(_mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0)) }
    }

    /// 1 with the sign of each lane (−0 gives −1), like `f64::copysign(1.0, x)`.
    #[inline(always)]
    pub fn sign_one(self) -> F4 {
        unsafe { F4(_mm256_or_pd(_mm256_and_pd(_mm256_set1_pd(-0.0), self.0), _mm256_set1_pd(1.0))) }
    }

    #[inline(always)]
    pub fn min(self, o: F4) -> F4 {
        unsafe { F4(_mm256_min_pd(self.0, o.0)) }
    }

    #[inline(always)]
    pub fn max(self, o: F4) -> F4 {
        unsafe { F4(_mm256_max_pd(self.0, o.0)) }
    }

    #[inline(always)]
    pub fn lt(self, o: F4) -> M4 {
        unsafe { M4(_mm256_cmp_pd::<_CMP_LT_OQ>(self.0, o.0)) }
    }

    #[inline(always)]
    pub fn le(self, o: F4) -> M4 {
        unsafe { M4(_mm256_cmp_pd::<_CMP_LE_OQ>(self.0, o.0)) }
    }

    #[inline(always)]
    pub fn gt(self, o: F4) -> M4 {
        o.lt(self)
    }

    #[inline(always)]
    pub fn ge(self, o: F4) -> M4 {
        o.le(self)
    }

    #[inline(always)]
    pub fn ne(self, o: F4) -> M4 {
        unsafe { M4(_mm256_cmp_pd::<_CMP_NEQ_OQ>(self.0, o.0)) }
    }

    /// Natural logarithm of positive normal lanes, within 2 ulp: x = 2^k m
    /// with m ∈ [√½, √2), ln m = 2 atanh s = 2s Σ s^{2j}/(2j + 1) with
    /// s = (m − 1)/(m + 1), |s| ≤ 0.1716, eleven terms (truncation < 1e-18
    /// relative), plus k ln 2 in two parts.
    #[inline(always)]
    pub fn ln(self) -> F4 {
        unsafe {
            let bits = _mm256_castpd_si256(self.0);
            // j = bits − bits(√½) + bits(1.0): its exponent field is the
            // biased k with m = x/2^k in [√½, √2); non-negative for x > 0.
            let j = _mm256_add_epi64(bits, _mm256_set1_epi64x(0x3FF0_0000_0000_0000 - 0x3FE6_A09E_667F_3BCD));
            let k_biased = _mm256_srli_epi64::<52>(j);
            let m_bits =
                _mm256_sub_epi64(bits, _mm256_slli_epi64::<52>(_mm256_sub_epi64(k_biased, _mm256_set1_epi64x(1023))));
            let m = F4(_mm256_castsi256_pd(m_bits));
            // k as f64: or the integer into the mantissa of 2^52.
            let k = small_u64_to_f64(k_biased) - F4::splat(1023.0);
            let one = F4::splat(1.0);
            let s = (m - one) / (m + one);
            let z = s * s;
            let mut p = F4::splat(1.0 / 21.0);
            for c in [19.0, 17.0, 15.0, 13.0, 11.0, 9.0, 7.0, 5.0, 3.0] {
                p = p.mul_add(z, F4::splat(1.0 / c));
            }
            let p = p.mul_add(z, one);
            let two_s = s + s;
            let lo = two_s.mul_add(p, k * F4::splat(LN2_LO));
            k.mul_add(F4::splat(LN2_HI), lo)
        }
    }

    /// e^x for x ∈ [−700, 0.35] (clamped below −700), within 2 ulp:
    /// x = k ln 2 + r with |r| ≤ ln 2 / 2, e^r by its Taylor polynomial to r¹³
    /// (truncation < 1e-17 relative), times 2^k through the exponent bits.
    #[inline(always)]
    pub fn exp(self) -> F4 {
        unsafe {
            let x = self.max(F4::splat(-700.0));
            let kd = F4(_mm256_round_pd::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(
                (x * F4::splat(std::f64::consts::LOG2_E)).0,
            ));
            let r = (-kd).mul_add(F4::splat(LN2_HI), x);
            let r = (-kd).mul_add(F4::splat(LN2_LO), r);
            let mut p = F4::splat(1.0 / 6_227_020_800.0);
            let mut fact = 6_227_020_800.0;
            for k in (1..13).rev() {
                fact /= (k + 1) as f64;
                p = p.mul_add(r, F4::splat(1.0 / fact));
            }
            let p = p.mul_add(r, F4::splat(1.0));
            // k into the exponent field: k + 1.5·2^52 holds k in its low bits.
            let magic = _mm256_set1_pd(6_755_399_441_055_744.0);
            let ki = _mm256_sub_epi64(_mm256_castpd_si256(_mm256_add_pd(kd.0, magic)), _mm256_castpd_si256(magic));
            F4(_mm256_castsi256_pd(_mm256_add_epi64(_mm256_castpd_si256(p.0), _mm256_slli_epi64::<52>(ki))))
        }
    }
}

impl M4 {
    /// Lane i true ↔ bit i set.
    #[inline(always)]
    pub fn bits(self) -> u32 {
        unsafe { _mm256_movemask_pd(self.0) as u32 }
    }

    /// `a` where true, `b` where false.
    #[inline(always)]
    pub fn select(self, a: F4, b: F4) -> F4 {
        unsafe { F4(_mm256_blendv_pd(b.0, a.0, self.0)) }
    }
}

impl BitAnd for M4 {
    type Output = M4;
    #[inline(always)]
    fn bitand(self, o: M4) -> M4 {
        unsafe { M4(_mm256_and_pd(self.0, o.0)) }
    }
}

impl BitOr for M4 {
    type Output = M4;
    #[inline(always)]
    fn bitor(self, o: M4) -> M4 {
        unsafe { M4(_mm256_or_pd(self.0, o.0)) }
    }
}

macro_rules! binary {
    ($trait:ident, $method:ident, $intrinsic:ident) => {
        impl $trait for F4 {
            type Output = F4;
            #[inline(always)]
            fn $method(self, o: F4) -> F4 {
                unsafe { F4($intrinsic(self.0, o.0)) }
            }
        }
    };
}
binary!(Add, add, _mm256_add_pd);
binary!(Sub, sub, _mm256_sub_pd);
binary!(Mul, mul, _mm256_mul_pd);
binary!(Div, div, _mm256_div_pd);

impl Neg for F4 {
    type Output = F4;
    #[inline(always)]
    fn neg(self) -> F4 {
        unsafe { F4(_mm256_xor_pd(self.0, _mm256_set1_pd(-0.0))) }
    }
}

/// Integer lanes below 2⁵² as f64 (exact): or them into the mantissa of 2⁵².
#[inline(always)]
fn small_u64_to_f64(v: __m256i) -> F4 {
    unsafe {
        let two52 = _mm256_set1_pd(4_503_599_627_370_496.0);
        F4(_mm256_sub_pd(_mm256_castsi256_pd(_mm256_or_si256(v, _mm256_castpd_si256(two52))), two52))
    }
}

/// [`Rng::next_f64`](crate::rng::Rng::next_f64) of four raw outputs, bit for
/// bit: the top 53 bits × 2⁻⁵³, formed as (top 32 bits · 2²¹ + next 21 bits)
/// · 2⁻⁵³, every step exact.
#[inline(always)]
pub fn unit_f64(raw: [u64; 4]) -> F4 {
    unsafe {
        let v = _mm256_set_epi64x(raw[3] as i64, raw[2] as i64, raw[1] as i64, raw[0] as i64);
        let hi = small_u64_to_f64(_mm256_srli_epi64::<32>(v));
        let lo = small_u64_to_f64(_mm256_and_si256(_mm256_srli_epi64::<11>(v), _mm256_set1_epi64x(0x1F_FFFF)));
        hi.mul_add(F4::splat(2_097_152.0), lo) * F4::splat(1.0 / 9_007_199_254_740_992.0)
    }
}

/// [`Rng::next_f64_pair`](crate::rng::Rng::next_f64_pair) of four raw
/// outputs, bit for bit: (high half, low half) × 2⁻³².
#[inline(always)]
pub fn unit_pair(raw: [u64; 4]) -> (F4, F4) {
    unsafe {
        let v = _mm256_set_epi64x(raw[3] as i64, raw[2] as i64, raw[1] as i64, raw[0] as i64);
        let hi = small_u64_to_f64(_mm256_srli_epi64::<32>(v));
        let lo = small_u64_to_f64(_mm256_and_si256(v, _mm256_set1_epi64x(0xFFFF_FFFF)));
        let unit = F4::splat(1.0 / 4_294_967_296.0);
        (hi * unit, lo * unit)
    }
}

/// Gathers `table[index[i]]` for the four lanes (indices < table length).
#[inline(always)]
pub fn gather(table: &[f64], index: [i32; 4]) -> F4 {
    debug_assert!(index.iter().all(|&i| (i as usize) < table.len()));
    unsafe {
        let idx = _mm_loadu_si128(index.as_ptr().cast());
        F4(_mm256_i32gather_pd::<8>(table.as_ptr(), idx))
    }
}

/// Truncates four non-negative lanes below 2³¹ to integers.
#[inline(always)]
pub fn to_i32(x: F4) -> [i32; 4] {
    let mut out = [0i32; 4];
    unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), _mm256_cvttpd_epi32(x.0)) };
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Largest error in ulp of `f` against `reference` over `xs`, four at a time.
    #[target_feature(enable = "avx2,fma")]
    fn max_ulp(xs: &[f64], f: impl Fn(F4) -> F4, reference: impl Fn(f64) -> f64) -> f64 {
        let mut worst: f64 = 0.0;
        for c in xs.chunks_exact(4) {
            let got = f(F4::load(&Lanes([c[0], c[1], c[2], c[3]]))).lanes();
            for (x, g) in c.iter().zip(got.0) {
                let r = reference(*x);
                let ulp = (r.abs() * f64::EPSILON).max(f64::MIN_POSITIVE);
                worst = worst.max((g - r).abs() / ulp);
            }
        }
        worst
    }

    fn uniforms(n: usize) -> Vec<f64> {
        let mut rng = crate::rng::Rng::new(11, 0);
        (0..n).map(|_| rng.next_f64()).collect()
    }

    #[test]
    fn ln_within_two_ulp() {
        if lanes_unavailable() {
            return;
        }
        // The simulator's inputs, 1 − u ∈ (0, 1], including the ends and
        // the reduction's break points; then a wide range of magnitudes.
        let mut xs: Vec<f64> = uniforms(400_000).into_iter().map(|u| 1.0 - u).collect();
        xs.extend([
            1.0,
            2f64.powi(-53),
            0.5,
            std::f64::consts::FRAC_1_SQRT_2,
            std::f64::consts::FRAC_1_SQRT_2.next_up(),
            1.0 - 1e-16,
            0.9999,
        ]);
        xs.extend(uniforms(100_000).into_iter().map(|u| 10f64.powf(600.0 * u - 300.0)));
        xs.truncate(xs.len() / 4 * 4);
        // SAFETY: AVX2 and FMA are present (checked above).
        let worst = unsafe { max_ulp(&xs, |x| x.ln(), f64::ln) };
        assert!(worst <= 2.0, "ln off by {worst} ulp");
        // ln 1 is exactly 0, as a free path of u = 0 must be.
        let one = unsafe { max_ulp(&[1.0; 4], |x| x.ln(), |_| 0.0) };
        assert_eq!(one, 0.0);
    }

    #[test]
    fn exp_within_two_ulp() {
        if lanes_unavailable() {
            return;
        }
        let mut xs: Vec<f64> = uniforms(400_000).into_iter().map(|u| -700.0 * u * u).collect();
        xs.extend([0.0, -1e-300, -0.3465735902799726, -0.34657359027997264, -40.0, -8.0, -699.99, 0.3]);
        xs.truncate(xs.len() / 4 * 4);
        let worst = unsafe { max_ulp(&xs, |x| x.exp(), f64::exp) };
        assert!(worst <= 2.0, "exp off by {worst} ulp");
        // Below the clamp the result is e^{−700}, not garbage.
        let clamped = unsafe { max_ulp(&[-800.0, -1e308, -701.0, -700.0], |x| x.exp(), |_| (-700f64).exp()) };
        assert!(clamped <= 2.0);
    }

    #[test]
    fn uniforms_as_the_generator_makes_them() {
        if lanes_unavailable() {
            return;
        }
        #[target_feature(enable = "avx2,fma")]
        fn check() {
            let mut rngs: Vec<crate::rng::Rng> = (0..4).map(|k| crate::rng::Rng::new(5, k)).collect();
            let mut extremes =
                [[0u64, u64::MAX, 1 << 11, (1 << 11) - 1], [u64::MAX - (1 << 11), 1 << 63, 0xFFFF_FFFF, 1 << 32]]
                    .into_iter();
            for round in 0..20_000 {
                let raw: [u64; 4] = match extremes.next() {
                    Some(r) => r,
                    None => std::array::from_fn(|l| rngs[l].clone().next_u64()),
                };
                let (single, (hi, lo)) = (unit_f64(raw).lanes(), unit_pair(raw));
                let (hi, lo) = (hi.lanes(), lo.lanes());
                for (l, raw) in raw.iter().enumerate() {
                    assert_eq!(single.0[l], (raw >> 11) as f64 / 9_007_199_254_740_992.0, "raw {raw:#x}");
                    assert_eq!(
                        (hi.0[l], lo.0[l]),
                        ((raw >> 32) as f64 / 4_294_967_296.0, (raw & 0xFFFF_FFFF) as f64 / 4_294_967_296.0)
                    );
                }
                if round >= 2 {
                    // The generator's own conversions of the same outputs.
                    for (l, rng) in rngs.iter_mut().enumerate() {
                        assert_eq!(rng.clone().next_f64(), single.0[l]);
                        assert_eq!(rng.next_f64_pair(), (hi.0[l], lo.0[l]));
                    }
                }
            }
        }
        unsafe { check() }
    }

    #[test]
    fn masks_and_selects() {
        if lanes_unavailable() {
            return;
        }
        #[target_feature(enable = "avx2,fma")]
        fn check() {
            let a = F4::load(&Lanes([1.0, -2.0, 3.0, -0.0]));
            let b = F4::splat(0.5);
            assert_eq!(a.lt(b).bits(), 0b1010);
            assert_eq!(a.ge(b).bits(), 0b0101);
            assert_eq!(a.sign_one().lanes(), Lanes([1.0, -1.0, 1.0, -1.0]));
            assert_eq!(a.lt(b).select(a, b).lanes(), Lanes([0.5, -2.0, 0.5, -0.0]));
            assert_eq!(to_i32(F4::load(&Lanes([0.0, 1.999, 7.5, 1e9]))), [0, 1, 7, 1_000_000_000]);
            assert_eq!(gather(&[10.0, 11.0, 12.0, 13.0, 14.0], [4, 0, 2, 2]).lanes(), Lanes([14.0, 10.0, 12.0, 12.0]));
        }
        unsafe { check() }
    }
}
