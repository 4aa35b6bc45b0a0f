//! The light view fitted to what the camera sees (issue #9, book §4.1): the GPU bounds of the
//! view samples in the light's view against their CPU twin, and `LightView::fit_to_receivers`
//! against the scene fit — it covers every view sample the scene fit covers, culls no caster
//! between a receiver and the light, spends at least as many map texels per view sample, keeps
//! a depth-range floor on a flat scene, and builds its off-centre matrix as computed by hand.

mod common;

use glam::{Mat4, Vec3, Vec4};
use penumbra::cpu::receiver_bounds::{receiver_bounds, texels_per_view_sample};
use penumbra::passes::{
    perspective_off_centre_rh, LightProjection, LightView, ReceiverBounds, DEPTH_FLOOR,
};
use penumbra::scene::{Light, Scene};
use penumbra::PreparedScene;

const BUNDLED: [&str; 4] = [
    "scenes/spot-point.toml",
    "scenes/teapot-rect.toml",
    "scenes/bunny-rect.toml",
    "scenes/rocker-arm-directional.toml",
];

/// A rect light at the plane's height-1 line, facing +x: the half of the plane at x < 0 is
/// behind it, and the scene fit's field of view is the 150° cap.
fn sideways_rect() -> Scene {
    common::bare_plane(Light::Rect {
        position: Vec3::new(0.0, 1.0, 0.0),
        u: Vec3::Y * 0.5,
        v: Vec3::Z * 0.5,
    })
}

/// A 2 × 2 occluder at y = 4 over a 10 × 10 plane, under `light`, seen by a low camera whose
/// frustum stays below the occluder: its shadow is seen, it is not. Its caster is nearer the
/// light than any receiver, so a fit that took near from the receivers would cull it.
fn hidden_occluder(light: Light) -> Scene {
    let mut scene = common::bare_plane(light);
    let (mut positions, indices) = penumbra::scene::shapes::plane(2.0, 2.0, 1);
    for p in &mut positions {
        p.y = 4.0;
    }
    scene.name = "hidden-occluder".into();
    scene.meshes.push(penumbra::scene::Mesh {
        name: "occluder".into(),
        positions,
        indices,
    });
    scene.camera.position = Vec3::new(0.0, 1.5, 6.0);
    scene
}

/// The small test scenes: the bundled ones at 128×96, a bare plane under a point light, a sun
/// and a sideways rect light, and a hidden occluder under a point light and a sun.
fn small_scenes() -> Vec<Scene> {
    let mut scenes: Vec<Scene> = BUNDLED.iter().map(|s| common::small(s)).collect();
    scenes.push(common::bare_plane(Light::Point {
        position: Vec3::new(0.0, 6.0, 0.0),
    }));
    scenes.push(common::bare_plane(Light::Directional {
        direction: Vec3::new(0.3, -1.0, 0.2),
        angular_diameter_deg: 0.0,
    }));
    scenes.push(sideways_rect());
    scenes.push(hidden_occluder(Light::Point {
        position: Vec3::new(0.0, 8.0, 0.0),
    }));
    scenes.push(hidden_occluder(Light::Directional {
        direction: Vec3::new(0.1, -1.0, 0.0),
        angular_diameter_deg: 0.0,
    }));
    scenes
}

fn is_perspective(view: &LightView) -> bool {
    matches!(view.projection, LightProjection::Perspective { .. })
}

/// Whether world point `p` projects inside `view`'s frustum (clip x, y in −1..1, depth 0..1).
fn inside(view: &LightView, p: Vec3) -> bool {
    let clip = view.view_proj * p.extend(1.0);
    if clip.w <= 0.0 {
        return false;
    }
    let ndc = clip.truncate() / clip.w;
    ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0 && (0.0..=1.0).contains(&ndc.z)
}

fn samples(positions: &[Vec4]) -> impl Iterator<Item = Vec3> + '_ {
    positions.iter().filter(|p| p.w > 0.0).map(|p| p.truncate())
}

/// Möller–Trumbore: the parameter `t` where `origin + t·dir` crosses triangle `(a, b, c)`.
fn ray_triangle(origin: Vec3, dir: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<f32> {
    let (e1, e2) = (b - a, c - a);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let s = origin - a;
    let u = s.dot(p) / det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) / det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) / det)
}

#[test]
fn off_centre_matrix_matches_hand_values_and_perspective_rh() {
    // Window x/−z in −1..3, y/−z in −2..2, depth 1..10, computed by hand:
    // 2/(r−l) = 0.5, (r+l)/(r−l) = 0.5, 2/(t−b) = 0.5, (t+b)/(t−b) = 0,
    // far/(near−far) = −10/9, near·far/(near−far) = −10/9.
    let m = perspective_off_centre_rh(-1.0, 3.0, -2.0, 2.0, 1.0, 10.0);
    let expected = Mat4::from_cols_array(&[
        0.5,
        0.0,
        0.0,
        0.0, //
        0.0,
        0.5,
        0.0,
        0.0, //
        0.5,
        0.0,
        -10.0 / 9.0,
        -1.0, //
        0.0,
        0.0,
        -10.0 / 9.0,
        0.0,
    ]);
    assert!(m.abs_diff_eq(expected, 1e-7), "{m:?}\nvs\n{expected:?}");
    // The window's corners at near and far land on the clip box's corners; its centre at depth
    // 5 on depth (far/(far − near))(1 − near/5) = 8/9.
    let corner = |t: Vec3| -> Vec3 { m.project_point3(Vec3::new(t.x * t.z, t.y * t.z, -t.z)) };
    assert!(corner(Vec3::new(-1.0, -2.0, 1.0)).abs_diff_eq(Vec3::new(-1.0, -1.0, 0.0), 1e-6));
    assert!(corner(Vec3::new(3.0, 2.0, 10.0)).abs_diff_eq(Vec3::new(1.0, 1.0, 1.0), 1e-6));
    assert!(corner(Vec3::new(1.0, 0.0, 5.0)).abs_diff_eq(Vec3::new(0.0, 0.0, 8.0 / 9.0), 1e-6));
    // glam's near-plane form agrees.
    let glam = Mat4::frustum_rh(-1.0, 3.0, -2.0, 2.0, 1.0, 10.0);
    assert!(m.abs_diff_eq(glam, 1e-6), "{m:?}\nvs glam\n{glam:?}");

    // Centred, it is `perspective_rh`, its depth row bit for bit.
    for (fov_deg, near, far) in [
        (60.0f32, 0.5f32, 20.0f32),
        (150.0, 1e-3, 1e3),
        (10.0, 5.9, 6.1),
    ] {
        let t = (fov_deg.to_radians() * 0.5).tan();
        let off = perspective_off_centre_rh(-t, t, -t, t, near, far);
        let sym = Mat4::perspective_rh(fov_deg.to_radians(), 1.0, near, far);
        assert_eq!(off.z_axis.z, sym.z_axis.z, "fov {fov_deg}");
        assert_eq!(off.w_axis.z, sym.w_axis.z, "fov {fov_deg}");
        assert_eq!(off.z_axis.w, sym.z_axis.w);
        let rel = (off.x_axis.x - sym.x_axis.x).abs() / sym.x_axis.x;
        assert!(
            rel < 1e-6,
            "fov {fov_deg}: {} vs {}",
            off.x_axis.x,
            sym.x_axis.x
        );
        assert!(
            off.abs_diff_eq(sym, 1e-6 * sym.x_axis.x.max(1.0)),
            "fov {fov_deg}"
        );
    }

    // `cross_section` reads the window back, off-centre or not, for both projections.
    let view = |proj: Mat4, projection| LightView {
        view: Mat4::IDENTITY,
        proj,
        view_proj: proj,
        projection,
        near: 1.0,
        far: 10.0,
        origin: Vec3::ZERO,
        direction: Vec3::NEG_Z,
    };
    let persp = view(
        m,
        LightProjection::Perspective {
            fov: 2.0 * 3f32.atan(),
        },
    );
    let (lo, hi) = persp.cross_section();
    assert!(
        lo.abs_diff_eq(glam::vec2(-1.0, -2.0), 1e-6) && hi.abs_diff_eq(glam::vec2(3.0, 2.0), 1e-6)
    );
    let ortho_m = Mat4::orthographic_rh(-4.0, 1.0, 0.5, 2.5, 1.0, 10.0);
    let ortho = view(ortho_m, LightProjection::Orthographic { half_extent: 4.0 });
    let (lo, hi) = ortho.cross_section();
    assert!(
        lo.abs_diff_eq(glam::vec2(-4.0, 0.5), 1e-6) && hi.abs_diff_eq(glam::vec2(1.0, 2.5), 1e-6)
    );
}

#[test]
fn no_receivers_fall_back_to_the_scene_fit_and_kinds_must_match() {
    let scene = common::small("scenes/spot-point.toml");
    let bounds = scene.bounds();
    let fit = LightView::fit(&scene.light, &bounds).expect("fit");
    let fallback = LightView::fit_to_receivers(&scene.light, &bounds, &ReceiverBounds::empty(true))
        .expect("fallback");
    assert_eq!(fallback.view_proj, fit.view_proj);
    assert_eq!((fallback.near, fallback.far), (fit.near, fit.far));
    // Receivers all beyond the scene fit's field of view (its 150° cap): nothing to focus on.
    let beyond = ReceiverBounds {
        perspective: true,
        min: Vec3::new(50.0, 50.0, 1.0),
        max: Vec3::new(60.0, 60.0, 2.0),
        receivers: 3,
        behind: 0,
    };
    let fallback = LightView::fit_to_receivers(&scene.light, &bounds, &beyond).expect("beyond");
    assert_eq!(fallback.view_proj, fit.view_proj);
    // Orthographic bounds for a point light are a caller's mistake, not a view.
    assert!(
        LightView::fit_to_receivers(&scene.light, &bounds, &ReceiverBounds::empty(false)).is_err()
    );
}

/// The GPU's bounds (computed in `Engine::prepare`) against the twin's on the view samples read
/// back, on every small scene: counts exact, bounds within the twin's declared tolerance.
#[test]
fn gpu_receiver_bounds_match_the_cpu_twin() {
    let engine = common::engine();
    let mut saw_behind = false;
    for scene in small_scenes() {
        let prepared = engine.prepare(&scene).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("read");
        let view = &prepared.light_view;
        let twin = receiver_bounds(&positions, &view.view, is_perspective(view));
        let (gpu, cpu) = (prepared.receiver_bounds, twin.bounds);
        let dmin = (gpu.min - cpu.min).abs();
        let dmax = (gpu.max - cpu.max).abs();
        let report = format!(
            "{}:\n  gpu {gpu:?}\n  cpu {cpu:?}\n  |Δmin| {dmin}\n  |Δmax| {dmax}\n  tolerance {}",
            scene.name, twin.tolerance
        );
        println!("{report}");
        assert_eq!(gpu.perspective, cpu.perspective, "{report}");
        assert_eq!(
            (gpu.receivers, gpu.behind),
            (cpu.receivers, cpu.behind),
            "{report}"
        );
        let all = samples(&positions).count() as u32;
        assert_eq!(gpu.receivers + gpu.behind, all, "{report}");
        assert!(gpu.receivers > 0, "{report}");
        assert!(
            dmin.cmple(twin.tolerance).all() && dmax.cmple(twin.tolerance).all(),
            "{report}"
        );
        saw_behind |= gpu.behind > 0;
    }
    assert!(saw_behind, "no scene had receivers behind its light");
    common::assert_clean(&engine.context().validation());
}

/// For one prepared scene: the fitted view keeps the scene fit's origin, direction and near, its
/// window lies inside the scene fit's, and every view sample inside the scene fit is inside it.
fn check_coverage(prepared: &PreparedScene, positions: &[Vec4]) {
    let (scene, fitted) = (&prepared.light_view, &prepared.receiver_light_view);
    let name = &prepared.name;
    assert_eq!(fitted.origin, scene.origin, "{name}");
    assert_eq!(fitted.direction, scene.direction, "{name}");
    assert_eq!(fitted.view, scene.view, "{name}");
    assert_eq!(fitted.near, scene.near, "{name}");
    assert_eq!(is_perspective(fitted), is_perspective(scene), "{name}");
    let (slo, shi) = scene.cross_section();
    let (flo, fhi) = fitted.cross_section();
    let tol = 1e-5 * (shi - slo).max_element();
    assert!(
        flo.cmpge(slo - tol).all() && fhi.cmple(shi + tol).all(),
        "{name}: fitted window {flo}..{fhi} is not inside the scene fit's {slo}..{shi}"
    );
    let mut covered = 0;
    let mut missed = Vec::new();
    for p in samples(positions) {
        if inside(scene, p) {
            covered += 1;
            if !inside(fitted, p) {
                missed.push(p);
            }
        }
    }
    assert!(covered > 0, "{name}: the scene fit covers no view sample");
    assert!(
        missed.is_empty(),
        "{name}: {} of {covered} view samples inside the scene fit are outside the fitted view \
         ({:?} ... ); bounds {:?}, window {flo}..{fhi}, near {} far {}",
        missed.len(),
        &missed[..missed.len().min(4)],
        prepared.receiver_bounds,
        fitted.near,
        fitted.far
    );
}

/// Every caster between a receiver and the light is inside the fitted frustum: for a subset of
/// the view samples inside the scene fit, every point where a scene triangle crosses the segment
/// from the sample to the light's origin (point and rect lights: the map is rendered from
/// there), or its ray towards a directional light, projects inside the fitted view (window
/// and near..far). Returns how many such caster points were checked.
fn check_casters(prepared: &PreparedScene, positions: &[Vec4]) -> usize {
    let (scene, fitted) = (&prepared.light_view, &prepared.receiver_light_view);
    let name = &prepared.name;
    let receivers: Vec<Vec3> = samples(positions).filter(|&p| inside(scene, p)).collect();
    let stride = (receivers.len() / 300).max(1);
    let tris: Vec<[Vec3; 3]> = prepared
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]].map(|i| prepared.positions[i as usize]))
        .collect();
    let b = &prepared
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let diagonal = (b.1 - b.0).length();
    let mut checked = 0;
    for &r in receivers.iter().step_by(stride) {
        // Segment start = receiver, end = the light (its origin, or beyond the box for a sun).
        let end = if is_perspective(scene) {
            scene.origin
        } else {
            r - scene.direction * 2.0 * diagonal
        };
        let dir = end - r;
        for [a, b, c] in &tris {
            let Some(t) = ray_triangle(r, dir, *a, *b, *c) else {
                continue;
            };
            // Leave out the receiver's own surface (t ≈ 0) and the light itself.
            if !(1e-4..=1.0 - 1e-4).contains(&t) {
                continue;
            }
            let p = r + dir * t;
            checked += 1;
            assert!(
                inside(fitted, p),
                "{name}: caster {p} between receiver {r} and the light is outside the fitted \
                 view (clip {:?}); scene fit: {}",
                fitted.view_proj * p.extend(1.0),
                inside(scene, p)
            );
        }
    }
    checked
}

/// On every small scene: coverage of the scene fit's samples and of the casters.
#[test]
fn fitted_view_covers_the_samples_and_casters_the_scene_fit_covers() {
    let engine = common::engine();
    for scene in small_scenes() {
        let prepared = engine.prepare(&scene).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("read");
        check_coverage(&prepared, &positions);
        let casters = check_casters(&prepared, &positions);
        println!("{}: {casters} caster points checked", scene.name);
        if scene.name == "hidden-occluder" {
            // The occluder must be out of the camera's view for this scene to mean anything.
            let hidden = samples(&positions).all(|p| p.y < 3.9);
            assert!(hidden, "the camera sees the hidden occluder");
        }
        if scene.name != "bare-plane" {
            assert!(
                casters > 0,
                "{}: no caster found, the check is empty",
                scene.name
            );
        }
    }
    common::assert_clean(&engine.context().validation());
}

/// Texels per view sample, scene fit and receiver fit, on the bundled scenes at their own
/// camera size and map size: the receiver fit never spends fewer.
#[test]
fn fitted_view_uses_at_least_as_many_texels_per_view_sample() {
    let engine = common::engine();
    for spec in BUNDLED {
        let scene = Scene::open(spec).expect("scene");
        let prepared = engine.prepare(&scene).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("read");
        check_coverage(&prepared, &positions);
        let map = scene.defaults.shadow_map_size;
        let whole = texels_per_view_sample(&positions, &prepared.light_view, map);
        let focused = texels_per_view_sample(&positions, &prepared.receiver_light_view, map);
        let (lo, hi) = prepared.receiver_light_view.cross_section();
        let (slo, shi) = prepared.light_view.cross_section();
        let area = |lo: glam::Vec2, hi: glam::Vec2| (hi - lo).x * (hi - lo).y;
        println!(
            "{} ({}x{}, map {map}): texels per view sample {whole:.4} (scene fit) -> {focused:.4} \
             (receiver fit), x{:.2}; window {lo}..{hi} ({:.1}x smaller than the scene fit's), \
             near {:.3} far {:.3} (scene far {:.3})",
            scene.name,
            scene.camera.width,
            scene.camera.height,
            focused / whole,
            area(slo, shi) / area(lo, hi),
            prepared.receiver_light_view.near,
            prepared.receiver_light_view.far,
            prepared.light_view.far,
        );
        assert!(
            focused >= whole,
            "{}: receiver fit {focused} < scene fit {whole} texels per view sample",
            scene.name
        );
    }
    common::assert_clean(&engine.context().validation());
}

/// A flat scene seen head-on: every receiver at one depth, so far − near comes from the floor.
#[test]
fn flat_plane_keeps_the_depth_floor() {
    let engine = common::engine();
    for light in [
        Light::Point {
            position: Vec3::new(0.0, 6.0, 0.0),
        },
        Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: 0.0,
        },
    ] {
        let scene = common::bare_plane(light);
        let bounds = scene.bounds();
        let floor = DEPTH_FLOOR * (bounds.max - bounds.min).length();
        let prepared = engine.prepare(&scene).expect("prepare");
        let fitted = &prepared.receiver_light_view;
        let rb = prepared.receiver_bounds;
        println!(
            "{light:?}: receivers' depth {}..{}, scene fit {}..{}, fitted {}..{} (floor {floor})",
            rb.min.z,
            rb.max.z,
            prepared.light_view.near,
            prepared.light_view.far,
            fitted.near,
            fitted.far
        );
        assert!(
            (rb.max.z - rb.min.z).abs() < 1e-4,
            "the plane is not seen head-on"
        );
        assert!(
            fitted.far - fitted.near >= floor * (1.0 - 1e-5),
            "far − near = {} < floor {floor}",
            fitted.far - fitted.near
        );
    }
    common::assert_clean(&engine.context().validation());
}

/// A light in the plane of a flat scene reaches none of it: the fit refuses it with an error
/// that says so (a scene error, not a degenerate matrix). A rect light shines from the side
/// facing the scene, so above or below the plane it is fitted.
#[test]
fn a_light_in_the_plane_of_a_flat_scene_is_refused() {
    let flat = penumbra::scene::Aabb {
        min: Vec3::new(-1.0, 0.0, -1.0),
        max: Vec3::new(1.0, 0.0, 1.0),
    };
    let rect = |y: f32| Light::Rect {
        position: Vec3::new(0.0, y, 0.0),
        u: Vec3::X,
        v: Vec3::Z,
    };
    let err = LightView::fit(&rect(0.0), &flat)
        .map(|_| ())
        .expect_err("a light in the scene's plane");
    assert!(
        err.to_string().contains("behind the light or in its plane"),
        "{err}"
    );
    assert!(LightView::fit(&rect(2.0), &flat).is_ok());
    assert!(LightView::fit(&rect(-2.0), &flat).is_ok());
}

/// The measure of the fit: `hard` at the scene's default map size misclassifies fewer
/// view samples with `fit = view` than with `fit = scene`, on every bundled scene. The reference
/// is the one `hard` approximates — rays to the light's centre (`samples = 1`, `jitter = 0`; the
/// point light and a hard sun are that already) — so what is measured is the map's aliasing and
/// bias, not the penumbra a hard shadow cannot have (against the area-light reference the two
/// fits differ by noise in where a hard edge cuts the penumbra: 0.0646 vs 0.0666 on teapot-rect).
/// The same frames' `map_texels_used` counter is the CPU measure for the view the technique used,
/// and larger with the view fit. At 128×96, with light clipping on as by default.
#[test]
fn view_fit_beats_the_scene_fit_on_every_bundled_scene() {
    let engine = common::engine();
    for name in [
        "spot-point",
        "teapot-rect",
        "bunny-rect",
        "rocker-arm-directional",
    ] {
        let path = format!("{}/scenes/{name}.toml", env!("CARGO_MANIFEST_DIR"));
        let prepared = engine.prepare(&common::small(&path)).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("positions");
        let is_sample: Vec<bool> = positions.iter().map(|p| p.w > 0.0).collect();
        let reference = engine
            .render(
                &prepared,
                "reference",
                &common::knobs(&[("samples", "1"), ("jitter", "0")]),
                1,
            )
            .expect("reference");
        // (misclassified fraction, map texels used) of `hard` with `fit`.
        let measure = |fit: &str| {
            let frame = engine
                .render(&prepared, "hard", &common::knobs(&[("fit", fit)]), 1)
                .expect("hard");
            let error =
                penumbra::metrics::compare(&reference.visibility, &frame.visibility, &is_sample)
                    .expect("metrics");
            (error.misclassified, frame.stats.counters["map_texels_used"])
        };
        let (scene_fit, view_fit) = (measure("scene"), measure("view"));
        eprintln!(
            "{name}: hard misclassifies {:.4} / uses {} texels (scene fit), {:.4} / {} (view fit)",
            scene_fit.0, scene_fit.1, view_fit.0, view_fit.1
        );
        assert!(
            view_fit.0 < scene_fit.0,
            "{name}: misclassified {} with the view fit, {} with the scene fit",
            view_fit.0,
            scene_fit.0
        );
        assert_eq!(
            scene_fit.1,
            penumbra::cpu::receiver_bounds::map_texels_used(
                &positions,
                &prepared.light_view,
                prepared.defaults.shadow_map_size
            ),
            "{name}: the counter is the CPU measure of the view used"
        );
        assert!(
            view_fit.1 > scene_fit.1,
            "{name}: texels {view_fit:?} vs {scene_fit:?}"
        );
    }
    common::assert_clean(&engine.context().validation());
}
