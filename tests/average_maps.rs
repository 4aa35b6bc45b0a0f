//! `average-maps` under validation: against `hard` (the unclipped mean of hard maps, one sample
//! or a point light is hard), its tangent-plane clip on a point light, and its set-up (light
//! samples, `LightView::fit`) against hand-computed values (the twin: `tests/gpu_vs_cpu.rs`).
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::collections::BTreeMap;

use glam::{Mat4, Vec3};
use penumbra::cpu::average_maps::{behind_plane, sample_lights};
use penumbra::passes::{light_samples, LightProjection, LightView};
use penumbra::scene::{Aabb, Light, Scene};
use penumbra::{Engine, Frame, PreparedScene};

/// With `light_clip = 0` average-maps is the plain average of K hard shadow maps, bit for bit as
/// before the clip existed: the count of lit `hard` results, each rendered with the scene's light
/// replaced by one light sample (a rect sample keeps its edges, and `hard` fits its view to the
/// sample's centre exactly as average-maps fits each sample's), divided once by K.
#[test]
fn average_maps_without_clip_is_the_mean_of_hard_maps() {
    let engine = common::engine();
    let mut scene = Scene::open("plane-boxes@rect").expect("procedural scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    let samples = 4u32;
    let set = common::knobs(&[("map_size", "256")]);
    let prepared = engine.prepare(&scene).expect("prepare");
    let mut avg_set = set.clone();
    avg_set.insert("samples".to_string(), samples.to_string());
    avg_set.insert("light_clip".to_string(), "0".to_string());
    let avg = engine
        .render(&prepared, "average-maps", &avg_set, 1)
        .expect("average-maps");
    assert_eq!(avg.stats.counters["horizon_umbra"], 0);
    drop(prepared);
    let set = hard_knobs(&set);
    let mut count = vec![0.0f32; avg.visibility.len()];
    for light in sample_lights(&scene.light, samples) {
        let mut one = scene.clone();
        one.light = light;
        let prepared = engine.prepare(&one).expect("prepare");
        let hard = engine.render(&prepared, "hard", &set, 1).expect("hard");
        for (c, v) in count.iter_mut().zip(&hard.visibility) {
            *c += v;
        }
    }
    let k = samples as f32;
    let mean: Vec<f32> = count
        .iter()
        .map(|&c| if c >= k { 1.0 } else { c / k })
        .collect();
    common::assert_same_bits(
        "average-maps-noclip",
        avg.width,
        avg.height,
        &mean,
        &avg.visibility,
    );
    assert!(
        mean.iter().any(|&v| v > 0.0 && v < 1.0),
        "no penumbra to compare"
    );
    common::assert_clean(&engine.context().validation());
}

/// `set` for `hard` as average-maps sees a light sample: no tangent-plane clipping and the map
/// fitted to the scene (average-maps fits each sample's map to the scene).
fn hard_knobs(set: &BTreeMap<String, String>) -> BTreeMap<String, String> {
    let mut hard = set.clone();
    hard.extend(common::knobs(&common::KERNEL_ONLY));
    hard
}

/// Renders `hard` and `average-maps` of `samples` light samples without its tangent-plane clip
/// (`hard` has none), both with 512² maps, and checks they are the same image bit for bit, with a
/// shadow in it: what a single map must give. Returns the `average-maps` frame.
fn unclipped_average_is_hard(engine: &Engine, prepared: &PreparedScene, samples: &str) -> Frame {
    let mut set = common::knobs(&[("map_size", "512")]);
    let hard = engine
        .render(prepared, "hard", &hard_knobs(&set), 1)
        .expect("hard");
    set.insert("samples".to_string(), samples.to_string());
    set.insert("light_clip".to_string(), "0".to_string());
    let avg = engine
        .render(prepared, "average-maps", &set, 1)
        .expect("average-maps");
    assert!(
        hard.visibility == avg.visibility,
        "average-maps differs from hard"
    );
    assert!(hard.visibility.contains(&0.0), "no shadow to compare");
    avg
}

/// On a point light (one sample) the clip changes exactly the view samples whose normal faces
/// away from the light, by the twin's own plane test: those read 0 with it, every other sample is
/// bit for bit the unclipped value; `horizon_umbra` counts the facing-away samples.
#[test]
fn average_maps_clip_on_a_point_light_changes_only_samples_facing_away() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let light = prepared.light;
    assert!(matches!(light, Light::Point { .. }), "{light:?}");
    let render = |clip: &str| {
        let set = common::knobs(&[("map_size", "512"), ("light_clip", clip)]);
        engine
            .render(&prepared, "average-maps", &set, 1)
            .expect("average-maps")
    };
    let (on, off) = (render("1"), render("0"));
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let (mut away, mut changed, mut ties) = (0u64, 0u64, 0u64);
    for i in 0..positions.len() {
        if positions[i].w <= 0.0 {
            assert_eq!(on.visibility[i].to_bits(), off.visibility[i].to_bits());
            continue;
        }
        let (facing, tie) = behind_plane(positions[i].truncate(), normals[i].truncate(), &light);
        if tie {
            ties += 1;
            continue;
        }
        changed += u64::from(on.visibility[i].to_bits() != off.visibility[i].to_bits());
        if facing <= 0.0 {
            away += 1;
            assert_eq!(on.visibility[i], 0.0, "view sample {i} faces away: blocked");
        } else {
            assert_eq!(
                on.visibility[i].to_bits(),
                off.visibility[i].to_bits(),
                "view sample {i} faces the light: unchanged"
            );
        }
    }
    eprintln!("{away} view samples face away, {changed} changed by the clip, {ties} plane ties");
    // Plane ties are samples seen edge-on by the light: capped at 0.5 % of the view.
    assert!(ties * 200 <= positions.len() as u64, "{ties} plane ties");
    // Measured: 55 view samples face away, 30 of them lit by the map (the depth bias hides the
    // box's own faces from themselves near its edges) and so changed by the clip.
    assert!(
        away > 30 && changed > 10,
        "{away} view samples face away, {changed} changed: the test proves little"
    );
    assert!(
        on.stats.counters["horizon_umbra"].abs_diff(away) <= ties,
        "horizon_umbra {} vs {away} facing away",
        on.stats.counters["horizon_umbra"]
    );
    assert_eq!(off.stats.counters["horizon_umbra"], 0);
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

/// A point light has nothing to average: whatever `samples` says, average-maps renders one map
/// (the twin's count for a point light) and without the clip equals `hard` exactly.
#[test]
fn average_maps_of_a_point_light_is_hard() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let light = prepared.light;
    assert!(matches!(light, Light::Point { .. }), "{light:?}");
    let avg = unclipped_average_is_hard(&engine, &prepared, "5");
    let twin_count = sample_lights(&light, 5).len() as u64;
    assert_eq!(twin_count, 1);
    assert_eq!(avg.stats.counters["light_samples"], twin_count);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// `light_samples` (the technique's set-up) against positions worked out by hand, and against
/// the twin's own [`sample_lights`] for many counts.
#[test]
fn light_samples_match_hand_computed_positions() {
    let rect = Light::Rect {
        position: Vec3::new(1.0, 5.0, 2.0),
        u: Vec3::new(2.0, 0.0, 0.0),
        v: Vec3::new(0.0, 0.0, 4.0),
    };
    let centres =
        |l: Vec<Light>| -> Vec<Vec3> { l.iter().map(|s| s.centre().expect("rect")).collect() };
    // k = 1: the centre.
    assert_eq!(centres(light_samples(&rect, 1)), [Vec3::new(1.0, 5.0, 2.0)]);
    // k = 4: a = (i + ½)/4 = ⅛, ⅜, ⅝, ⅞; b = φ(i) + ⅛ with φ = 0, ½, ¼, ¾; the sample is
    // (1 + 2(a − ½), 5, 2 + 4(b − ½)).
    let four = [
        Vec3::new(0.25, 5.0, 0.5),
        Vec3::new(0.75, 5.0, 2.5),
        Vec3::new(1.25, 5.0, 1.5),
        Vec3::new(1.75, 5.0, 3.5),
    ];
    assert_eq!(centres(light_samples(&rect, 4)), four);
    for s in light_samples(&rect, 4) {
        let Light::Rect { u, v, .. } = s else {
            panic!("a rect sample keeps its edges: {s:?}")
        };
        assert_eq!((u, v), (Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 4.0)));
    }
    // A 10° sun travelling down. Sample 1 of 4 sits at (a, b) = (⅜, ⅝): the square point
    // (−¼, ¼), which the concentric map takes to radius ¼ at 135°. Duff et al.'s frame around
    // (0, −1, 0) is e1 = (1, 0, 0), e2 = (0, 0, 1), so the direction is
    // normalise((0, −1, 0) + ¼·tan 5°·(cos 135°, 0, sin 135°)).
    let sun = Light::Directional {
        direction: Vec3::NEG_Y,
        angular_diameter_deg: 10.0,
    };
    let dir = |l: &Light| match *l {
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            assert_eq!(angular_diameter_deg, 0.0, "a sun sample is a hard sun");
            direction
        }
        _ => panic!("a sun sample is directional: {l:?}"),
    };
    let tan5 = 0.087_488_663_525_924_01_f64 as f32;
    let off = 0.25 * tan5 * std::f32::consts::FRAC_1_SQRT_2;
    let expected = Vec3::new(-off, -1.0, off).normalize();
    let s = light_samples(&sun, 4);
    assert_eq!(s.len(), 4);
    assert!(
        (dir(&s[1]) - expected).length() < 1e-6,
        "{:?} vs {expected}",
        s[1]
    );
    assert!((dir(&light_samples(&sun, 1)[0]) - Vec3::NEG_Y).length() < 1e-7);

    // The twin's samples: rect positions bit for bit, sun directions to an ulp.
    for k in [1u32, 2, 3, 5, 8, 16, 64, 100] {
        let rect = Light::Rect {
            position: Vec3::new(-0.3, 4.7, 1.1),
            u: Vec3::new(1.3, 0.2, 0.0),
            v: Vec3::new(0.0, -0.1, 0.9),
        };
        assert_eq!(
            light_samples(&rect, k),
            sample_lights(&rect, k),
            "rect, k = {k}"
        );
        let sun = Light::Directional {
            direction: Vec3::new(0.3, -1.0, 0.1),
            angular_diameter_deg: 3.0,
        };
        for (a, b) in light_samples(&sun, k).iter().zip(sample_lights(&sun, k)) {
            assert!(
                (dir(a) - dir(&b)).length() < 1e-6,
                "sun, k = {k}: {a:?} vs {b:?}"
            );
        }
    }
}

/// `LightView::fit`, which the average-maps twin shares with the technique (and every
/// shadow-map technique uses), against hand-computed frusta for the scene box
/// [−1, 1] × [0, 1] × [−1, 1]. Reusing it is acceptable because both a map and its lookups use
/// the one fitted matrix: a fit that still holds the scene only changes the sampling, and what
/// would change visibility (a frustum that clips receivers, a wrong near or far plane, a
/// rect light facing away) is pinned here.
#[test]
fn light_view_fit_matches_hand_computed_values() {
    let bounds = Aabb {
        min: Vec3::new(-1.0, 0.0, -1.0),
        max: Vec3::new(1.0, 1.0, 1.0),
    };
    // A point light at (0, 5, 0) looks down at the box centre; the box's top corners (depth 4,
    // 1 off axis) set tan(fov/2) = ¼, widened by 1e-4; near = 0.999·4, far = 1.001·5.
    let point = LightView::fit(
        &Light::Point {
            position: Vec3::new(0.0, 5.0, 0.0),
        },
        &bounds,
    )
    .expect("point");
    let fov = 2.0 * 0.25f32.atan() * 1.0001;
    match point.projection {
        LightProjection::Perspective { fov: f } => assert!((f - fov).abs() < 1e-6, "{f} vs {fov}"),
        p => panic!("a point light is a perspective: {p:?}"),
    }
    assert!((point.near - 3.996).abs() < 1e-5 && (point.far - 5.005).abs() < 1e-5);
    assert_eq!(
        (point.origin, point.direction),
        (Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y)
    );
    let ndc = |m: Mat4, p: Vec3| m.project_point3(p);
    let below = ndc(point.view_proj, Vec3::ZERO);
    assert!(below.x.abs() < 1e-6 && below.y.abs() < 1e-6);
    // Depth 5 of [3.996, 5.005]: z = far·(d − near) / (d·(far − near)).
    let z = 5.005 * (5.0 - 3.996) / (5.0 * (5.005 - 3.996));
    assert!((below.z - z).abs() < 1e-5, "{below}");
    let corner = ndc(point.view_proj, Vec3::new(1.0, 1.0, 1.0));
    let edge = 0.25 / (fov / 2.0).tan();
    assert!((corner.x.abs() - edge).abs() < 1e-5 && (corner.y.abs() - edge).abs() < 1e-5);
    // A rect light whose u × v points up shines down all the same, from its centre.
    let rect = Light::Rect {
        position: Vec3::new(0.0, 5.0, 0.0),
        u: Vec3::X,
        v: Vec3::NEG_Z,
    };
    let r = LightView::fit(&rect, &bounds).expect("rect");
    assert_eq!((r.view_proj, r.direction), (point.view_proj, Vec3::NEG_Y));
    // A sun straight down: an orthographic box from the centre (0, ½, 0) backed off by the
    // box's diagonal 3, half side 1, depths 2.5 to 3.5, each widened by 1e-3 of the diagonal.
    let sun = Light::Directional {
        direction: Vec3::NEG_Y,
        angular_diameter_deg: 0.5,
    };
    let s = LightView::fit(&sun, &bounds).expect("sun");
    match s.projection {
        LightProjection::Orthographic { half_extent } => {
            assert!((half_extent - 1.003).abs() < 1e-5, "{half_extent}")
        }
        p => panic!("a sun is orthographic: {p:?}"),
    }
    assert!((s.near - 2.497).abs() < 1e-5 && (s.far - 3.503).abs() < 1e-5);
    assert!((s.origin - Vec3::new(0.0, 3.5, 0.0)).length() < 1e-6);
    let top = ndc(s.view_proj, Vec3::new(1.0, 1.0, 1.0));
    assert!((top.x.abs() - 1.0 / 1.003).abs() < 1e-5 && (top.z - 0.003 / 1.006).abs() < 1e-5);
}

/// One light sample of a rect light is its centre: average-maps without the clip then equals
/// `hard` exactly.
#[test]
fn average_maps_with_one_sample_is_hard() {
    let engine = common::engine();
    let mut scene = Scene::open("thin-bars@rect").expect("procedural scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    let prepared = engine.prepare(&scene).expect("prepare");
    unclipped_average_is_hard(&engine, &prepared, "1");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
