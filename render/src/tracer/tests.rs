//! Unit tests of the tracer's private parts: the distances to the face
//! planes that set the connections' attempt probability.

use super::connections::{distance_to_lit_planes, distance_to_planes};
use glam::DVec3;

/// A 149.1 × 104.5 × 6.35 mm plaque's outward face planes n·x ≤ c, its bottom at z = 0.
fn plaque_planes() -> Vec<(DVec3, f64)> {
    vec![
        (DVec3::Z, 0.00635),
        (-DVec3::Z, 0.0),
        (DVec3::X, 0.07455),
        (-DVec3::X, 0.07455),
        (DVec3::Y, 0.05225),
        (-DVec3::Y, 0.05225),
    ]
}

#[test]
fn lit_planes_leave_out_the_faces_that_look_down_at_the_board() {
    let planes = plaque_planes();
    let x = DVec3::new(0.01, -0.02, 0.001);
    // 1 mm above the bottom: the bottom face is nearest, the top 5.35 mm away.
    assert!((distance_to_planes(&planes, x) - 0.001).abs() < 1e-15);
    assert!((distance_to_lit_planes(&planes, x, Some(DVec3::Z)) - 0.00535).abs() < 1e-15);
    // Without a favoured hemisphere every face counts.
    assert_eq!(distance_to_lit_planes(&planes, x, None), distance_to_planes(&planes, x));
    // Near a side, the side (vertical, n·up = 0) counts.
    let y = DVec3::new(0.0745, 0.0, 0.001);
    assert!((distance_to_lit_planes(&planes, y, Some(DVec3::Z)) - 0.00005).abs() < 1e-12);
    // A board seen from below favours −z: now the top face is the hidden one.
    let z = DVec3::new(0.0, 0.0, 0.006);
    assert!((distance_to_lit_planes(&planes, z, Some(-DVec3::Z)) - 0.006).abs() < 1e-15);
}
