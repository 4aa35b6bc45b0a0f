//! The ray-cast reference against geometry worked out by hand: the closed forms of the
//! parallel-plane and sun-edge penumbrae, no acne on unoccluded surfaces, no light through
//! closed boxes. Images are small (≤ 96 × 72) and soft lights use N ≤ 8.

mod common;

use glam::{Mat4, Vec3};
use penumbra::scene::{shapes, Light};

use common::reference::{at, camera, knobs, mesh, render, samples_of, scene};

#[test]
fn parallel_planes_match_the_closed_form() {
    // Square occluder (side 4, edge at x = 2) at height 1 over a receiver at 0, under a parallel
    // square light of side L = 1 at height 4. Along x the penumbra is linear, centred where the
    // light's centre sees the edge, of width L · gap / (light height − occluder height).
    let (edge, h_occ, h_light, size) = (2.0f32, 1.0f32, 4.0f32, 1.0f32);
    let width = size * h_occ / (h_light - h_occ);
    let centre = edge * h_light / (h_light - h_occ);
    let exact = |x: f32| (0.5 + (x - centre) / width).clamp(0.0, 1.0);
    // The camera sits between receiver and occluder, looking straight down at the penumbra.
    let s = scene(
        "parallel-planes",
        vec![
            mesh("receiver", shapes::plane(20.0, 20.0, 1), Mat4::IDENTITY),
            mesh("occluder", shapes::plane(4.0, 4.0, 1), at(0.0, h_occ, 0.0)),
        ],
        camera([centre, 0.5, 0.0], [centre, 0.0, 0.0], Vec3::Z, 60.0),
        Light::Rect {
            position: Vec3::new(0.0, h_light, 0.0),
            u: Vec3::X * size,
            v: Vec3::Z * size,
        },
    );
    let engine = common::engine();
    let prepared = engine.prepare(&s).expect("prepare");
    let (positions, _) = samples_of(&engine, &prepared);
    let n = 8u32;
    for jitter in [1, 0] {
        let frame = engine
            .render(&prepared, "reference", &knobs(n, jitter), 1)
            .expect("render");
        // Jittered, the one column of light cells that straddles the edge is off by up to N
        // cells (1/N); at cell centres the staircase is off by at most half a column (1/2N).
        let bound = if jitter == 1 {
            1.0 / n as f32
        } else {
            0.5 / n as f32
        } + 1e-3;
        let (mut worst, mut sum_err, mut count) = (0.0f32, 0.0f32, 0);
        // Least-squares slope of V against x over the inner penumbra: 1 / width.
        let (mut m, mut sx, mut sv, mut sxx, mut sxv) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for (p, &v) in positions.iter().zip(&frame.visibility) {
            if p.w <= 0.0 {
                continue;
            }
            let e = exact(p.x);
            worst = worst.max((v - e).abs());
            if e > 0.0 && e < 1.0 {
                sum_err += (v - e).abs();
                count += 1;
            }
            if e > 0.1 && e < 0.9 {
                let (x, v) = (f64::from(p.x), f64::from(v));
                (m, sx, sv) = (m + 1.0, sx + x, sv + v);
                (sxx, sxv) = (sxx + x * x, sxv + x * v);
            }
        }
        assert!(count > 500, "too few penumbra samples: {count}");
        let slope = (m * sxv - sx * sv) / (m * sxx - sx * sx);
        let fitted = (1.0 / slope) as f32;
        eprintln!(
            "jitter {jitter}: max |V − exact| {worst}, mean {}, width {fitted} vs {width}",
            sum_err / count as f32
        );
        assert!(worst <= bound, "max error {worst} > {bound}");
        assert!(
            (fitted - width).abs() < 0.03 * width,
            "penumbra width {fitted} ≠ {width}"
        );
        if jitter == 1 {
            assert!(
                sum_err / (count as f32) < 0.3 / n as f32,
                "jitter does not average"
            );
        }
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn unoccluded_plane_and_sphere_are_fully_lit() {
    let engine = common::engine();
    // A tessellated plane seen from above, lit from grazing to steep.
    let plane = scene(
        "plane",
        vec![mesh("plane", shapes::plane(16.0, 16.0, 8), Mat4::IDENTITY)],
        camera([1.0, 6.0, 9.0], [0.0; 3], Vec3::Y, 50.0),
        Light::Point {
            position: Vec3::new(-3.0, 5.0, 2.0),
        },
    );
    let mut prepared = engine.prepare(&plane).expect("prepare");
    let key = |deg: f32| Vec3::new(-deg.to_radians().sin(), deg.to_radians().cos(), 0.3);
    let lights = [
        plane.light,
        Light::Rect {
            position: Vec3::new(2.0, 3.0, -1.0),
            u: Vec3::new(2.0, 0.5, 0.0),
            v: Vec3::new(0.0, 0.3, 2.0),
        },
        Light::Directional {
            direction: -key(89.5),
            angular_diameter_deg: 0.0,
        },
        Light::Directional {
            direction: -key(85.0),
            angular_diameter_deg: 0.5,
        },
        Light::Point {
            position: Vec3::new(40.0, 0.2, 0.0),
        },
    ];
    for light in lights {
        prepared.light = light;
        let frame = render(&engine, &prepared, "reference", 4);
        let (positions, _) = samples_of(&engine, &prepared);
        for (p, v) in positions.iter().zip(&frame.visibility) {
            assert!(
                p.w <= 0.0 || *v == 1.0,
                "acne on the plane under {light:?}: V = {v} at {p}"
            );
        }
        assert_eq!(
            frame.stats.counters["lit"],
            frame.stats.counters["view_samples"]
        );
    }
    drop(prepared);

    // A lone sphere: every sample that faces the light sees all of it, every other sees none.
    let centre = Vec3::new(2.5, 2.0, 2.0);
    let sphere = scene(
        "sphere",
        vec![mesh("sphere", shapes::sphere(1.0, 48), Mat4::IDENTITY)],
        camera([0.5, 0.8, 4.0], [0.0; 3], Vec3::Y, 40.0),
        Light::Point { position: centre },
    );
    let mut prepared = engine.prepare(&sphere).expect("prepare");
    let (positions, normals) = samples_of(&engine, &prepared);
    let corners = [(-0.5f32, -0.5f32), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)];
    let (u, v) = (Vec3::new(0.6, 0.0, -0.3), Vec3::new(0.0, 0.6, 0.0));
    for light in [
        sphere.light,
        Light::Rect {
            position: centre,
            u,
            v,
        },
    ] {
        prepared.light = light;
        let frame = render(&engine, &prepared, "reference", 4);
        let mut lit = 0;
        for ((p, n), &vis) in positions.iter().zip(&normals).zip(&frame.visibility) {
            if p.w <= 0.0 {
                continue;
            }
            let (p, n) = (p.truncate(), n.truncate());
            let faces = |s: Vec3| n.dot(s - p) > 1e-5 * (s - p).length();
            let all = match light {
                Light::Rect { .. } => corners.iter().all(|(a, b)| faces(centre + u * *a + v * *b)),
                _ => faces(centre),
            };
            if all {
                assert_eq!(vis, 1.0, "acne on the sphere at {p} under {light:?}");
                lit += 1;
            }
            if !faces(centre) && matches!(light, Light::Point { .. }) {
                assert_eq!(vis, 0.0, "light through the sphere at {p}");
            }
        }
        assert!(lit > 500, "too few lit sphere samples: {lit}");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn closed_boxes_do_not_leak() {
    let engine = common::engine();
    // Inside a closed box nothing is lit, whatever the light outside.
    let inside = scene(
        "inside-box",
        vec![mesh(
            "box",
            shapes::cuboid(Vec3::splat(4.0)),
            Mat4::IDENTITY,
        )],
        camera([-0.5, -0.3, -0.4], [1.0, 0.6, 1.5], Vec3::Y, 100.0),
        Light::Point {
            position: Vec3::new(3.0, 8.0, 5.0),
        },
    );
    let mut prepared = engine.prepare(&inside).expect("prepare");
    let lights = [
        inside.light,
        Light::Rect {
            position: Vec3::new(0.0, 6.0, 0.0),
            u: Vec3::X * 3.0,
            v: Vec3::Z * 3.0,
        },
        Light::Directional {
            direction: Vec3::new(0.3, -1.0, 0.2),
            angular_diameter_deg: 2.0,
        },
    ];
    for light in lights {
        prepared.light = light;
        let frame = render(&engine, &prepared, "reference", 4);
        assert_eq!(
            frame.stats.counters["view_samples"],
            96 * 64,
            "the walls fill the view"
        );
        assert_eq!(
            frame.stats.counters["umbra"],
            96 * 64,
            "light leaks in under {light:?}"
        );
    }
    drop(prepared);

    // A box on the ground under a point light right above its centre: rays through the top
    // face's diagonal and edges must not slip through. Umbra: |x|, |z| < 1.25 (similar triangles).
    let on_ground = scene(
        "box-on-ground",
        vec![
            mesh("ground", shapes::plane(10.0, 10.0, 1), Mat4::IDENTITY),
            mesh(
                "box",
                shapes::cuboid(Vec3::new(2.0, 1.0, 2.0)),
                at(0.0, 0.5, 0.0),
            ),
        ],
        camera([0.4, 6.0, 3.0], [0.0; 3], Vec3::Y, 45.0),
        Light::Point {
            position: Vec3::new(0.0, 5.0, 0.0),
        },
    );
    let prepared = engine.prepare(&on_ground).expect("prepare");
    let frame = render(&engine, &prepared, "reference", 1);
    let (positions, _) = samples_of(&engine, &prepared);
    let (mut umbra, mut lit) = (0, 0);
    for (p, &v) in positions.iter().zip(&frame.visibility) {
        if p.w <= 0.0 || p.y.abs() > 1e-4 {
            continue;
        }
        let r = p.x.abs().max(p.z.abs());
        if r < 1.25 - 0.01 {
            assert_eq!(v, 0.0, "light leaks through the box to {p}");
            umbra += 1;
        } else if r > 1.25 + 0.01 {
            assert_eq!(v, 1.0, "spurious shadow at {p}");
            lit += 1;
        }
    }
    assert!(umbra > 100 && lit > 1000, "umbra {umbra}, lit {lit}");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// The sun's half-angle, checked by geometry alone. A sun overhead of angular radius α
/// (tan α = r) shines on a receiver at y = 0 past a half-plane occluder x < 0 at height h. The
/// shader spreads the sun's samples uniformly (area-preserving concentric map) over the disk of
/// radius r in the plane tangent to the unit sphere at the sun's centre, so a receiver at x sees
/// the part of that disk with X ≥ t = −x / (h·r): V = (acos t − t·√(1 − t²)) / π — one half on
/// the edge's shadow line x = 0, a penumbra 2hr wide.
#[test]
fn sun_past_a_straight_edge_matches_the_closed_form() {
    let (h, diameter) = (2.0f64, 20.0f32);
    let r = (f64::from(diameter) / 2.0).to_radians().tan();
    let exact = |x: f64| {
        let t = (-x / (h * r)).clamp(-1.0, 1.0);
        (t.acos() - t * (1.0 - t * t).sqrt()) / std::f64::consts::PI
    };
    let s = scene(
        "sun-edge",
        vec![
            mesh("receiver", shapes::plane(20.0, 20.0, 1), Mat4::IDENTITY),
            // 10 × 10 at x ∈ [−10, 0]: its edge is the line x = 0, y = h.
            mesh(
                "occluder",
                shapes::plane(10.0, 10.0, 1),
                at(-5.0, h as f32, 0.0),
            ),
        ],
        // Between receiver and occluder, looking down at the penumbra (|x| ≤ hr ≈ 0.35).
        camera([0.0, 1.0, 0.0], [0.0; 3], Vec3::Z, 60.0),
        Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: diameter,
        },
    );
    let engine = common::engine();
    let prepared = engine.prepare(&s).expect("prepare");
    let (positions, _) = samples_of(&engine, &prepared);
    let n = 8u32;
    let frame = render(&engine, &prepared, "reference", n);
    let (mut worst, mut sum_err, mut count) = (0.0f64, 0.0f64, 0);
    let (mut line_sum, mut line_count) = (0.0f64, 0);
    for (p, &v) in positions.iter().zip(&frame.visibility) {
        if p.w <= 0.0 {
            continue;
        }
        let (x, v) = (f64::from(p.x), f64::from(v));
        let e = exact(x);
        worst = worst.max((v - e).abs());
        if e > 0.0 && e < 1.0 {
            sum_err += (v - e).abs();
            count += 1;
        }
        if x.abs() < 0.01 {
            line_sum += v;
            line_count += 1;
        }
    }
    let (mean, on_line) = (sum_err / f64::from(count), line_sum / f64::from(line_count));
    eprintln!(
        "sun edge: max |V − exact| {worst}, mean {mean} over {count}; V on the line {on_line} \
         over {line_count}"
    );
    assert!(count > 2000, "too few penumbra samples: {count}");
    assert!(line_count > 50, "too few samples on the shadow line");
    // Jittered strata: the chord through the disk crosses about N of the N² cells, each off by
    // up to 1/N² (measured at N = 8: max 0.067, mean 0.014, 0.499 on the line). A sun of the
    // full angle as its radius would double the penumbra (errors near 0.2).
    let nf = f64::from(n);
    assert!(worst <= 1.0 / nf, "max error {worst} > 1/N");
    assert!(
        mean < 0.3 / nf,
        "mean error {mean}: jitter does not average"
    );
    assert!(
        (on_line - 0.5).abs() < 0.02,
        "V on the shadow line {on_line}"
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
