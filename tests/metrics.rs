//! Error metrics, FLIP and the two charts, on synthetic images with hand-computed answers.
//! No GPU needed.

use std::path::PathBuf;

use penumbra::metrics::{compare, flip, ErrorMetrics, CLASS_EPS};
use penumbra::plots::{
    diverging_color, heatmap_size, pareto_front, write_error_heatmap, write_pareto_chart,
    ParetoPoint, PARETO_CHART_SIZE,
};
use penumbra::Error;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-6
}

fn all(n: usize) -> Vec<bool> {
    vec![true; n]
}

fn out(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name)
}

#[test]
fn identical_images_have_no_error() {
    let v = [0.0, 0.5, 1.0, 0.25];
    let m = compare(&v, &v, &all(4)).unwrap();
    assert_eq!(
        m,
        ErrorMetrics {
            rmse: 0.0,
            mae: 0.0,
            max: 0.0,
            penumbra_mae: Some(0.0),
            shadow_mae: Some(0.0),
            misclassified: 0.0,
            light_leak: 0.0,
            samples: 4,
            non_finite: 0,
            flip: None,
        }
    );
}

#[test]
fn constant_offset() {
    let r = [0.2f32, 0.4, 0.6, 0.8];
    let t: Vec<f32> = r.iter().map(|v| v + 0.1).collect();
    let m = compare(&r, &t, &all(4)).unwrap();
    assert!(
        close(m.rmse, 0.1) && close(m.mae, 0.1) && close(m.max, 0.1),
        "{m:?}"
    );
    assert!(close(m.penumbra_mae.unwrap(), 0.1));
    assert_eq!(m.misclassified, 0.0);
    assert_eq!(m.light_leak, 0.0, "no umbra in the reference, so no leak");
}

#[test]
fn single_pixel_error() {
    let r = vec![0.5f32; 10];
    let mut t = r.clone();
    t[7] = 0.9;
    let m = compare(&r, &t, &all(10)).unwrap();
    assert!(close(m.max, 0.4));
    assert!(close(m.mae, 0.04));
    assert!(close(m.rmse, (0.16f64 / 10.0).sqrt()));
}

#[test]
fn penumbra_mae_only_over_reference_penumbra() {
    let r = [0.0f32, 1.0, 0.5, 0.5];
    let t = [0.2f32, 0.6, 0.6, 0.3];
    let m = compare(&r, &t, &all(4)).unwrap();
    assert!(close(m.penumbra_mae.unwrap(), 0.15), "{m:?}");
    assert!(close(m.mae, (0.2 + 0.4 + 0.1 + 0.2) / 4.0));

    // A hard-shadow reference has no penumbra to average over.
    let m = compare(&[0.0, 1.0], &[0.5, 0.5], &all(2)).unwrap();
    assert_eq!(m.penumbra_mae, None);
}

#[test]
fn misclassification_uses_the_tolerance() {
    let r = [0.0f32, 0.0, 1.0, 1.0, 0.5, 0.5, 0.0];
    // Index 1: umbra → penumbra; index 5: penumbra → lit. Index 3 is within CLASS_EPS of 1 and
    // index 6 within it of 0, so both keep their class.
    let t = [
        0.0f32,
        0.5,
        1.0,
        1.0 - CLASS_EPS / 2.0,
        0.5,
        1.0,
        CLASS_EPS / 2.0,
    ];
    let m = compare(&r, &t, &all(7)).unwrap();
    assert!(close(m.misclassified, 2.0 / 7.0), "{m:?}");
    // Just outside the tolerance, 1 − 2ε is penumbra.
    let m = compare(&[1.0], &[1.0 - 2.0 * CLASS_EPS], &all(1)).unwrap();
    assert_eq!(m.misclassified, 1.0);
}

#[test]
fn light_leak_is_positive_error_in_reference_umbra() {
    let r = [0.0f32, 0.0, 0.0, 1.0, 0.5];
    // 0.3 leaks; −0.2 is too dark, not a leak; the lit and penumbra samples never count.
    let t = [0.3f32, 0.0, -0.2, 0.5, 0.9];
    let m = compare(&r, &t, &all(5)).unwrap();
    assert!(close(m.light_leak, 0.1), "{m:?}");
}

#[test]
fn mask_excludes_non_samples() {
    let r = [0.0f32, 1.0, f32::NAN];
    let t = [1.0f32, 1.0, f32::NAN];
    let m = compare(&r, &t, &[false, true, false]).unwrap();
    assert_eq!(m.samples, 1);
    assert_eq!(
        (m.rmse, m.mae, m.max, m.misclassified),
        (0.0, 0.0, 0.0, 0.0)
    );
    assert_eq!(m.non_finite, 0);

    let m = compare(&r, &t, &[false; 3]).unwrap();
    assert_eq!(m.samples, 0);
    assert_eq!((m.rmse, m.mae, m.light_leak), (0.0, 0.0, 0.0));
    assert_eq!(m.penumbra_mae, None);
}

#[test]
fn length_mismatch_is_an_error() {
    let v = [0.5f32; 4];
    for (r, t, s) in [
        (&v[..3], &v[..], 4),
        (&v[..], &v[..3], 4),
        (&v[..], &v[..], 3),
    ] {
        let e = compare(r, t, &all(s)).unwrap_err();
        assert!(matches!(e, Error::Input { .. }), "{e}");
        assert!(e.to_string().contains("lengths differ"), "{e}");
    }
}

#[test]
fn non_finite_test_values_count_as_error_one() {
    let r = [0.5f32, 0.5, 0.0, 1.0];
    let t = [f32::NAN, 0.5, f32::NAN, f32::INFINITY];
    let m = compare(&r, &t, &all(4)).unwrap();
    assert_eq!(m.non_finite, 3);
    assert_eq!(m.max, 1.0);
    assert!(close(m.mae, 0.75) && close(m.rmse, 0.75f64.sqrt()), "{m:?}");
    assert!(close(m.misclassified, 0.75));
    assert_eq!(
        m.light_leak, 1.0,
        "NaN where the reference is dark counts as a full leak"
    );
    assert!(close(m.penumbra_mae.unwrap(), 0.5));

    // A broken reference is an error, not a metric.
    let e = compare(&[f32::NAN], &[0.5], &all(1)).unwrap_err();
    assert!(matches!(e, Error::Input { .. }), "{e}");
}

#[test]
fn flip_identical_zero_black_white_large() {
    let (w, h) = (32u32, 24u32);
    let img: Vec<[u8; 3]> = (0..w * h)
        .map(|i| [(i % 251) as u8, (i * 7 % 256) as u8, 128])
        .collect();
    assert_eq!(flip(&img, &img, w, h).unwrap(), 0.0);

    let black = vec![[0u8; 3]; (w * h) as usize];
    let white = vec![[255u8; 3]; (w * h) as usize];
    let f = flip(&black, &white, w, h).unwrap();
    assert!(f > 0.5 && f <= 1.0, "black vs white FLIP {f}");
}

#[test]
fn flip_checks_sizes() {
    let img = vec![[0u8; 3]; 12];
    assert!(matches!(flip(&img, &img, 4, 4), Err(Error::Input { .. })));
    assert!(matches!(
        flip(&img, &img[..8], 4, 3),
        Err(Error::Input { .. })
    ));
    assert!(matches!(flip(&[], &[], 0, 3), Err(Error::Input { .. })));
}

fn point(technique: &str, time_ms: f64, error: f64) -> ParetoPoint {
    ParetoPoint {
        technique: technique.into(),
        label: format!("t={time_ms}"),
        scene: "test".into(),
        time_ms,
        error,
    }
}

fn hand_made_points() -> Vec<ParetoPoint> {
    vec![
        point("hard", 1.0, 0.5),      // 0: front
        point("hard", 2.0, 0.3),      // 1: front
        point("pcf", 2.0, 0.4),       // 2: same time as 1, worse
        point("pcf", 4.0, 0.3),       // 3: same error as 1, slower
        point("pcss", 8.0, 0.1),      // 4: front
        point("pcss", 8.0, 0.1),      // 5: duplicate of 4: front too
        point("pcss", f64::NAN, 0.0), // 6: skipped
        point("pcss", 0.0, 0.0),      // 7: skipped (not positive)
        point("vsm", 0.5, 0.9),       // 8: front (fastest)
        point("vsm", 16.0, 0.2),      // 9: dominated by 4
    ]
}

#[test]
fn pareto_front_of_hand_made_set() {
    assert_eq!(pareto_front(&hand_made_points()), vec![8, 0, 1, 4, 5]);
    assert!(pareto_front(&[]).is_empty());
}

#[test]
fn diverging_colour_map_ends_and_centre() {
    assert_eq!(diverging_color(0.0), [255, 255, 255]);
    let [r, _, b] = diverging_color(1.0);
    assert!(r > b, "positive error (light leak) is red");
    let [r, _, b] = diverging_color(-1.0);
    assert!(b > r, "negative error (over-shadowing) is blue");
    assert_eq!(diverging_color(5.0), diverging_color(1.0));
}

/// A soft disc shadow as reference and a hard, slightly shifted one as the test, on a ground
/// plane with background above the horizon.
fn synthetic_frame(w: u32, h: u32) -> (Vec<f32>, Vec<f32>, Vec<bool>) {
    let (mut r, mut t, mut s) = (Vec::new(), Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
            let d = ((fx - 0.5).powi(2) + (fy - 0.6).powi(2)).sqrt();
            r.push(((d - 0.15) / 0.1).clamp(0.0, 1.0));
            let dt = ((fx - 0.53).powi(2) + (fy - 0.6).powi(2)).sqrt();
            t.push(if dt < 0.2 { 0.0 } else { 1.0 });
            s.push(fy > 0.2);
        }
    }
    // One broken pixel, to show the non-finite colour.
    let i = (h / 2 * w + w / 10) as usize;
    t[i] = f32::NAN;
    (r, t, s)
}

/// Height of the heat map's title band (documented in `heatmap_size`).
const TITLE_H: u32 = 30;

#[test]
fn heatmap_pixels_are_the_frame_errors_in_place() {
    for (w, h) in [(400u32, 300u32), (160, 120)] {
        let (r, t, s) = synthetic_frame(w, h);
        let path = out(&format!("heatmap_{w}x{h}.png"));
        write_error_heatmap(&path, w, h, &r, &t, &s).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), heatmap_size(w, h));

        // Every frame pixel sits at (x, TITLE_H + y) in the colour its error maps to. Column 0
        // is under the frame drawn around the map.
        let mut kinds = [0usize; 4]; // grey, black, white, coloured
        for y in 0..h {
            for x in 1..w {
                let i = (y * w + x) as usize;
                let expected = if !s[i] {
                    kinds[0] += 1;
                    [150, 150, 150]
                } else if !t[i].is_finite() {
                    kinds[1] += 1;
                    [0, 0, 0]
                } else {
                    let c = diverging_color(t[i] - r[i]);
                    kinds[if c == [255, 255, 255] { 2 } else { 3 }] += 1;
                    c
                };
                assert_eq!(
                    img.get_pixel(x, TITLE_H + y).0,
                    expected,
                    "{w}x{h}: frame pixel ({x}, {y})"
                );
            }
        }
        // The synthetic frame exercises every kind of pixel, so a blank map cannot pass.
        assert!(kinds.iter().all(|&n| n > 0), "{kinds:?}");

        // The title band holds text, and the legend right of the map holds the colour bar's
        // reds and blues.
        let dark = |p: &image::Rgb<u8>| p.0.iter().all(|&c| c < 100);
        assert!(
            (0..TITLE_H - 2).any(|y| (0..w).any(|x| dark(img.get_pixel(x, y)))),
            "no title text"
        );
        let legend = |pred: &dyn Fn([u8; 3]) -> bool| {
            (TITLE_H..img.height())
                .any(|y| (w + 1..img.width()).any(|x| pred(img.get_pixel(x, y).0)))
        };
        assert!(
            legend(&|[r, _, b]| r > 150 && b < 100),
            "no red in the colour bar"
        );
        assert!(
            legend(&|[r, _, b]| b > 150 && r < 100),
            "no blue in the colour bar"
        );
    }
}

#[test]
fn heatmap_errors_are_reported() {
    let (r, t, s) = synthetic_frame(8, 8);
    let e = write_error_heatmap(&out("bad.png"), 8, 9, &r, &t, &s).unwrap_err();
    assert!(matches!(e, Error::Input { .. }), "{e}");
    let e = write_error_heatmap(&out("no/such/dir/h.png"), 8, 8, &r, &t, &s).unwrap_err();
    assert!(matches!(e, Error::Image { .. }), "{e}");
}

/// Connected regions (4-neighbour) of pixels of exactly `colour`: (pixel count, centroid).
fn blobs(img: &image::RgbImage, colour: [u8; 3]) -> Vec<(usize, (f64, f64))> {
    let (w, h) = img.dimensions();
    let mut seen = vec![false; (w * h) as usize];
    let mut found = Vec::new();
    for start in 0..w * h {
        let (sx, sy) = (start % w, start / w);
        if seen[start as usize] || img.get_pixel(sx, sy).0 != colour {
            continue;
        }
        let (mut n, mut cx, mut cy) = (0usize, 0.0, 0.0);
        let mut stack = vec![(sx, sy)];
        seen[start as usize] = true;
        while let Some((x, y)) = stack.pop() {
            n += 1;
            cx += f64::from(x);
            cy += f64::from(y);
            let neighbours = [
                (x.wrapping_sub(1), y),
                (x + 1, y),
                (x, y.wrapping_sub(1)),
                (x, y + 1),
            ];
            for (nx, ny) in neighbours {
                if nx < w && ny < h {
                    let k = (ny * w + nx) as usize;
                    if !seen[k] && img.get_pixel(nx, ny).0 == colour {
                        seen[k] = true;
                        stack.push((nx, ny));
                    }
                }
            }
        }
        found.push((n, (cx / n as f64, cy / n as f64)));
    }
    found
}

/// The longest straight run of pure black pixels, vertical or horizontal: (the column or row,
/// first, last). The chart's axes are such runs along the plotting area's left and bottom edges.
fn longest_black_run(img: &image::RgbImage, vertical: bool) -> (u32, u32, u32) {
    let (w, h) = img.dimensions();
    let (lines, len) = if vertical { (w, h) } else { (h, w) };
    let mut best = (0, 0, 0);
    for line in 0..lines {
        let mut first = None;
        for i in 0..=len {
            let black = i < len && {
                let (x, y) = if vertical { (line, i) } else { (i, line) };
                img.get_pixel(x, y).0 == [0, 0, 0]
            };
            match (black, first) {
                (true, None) => first = Some(i),
                (false, Some(f)) => {
                    if i - f > best.2 - best.1 + 1 || best == (0, 0, 0) {
                        best = (line, f, i - 1);
                    }
                    first = None;
                }
                _ => {}
            }
        }
    }
    best
}

/// The first two colours of the chart's palette (Tableau 10), taken by techniques in order.
const BLUE: [u8; 3] = [31, 119, 180];
const ORANGE: [u8; 3] = [255, 127, 14];

#[test]
fn pareto_chart_draws_each_point_where_its_data_maps() {
    let points = vec![
        point("pcf", 1.0, 0.10),
        point("pcf", 10.0, 0.07),
        point("pcf", 100.0, 0.01),
        point("vsm", 30.0, 0.09),
    ];
    let path = out("pareto.png");
    write_pareto_chart(&path, "penumbra MAE vs GPU time — test scene", &points).unwrap();
    let img = image::open(&path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), PARETO_CHART_SIZE);

    // The plotting area, found from the drawn axes: the y axis along its left edge, the x axis
    // along its bottom edge.
    let (y_axis_x, top, y_axis_end) = longest_black_run(&img, true);
    let (x_axis_y, left, right) = longest_black_run(&img, false);
    assert!(
        right - left > 500 && y_axis_end - top > 300,
        "no axes found"
    );
    let bottom = x_axis_y - 1;
    assert!(left.abs_diff(y_axis_x) <= 1, "axes do not meet");
    // Where `write_pareto_chart` documents the data to go: x over [t_min / 1.6, t_max × 1.6] on
    // a log scale, y over [0, 1.12 × the largest error].
    let (lo, hi, e1) = (1.0 / 1.6, 100.0 * 1.6, 0.10 * 1.12);
    let expected = |t: f64, e: f64| {
        let fx = (t / lo).ln() / (hi / lo).ln();
        (
            f64::from(left) + fx * f64::from(right - left),
            f64::from(bottom) - e / e1 * f64::from(bottom - top),
        )
    };

    // A filled marker of radius 5 covers some 80 pixels; specks of the colour do not count.
    let markers = |colour| -> Vec<(f64, f64)> {
        blobs(&img, colour)
            .into_iter()
            .filter(|(n, _)| *n >= 40)
            .map(|(_, c)| c)
            .collect()
    };
    let pcf = markers(BLUE);
    let vsm = markers(ORANGE);
    // One marker per point plus one in the legend.
    assert_eq!(pcf.len(), 4, "pcf markers: {pcf:?}");
    assert_eq!(vsm.len(), 2, "vsm markers: {vsm:?}");
    let near =
        |m: &(f64, f64), at: (f64, f64)| (m.0 - at.0).abs() <= 3.0 && (m.1 - at.1).abs() <= 3.0;
    for p in &points {
        let at = expected(p.time_ms, p.error);
        let drawn = if p.technique == "pcf" { &pcf } else { &vsm };
        assert!(
            drawn.iter().any(|m| near(m, at)),
            "{} ({} ms, {}) should be drawn at {at:?}; markers at {drawn:?}",
            p.technique,
            p.time_ms,
            p.error
        );
    }
    // The remaining marker is the legend's, with the technique's name written right of it.
    let (lx, ly) = *pcf
        .iter()
        .find(|m| !points.iter().any(|p| near(m, expected(p.time_ms, p.error))))
        .expect("a legend marker");
    let text = (ly as u32 - 8..ly as u32 + 8).any(|y| {
        (lx as u32 + 8..lx as u32 + 60).any(|x| img.get_pixel(x, y).0.iter().all(|&c| c < 120))
    });
    assert!(text, "no legend label right of the marker at ({lx}, {ly})");

    // The same checks fail on a chart without points.
    let empty = out("pareto_empty.png");
    write_pareto_chart(&empty, "no points", &[]).unwrap();
    let empty = image::open(&empty).unwrap().to_rgb8();
    assert_eq!(empty.dimensions(), PARETO_CHART_SIZE);
    assert!(blobs(&empty, BLUE).is_empty() && blobs(&empty, ORANGE).is_empty());
}

/// A chart with realistic numbers: small errors, several decades of time, long knob labels.
#[test]
fn pareto_chart_with_realistic_numbers() {
    let mut points = Vec::new();
    for (k, technique) in ["hard", "pcf", "pcss", "vsm", "esm", "msm"]
        .iter()
        .enumerate()
    {
        for (j, size) in [512u32, 1024, 2048, 4096].iter().enumerate() {
            let time_ms = 0.08 * 2f64.powi(j as i32 * 2) * (1.0 + k as f64 * 0.7);
            let error = 0.06 / (1.0 + j as f64) / (1.0 + 0.3 * k as f64) + 0.001 * k as f64;
            points.push(ParetoPoint {
                technique: technique.to_string(),
                label: format!("map_size={size} kernel={}", 2 * k + 1),
                scene: "contact".into(),
                time_ms,
                error,
            });
        }
    }
    let path = out("pareto_realistic.png");
    write_pareto_chart(&path, "penumbra MAE vs GPU time — contact", &points).unwrap();
    let img = image::open(&path).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), PARETO_CHART_SIZE);
    // Each of the six techniques has its palette colour (Tableau 10, in order of appearance)
    // on its points and its legend marker.
    let palette = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
    ];
    for (technique, colour) in ["hard", "pcf", "pcss", "vsm", "esm", "msm"]
        .iter()
        .zip(palette)
    {
        let markers = blobs(&img, colour).iter().filter(|(n, _)| *n >= 40).count();
        assert!(markers >= 2, "{technique}: {markers} markers of {colour:?}");
    }
    let front = pareto_front(&points);
    assert!(!front.is_empty());
    // Along the front, time rises and error falls.
    for w in front.windows(2) {
        let (a, b) = (&points[w[0]], &points[w[1]]);
        assert!(a.time_ms <= b.time_ms && a.error >= b.error);
    }
}

#[test]
fn shadow_mae_is_attys_measure_over_umbra_and_penumbra() {
    // Umbra 0 → 0.1, penumbra 0.5 → 0.3, lit 1 → 0.6: the lit sample's 0.4 stays out.
    let m = compare(&[0.0, 0.5, 1.0], &[0.1, 0.3, 0.6], &all(3)).unwrap();
    let s = m.shadow_mae.expect("a shadow");
    assert!((s - 0.15).abs() < 1e-6, "{s}");
    let lit = compare(&[1.0, 1.0], &[0.5, 1.0], &all(2)).unwrap();
    assert_eq!(lit.shadow_mae, None, "no shadow in the reference");
}

/// Bit-for-bit difference: -0.0 and 0.0 differ in bits, a NaN pair differs, the largest |Δ| is
/// over the finite pairs.
#[test]
fn bitwise_difference_counts_bits_and_keeps_the_largest_gap() {
    use penumbra::metrics::bitwise_difference;
    assert_eq!(bitwise_difference(&[0.5, 1.0], &[0.5, 1.0]), (0, 0.0));
    assert_eq!(
        bitwise_difference(&[0.5, 1.0, 0.0], &[0.25, 1.0, -0.0]),
        (2, 0.25)
    );
    assert_eq!(
        bitwise_difference(&[f32::NAN, 0.0], &[0.0, 0.75]),
        (2, 0.75)
    );
}
