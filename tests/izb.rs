//! `izb` and `izb-soft` under validation: exactly the ray-cast reference with a point light
//! (bit for bit), exactly the reference's own light samples with a rect light or a sun disk, the
//! CPU twin's brute force over every triangle (so no footprint or back-projection ever drops a
//! blocker) and its binning, error falling with the sample count, monotone in added occluders,
//! a frame past its pair capacity grown and rendered again, and the corner cases (grazing plane
//! with a coarse grid, thin bars, an empty scene, a scene all in shadow).

mod common;

use common::counter;

use glam::{Mat4, Vec3};
use penumbra::cpu::izb::{self as twin, GridTwin, LightTwin};
use penumbra::reference::bvh::scene_scale;
use penumbra::scene::{shapes, Light, Mesh, Scene};
use penumbra::{Engine, Frame, PreparedScene};

fn render(
    engine: &Engine,
    prepared: &PreparedScene,
    technique: &str,
    set: &[(&str, &str)],
) -> Frame {
    let frame = engine
        .render(prepared, technique, &common::knobs(set), 1)
        .unwrap_or_else(|e| panic!("{technique} {set:?}: {e}"));
    assert_eq!(frame.stats.nan_count, 0);
    assert_eq!(frame.stats.out_of_range_count, 0);
    frame
}

/// Pixels whose visibility differs (bit for bit), writing a diff image when there are any.
fn differ(name: &str, a: &Frame, b: &Frame) -> usize {
    let n = a
        .visibility
        .iter()
        .zip(&b.visibility)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .count();
    if n > 0 {
        let dir = common::write_diff(name, a.width, a.height, &a.visibility, &b.visibility);
        eprintln!("{name}: {n} pixels differ, images in {}", dir.display());
    }
    n
}

#[test]
fn izb_equals_the_reference_with_point_lights() {
    let engine = common::engine();
    for spec in [
        "scenes/spot-point.toml",
        "plane-boxes:6@point",
        "thin-bars@point",
        "grazing-plane@point",
        "teapot-rect-as-point",
    ] {
        let mut scene = if spec == "teapot-rect-as-point" {
            let mut s = common::small("scenes/teapot-rect.toml");
            if let Light::Rect { position, .. } = s.light {
                s.light = Light::Point { position };
            }
            s
        } else {
            common::small(spec)
        };
        scene.camera.width = 192;
        scene.camera.height = 144;
        let prepared = engine.prepare(&scene).expect("prepare");
        let reference = render(&engine, &prepared, "reference", &[]);
        // 2048: the ground's two triangles take the huge-footprint path of the large pass.
        let grids: &[&str] = if spec.starts_with("scenes/spot") {
            &["2048", "128", "8"]
        } else {
            &["512", "64", "8"]
        };
        for &grid in grids {
            let izb = render(&engine, &prepared, "izb", &[("grid", grid)]);
            assert_eq!(
                differ(&format!("izb-{}-{grid}", scene.name), &reference, &izb),
                0,
                "{spec} grid {grid}"
            );
            assert!(counter(&izb, "samples_binned") > 0);
        }
    }
    common::assert_clean(&engine.context().validation());
}

#[test]
fn izb_soft_draws_the_references_light_samples() {
    let engine = common::engine();
    // The suns' 0.5° at 3°: penumbrae a few pixels wide at this size (the grazing plane's sun
    // then partly below its horizon); one at 40°, whose strata cull (disk_strata.glsl) meets
    // boxes over the whole disk, in every octant of the concentric map.
    for (spec, sun_deg) in [
        ("scenes/teapot-rect.toml", None),
        ("scenes/bunny-rect.toml", None),
        ("scenes/rocker-arm-directional.toml", Some(3.0)),
        ("thin-bars@directional", Some(3.0)),
        ("grazing-plane@directional", Some(3.0)),
        ("plane-boxes@directional", Some(40.0)),
    ] {
        let mut scene = common::small(spec);
        if let (
            Light::Directional {
                angular_diameter_deg,
                ..
            },
            Some(deg),
        ) = (&mut scene.light, sun_deg)
        {
            *angular_diameter_deg = deg;
        }
        scene.camera.width = 96;
        scene.camera.height = 72;
        let prepared = engine.prepare(&scene).expect("prepare");
        for jitter in ["0", "1"] {
            let reference = render(
                &engine,
                &prepared,
                "reference",
                &[("samples", "8"), ("jitter", jitter)],
            );
            let soft = render(
                &engine,
                &prepared,
                "izb-soft",
                &[("samples", "64"), ("jitter", jitter)],
            );
            assert_eq!(
                differ(
                    &format!("izb-soft-{}-{jitter}", scene.name),
                    &reference,
                    &soft
                ),
                0,
                "{spec} jitter {jitter}"
            );
            assert!(counter(&soft, "penumbra") > 0);
        }
    }
    common::assert_clean(&engine.context().validation());
}

/// A small scene of a few boxes over a plane: few enough triangles for the brute-force twin.
fn boxes(light: Light, extra: bool) -> Scene {
    let mut scene = common::bare_plane(light);
    let mut add = |size: Vec3, at: Vec3| {
        let (positions, indices) = shapes::cuboid(size);
        let m = Mat4::from_translation(at);
        scene.meshes.push(Mesh {
            name: "box".into(),
            positions: positions.iter().map(|&p| m.transform_point3(p)).collect(),
            indices,
        });
    };
    add(Vec3::new(1.5, 0.4, 1.0), Vec3::new(-0.5, 1.0, 0.0));
    add(Vec3::new(0.3, 2.0, 0.3), Vec3::new(1.2, 1.0, -0.6));
    if extra {
        add(Vec3::new(0.8, 0.2, 0.8), Vec3::new(0.3, 2.2, 0.8));
    }
    scene.camera.width = 64;
    scene.camera.height = 48;
    scene
}

fn rect_light() -> Light {
    Light::Rect {
        position: Vec3::new(0.5, 5.0, 0.5),
        u: Vec3::new(2.0, 0.0, 0.0),
        v: Vec3::new(0.0, 0.0, 1.2),
    }
}

/// A 12° sun, oblique: the boxes cast penumbrae several pixels wide.
fn sun_disk() -> Light {
    Light::Directional {
        direction: Vec3::new(0.4, -1.0, 0.2),
        angular_diameter_deg: 12.0,
    }
}

#[test]
fn izb_matches_its_cpu_twin() {
    let engine = common::engine();
    let lights = [
        (rect_light(), true, "32"),
        (rect_light(), true, "24"),
        (rect_light(), false, "1"),
        (
            Light::Point {
                position: Vec3::new(-1.0, 4.0, 1.0),
            },
            false,
            "1",
        ),
        (
            Light::Directional {
                direction: Vec3::new(0.4, -1.0, 0.2),
                angular_diameter_deg: 0.0,
            },
            false,
            "1",
        ),
        // A sun disk: izb-soft's light samples are directions (the concentric map).
        (sun_disk(), true, "32"),
        (sun_disk(), true, "48"),
    ];
    for (light, soft, samples) in lights {
        let scene = boxes(light, false);
        let prepared = engine.prepare(&scene).expect("prepare");
        let ctx = engine.context();
        let positions = prepared.view.read_positions(ctx).expect("positions");
        let normals = prepared.view.read_normals(ctx).expect("normals");
        let scale = scene_scale(&prepared.positions);
        let offset = scale / 65536.0;
        let lt = LightTwin::new(&light, soft, samples.parse().unwrap(), true, scale);
        let b = &prepared.receiver_bounds;
        let grid = GridTwin::new(prepared.light_view.view, b.min, b.max, 32, b.perspective);
        let binning = twin::bin(&grid, &lt, &positions, &normals, offset);
        let expected = twin::visibility(
            &lt,
            &positions,
            &normals,
            &prepared.positions,
            &prepared.indices,
            offset,
        );
        let (technique, set) = if soft {
            ("izb-soft", vec![("grid", "32"), ("samples", samples)])
        } else {
            // The twin is the technique's own test; the engine's light clipping after it has
            // its own twin (src/cpu/receivers.rs).
            ("izb", vec![("grid", "32"), ("light_clip", "0")])
        };
        // Both test passes: triangles eight at a time by subgroup shuffles (where the device
        // has them) and one at a time — the same tests in the same order, so the same counts.
        let mut tests_made = Vec::new();
        for batch in ["1", "0"] {
            let mut set = set.clone();
            set.push(("triangle_batch", batch));
            let frame = render(&engine, &prepared, technique, &set);
            tests_made.push((
                counter(&frame, "sample_tests"),
                counter(&frame, "ray_tests"),
            ));
            let name = format!(
                "izb-twin-{technique}-{samples}-{}-batch{batch}",
                scene.light_kind_name()
            );
            let mismatched: Vec<(f32, f32)> = expected
                .iter()
                .zip(&frame.visibility)
                .filter(|(e, a)| e.to_bits() != a.to_bits())
                .map(|(&e, &a)| (e, a))
                .collect();
            if !mismatched.is_empty() {
                common::write_diff(&name, 64, 48, &expected, &frame.visibility);
            }
            // A sun's light samples go through cos and sin, Rust's on the CPU and the driver's
            // on the GPU (src/cpu/izb.rs, "Tolerance"): at most 1 % of the pixels, each one
            // light sample apart. Everything else: bit for bit.
            let sun = matches!(light, Light::Directional { .. }) && soft;
            if soft {
                assert!(
                    counter(&frame, "penumbra") > 0,
                    "{name}: no penumbra to test"
                );
            }
            let one_sample = 1.0 / samples.parse::<f32>().unwrap() + 1e-6;
            let allowed = if sun { 64 * 48 / 100 } else { 0 };
            assert!(
                mismatched.len() <= allowed
                    && mismatched.iter().all(|(e, a)| (e - a).abs() <= one_sample),
                "{name}: visibility differs from the brute-force twin at {} pixels (allowed \
                 {allowed} one light sample apart): {:?}",
                mismatched.len(),
                &mismatched[..mismatched.len().min(8)]
            );
            assert_eq!(
                counter(&frame, "view_samples"),
                binning.view_samples,
                "{name}"
            );
            assert_eq!(
                counter(&frame, "behind_tangent_plane"),
                binning.behind,
                "{name}"
            );
            assert_eq!(counter(&frame, "samples_binned"), binning.binned, "{name}");
            assert_eq!(
                counter(&frame, "overflow_samples"),
                binning.overflow,
                "{name}"
            );
            // Cell borders may round the other way for a sample within an ulp of one.
            let used = counter(&frame, "cells_used") as i64;
            assert!(
                (used - binning.cells_used() as i64).abs() <= 2,
                "{name}: cells used {used} vs {}",
                binning.cells_used()
            );
            let longest = counter(&frame, "longest_cell") as i64;
            assert!(
                (longest - binning.longest() as i64).abs() <= 2,
                "{name}: longest {longest} vs {}",
                binning.longest()
            );
        }
        assert_eq!(
            tests_made[0], tests_made[1],
            "{technique} {samples}: (sample tests, ray tests) batched vs one at a time"
        );
    }
    common::assert_clean(&engine.context().validation());
}

trait LightName {
    fn light_kind_name(&self) -> &'static str;
}

impl LightName for Scene {
    fn light_kind_name(&self) -> &'static str {
        match self.light {
            Light::Point { .. } => "point",
            Light::Rect { .. } => "rect",
            Light::Directional { .. } => "sun",
        }
    }
}

/// With nothing to sample (a point light, a hard sun, a rect of zero extent) `izb-soft` runs
/// `izb`'s test: the same visibility bit for bit.
#[test]
fn izb_soft_without_an_area_light_is_izb() {
    let engine = common::engine();
    let lights = [
        Light::Point {
            position: Vec3::new(-1.0, 4.0, 1.0),
        },
        Light::Directional {
            direction: Vec3::new(0.4, -1.0, 0.2),
            angular_diameter_deg: 0.0,
        },
        Light::Rect {
            position: Vec3::new(0.5, 5.0, 0.5),
            u: Vec3::ZERO,
            v: Vec3::ZERO,
        },
    ];
    for light in lights {
        let scene = boxes(light, false);
        let prepared = engine.prepare(&scene).expect("prepare");
        let hard = render(&engine, &prepared, "izb", &[]);
        let soft = render(&engine, &prepared, "izb-soft", &[]);
        let name = format!("izb-soft-as-izb-{}", scene.light_kind_name());
        assert_eq!(differ(&name, &hard, &soft), 0, "{name}");
        assert!(counter(&soft, "umbra") > 0, "{name}: no shadow to compare");
    }
    common::assert_clean(&engine.context().validation());
}

#[test]
fn izb_soft_error_falls_with_samples() {
    let engine = common::engine();
    let mut scene = common::small("scenes/teapot-rect.toml");
    scene.camera.width = 96;
    scene.camera.height = 72;
    let prepared = engine.prepare(&scene).expect("prepare");
    let reference = render(&engine, &prepared, "reference", &[("samples", "32")]);
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    let mut errors = Vec::new();
    for samples in ["32", "128", "512", "1024"] {
        let soft = render(&engine, &prepared, "izb-soft", &[("samples", samples)]);
        let is_sample: Vec<bool> = positions.iter().map(|p| p.w > 0.0).collect();
        let m = penumbra::metrics::compare(&reference.visibility, &soft.visibility, &is_sample)
            .expect("compare");
        errors.push(m.penumbra_mae.expect("penumbra"));
    }
    eprintln!("penumbra MAE at 32, 128, 512, 1024 samples: {errors:?}");
    for w in errors.windows(2) {
        assert!(w[1] < w[0] * 1.02, "error grew with samples: {errors:?}");
    }
    assert!(errors[3] < 0.5 * errors[0], "{errors:?}");
    assert!(errors[0] <= 0.04, "{errors:?}");
    common::assert_clean(&engine.context().validation());
}

#[test]
fn adding_an_occluder_never_brightens() {
    let engine = common::engine();
    for (technique, set) in [("izb", vec![]), ("izb-soft", vec![("samples", "64")])] {
        let a = engine
            .prepare(&boxes(rect_light(), false))
            .expect("prepare");
        let b = engine.prepare(&boxes(rect_light(), true)).expect("prepare");
        let fa = render(&engine, &a, technique, &set);
        let fb = render(&engine, &b, technique, &set);
        // Only the samples both scenes share: the new box hides some of the plane.
        let pa = a.view.read_positions(engine.context()).expect("positions");
        let pb = b.view.read_positions(engine.context()).expect("positions");
        let brighter = fa
            .visibility
            .iter()
            .zip(&fb.visibility)
            .zip(pa.iter().zip(&pb))
            .filter(|((va, vb), (p, q))| p.w > 0.0 && p == q && vb > va)
            .count();
        assert_eq!(
            brighter, 0,
            "{technique}: an added occluder brightened {brighter} samples"
        );
        let darker = fa
            .visibility
            .iter()
            .zip(&fb.visibility)
            .filter(|(va, vb)| vb < va)
            .count();
        assert!(darker > 0, "{technique}: the added occluder casts nothing");
    }
    common::assert_clean(&engine.context().validation());
}

#[test]
fn empty_and_fully_shadowed_scenes() {
    let engine = common::engine();
    // A plane alone: nothing casts, every sample facing the light is lit.
    let plane = common::bare_plane(rect_light());
    let prepared = engine.prepare(&plane).expect("prepare");
    for technique in ["izb", "izb-soft"] {
        // The technique itself (the caster skip would answer without it).
        let f = render(&engine, &prepared, technique, &[("caster_skip", "0")]);
        assert_eq!(
            counter(&f, "umbra") + counter(&f, "penumbra"),
            0,
            "{technique}"
        );
        // The plane lies at its own samples' depth: culled, it takes no pair.
        assert_eq!(counter(&f, "pairs"), 0, "{technique}");
        assert!(f.visibility.iter().all(|&v| v == 1.0), "{technique}");
        // With the skip (the default) the same image, and no pair at all.
        let skipped = render(&engine, &prepared, technique, &[]);
        assert_eq!(counter(&skipped, "caster_skip"), 1, "{technique}");
        assert_eq!(skipped.visibility, f.visibility, "{technique}");
    }
    // A wide slab between the light and the plane: everything in umbra.
    let mut covered = common::bare_plane(rect_light());
    let (positions, indices) = shapes::cuboid(Vec3::new(40.0, 0.2, 40.0));
    let m = Mat4::from_translation(Vec3::new(0.0, 3.0, 0.0));
    covered.meshes.push(Mesh {
        name: "slab".into(),
        positions: positions.iter().map(|&p| m.transform_point3(p)).collect(),
        indices,
    });
    // The camera under the slab, looking at the plane.
    covered.camera.position = Vec3::new(0.0, 2.0, 2.0);
    let prepared = engine.prepare(&covered).expect("prepare");
    for technique in ["izb", "izb-soft"] {
        let f = render(&engine, &prepared, technique, &[]);
        assert_eq!(
            counter(&f, "lit") + counter(&f, "penumbra"),
            0,
            "{technique}"
        );
    }
    common::assert_clean(&engine.context().validation());
}

/// A frame that counts more (triangle, cell) pairs than `pair_capacity` holds is rendered again
/// with room for them: the image of a roomy build bit for bit, the same pairs, the knob grown
/// in the frame's stats (what the bench's rows show). The count is the cells' lists' total.
#[test]
fn pairs_past_the_capacity_grow_it() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&boxes(rect_light(), false))
        .expect("prepare");
    let ctx = engine.context().clone();
    for technique in ["izb", "izb-soft"] {
        // The pairs counted (in 64 bits, per invocation of the args pass) are the cells' lists'.
        let mut listed = 0u64;
        let roomy = engine
            .render_inspect(&prepared, technique, &common::knobs(&[]), 1, |t| {
                listed = common::read_named_words(&ctx, t, "cell_triangles")?
                    .iter()
                    .map(|&n| u64::from(n))
                    .sum();
                Ok(())
            })
            .expect(technique);
        let pairs = counter(&roomy, "pairs");
        assert!(pairs > 1, "{technique}: {pairs} pairs");
        assert_eq!(
            listed, pairs,
            "{technique}: the cells' lists against the count"
        );
        let tight = render(
            &engine,
            &prepared,
            technique,
            &[("pair_capacity", "0.000001")],
        );
        assert_eq!(differ(&format!("{technique}-grown"), &roomy, &tight), 0);
        assert_eq!(counter(&tight, "pairs"), pairs, "{technique}");
        let grown = tight.stats.params["pair_capacity"];
        assert!(
            grown * 1e6 >= pairs as f64,
            "{technique}: {grown} for {pairs}"
        );
    }
    common::assert_clean(&engine.context().validation());
}

#[test]
fn bad_input_gives_clear_errors() {
    let engine = common::engine();
    let mut scene = common::bare_plane(Light::Directional {
        direction: Vec3::new(0.0, -1.0, 0.2),
        angular_diameter_deg: 2.0,
    });
    scene.camera.width = 32;
    scene.camera.height = 24;
    let prepared = engine.prepare(&scene).expect("prepare");
    // Both take a sun disk: the hard variant its centre direction, the soft one its light
    // samples over the disk.
    render(&engine, &prepared, "izb", &[]);
    render(&engine, &prepared, "izb-soft", &[]);
    for (knob, value) in [
        ("grid", "4"),
        ("grid", "100000"),
        ("samples", "0"),
        ("samples", "2048"),
    ] {
        let err = engine
            .render(
                &prepared,
                if knob == "samples" { "izb-soft" } else { "izb" },
                &common::knobs(&[(knob, value)]),
                1,
            )
            .err()
            .unwrap_or_else(|| panic!("{knob}={value} accepted"));
        assert!(err.to_string().contains(knob), "{err}");
    }
    // izb-soft's grid: 0 (its default) picks 64 cells with a rect light; 1-7 are refused.
    let prepared = engine
        .prepare(&boxes(rect_light(), false))
        .expect("prepare");
    let auto = render(&engine, &prepared, "izb-soft", &[]);
    let explicit = render(&engine, &prepared, "izb-soft", &[("grid", "64")]);
    assert_eq!(differ("izb-soft-grid-auto", &auto, &explicit), 0);
    assert_eq!(counter(&auto, "pairs"), counter(&explicit, "pairs"));
    let err = engine
        .render(&prepared, "izb-soft", &common::knobs(&[("grid", "4")]), 1)
        .err()
        .expect("izb-soft grid=4 accepted");
    assert!(err.to_string().contains("grid"), "{err}");
    common::assert_clean(&engine.context().validation());
}
