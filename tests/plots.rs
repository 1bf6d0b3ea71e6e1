//! Plots a reader can trust: properties of the drawn pixels that a
//! wrong plot would not have.

use lucent::bssrdf::{compare, heatmap_png, Grid, OVER};
use lucent::plot::MASKED;
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

/// Masked and clipped pixels of compare's triplet.png are told apart: the masked half of a clipped photo is greyed
/// and never striped, the included half striped; the masked half of the difference is the flat mask grey; the key
/// under the panels shows both marks.
#[test]
fn triplet_marks_masked_and_clipped_pixels_apart() {
    use lucent::compare::mask::Mask;
    use lucent::compare::triplet::{triplet_png, Row, Style, CLIP_MARK, GAP, MARGIN, MASK_MARK};
    use lucent::imageio::RgbImage;
    // 40 × 40 images are drawn 8 × enlarged: panels 320 px square.
    let (w, h, pw) = (40usize, 40usize, 320u32);
    let photo = RgbImage::new(w, h, vec![0.8; w * h * 3]).unwrap();
    let render = RgbImage::new(w, h, vec![0.2; w * h * 3]).unwrap();
    // Left half excluded.
    let mask = Mask { width: w, height: h, include: (0..w * h).map(|i| i % w >= 20).collect() };
    let draw = |mask: Option<&Mask>| {
        let row = Row { title: "t".into(), photo: &photo, render: &render, mask, caption: "c".into() };
        // 0.8 × 2 > 1: every photo pixel clips; the render (0.4) does not.
        let style = Style { exposure: 2.0, luminance: [0.2126, 0.7152, 0.0722], diff_range: 0.1, header: vec![] };
        image::load_from_memory(&triplet_png(&[row], &style).unwrap()).unwrap().to_rgb8()
    };
    let photo_x = MARGIN as u32;
    let diff_x = (MARGIN + 2 * (pw as i32 + GAP)) as u32;
    // The panel rows: where the included half of the difference is saturated blue (render darker by 6 × the range).
    let rows = |img: &image::RgbImage| -> Vec<u32> {
        (0..img.height()).filter(|&y| img.get_pixel(diff_x + 3 * pw / 4, y).0 == [5, 48, 97]).collect()
    };
    // Pixels of colour `c` in columns x0..x1 of the panel rows (captions and tick labels have grey anti-aliasing).
    let count = |img: &image::RgbImage, c: RGBColor, x0: u32, x1: u32| {
        let ys = rows(img);
        assert_eq!(ys.len() as u32, pw, "panel rows");
        (x0..x1)
            .flat_map(|x| ys.iter().map(move |&y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 == [c.0, c.1, c.2])
            .count()
    };
    let half = (pw / 2) as usize * pw as usize;

    let masked = draw(Some(&mask));
    assert_eq!(count(&masked, CLIP_MARK, photo_x, photo_x + pw / 2), 0, "masked photo pixels carry no stripes");
    let striped = count(&masked, CLIP_MARK, photo_x + pw / 2, photo_x + pw);
    assert!(striped > half / 4 && striped < half * 3 / 4, "included clipped half striped: {striped} of {half}");
    let grey = count(&masked, MASK_MARK, diff_x, diff_x + pw / 2);
    assert!(grey >= half, "masked difference half in the mask grey: {grey} of {half}");
    assert_eq!(count(&masked, MASK_MARK, diff_x + pw / 2 + 1, diff_x + pw), 0, "included difference half not grey");
    // The key under the panels (below the last panel row): a mask-grey swatch and a clipping-stripe swatch.
    let below = |img: &image::RgbImage, c: RGBColor| {
        let top = rows(img).last().copied().unwrap_or(0) + 1;
        (0..img.width())
            .flat_map(|x| (top..img.height()).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 == [c.0, c.1, c.2])
            .count()
    };
    assert!(below(&masked, MASK_MARK) >= 28 * 16, "mask key");
    assert!(below(&masked, CLIP_MARK) >= 28 * 4, "clipping key");

    // Without a mask: stripes over the whole photo panel, no mask grey anywhere, no mask key.
    let plain = draw(None);
    let all = count(&plain, CLIP_MARK, photo_x, photo_x + pw);
    assert!(all > 2 * striped * 9 / 10, "whole clipped photo striped: {all}");
    assert_eq!(count(&plain, MASK_MARK, 0, plain.width()), 0, "no mask grey in the panels");
}

/// The polar phase plot keeps its legend in the column right of the chart: both series' marks (Lorenz–Mie blue,
/// Henyey–Greenstein red) are drawn there, clear of the curves.
#[test]
fn polar_phase_legend_is_beside_the_chart() {
    use lucent::plot::{phase_polar_png, POLAR_LEGEND_W, POLAR_SIDE, POLAR_TITLE_H};
    // The table: Henyey–Greenstein with g = 0.9, drawn against the plot's own g = 0.7 curve (two distinct curves).
    let g: f64 = 0.7;
    let hg = |g: f64, mu: f64| (1.0 - g * g) / (4.0 * std::f64::consts::PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
    let table: Vec<f64> = (0..181).map(|i| hg(0.9, (std::f64::consts::PI * i as f64 / 180.0).cos())).collect();
    let img = image::load_from_memory(&phase_polar_png("t", &table, g).unwrap()).unwrap().to_rgb8();
    assert_eq!((img.width(), img.height()), (POLAR_SIDE + POLAR_LEGEND_W, POLAR_SIDE + POLAR_TITLE_H));
    let count = |c: [u8; 3], x0: u32, x1: u32| {
        (x0..x1)
            .flat_map(|x| (0..img.height()).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 == c)
            .count()
    };
    let (blue, red) = ([31, 119, 180], [214, 39, 40]);
    let width = img.width();
    assert!(count(blue, POLAR_SIDE, width) >= 40, "Lorenz–Mie mark in the legend column");
    assert!(count(red, POLAR_SIDE, width) >= 40, "Henyey–Greenstein mark in the legend column");
    assert!(count(blue, 0, POLAR_SIDE) > 500 && count(red, 0, POLAR_SIDE) > 500, "both curves in the chart");
}
