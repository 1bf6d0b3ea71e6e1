//! Plots a reader can trust (issue 17): properties of the drawn pixels that a
//! wrong plot would not have.

use lucent::bssrdf::{compare, heatmap_png, Grid, MASKED, OVER};
use plotters::style::RGBColor;

/// Pixels of colour `c` inside the map of the third panel (panels 620 px wide; the map between
/// the axes, clear of captions, tick labels and the colour bars below 600 px).
fn count_in_difference_panel(img: &image::RgbImage, c: RGBColor) -> usize {
    (1300..1845)
        .flat_map(|x| (50..550).map(move |y| (x, y)))
        .filter(|&(x, y)| img.get_pixel(x, y).0 == [c.0, c.1, c.2])
        .count()
}

#[test]
fn panel_shows_masked_pixels_and_clipping_apart_from_zero_difference() {
    let n = 20;
    let column = |i: usize| i % n;
    // Measured: zero in columns 0..5 (outside the mask), 1 elsewhere.
    let m =
        Grid { size: n, pixel_m: 1e-4, values: (0..n * n).map(|i| if column(i) < 5 { 0.0 } else { 1.0 }).collect() };
    // Simulated: equal in columns 5..15 (zero difference), 3 × in 15..20 (relative difference +2, beyond the range).
    let s = Grid {
        size: n,
        pixel_m: 1e-4,
        values: (0..n * n).map(|i| if column(i) >= 15 { 3.0 } else { m.values[i] }).collect(),
    };
    let (_, rel) = compare(&m, &s, 0.01).unwrap();
    assert!(rel.values[0].is_nan() && rel.values[7] == 0.0 && rel.values[17] == 2.0);
    let png = heatmap_png(&[("measured", &m), ("simulated", &s)], Some(("difference", &rel))).unwrap();
    let img = image::load_from_memory(&png).unwrap().to_rgb8();
    // A quarter of the ~500 × 550 px map is masked, a quarter clipped.
    let (masked, over) = (count_in_difference_panel(&img, MASKED), count_in_difference_panel(&img, OVER));
    assert!(masked > 30_000, "masked pixels drawn in the mask colour: {masked}");
    assert!(over > 30_000, "clipped pixels drawn in the clipping colour: {over}");

    // Nothing masked, nothing beyond ±1: neither colour appears in the map.
    let s2 = Grid { size: n, pixel_m: 1e-4, values: vec![1.5; n * n] };
    let m2 = Grid { size: n, pixel_m: 1e-4, values: vec![1.0; n * n] };
    let (_, rel2) = compare(&m2, &s2, 0.01).unwrap();
    let png = heatmap_png(&[("measured", &m2), ("simulated", &s2)], Some(("difference", &rel2))).unwrap();
    let img = image::load_from_memory(&png).unwrap().to_rgb8();
    assert_eq!(count_in_difference_panel(&img, MASKED), 0);
    assert_eq!(count_in_difference_panel(&img, OVER), 0);
}
