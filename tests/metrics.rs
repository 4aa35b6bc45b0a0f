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

#[test]
fn heatmap_png_has_expected_size_and_colours() {
    for (w, h) in [(400u32, 300u32), (160, 120)] {
        let (r, t, s) = synthetic_frame(w, h);
        let path = out(&format!("heatmap_{w}x{h}.png"));
        write_error_heatmap(&path, w, h, &r, &t, &s).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), heatmap_size(w, h));
        assert!(img.width() > w, "legend area to the right");

        if h >= 300 {
            // The map sits at the bottom-left: a non-sample (top row) is grey, a far-lit pixel
            // (no error) is white.
            let top = img.height() - h;
            assert_eq!(img.get_pixel(w / 2, top + 2).0, [150, 150, 150]);
            assert_eq!(img.get_pixel(5, top + h - 5).0, [255, 255, 255]);
        }
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

#[test]
fn pareto_chart_png_has_expected_size() {
    let mut points = hand_made_points();
    for p in &mut points {
        p.label = format!("knob={}", p.time_ms);
    }
    let path = out("pareto.png");
    write_pareto_chart(&path, "penumbra MAE vs GPU time — test scene", &points).unwrap();
    let img = image::open(&path).unwrap();
    assert_eq!((img.width(), img.height()), PARETO_CHART_SIZE);

    let empty = out("pareto_empty.png");
    write_pareto_chart(&empty, "no points", &[]).unwrap();
    assert_eq!(image::image_dimensions(&empty).unwrap(), PARETO_CHART_SIZE);
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
    assert_eq!(image::image_dimensions(&path).unwrap(), PARETO_CHART_SIZE);
    let front = pareto_front(&points);
    assert!(!front.is_empty());
    // Along the front, time rises and error falls.
    for w in front.windows(2) {
        let (a, b) = (&points[w[0]], &points[w[1]]);
        assert!(a.time_ms <= b.time_ms && a.error >= b.error);
    }
}
