//! How a technique's cost grows with the work: the growth exponent of its time against a size
//! (triangles, view samples, light size), fitted on log–log axes, and the chart of those curves.
//! `penumbra bench --suite scaling` measures the points (`tools/penumbra/scaling.rs`).
//!
//! The exponent is the least-squares slope of ln(time) against ln(size): time ∝ size^k, so 1 is
//! linear in the work, 0 is a cost that does not depend on it. A fit needs two or more points
//! with positive, finite time and size at two sizes or more; otherwise there is none (`None`),
//! never a NaN.

use std::path::Path;

use plotters::prelude::*;

use crate::error::Result;
use crate::plots::{format_tick, image_error, render, LogAxis, PALETTE};

/// Size of the PNG [`write_scaling_chart`] writes: one panel per sweep, side by side.
pub const PANEL_SIZE: (u32, u32) = (620, 560);

/// The least-squares slope of ln(time) against ln(size) over `points` (size, time); points with
/// a non-positive or non-finite coordinate are left out. `None` with fewer than two points left
/// or with all sizes equal.
pub fn growth_exponent(points: &[(f64, f64)]) -> Option<f64> {
    let logs: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| x.is_finite() && y.is_finite() && *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.ln(), y.ln()))
        .collect();
    if logs.len() < 2 {
        return None;
    }
    let n = logs.len() as f64;
    let mx = logs.iter().map(|p| p.0).sum::<f64>() / n;
    let my = logs.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = logs.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
    let sxy: f64 = logs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 1e-12).then(|| sxy / sxx)
}

/// One curve of a panel: a technique's (size, time ms) points and its fitted exponent.
pub struct Curve {
    /// Technique name.
    pub technique: String,
    /// (size, GPU ms) points.
    pub points: Vec<(f64, f64)>,
    /// Fitted growth exponent ([`growth_exponent`]).
    pub exponent: Option<f64>,
}

/// One panel: a sweep's name, its x-axis label and its curves.
pub struct Panel {
    /// Panel title (the sweep).
    pub title: String,
    /// What the x axis counts.
    pub x_label: String,
    /// One curve per technique.
    pub curves: Vec<Curve>,
}

/// Writes the panels side by side, each on log–log axes (size against GPU ms), one colour per
/// technique (markers hollow past the palette's ten), the exponent in the legend. Points that
/// cannot go on a log axis are left out; a panel with none is drawn empty. Failures are
/// [`crate::Error::Image`] naming the file.
pub fn write_scaling_chart(path: &Path, panels: &[Panel]) -> Result<()> {
    let count = panels.len().max(1) as u32;
    let size = (PANEL_SIZE.0 * count, PANEL_SIZE.1);
    let draw = |root: &DrawingArea<BitMapBackend<'_, plotters::backend::RGBPixel>, _>| {
        let err = |e: DrawingAreaErrorKind<_>| image_error(path, e);
        let areas = root.split_evenly((1, count as usize));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            let valid =
                |p: &&(f64, f64)| p.0 > 0.0 && p.1 > 0.0 && p.0.is_finite() && p.1.is_finite();
            let all: Vec<(f64, f64)> = panel
                .curves
                .iter()
                .flat_map(|c| c.points.iter().filter(valid).copied())
                .collect();
            let range = |f: fn(&(f64, f64)) -> f64| {
                let lo = all.iter().map(f).fold(f64::INFINITY, f64::min);
                let hi = all.iter().map(f).fold(0.0, f64::max);
                if all.is_empty() || lo >= hi {
                    (lo.clamp(1e-3, 1.0) / 2.0, hi.max(1.0) * 2.0)
                } else {
                    (lo / 1.5, hi * 1.5)
                }
            };
            let (x0, x1) = range(|p| p.0);
            let (y0, y1) = range(|p| p.1);
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.title, ("sans-serif", 20))
                .margin(14)
                .x_label_area_size(44)
                .y_label_area_size(64)
                .build_cartesian_2d(LogAxis::new(x0, x1), LogAxis::new(y0, y1))
                .map_err(err)?;
            chart
                .configure_mesh()
                .x_desc(panel.x_label.as_str())
                .y_desc("GPU ms (log)")
                .x_label_formatter(&|v| format_tick(*v))
                .y_label_formatter(&|v| format_tick(*v))
                .axis_desc_style(("sans-serif", 15))
                .label_style(("sans-serif", 12))
                .light_line_style(BLACK.mix(0.06))
                .bold_line_style(BLACK.mix(0.18))
                .draw()
                .map_err(err)?;
            for (k, curve) in panel.curves.iter().enumerate() {
                let color = PALETTE[k % PALETTE.len()];
                let style = if k < PALETTE.len() {
                    color.filled()
                } else {
                    color.stroke_width(2)
                };
                let pts: Vec<(f64, f64)> = curve.points.iter().filter(valid).copied().collect();
                if pts.is_empty() {
                    continue;
                }
                let label = match curve.exponent {
                    Some(e) => format!("{} ({e:.2})", curve.technique),
                    None => curve.technique.clone(),
                };
                chart
                    .draw_series(LineSeries::new(pts.clone(), color.stroke_width(1)))
                    .map_err(err)?;
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 3, style)))
                    .map_err(err)?
                    .label(label)
                    .legend(move |(x, y)| Circle::new((x + 9, y), 4, style));
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.4))
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(err)?;
        }
        Ok(())
    };
    render(path, size, |_| {}, draw)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exponent_of_a_power_law_is_its_power() {
        let pts: Vec<(f64, f64)> = [1e3, 1e4, 1e5, 1e6]
            .iter()
            .map(|&x: &f64| (x, 3.0 * x.powf(0.75)))
            .collect();
        let k = growth_exponent(&pts).expect("fit");
        assert!((k - 0.75).abs() < 1e-9, "{k}");
        // A constant cost grows with exponent 0.
        let flat = [(1.0, 5.0), (10.0, 5.0), (100.0, 5.0)];
        assert!(growth_exponent(&flat).expect("fit").abs() < 1e-12);
    }

    #[test]
    fn exponent_needs_two_sizes_and_skips_bad_points() {
        assert_eq!(growth_exponent(&[]), None);
        assert_eq!(growth_exponent(&[(10.0, 1.0)]), None);
        assert_eq!(growth_exponent(&[(10.0, 1.0), (10.0, 2.0)]), None);
        let pts = [
            (1.0, 1.0),
            (f64::NAN, 3.0),
            (0.0, 2.0),
            (4.0, 2.0),
            (16.0, -1.0),
        ];
        let k = growth_exponent(&pts).expect("fit");
        assert!((k - 0.5).abs() < 1e-12, "{k}");
    }

    #[test]
    fn chart_is_written_with_empty_and_full_panels() {
        let dir = std::env::temp_dir().join(format!("penumbra-scaling-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let path = dir.join("scaling.png");
        let panels = vec![
            Panel {
                title: "triangles".into(),
                x_label: "triangles".into(),
                curves: vec![Curve {
                    technique: "hard".into(),
                    points: vec![(1e3, 1.0), (1e6, 100.0)],
                    exponent: Some(2.0 / 3.0),
                }],
            },
            Panel {
                title: "empty".into(),
                x_label: "nothing".into(),
                curves: Vec::new(),
            },
        ];
        write_scaling_chart(&path, &panels).expect("chart");
        let img = image::open(&path).expect("png");
        assert_eq!(img.width(), 2 * PANEL_SIZE.0);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
