//! The triplet picture: photo | render | signed difference, one row per
//! alignment (as calibrated; after ECC refinement), as an 8-bit PNG.
//!
//! * Photo and render share one exposure `k`: the shown value is
//!   `sRGB(k × linear)` per channel, clipped to [0, 1] (IEC 61966-2-1
//!   transfer function); pixels with any `k × value > 1` clip, are marked
//!   with magenta diagonal stripes ([`CLIP_MARK`]) in the photo and render
//!   columns, and their fraction is stated in the header and in
//!   metrics.json. Only included pixels are striped: stripes always mean
//!   "clipped", never "masked".
//! * The difference is the luminance `Y(render) − Y(photo)` (linear, the
//!   images' own units, not scaled by `k`) in a diverging map — ColorBrewer
//!   RdBu (Brewer 2002), blue where the render is darker, white at 0, red
//!   where it is brighter — over a symmetric range ±`diff_range`, with a
//!   colour bar under the difference column. Values beyond it saturate.
//! * Excluded (masked) pixels are greyed in the photo and render
//!   (desaturated, pulled half-way to mid-grey, so the context stays
//!   visible, and never striped) and flat grey ([`MASK_MARK`]) in the
//!   difference, apart from the near-white of zero difference. A key under
//!   the panels shows both marks.
//! * Panels are at most [`PANEL_MAX`] px wide (box average in linear light
//!   over `f × f` pixels; the difference averages included pixels only, and
//!   a panel pixel counts as masked when fewer than half of its pixels are
//!   included) and at least [`PANEL_MIN`] px wide (pixels repeated).
//!
//! ```
//! use lucent::compare::triplet::{triplet_png, Row, Style};
//! use lucent::imageio::RgbImage;
//! let photo = RgbImage::new(16, 12, vec![0.2; 16 * 12 * 3]).unwrap();
//! let render = RgbImage::new(16, 12, vec![0.25; 16 * 12 * 3]).unwrap();
//! let row = Row { title: "as calibrated".into(), photo: &photo, render: &render, mask: None, caption: "RMSE 0.05".into() };
//! let style = Style { exposure: 2.0, luminance: [0.1769, 0.8124, 0.0107], diff_range: 0.1, header: vec!["test".into()] };
//! let png = triplet_png(&[row], &style).unwrap();
//! assert_eq!(&png[1..4], b"PNG");
//! ```

use super::mask::Mask;
use crate::imageio::{srgb_encode, RgbImage};
use crate::plot::{perr, render_png, PlotError};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Widest panel in pixels (larger images are box-averaged down).
pub const PANEL_MAX: usize = 720;
/// Narrowest panel in pixels (smaller images are enlarged by repetition).
pub const PANEL_MIN: usize = 320;

/// The stripes over clipped photo and render pixels.
pub const CLIP_MARK: RGBColor = RGBColor(255, 0, 255);

/// Excluded (masked) pixels in the difference column: a flat mid-grey, which
/// the diverging map (blue, near-white, red) never produces.
pub const MASK_MARK: RGBColor = RGBColor(150, 150, 150);

/// Blank border around the picture, pixels.
pub const MARGIN: i32 = 16;
/// Gap between the photo, render and difference columns, pixels.
pub const GAP: i32 = 12;
const LINE: i32 = 22;

/// One row of the picture.
pub struct Row<'a> {
    /// Above the row, e.g. "as calibrated".
    pub title: String,
    pub photo: &'a RgbImage,
    pub render: &'a RgbImage,
    /// Included pixels (None: all).
    pub mask: Option<&'a Mask>,
    /// Below the row, e.g. the metrics.
    pub caption: String,
}

/// What is shared by all rows.
pub struct Style {
    /// Display exposure k (shown value = sRGB(k × linear)).
    pub exposure: f64,
    /// Luminance weights for the difference.
    pub luminance: [f64; 3],
    /// The colour bar spans ±diff_range (linear units).
    pub diff_range: f64,
    /// Text lines at the top.
    pub header: Vec<String>,
}

/// ColorBrewer RdBu (11 classes), from blue (−1) through white to red (+1).
pub fn diverging(t: f64) -> RGBColor {
    const S: [(u8, u8, u8); 11] = [
        (5, 48, 97),
        (33, 102, 172),
        (67, 147, 195),
        (146, 197, 222),
        (209, 229, 240),
        (247, 247, 247),
        (253, 219, 199),
        (244, 165, 130),
        (214, 96, 77),
        (178, 24, 43),
        (103, 0, 31),
    ];
    let u = if t.is_nan() { 5.0 } else { (t.clamp(-1.0, 1.0) + 1.0) * 0.5 * 10.0 };
    let i = (u.floor() as usize).min(9);
    let f = u - i as f64;
    let lerp = |a: u8, b: u8| (f64::from(a) + (f64::from(b) - f64::from(a)) * f).round() as u8;
    RGBColor(lerp(S[i].0, S[i + 1].0), lerp(S[i].1, S[i + 1].1), lerp(S[i].2, S[i + 1].2))
}

/// How source pixels map to panel pixels.
#[derive(Debug, Clone, Copy)]
struct Scale {
    /// Source pixels per panel pixel (box), ≥ 1.
    down: usize,
    /// Panel pixels per source pixel (repeat), ≥ 1.
    up: usize,
    pw: usize,
    ph: usize,
}

fn scale_for(w: usize, h: usize) -> Scale {
    scale_within(w, h, PANEL_MAX)
}

/// [`scale_for`] with panels at most `max` pixels wide or high.
fn scale_within(w: usize, h: usize, max: usize) -> Scale {
    let side = w.max(h);
    if side > max {
        let down = side.div_ceil(max);
        Scale { down, up: 1, pw: w.div_ceil(down), ph: h.div_ceil(down) }
    } else if w < PANEL_MIN {
        let up = PANEL_MIN.div_ceil(w).min((max / side).max(1));
        Scale { down: 1, up, pw: w * up, ph: h * up }
    } else {
        Scale { down: 1, up: 1, pw: w, ph: h }
    }
}

/// Box-averaged panel data: RGB of photo and render, ΔY over included
/// pixels, and whether the panel pixel counts as masked.
struct Panels {
    photo: Vec<[f64; 3]>,
    render: Vec<[f64; 3]>,
    diff: Vec<f64>,
    masked: Vec<bool>,
    /// Source-resolution width and height (panel = this × up).
    w: usize,
    h: usize,
}

fn reduce(row: &Row, s: Scale, luma: [f64; 3]) -> Panels {
    let (w, h) = (row.photo.width, row.photo.height);
    let (bw, bh) = (w.div_ceil(s.down), h.div_ceil(s.down));
    let mut out = Panels {
        photo: vec![[0.0; 3]; bw * bh],
        render: vec![[0.0; 3]; bw * bh],
        diff: vec![0.0; bw * bh],
        masked: vec![false; bw * bh],
        w: bw,
        h: bh,
    };
    for by in 0..bh {
        for bx in 0..bw {
            let (mut p, mut r, mut d) = ([0.0f64; 3], [0.0f64; 3], 0.0);
            let (mut n, mut inc) = (0usize, 0usize);
            for y in by * s.down..((by + 1) * s.down).min(h) {
                for x in bx * s.down..((bx + 1) * s.down).min(w) {
                    let (a, b) = (row.photo.pixel(x, y), row.render.pixel(x, y));
                    for c in 0..3 {
                        p[c] += f64::from(a[c]);
                        r[c] += f64::from(b[c]);
                    }
                    n += 1;
                    if row.mask.is_none_or(|m| m.get(x, y)) {
                        inc += 1;
                        d += (0..3).map(|c| luma[c] * (f64::from(b[c]) - f64::from(a[c]))).sum::<f64>();
                    }
                }
            }
            let k = by * bw + bx;
            out.photo[k] = p.map(|v| v / n as f64);
            out.render[k] = r.map(|v| v / n as f64);
            out.diff[k] = if inc > 0 { d / inc as f64 } else { 0.0 };
            out.masked[k] = 2 * inc < n;
        }
    }
    out
}

/// Stripes of the clipping mark.
fn clip_stripe(x: usize, y: usize) -> bool {
    (x + 1000 - y % 1000) % 8 < 3
}

/// Whether `k × value` exceeds 1 in any channel (shown clipped).
fn clipped(rgb: [f64; 3], k: f64) -> bool {
    rgb.iter().any(|v| k * v > 1.0)
}

/// Photo/render pixel: sRGB of k × value; excluded pixels greyed
/// (desaturated, pulled half-way to mid-grey) so the context stays visible.
fn shown(rgb: [f64; 3], k: f64, masked: bool) -> RGBColor {
    let c = rgb.map(|v| f64::from(srgb_encode((k * v) as f32)) * 255.0);
    if masked {
        let g = (c[0] + c[1] + c[2]) / 3.0;
        let m = |v: f64| (0.5 * (0.25 * v + 0.75 * g) + 0.5 * 160.0).round() as u8;
        return RGBColor(m(c[0]), m(c[1]), m(c[2]));
    }
    RGBColor(c[0].round() as u8, c[1].round() as u8, c[2].round() as u8)
}

fn tick_label(v: f64, range: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    if (0.01..1000.0).contains(&range) {
        let digits = (2 - range.log10().floor() as i32).max(0) as usize;
        format!("{v:+.digits$}")
    } else {
        format!("{v:+.2e}")
    }
}

/// The diverging colour bar from −`range` to +`range`, 16 px high and
/// `width` wide with its top-left corner at `at`, five ticks with labels
/// of `label_size` px under it (the end labels inside the bar's extent).
fn diverging_bar(
    root: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
    at: (i32, i32),
    width: i32,
    range: f64,
    label_size: i32,
) -> Result<(), PlotError> {
    let (bx, y0) = at;
    for i in 0..width {
        let t = 2.0 * (f64::from(i) + 0.5) / f64::from(width) - 1.0;
        root.draw(&Rectangle::new([(bx + i, y0), (bx + i + 1, y0 + 16)], diverging(t).filled())).map_err(perr)?;
    }
    root.draw(&Rectangle::new([(bx, y0), (bx + width, y0 + 16)], BLACK.stroke_width(1))).map_err(perr)?;
    for k in 0..5 {
        let x = bx + ((width - 1) * k) / 4;
        root.draw(&PathElement::new(vec![(x, y0 + 16), (x, y0 + 21)], BLACK.stroke_width(1))).map_err(perr)?;
        let v = range * (f64::from(k) / 2.0 - 1.0);
        let hpos = match k {
            0 => HPos::Left,
            4 => HPos::Right,
            _ => HPos::Center,
        };
        let st = TextStyle::from(("sans-serif", label_size).into_font()).color(&BLACK).pos(Pos::new(hpos, VPos::Top));
        root.draw(&Text::new(tick_label(v, range), (x, y0 + 22), st)).map_err(perr)?;
    }
    Ok(())
}

/// Draws the picture and returns PNG bytes. All rows must have images of
/// one size.
pub fn triplet_png(rows: &[Row], style: &Style) -> Result<Vec<u8>, PlotError> {
    let first = rows.first().ok_or_else(|| perr("no rows to draw"))?;
    let (w, h) = (first.photo.width, first.photo.height);
    for r in rows {
        let sizes = [(r.photo.width, r.photo.height), (r.render.width, r.render.height)];
        if sizes.iter().any(|&s| s != (w, h)) || r.mask.is_some_and(|m| (m.width, m.height) != (w, h)) {
            return Err(perr("triplet rows of different image sizes"));
        }
    }
    let s = scale_for(w, h);
    let (pw, ph) = (s.pw as i32, s.ph as i32);
    let header_h = LINE * style.header.len() as i32 + 8;
    let row_h = LINE + LINE + ph + LINE + 8;
    let bar_h = 16 + 24 + LINE;
    let width = 2 * MARGIN + 3 * pw + 2 * GAP;
    let height = MARGIN + header_h + rows.len() as i32 * row_h + bar_h + MARGIN;
    let reduced: Vec<Panels> = rows.iter().map(|r| reduce(r, s, style.luminance)).collect();
    render_png(width as u32, height as u32, |root| {
        let text = |t: &str, x: i32, y: i32, size: i32, pos: Pos| {
            let st = TextStyle::from(("sans-serif", size).into_font()).color(&BLACK).pos(pos);
            root.draw(&Text::new(t.to_string(), (x, y), st)).map_err(perr)
        };
        let left = Pos::new(HPos::Left, VPos::Top);
        let centre = Pos::new(HPos::Center, VPos::Top);
        let mut y0 = MARGIN;
        for line in &style.header {
            text(line, MARGIN, y0, 15, left)?;
            y0 += LINE;
        }
        y0 += 8;
        let range = if style.diff_range > 0.0 && style.diff_range.is_finite() { style.diff_range } else { 1.0 };
        let columns = ["photo", "render", "render − photo (luminance)"];
        for (row, p) in rows.iter().zip(&reduced) {
            text(&row.title, MARGIN, y0, 17, left)?;
            y0 += LINE;
            for (c, name) in columns.iter().enumerate() {
                text(name, MARGIN + c as i32 * (pw + GAP) + pw / 2, y0, 15, centre)?;
            }
            y0 += LINE;
            for py in 0..s.ph {
                for px in 0..s.pw {
                    let k = (py / s.up).min(p.h - 1) * p.w + (px / s.up).min(p.w - 1);
                    let m = p.masked[k];
                    // Stripes mark clipped included pixels only: masked ones are greyed, not striped.
                    let mark = |rgb: [f64; 3]| {
                        if !m && clipped(rgb, style.exposure) && clip_stripe(px, py) {
                            CLIP_MARK
                        } else {
                            shown(rgb, style.exposure, m)
                        }
                    };
                    let colours =
                        [mark(p.photo[k]), mark(p.render[k]), if m { MASK_MARK } else { diverging(p.diff[k] / range) }];
                    for (c, colour) in colours.iter().enumerate() {
                        root.draw_pixel((MARGIN + c as i32 * (pw + GAP) + px as i32, y0 + py as i32), colour)
                            .map_err(perr)?;
                    }
                }
            }
            y0 += ph + 4;
            text(&row.caption, MARGIN, y0, 15, left)?;
            y0 += LINE + 4;
        }
        // Colour bar under the difference column.
        let bx = MARGIN + 2 * (pw + GAP);
        diverging_bar(root, (bx, y0), pw, range, 13)?;
        text("Y(render) − Y(photo), linear units", bx + pw / 2, y0 + 40, 13, centre)?;
        // Legend for excluded pixels, under the photo column.
        if rows.iter().any(|r| r.mask.is_some()) {
            for i in 0..28 {
                for j in 0..16 {
                    root.draw_pixel((MARGIN + i, y0 + j), &MASK_MARK).map_err(perr)?;
                    let greyed = shown([0.05, 0.4, 0.1], 1.0, true);
                    root.draw_pixel((MARGIN + 36 + i, y0 + j), &greyed).map_err(perr)?;
                }
            }
            let note = "excluded by the mask: grey (difference), greyed (photo, render)";
            text(note, MARGIN + 72, y0, 14, left)?;
        }
        // Legend for clipped pixels, under the render column, when there are any.
        let any_clipped = reduced.iter().any(|p| {
            let included = |k: &usize| !p.masked[*k];
            (0..p.masked.len())
                .filter(included)
                .any(|k| clipped(p.photo[k], style.exposure) || clipped(p.render[k], style.exposure))
        });
        if any_clipped {
            let lx = MARGIN + pw + GAP;
            let ly = y0 + if rows.iter().any(|r| r.mask.is_some()) { 24 } else { 0 };
            for i in 0..28 {
                for j in 0..16 {
                    let c = if clip_stripe(i, j) { CLIP_MARK } else { RGBColor(255, 255, 255) };
                    root.draw_pixel((lx + i as i32, ly + j as i32), &c).map_err(perr)?;
                }
            }
            text(
                &format!("clipped at exposure ×{} (striped)", crate::plot::short_number(style.exposure)),
                lx + 36,
                ly,
                14,
                left,
            )?;
        }
        Ok(())
    })
}

/// Widest panel of the twins' picture ([`twins_png`]): five panels side by
/// side must fit a page.
pub const TWIN_PANEL_MAX: usize = 400;

/// One twin of [`twins_png`]: its render, the title above its two columns
/// (e.g. "A: recipe twin — model RMSE …") and the caption under them.
pub struct Twin<'a> {
    pub render: &'a RgbImage,
    pub title: String,
    pub caption: String,
}

/// Two twins side by side against one photo: photo | A render | A
/// difference | B render | B difference, both difference columns under ONE
/// colour scale (±`style.diff_range`), so the twins can be compared by eye.
/// PNG bytes.
pub fn twins_png(photo: &RgbImage, mask: Option<&Mask>, twins: [Twin; 2], style: &Style) -> Result<Vec<u8>, PlotError> {
    let (w, h) = (photo.width, photo.height);
    for t in &twins {
        if (t.render.width, t.render.height) != (w, h) || mask.is_some_and(|m| (m.width, m.height) != (w, h)) {
            return Err(perr("twins of different image sizes"));
        }
    }
    let s = scale_within(w, h, TWIN_PANEL_MAX);
    let (pw, ph) = (s.pw as i32, s.ph as i32);
    let header_h = LINE * style.header.len() as i32 + 8;
    let bar_h = 16 + 24 + LINE;
    let width = 2 * MARGIN + 5 * pw + 4 * GAP;
    let height = MARGIN + header_h + LINE + LINE + ph + 4 + 2 * LINE + 8 + bar_h + MARGIN;
    let rows: Vec<Row> = twins
        .iter()
        .map(|t| Row { title: String::new(), photo, render: t.render, mask, caption: String::new() })
        .collect();
    let reduced: Vec<Panels> = rows.iter().map(|r| reduce(r, s, style.luminance)).collect();
    let range = if style.diff_range > 0.0 && style.diff_range.is_finite() { style.diff_range } else { 1.0 };
    let col_x = |c: i32| MARGIN + c * (pw + GAP);
    render_png(width as u32, height as u32, |root| {
        let text = |t: &str, x: i32, y: i32, size: i32, pos: Pos| {
            let st = TextStyle::from(("sans-serif", size).into_font()).color(&BLACK).pos(pos);
            root.draw(&Text::new(t.to_string(), (x, y), st)).map_err(perr)
        };
        let left = Pos::new(HPos::Left, VPos::Top);
        let centre = Pos::new(HPos::Center, VPos::Top);
        let mut y0 = MARGIN;
        for line in &style.header {
            text(line, MARGIN, y0, 16, left)?;
            y0 += LINE;
        }
        y0 += 8;
        for (k, t) in twins.iter().enumerate() {
            text(&t.title, col_x(1 + 2 * k as i32), y0, 18, left)?;
        }
        y0 += LINE;
        let columns = ["photo", "A: render", "A: render − photo", "B: render", "B: render − photo"];
        for (c, name) in columns.iter().enumerate() {
            text(name, col_x(c as i32) + pw / 2, y0, 16, centre)?;
        }
        y0 += LINE;
        for py in 0..s.ph {
            for px in 0..s.pw {
                let k = (py / s.up).min(reduced[0].h - 1) * reduced[0].w + (px / s.up).min(reduced[0].w - 1);
                let m = reduced[0].masked[k];
                let mark = |rgb: [f64; 3]| {
                    if !m && clipped(rgb, style.exposure) && clip_stripe(px, py) {
                        CLIP_MARK
                    } else {
                        shown(rgb, style.exposure, m)
                    }
                };
                let diff = |p: &Panels| if m { MASK_MARK } else { diverging(p.diff[k] / range) };
                let colours = [
                    mark(reduced[0].photo[k]),
                    mark(reduced[0].render[k]),
                    diff(&reduced[0]),
                    mark(reduced[1].render[k]),
                    diff(&reduced[1]),
                ];
                for (c, colour) in colours.iter().enumerate() {
                    root.draw_pixel((col_x(c as i32) + px as i32, y0 + py as i32), colour).map_err(perr)?;
                }
            }
        }
        y0 += ph + 4;
        for (k, t) in twins.iter().enumerate() {
            // Both under the twins' four columns (a caption is wider than its own two).
            text(&t.caption, col_x(1), y0 + LINE * k as i32, 15, left)?;
        }
        y0 += 2 * LINE + 8;
        // One colour bar for both difference columns, under the four twin columns.
        let (bx, bw) = (col_x(1), 4 * pw + 3 * GAP);
        diverging_bar(root, (bx, y0), bw, range, 15)?;
        text(
            "Y(render) − Y(photo), linear units: ONE scale for both twins' difference columns",
            bx + bw / 2,
            y0 + 40,
            15,
            centre,
        )?;
        if mask.is_some() {
            text("grey: excluded by the mask", MARGIN, y0, 15, left)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diverging_map_is_white_at_zero_and_saturates() {
        assert_eq!(diverging(0.0), RGBColor(247, 247, 247));
        assert_eq!(diverging(-1.0), RGBColor(5, 48, 97));
        assert_eq!(diverging(7.0), RGBColor(103, 0, 31));
        assert_eq!(diverging(f64::NAN), RGBColor(247, 247, 247));
    }

    /// Clipped photo pixels carry the clipping stripes; at an exposure that clips nothing, no stripes.
    #[test]
    fn clipped_pixels_are_marked() {
        let (w, h) = (40, 30);
        let photo_data: Vec<f32> = (0..w * h).flat_map(|i| if i % w < 20 { [0.8f32; 3] } else { [0.1; 3] }).collect();
        let photo = RgbImage::new(w, h, photo_data).unwrap();
        let render = RgbImage::new(w, h, vec![0.2; w * h * 3]).unwrap();
        let draw = |exposure: f64| {
            let row = Row { title: "t".into(), photo: &photo, render: &render, mask: None, caption: "c".into() };
            let style = Style { exposure, luminance: [0.2126, 0.7152, 0.0722], diff_range: 0.1, header: vec![] };
            image::load_from_memory(&triplet_png(&[row], &style).unwrap()).unwrap().to_rgb8()
        };
        let marked = |img: &image::RgbImage, x0: u32, x1: u32| {
            (x0..x1)
                .flat_map(|x| (0..img.height()).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x, y).0 == [255, 0, 255])
                .count()
        };
        let pw = scale_for(w, h).pw as u32;
        let m = MARGIN as u32;
        // 0.8 × 2 > 1 on the left half of the photo: about 3/8 of its half-panel pixels are stripes.
        let img = draw(2.0);
        let n = marked(&img, m, m + pw);
        assert!(n as u32 > pw * pw * 3 / 4 / 2 * 3 / 8 / 2, "{n} marked photo pixels");
        assert_eq!(marked(&img, m + pw / 2 + 4, m + pw), 0, "the unclipped half is not marked");
        // 0.8 × 1 ≤ 1: nothing clips.
        let img = draw(1.0);
        assert_eq!(marked(&img, 0, img.width()), 0);
    }

    #[test]
    fn twins_sit_side_by_side_under_one_bar() {
        let (w, h) = (64, 48);
        let photo = RgbImage::new(w, h, vec![0.5; w * h * 3]).unwrap();
        let a = RgbImage::new(w, h, vec![0.6; w * h * 3]).unwrap();
        let b = RgbImage::new(w, h, vec![0.4; w * h * 3]).unwrap();
        let style = Style { exposure: 1.0, luminance: [0.2126, 0.7152, 0.0722], diff_range: 0.1, header: vec![] };
        let twin = |render, t: &str| Twin { render, title: t.into(), caption: String::new() };
        let png = twins_png(&photo, None, [twin(&a, "A: recipe twin"), twin(&b, "B: fitted twin")], &style).unwrap();
        let img = image::load_from_memory(&png).unwrap();
        assert_eq!(img.width() as i32, 2 * MARGIN + 5 * 320 + 4 * GAP);
        // A's difference (+0.1 = the bar's end) is dark red, B's (−0.1) dark blue: one scale.
        let at = |c: i32| img.to_rgb8().get_pixel((MARGIN + c * (320 + GAP) + 160) as u32, 200).0;
        assert_eq!(at(2), [103, 0, 31]);
        assert_eq!(at(4), [5, 48, 97]);
        // A 640 × 480 render's panels are halved to fit five on a page.
        assert_eq!(scale_within(640, 480, TWIN_PANEL_MAX).pw, 320);
    }

    #[test]
    fn panel_scales() {
        let s = scale_for(4000, 3000);
        assert_eq!((s.down, s.pw, s.ph), (6, 667, 500));
        let s = scale_for(64, 48);
        assert_eq!((s.up, s.pw, s.ph), (5, 320, 240));
        let s = scale_for(500, 400);
        assert_eq!((s.down, s.up, s.pw), (1, 1, 500));
        // A tall narrow image stays within PANEL_MAX.
        let s = scale_for(20, 700);
        assert_eq!(s.up, 1);
    }

    #[test]
    fn tick_labels() {
        assert_eq!(tick_label(0.0, 0.05), "0");
        assert_eq!(tick_label(-0.05, 0.05), "-0.0500");
        assert_eq!(tick_label(0.025, 0.05), "+0.0250");
        assert_eq!(tick_label(2.5, 5.0), "+2.50");
        assert_eq!(tick_label(1e-4, 1e-4), "+1.00e-4");
    }
}
