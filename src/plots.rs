//! Pictures of error for people: a signed-error heat map per frame and a time/error Pareto chart
//! per scene.
//!
//! Design notes:
//! - `plotters` runs without system font libraries (no fontconfig on build machines): its
//!   `ab_glyph` feature draws text with a TTF we embed (`assets/DejaVuSans.ttf`, Bitstream Vera
//!   licence in `assets/DejaVuSans-LICENSE.txt`), registered once per process as `sans-serif`,
//!   the family plotters' own defaults ask for.
//! - Charts are drawn into an RGB buffer and saved with `image` 0.25; plotters' own encoder would
//!   pull in a second `image` (0.24).
//! - The heat map's pixels are written straight into that buffer (one per frame pixel, no
//!   scaling, so a pixel in the map is a pixel in the frame); plotters then draws only the
//!   title, frame and legend on top.
//! - Slices that do not match the frame size are [`Error::Input`] (as in [`metrics::compare`]);
//!   drawing and saving failures are [`Error::Image`] naming the file; nothing here panics.

use std::ops::Range;
use std::path::Path;
use std::sync::OnceLock;

use plotters::backend::RGBPixel;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::error::{Error, Result};
use crate::metrics;

static FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Registers the embedded font once; later calls return the first call's outcome.
fn ensure_font() -> std::result::Result<(), String> {
    static REGISTERED: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            plotters::style::register_font("sans-serif", FontStyle::Normal, FONT_BYTES)
                .map_err(|_| "the embedded DejaVuSans.ttf is not a valid font".to_string())
        })
        .clone()
}

pub(crate) fn image_error(path: &Path, message: impl std::fmt::Display) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

/// Draws with plotters into a fresh white RGB canvas of `size` and saves it as `path`.
/// `prefill` may write pixels before plotters draws on top.
pub(crate) fn render(
    path: &Path,
    size: (u32, u32),
    prefill: impl FnOnce(&mut [u8]),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_, RGBPixel>, Shift>) -> Result<()>,
) -> Result<()> {
    ensure_font().map_err(|e| image_error(path, e))?;
    // plotters multiplies width × height in u32; refuse what would overflow there.
    let pixels = u64::from(size.0) * u64::from(size.1);
    if pixels > u64::from(u32::MAX) / 3 {
        return Err(image_error(
            path,
            format!("{}×{} is too large", size.0, size.1),
        ));
    }
    let bytes = usize::try_from(pixels * 3).map_err(|_| image_error(path, "image too large"))?;
    let mut buf = vec![255u8; bytes];
    prefill(&mut buf);
    {
        let backend = BitMapBackend::<RGBPixel>::with_buffer_and_format(&mut buf, size)
            .map_err(|e| image_error(path, e))?;
        let root = backend.into_drawing_area();
        draw(&root)?;
        root.present().map_err(|e| image_error(path, e))?;
    }
    let img = image::RgbImage::from_raw(size.0, size.1, buf)
        .ok_or_else(|| image_error(path, "buffer does not match the image size"))?;
    img.save(path).map_err(|e| image_error(path, e))
}

// ------------------------------------------------------------------------------------------------
// Error heat map

/// Width of the legend area right of the map.
const LEGEND_W: u32 = 150;
/// Height of the title band above the map.
const TITLE_H: u32 = 30;
/// The legend needs this much height; smaller frames are padded below.
const MIN_MAP_H: u32 = 220;

const NOT_SAMPLE: [u8; 3] = [150, 150, 150];
const NON_FINITE: [u8; 3] = [0, 0, 0];

/// Size of the PNG [`write_error_heatmap`] writes for a `width × height` frame: the frame plus a
/// legend area of 150 px on the right and a 30 px title band on top; frames shorter than 220 px
/// are padded below so the legend fits.
pub fn heatmap_size(width: u32, height: u32) -> (u32, u32) {
    (
        width.saturating_add(LEGEND_W),
        height.max(MIN_MAP_H).saturating_add(TITLE_H),
    )
}

/// Diverging colour map for a signed error in [−1, 1]: blue below 0 (too dark), white at 0, red
/// above (too bright). Stops are ColorBrewer's RdBu, with the centre pushed to pure white so that
/// "no error" reads as the page.
pub fn diverging_color(e: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 5] = [
        [5.0, 48.0, 97.0],
        [67.0, 147.0, 195.0],
        [255.0, 255.0, 255.0],
        [214.0, 96.0, 77.0],
        [103.0, 0.0, 31.0],
    ];
    let t = (e.clamp(-1.0, 1.0) + 1.0) * 2.0; // 0..4 over the stops
    let i = (t.floor() as usize).min(3);
    let f = t - i as f32;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    std::array::from_fn(|c| (a[c] + (b[c] - a[c]) * f).round() as u8)
}

/// The heat map's colour for one pixel: grey for a pixel that is not a view sample, black for a
/// non-finite test value, else [`diverging_color`] of `test − reference`.
pub fn error_pixel(reference: f32, test: f32, is_sample: bool) -> [u8; 3] {
    if !is_sample {
        NOT_SAMPLE
    } else if !test.is_finite() {
        NON_FINITE
    } else {
        diverging_color(test - reference)
    }
}

/// Writes the signed error `test − reference` of a `width × height` frame as a PNG heat map of
/// size [`heatmap_size`]: blue where the technique is too dark (over-shadowed), red where it is
/// too bright (light leak), white where it is right, grey for pixels that are not view samples
/// and black for non-finite test values; a colour bar with ticks −1 … +1 and a title with RMSE
/// and max error.
///
/// The slices must hold `width × height` entries (otherwise [`Error::Input`], as in
/// [`metrics::compare`]); drawing or saving failures are [`Error::Image`].
pub fn write_error_heatmap(
    path: &Path,
    width: u32,
    height: u32,
    reference: &[f32],
    test: &[f32],
    is_sample: &[bool],
) -> Result<()> {
    let pixels = u64::from(width) * u64::from(height);
    if reference.len() as u64 != pixels {
        return Err(Error::input(
            "plots::write_error_heatmap",
            None,
            format!(
                "{width}×{height} frame needs {pixels} values; got {}",
                reference.len()
            ),
        ));
    }
    let m = metrics::compare(reference, test, is_sample)?;
    let size = heatmap_size(width, height);
    let (w, h) = (width as usize, height as usize);

    let prefill = |buf: &mut [u8]| {
        let stride = size.0 as usize * 3;
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let rgb = error_pixel(reference[i], test[i], is_sample[i]);
                let o = (y + TITLE_H as usize) * stride + x * 3;
                buf[o..o + 3].copy_from_slice(&rgb);
            }
        }
    };

    let draw = |root: &DrawingArea<BitMapBackend<'_, RGBPixel>, Shift>| -> Result<()> {
        let err = |e: DrawingAreaErrorKind<_>| image_error(path, e);
        let text = |size: u32| ("sans-serif", size).into_font().color(&BLACK);
        let title = format!("V − V_ref   RMSE {:.4}   max {:.3}", m.rmse, m.max);
        root.draw(&Text::new(title, (8, 7), text(15)))
            .map_err(err)?;

        // Thin frame around the map so white (no error) is told apart from the page.
        let (x1, y1) = (width as i32, (TITLE_H + height) as i32);
        root.draw(&Rectangle::new(
            [(0, TITLE_H as i32 - 1), (x1, y1)],
            BLACK.mix(0.6).stroke_width(1),
        ))
        .map_err(err)?;

        // Colour bar: +1 (red, too bright) at the top, −1 (blue, too dark) at the bottom.
        let lx = width as i32 + 14;
        let top = TITLE_H as i32 + 40;
        let legend_bottom = (TITLE_H + height.max(MIN_MAP_H)) as i32;
        let bar_h = (legend_bottom - 60 - top).max(60);
        root.draw(&Text::new("too bright", (lx, top - 34), text(12)))
            .map_err(err)?;
        root.draw(&Text::new("(light leak)", (lx, top - 20), text(12)))
            .map_err(err)?;
        for row in 0..bar_h {
            let e = 1.0 - 2.0 * row as f32 / (bar_h - 1) as f32;
            let [r, g, b] = diverging_color(e);
            root.draw(&Rectangle::new(
                [(lx, top + row), (lx + 18, top + row + 1)],
                RGBColor(r, g, b).filled(),
            ))
            .map_err(err)?;
        }
        root.draw(&Rectangle::new(
            [(lx, top), (lx + 18, top + bar_h)],
            BLACK.stroke_width(1),
        ))
        .map_err(err)?;
        for (value, label) in [
            (1.0f32, "+1"),
            (0.5, "+0.5"),
            (0.0, "0"),
            (-0.5, "−0.5"),
            (-1.0, "−1"),
        ] {
            let y = top + ((1.0 - value) * 0.5 * (bar_h - 1) as f32).round() as i32;
            root.draw(&PathElement::new(
                vec![(lx + 18, y), (lx + 23, y)],
                BLACK.stroke_width(1),
            ))
            .map_err(err)?;
            root.draw(&Text::new(label, (lx + 26, y - 6), text(12)))
                .map_err(err)?;
        }
        root.draw(&Text::new("too dark", (lx, top + bar_h + 5), text(12)))
            .map_err(err)?;

        // Swatches for the two colours outside the scale. The non-finite count sits here rather
        // than in the title, which narrow frames would clip.
        let non_finite = format!("NaN / inf: {}", m.non_finite);
        for (k, (rgb, label)) in [(NOT_SAMPLE, "not a sample"), (NON_FINITE, &*non_finite)]
            .into_iter()
            .enumerate()
        {
            let y = legend_bottom - 34 + 17 * k as i32;
            let [r, g, b] = rgb;
            root.draw(&Rectangle::new(
                [(lx, y), (lx + 12, y + 12)],
                RGBColor(r, g, b).filled(),
            ))
            .map_err(err)?;
            root.draw(&Text::new(label, (lx + 17, y), text(12)))
                .map_err(err)?;
        }
        Ok(())
    };

    render(path, size, prefill, draw)
}

// ------------------------------------------------------------------------------------------------
// Pareto chart

/// One technique configuration measured on one scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ParetoPoint {
    /// Technique name, e.g. `pcf`.
    pub technique: String,
    /// The knob settings, e.g. `map_size=1024 kernel=3`.
    pub label: String,
    /// The scene it was measured on.
    pub scene: String,
    /// GPU time of the technique's passes, in milliseconds.
    pub time_ms: f64,
    /// Error against the reference (the chart plots penumbra MAE).
    pub error: f64,
}

fn plottable(p: &ParetoPoint) -> bool {
    p.time_ms.is_finite() && p.time_ms > 0.0 && p.error.is_finite()
}

/// Indices of the non-dominated points, in order of increasing time (decreasing error).
///
/// A point is dominated when another is no slower and no worse and strictly better in one of
/// the two; exact duplicates of a front point are all on the front. Points whose time is NaN,
/// infinite or not positive, or whose error is not finite, are skipped. The front is taken over
/// all points given: pass one scene's points.
pub fn pareto_front(points: &[ParetoPoint]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| plottable(&points[i]))
        .collect();
    order.sort_by(|&a, &b| {
        let (p, q) = (&points[a], &points[b]);
        p.time_ms
            .total_cmp(&q.time_ms)
            .then(p.error.total_cmp(&q.error))
    });
    let mut front: Vec<usize> = Vec::new();
    for i in order {
        let p = &points[i];
        // Sorted by time, so only the last front point (the lowest error so far) can dominate p.
        let keep = match front.last().map(|&j| &points[j]) {
            None => true,
            Some(best) => {
                p.error < best.error || (p.error == best.error && p.time_ms == best.time_ms)
            }
        };
        if keep {
            front.push(i);
        }
    }
    front
}

/// Ten colours that stay apart on white (Tableau 10); techniques take them in order of first
/// appearance and wrap around after ten.
pub(crate) const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Size of the PNG [`write_pareto_chart`] writes.
pub const PARETO_CHART_SIZE: (u32, u32) = (1000, 700);

/// A tick value with two significant digits and no trailing zeros: 0.05, 0.5, 2, 20, 150.
pub(crate) fn format_tick(v: f64) -> String {
    if v <= 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let digits = (1.0 - v.log10().floor()).clamp(0.0, 8.0) as usize;
    let s = format!("{v:.digits$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// Whether two pixel boxes `[x0, y0, x1, y1]` overlap.
fn overlaps(a: &[i32; 4], b: &[i32; 4]) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

/// A log10 axis in milliseconds with our own ticks: bold at 1, 2, 5 × 10^k (only 1 × 10^k past
/// three decades, so labels never crowd), light at every other integer multiple. plotters' own
/// log axis crowds its labels, and its key-point override does not compose with `f64` labels.
pub(crate) struct LogAxis {
    lo: f64,
    hi: f64,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl LogAxis {
    /// `lo` and `hi` must be positive with `lo < hi`.
    pub(crate) fn new(lo: f64, hi: f64) -> Self {
        let bold_mantissas: &[u32] = if (hi / lo).log10() > 3.0 {
            &[1]
        } else {
            &[1, 2, 5]
        };
        let (mut bold, mut light) = (Vec::new(), Vec::new());
        let mut decade = 10f64.powf(lo.log10().floor());
        while decade <= hi {
            for m in 1..10u32 {
                let v = f64::from(m) * decade;
                if (lo..=hi).contains(&v) {
                    if bold_mantissas.contains(&m) {
                        bold.push(v);
                    } else {
                        light.push(v);
                    }
                }
            }
            decade *= 10.0;
        }
        LogAxis {
            lo,
            hi,
            bold,
            light,
        }
    }
}

impl Ranged for LogAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let t = (value / self.lo).log10() / (self.hi / self.lo).log10();
        limit.0 + (t * f64::from(limit.1 - limit.0)).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

/// Writes a time/error scatter chart of [`PARETO_CHART_SIZE`]: GPU time in ms on a log x axis,
/// penumbra MAE on y, one colour per technique with a legend, and the Pareto front (see
/// [`pareto_front`]) as a staircase through its points, each front point labelled with its knobs
/// where the label finds room.
/// The x axis spans [t_min / 1.6, t_max × 1.6] of the points' times; the y axis spans
/// [0, 1.12 × the largest error] (reaching below 0 by 12 % of the smallest error if one is
/// negative). Points that cannot be placed on a log axis are left out (as in [`pareto_front`]);
/// with none left the chart is drawn empty over 0.1–100 ms and 0–1. Failures are
/// [`Error::Image`].
pub fn write_pareto_chart(path: &Path, title: &str, points: &[ParetoPoint]) -> Result<()> {
    let valid: Vec<&ParetoPoint> = points.iter().filter(|p| plottable(p)).collect();
    let front = pareto_front(points);

    // Axis ranges with a margin; the log axis needs positive bounds and a non-empty span.
    let (mut t0, mut t1) = valid.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
        (lo.min(p.time_ms), hi.max(p.time_ms))
    });
    if valid.is_empty() {
        (t0, t1) = (0.1, 100.0);
    }
    let x_axis = LogAxis::new(t0 / 1.6, t1 * 1.6);
    let e_max = valid.iter().fold(0.0f64, |m, p| m.max(p.error));
    let e_min = valid.iter().fold(0.0f64, |m, p| m.min(p.error));
    let e1 = if e_max > 0.0 { e_max * 1.12 } else { 1.0 };
    let e0 = if e_min < 0.0 { e_min * 1.12 } else { 0.0 };
    // Enough decimals for ~10 y ticks to differ.
    let y_digits = (-((e1 - e0) / 10.0).log10()).ceil().clamp(0.0, 8.0) as usize;

    let mut techniques: Vec<&str> = Vec::new();
    for p in &valid {
        if !techniques.contains(&p.technique.as_str()) {
            techniques.push(&p.technique);
        }
    }

    // Front labels, one per distinct position (duplicates share a label).
    let mut front_labels: Vec<((f64, f64), String)> = Vec::new();
    for &i in &front {
        let p = &points[i];
        let at = (p.time_ms, p.error);
        match front_labels.last_mut() {
            Some((last, text)) if *last == at => {
                if !text.split(" / ").any(|l| l == p.label) {
                    text.push_str(" / ");
                    text.push_str(&p.label);
                }
            }
            _ => front_labels.push((at, p.label.clone())),
        }
    }

    let draw = |root: &DrawingArea<BitMapBackend<'_, RGBPixel>, Shift>| -> Result<()> {
        let err = |e: DrawingAreaErrorKind<_>| image_error(path, e);
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 24))
            .margin(18)
            .x_label_area_size(50)
            .y_label_area_size(80)
            .build_cartesian_2d(x_axis, e0..e1)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("GPU time (ms, log scale)")
            .y_desc("penumbra MAE")
            .x_label_formatter(&|v| format_tick(*v))
            .y_label_formatter(&|v| format!("{v:.y_digits$}"))
            .axis_desc_style(("sans-serif", 17))
            .label_style(("sans-serif", 14))
            .light_line_style(BLACK.mix(0.06))
            .bold_line_style(BLACK.mix(0.18))
            .draw()
            .map_err(err)?;

        // The front first, so the points sit on top of the line.
        let mut stairs: Vec<(f64, f64)> = Vec::new();
        for &i in &front {
            let p = &points[i];
            if let Some(&(_, prev_e)) = stairs.last() {
                stairs.push((p.time_ms, prev_e));
            }
            stairs.push((p.time_ms, p.error));
        }
        if !stairs.is_empty() {
            chart
                .draw_series(LineSeries::new(stairs, BLACK.mix(0.7).stroke_width(2)))
                .map_err(err)?
                .label("Pareto front")
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2))
                });
        }

        for (k, &name) in techniques.iter().enumerate() {
            let color = PALETTE[k % PALETTE.len()];
            // Past ten techniques the colours repeat; hollow markers keep them apart.
            let style = if k < PALETTE.len() {
                color.filled()
            } else {
                color.stroke_width(2)
            };
            let series = valid
                .iter()
                .filter(|p| p.technique == name)
                .map(|p| Circle::new((p.time_ms, p.error), 5, style));
            chart
                .draw_series(series)
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| Circle::new((x + 9, y), 5, style));
        }

        // Label the front's points with their knobs: the configurations worth choosing. Each
        // label takes the first free spot around its point; one that fits nowhere is left out.
        let label_style = ("sans-serif", 12).into_font().color(&BLACK.mix(0.8));
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        let mut taken: Vec<[i32; 4]> = valid
            .iter()
            .map(|p| {
                let (x, y) = chart.backend_coord(&(p.time_ms, p.error));
                [x - 6, y - 6, x + 6, y + 6]
            })
            .collect();
        for (at, text) in &front_labels {
            let (tw, th) = root.estimate_text_size(text, &label_style).map_err(err)?;
            // A little air around each label so neighbours do not touch.
            let (tw, th) = (tw as i32 + 2, th as i32 + 2);
            let (px, py) = chart.backend_coord(at);
            let spots = [
                (px + 7, py - 7 - th),
                (px + 7, py + 7),
                (px - 7 - tw, py - 7 - th),
                (px - 7 - tw, py + 7),
            ];
            let free = spots
                .into_iter()
                .map(|(x, y)| [x, y, x + tw, y + th])
                .find(|b| {
                    xr.contains(&b[0])
                        && xr.contains(&b[2])
                        && yr.contains(&b[1])
                        && yr.contains(&b[3])
                        && !taken.iter().any(|o| overlaps(b, o))
                });
            if let Some(b) = free {
                root.draw(&Text::new(text.as_str(), (b[0], b[1]), label_style.clone()))
                    .map_err(err)?;
                taken.push(b);
            }
        }

        if valid.is_empty() {
            root.draw(&Text::new(
                "no points with a positive, finite time and a finite error",
                (300, 340),
                ("sans-serif", 18).into_font(),
            ))
            .map_err(err)?;
        } else {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.9))
                .border_style(BLACK.mix(0.5))
                .label_font(("sans-serif", 15))
                .draw()
                .map_err(err)?;
        }
        Ok(())
    };

    render(path, PARETO_CHART_SIZE, |_| {}, draw)
}
