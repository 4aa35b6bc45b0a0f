//! Caster culling (`glsl/caster_cull/`) under validation: the tile bounds and the "may any
//! triangle cast?" decision against their CPU twin on scenes that cast and scenes that cannot,
//! and the renderer's `caster_skip`: where nothing can cast, every technique is replaced by the
//! lit answer — no map, the receivers' light clipping applied exactly as the twin computes it —
//! counted as `caster_skip`; with the knob off or a caster present, the technique runs.

mod common;

use glam::{Mat4, Vec3};
use penumbra::cpu::caster_cull as twin;
use penumbra::cpu::receivers as receivers_twin;
use penumbra::passes::caster_cull::{tolerance, CasterCull};
use penumbra::scene::{Light, Scene};

/// `common::bare_plane` tilted by 20° about x and 10° about z and lifted, so that no axis is
/// normal to it (its tiles' boxes straddle its plane): a lone receiver that shadows nothing.
fn tilted_plane(light: Light) -> Scene {
    let mut scene = common::bare_plane(light);
    let m = Mat4::from_translation(Vec3::new(0.3, 0.5, -0.2))
        * Mat4::from_rotation_x(20f32.to_radians())
        * Mat4::from_rotation_z(10f32.to_radians());
    for p in &mut scene.meshes[0].positions {
        *p = m.transform_point3(*p);
    }
    scene.name = "tilted-plane".into();
    scene
}

fn lights() -> [(&'static str, Light); 4] {
    [
        (
            "point",
            Light::Point {
                position: Vec3::new(1.0, 8.0, 1.0),
            },
        ),
        (
            "rect",
            Light::Rect {
                position: Vec3::new(-1.0, 7.0, 0.5),
                u: Vec3::new(3.0, 0.0, 0.0),
                v: Vec3::new(0.0, 0.0, 2.0),
            },
        ),
        (
            "sun",
            Light::Directional {
                direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
                angular_diameter_deg: 4.0,
            },
        ),
        (
            // Low enough that part of the light is behind the plane for some samples: the lit
            // answer is then the clipped fraction, not 1.
            "low-rect",
            Light::Rect {
                position: Vec3::new(9.0, 1.6, 0.0),
                u: Vec3::new(0.0, 3.0, 0.0),
                v: Vec3::new(0.0, 0.0, 2.0),
            },
        ),
    ]
}

/// Runs the GPU test on `scene` and checks it against the twin; returns whether some triangle
/// may cast.
fn gpu_and_twin(scene: &Scene) -> bool {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(scene).expect("prepare");
    let (pass, eps, cpu) = common::caster_pass(&prepared, &ctx);
    let gpu = pass.run().expect("run");
    let tiles = pass.read_tiles().expect("tiles");
    assert_eq!(tiles.len(), cpu.len(), "{}: tile count", scene.name);
    let scale = penumbra::reference::bvh::scene_scale(&prepared.positions);
    for (k, (g, c)) in tiles.iter().zip(&cpu).enumerate() {
        assert_eq!(g[2].w as u32, c.samples, "{}: tile {k} samples", scene.name);
        if c.samples == 0 {
            continue;
        }
        let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol * scale;
        for i in 0..3 {
            assert!(
                close(g[0][i], c.lo[i], 1e-5),
                "{}: tile {k} lo {g:?} vs {c:?}",
                scene.name
            );
            assert!(
                close(g[1][i], c.hi[i], 1e-5),
                "{}: tile {k} hi {g:?} vs {c:?}",
                scene.name
            );
            assert!(
                (g[2][i] - c.axis[i]).abs() <= 1e-4,
                "{}: tile {k} axis",
                scene.name
            );
        }
        assert!(
            close(g[0].w, c.slab[0], 1e-5),
            "{}: tile {k} slab {g:?} vs {c:?}",
            scene.name
        );
        assert!(
            close(g[1].w, c.slab[1], 1e-5),
            "{}: tile {k} slab {g:?} vs {c:?}",
            scene.name
        );
    }
    let cpu_may = twin::may_cast(
        &cpu,
        &prepared.positions,
        &prepared.indices,
        &prepared.light,
        eps,
    );
    assert_eq!(
        gpu.may_cast, cpu_may,
        "{}: GPU and twin disagree",
        scene.name
    );
    if !gpu.may_cast {
        assert_eq!(
            gpu.tested as usize, prepared.triangles,
            "{}: all tested",
            scene.name
        );
    }
    gpu.may_cast
}

#[test]
fn a_lone_tilted_plane_casts_nothing_under_every_light_kind() {
    for (name, light) in lights() {
        assert!(
            !gpu_and_twin(&tilted_plane(light)),
            "{name}: the lone plane may cast?"
        );
    }
}

#[test]
fn scenes_with_casters_may_cast() {
    for spec in ["plane-boxes", "scenes/teapot-rect.toml"] {
        let spec = if spec.starts_with("scenes/") {
            format!("{}/{spec}", env!("CARGO_MANIFEST_DIR"))
        } else {
            spec.to_string()
        };
        assert!(
            gpu_and_twin(&common::small(&spec)),
            "{spec}: no caster found"
        );
    }
    // A quad 1e-3 above the plane, under the point light: a caster the tolerance must not hide.
    let (_, light) = lights()[0];
    let mut scene = common::bare_plane(light);
    let (p, i) = penumbra::scene::shapes::plane(2.0, 2.0, 1);
    scene.meshes.push(penumbra::scene::Mesh {
        name: "sheet".into(),
        positions: p
            .into_iter()
            .map(|p| p + Vec3::new(0.0, 1e-3, 0.0))
            .collect(),
        indices: i,
    });
    assert!(gpu_and_twin(&scene), "a sheet 1e-3 above the plane casts");
}

#[test]
fn nothing_casting_gives_the_lit_answer_without_a_map() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    for (name, light) in lights() {
        let prepared = engine.prepare(&tilted_plane(light)).expect("prepare");
        assert!(prepared.nothing_casts(&ctx).expect("test"), "{name}");
        let positions = prepared.view.read_positions(&ctx).expect("positions");
        let normals = prepared.view.read_normals(&ctx).expect("normals");
        // The twin of the lit answer: the light's clipped fraction, 0 where it is all behind.
        let lit = receivers_twin::prepare(
            &positions,
            &normals,
            &prepared.light,
            &prepared.light_view,
            receivers_twin::Knobs {
                map_size: 256,
                light_clip: true,
                normal_offset: 0.0,
                skip_horizon: true,
            },
        )
        .clip;
        let mut clipped = 0;
        for technique in [
            "hard",
            "pcss",
            "vssm",
            "average-maps",
            "pvssm",
            "izb",
            "izb-soft",
        ] {
            let mut r = engine
                .renderer(&prepared, technique, &common::knobs(&[]))
                .expect("renderer");
            r.render().expect("frame");
            let counters = r.counters().expect("counters");
            assert_eq!(counters["caster_skip"], 1, "{name} {technique}");
            let passes: Vec<String> = r
                .pass_times()
                .expect("times")
                .into_iter()
                .map(|p| p.name)
                .collect();
            assert!(
                passes.iter().any(|p| p == "unshadowed"),
                "{name} {technique}: {passes:?}"
            );
            assert!(
                r.technique().shadow_map().is_none(),
                "{name} {technique}: a map was built"
            );
            let v = r.read_visibility().expect("read");
            let mut worst = 0.0f32;
            for (i, p) in positions.iter().enumerate() {
                let expected = if p.w > 0.0 { lit[i] } else { 1.0 };
                worst = worst.max((v[i] - expected).abs());
                clipped += usize::from(p.w > 0.0 && lit[i] < 1.0);
            }
            // The twin's clipped fraction is f64, the shader's f32 (tests/receivers.rs).
            assert!(
                worst <= 1e-5,
                "{name} {technique}: |V - twin| up to {worst}"
            );
            // Off: the technique itself runs.
            let mut off = engine
                .renderer(
                    &prepared,
                    technique,
                    &common::knobs(&[("caster_skip", "0")]),
                )
                .expect("renderer");
            off.render().expect("frame");
            assert_eq!(off.counters().expect("counters")["caster_skip"], 0);
        }
        if name == "low-rect" {
            assert!(
                clipped > 0,
                "the low light should be partly behind the plane somewhere"
            );
        }
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn a_scene_with_a_caster_keeps_its_technique() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    assert!(!prepared.nothing_casts(&ctx).expect("test"));
    let mut r = engine
        .renderer(&prepared, "pcss", &common::knobs(&[]))
        .expect("renderer");
    r.render().expect("frame");
    assert_eq!(r.counters().expect("counters")["caster_skip"], 0);
    assert!(r.technique().shadow_map().is_some());
    // The references are the ground truth the skip is measured against: they have no such knob.
    let reference = penumbra::techniques::find("reference").expect("reference");
    assert!(!reference
        .all_knobs()
        .iter()
        .any(|k| k.name == "caster_skip"));
}

#[test]
fn degenerate_triangles_cast_nothing() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let (_, light) = lights()[1];
    let scene = tilted_plane(light);
    let prepared = engine.prepare(&scene).expect("prepare");
    // A zero-area triangle (three collinear points) between the plane and the light. The scene
    // loaders and `Scene::validate` reject it; a caller's geometry that bypasses them must
    // still not make the test fail or claim a caster.
    let mut positions = prepared.positions.clone();
    let mut indices = prepared.indices.clone();
    let base = positions.len() as u32;
    positions.extend([
        Vec3::new(0.0, 3.0, 0.0),
        Vec3::new(1.0, 3.0, 0.0),
        Vec3::new(2.0, 3.0, 0.0),
    ]);
    indices.extend([base, base + 1, base + 2]);
    let geometry = penumbra::passes::SceneGeometry::from_triangles(&ctx, &positions, &indices)
        .expect("geometry");
    let eps = tolerance(&positions);
    let pass =
        CasterCull::new(&ctx, &prepared.view, &geometry, &prepared.light, eps).expect("pass");
    let gpu = pass.run().expect("run");
    assert!(!gpu.may_cast, "a zero-area triangle cast");
    assert_eq!(gpu.tested as usize, indices.len() / 3);
    let view = &prepared.view;
    let tiles = twin::tile_bounds(
        &view.read_positions(&ctx).expect("positions"),
        &view.read_normals(&ctx).expect("normals"),
        view.width as usize,
        view.height as usize,
    );
    assert!(!twin::may_cast(
        &tiles,
        &positions,
        &indices,
        &prepared.light,
        eps
    ));
    // A real triangle there does cast.
    positions[base as usize + 2] = Vec3::new(1.0, 3.0, 1.0);
    assert!(twin::may_cast(
        &tiles,
        &positions,
        &indices,
        &prepared.light,
        eps
    ));
    common::assert_clean(&ctx.validation());
}

/// `plane-boxes` seen from above a corner of its ground on the light's side: the boxes and
/// spheres are in the scene but their shadows fall away from the view. Each triangle's plane has
/// view samples beyond it (the plane test alone proves nothing here); its shadow volume misses
/// every tile. Checked against the ray-cast reference: every view sample is lit there.
fn corner_view(light: &str) -> Scene {
    let mut scene = Scene::procedural(&format!("plane-boxes:6@{light}")).expect("scene");
    scene.camera.position = Vec3::new(-10.0, 5.0, 10.5);
    scene.camera.target = Vec3::new(-10.0, 0.0, 9.8);
    scene.camera.width = 128;
    scene.camera.height = 96;
    scene.name = format!("plane-boxes-corner@{light}");
    scene
}

#[test]
fn casters_whose_shadows_miss_the_view_cast_nothing_into_it() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    for light in ["rect", "point", "directional"] {
        let scene = corner_view(light);
        assert!(!gpu_and_twin(&scene), "{light}: a caster found");
        let prepared = engine.prepare(&scene).expect("prepare");
        let truth = engine
            .render(
                &prepared,
                "reference",
                &common::knobs(&[("samples", "4")]),
                1,
            )
            .expect("reference");
        let positions = prepared.view.read_positions(&ctx).expect("positions");
        let samples = positions.iter().filter(|p| p.w > 0.0).count();
        assert!(samples > 5000, "{light}: the ground fills the view");
        let lowest = truth
            .visibility
            .iter()
            .zip(&positions)
            .filter(|(_, p)| p.w > 0.0)
            .map(|(v, _)| *v)
            .fold(1.0f32, f32::min);
        assert_eq!(
            lowest, 1.0,
            "{light}: the reference sees a shadow in the view"
        );
        let mut r = engine
            .renderer(&prepared, "pcss", &common::knobs(&[]))
            .expect("renderer");
        r.render().expect("frame");
        assert_eq!(r.counters().expect("counters")["caster_skip"], 1, "{light}");
        assert_eq!(
            r.read_visibility().expect("read"),
            truth.visibility,
            "{light}"
        );
    }
    // The same scene seen from its usual camera: the boxes shadow the ground in view.
    let mut usual = Scene::procedural("plane-boxes:6@rect").expect("scene");
    usual.camera.width = 128;
    usual.camera.height = 96;
    assert!(gpu_and_twin(&usual));
    common::assert_clean(&ctx.validation());
}
