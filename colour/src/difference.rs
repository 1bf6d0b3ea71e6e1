//! Colour differences between two CIE L\*a\*b\* colours (same white):
//! ΔE\*ab (CIE 1976, Euclidean) and ΔE00 (CIEDE2000, CIE 142:2001) exactly as
//! written out by Sharma, Wu & Dalal (2005), "The CIEDE2000 color-difference
//! formula: implementation notes, supplementary test data, and mathematical
//! observations", Color Res. Appl. 30(1), 21–30 — including the hue-angle
//! conventions (h = 0 for a neutral, mean hue = sum when a chroma is 0). Both
//! are unitless; ΔE00 ≈ 1 is a just-noticeable difference. NaN in gives NaN.
//!
//! ```
//! use lucent_colour::difference::{delta_e_2000, delta_e_76};
//! // Sharma et al. (2005) Table 1, pair 17.
//! let (a, b) = ([50.0, 2.5, 0.0], [73.0, 25.0, -18.0]);
//! assert!((delta_e_2000(a, b) - 27.1492).abs() < 5e-5);
//! assert!((delta_e_76([50.0, 0.0, 0.0], [53.0, 4.0, 0.0]) - 5.0).abs() < 1e-12);
//! ```

/// ΔE\*ab = ‖Lab₁ − Lab₂‖ (CIE 1976).
pub fn delta_e_76(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    ((lab1[0] - lab2[0]).powi(2) + (lab1[1] - lab2[1]).powi(2) + (lab1[2] - lab2[2]).powi(2)).sqrt()
}

/// ΔE00 with the parametric factors k_L = k_C = k_H = 1.
pub fn delta_e_2000(lab1: [f64; 3], lab2: [f64; 3]) -> f64 {
    delta_e_2000_weighted(lab1, lab2, [1.0, 1.0, 1.0])
}

/// ΔE00 with parametric factors `k = [k_L, k_C, k_H]`.
pub fn delta_e_2000_weighted(lab1: [f64; 3], lab2: [f64; 3], k: [f64; 3]) -> f64 {
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let pow7_25 = 25f64.powi(7);
    let c1 = a1.hypot(b1);
    let c2 = a2.hypot(b2);
    let c_bar7 = ((c1 + c2) / 2.0).powi(7);
    let g = 0.5 * (1.0 - (c_bar7 / (c_bar7 + pow7_25)).sqrt());
    let a1p = (1.0 + g) * a1;
    let a2p = (1.0 + g) * a2;
    let c1p = a1p.hypot(b1);
    let c2p = a2p.hypot(b2);
    let hue = |b: f64, ap: f64| {
        if b == 0.0 && ap == 0.0 {
            0.0
        } else {
            b.atan2(ap).to_degrees().rem_euclid(360.0)
        }
    };
    let h1p = hue(b1, a1p);
    let h2p = hue(b2, a2p);

    let dl = l2 - l1;
    let dc = c2p - c1p;
    let chroma_product = c1p * c2p;
    let dh = if chroma_product == 0.0 {
        0.0
    } else {
        let d = h2p - h1p;
        if d.abs() <= 180.0 {
            d
        } else if d > 180.0 {
            d - 360.0
        } else {
            d + 360.0
        }
    };
    let d_big_h = 2.0 * chroma_product.sqrt() * (dh.to_radians() / 2.0).sin();

    let l_bar = (l1 + l2) / 2.0;
    let c_bar_p = (c1p + c2p) / 2.0;
    let h_bar = if chroma_product == 0.0 {
        h1p + h2p
    } else if (h1p - h2p).abs() <= 180.0 {
        (h1p + h2p) / 2.0
    } else if h1p + h2p < 360.0 {
        (h1p + h2p + 360.0) / 2.0
    } else {
        (h1p + h2p - 360.0) / 2.0
    };
    let t = 1.0 - 0.17 * (h_bar - 30.0).to_radians().cos()
        + 0.24 * (2.0 * h_bar).to_radians().cos()
        + 0.32 * (3.0 * h_bar + 6.0).to_radians().cos()
        - 0.20 * (4.0 * h_bar - 63.0).to_radians().cos();
    let d_theta = 30.0 * (-((h_bar - 275.0) / 25.0).powi(2)).exp();
    let c_bar_p7 = c_bar_p.powi(7);
    let r_c = 2.0 * (c_bar_p7 / (c_bar_p7 + pow7_25)).sqrt();
    let l50 = (l_bar - 50.0).powi(2);
    let s_l = 1.0 + 0.015 * l50 / (20.0 + l50).sqrt();
    let s_c = 1.0 + 0.045 * c_bar_p;
    let s_h = 1.0 + 0.015 * c_bar_p * t;
    let r_t = -(2.0 * d_theta).to_radians().sin() * r_c;

    let tl = dl / (k[0] * s_l);
    let tc = dc / (k[1] * s_c);
    let th = d_big_h / (k[2] * s_h);
    let sum = tl * tl + tc * tc + th * th + r_t * tc * th;
    // The sum is ≥ 0 up to rounding; `f64::max` would turn NaN into 0.
    if sum < 0.0 {
        0.0
    } else {
        sum.sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_for_equal_colours_and_symmetric() {
        for lab in [[50.0, 0.0, 0.0], [30.0, 20.0, -40.0], [0.0, 0.0, 0.0]] {
            assert_eq!(delta_e_2000(lab, lab), 0.0);
        }
        let (a, b) = ([61.2901, 3.7196, -5.3901], [61.4292, 2.2480, -4.9620]);
        assert!((delta_e_2000(a, b) - delta_e_2000(b, a)).abs() < 1e-12);
    }

    #[test]
    fn nan_gives_nan_not_a_panic() {
        assert!(delta_e_2000([f64::NAN, 0.0, 0.0], [50.0, 1.0, 1.0]).is_nan());
        assert!(delta_e_76([f64::NAN, 0.0, 0.0], [50.0, 1.0, 1.0]).is_nan());
    }
}
