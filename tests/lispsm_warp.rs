//! `lispsm`'s warp on the CPU (`penumbra::passes::lispsm::warp` on hand-built light views,
//! cameras and receiver bounds; book §4.2): as `n_scale` grows the texel coordinates converge to
//! an affine map in the warp's orientation with an error falling like 1/n; a viewer looking along
//! the light (either way) gets the base view unchanged; at n_opt the perspective error m̃_t of an
//! overhead light is the same on the warp's near and far planes (Eq. 4.15), and not for
//! n ≠ n_opt; every body corner lands inside clip space with w > 0; a caster between the light and
//! a receiver lands on the receiver's texel, nearer; bad inputs are errors and random
//! configurations stay finite. The technique on the GPU: `tests/lispsm.rs`.

use glam::{Mat4, Vec2, Vec3, Vec4};
use penumbra::passes::lispsm::{warp, Fallback, Warped, MIN_SIN_GAMMA};
use penumbra::passes::{LightProjection, LightView, ReceiverBounds};
use penumbra::scene::{Aabb, Camera, Light};

/// Texel units of the CPU checks: a 1024² map.
const SIZE: f32 = 1024.0;

/// Clip coordinates of a world point.
fn clip(m: Mat4, p: Vec3) -> Vec4 {
    m * p.extend(1.0)
}

/// (texel x, texel y, depth) of a world point, as `shadow_coord` computes them; panics when
/// w ≤ 0.
fn texel(m: Mat4, p: Vec3) -> Vec3 {
    let c = clip(m, p);
    assert!(c.w > 0.0, "w = {} at {p}", c.w);
    let n = c.truncate() / c.w;
    Vec3::new((n.x * 0.5 + 0.5) * SIZE, (n.y * 0.5 + 0.5) * SIZE, n.z)
}

fn camera(position: Vec3, target: Vec3) -> Camera {
    let forward = (target - position).normalize();
    let up = if forward.y.abs() > 0.9 {
        Vec3::Z
    } else {
        Vec3::Y
    };
    Camera {
        position,
        target,
        up,
        fov_y_deg: 60.0,
        width: 512,
        height: 384,
        near: 0.1,
        far: 200.0,
    }
}

fn sun(direction: Vec3) -> Light {
    Light::Directional {
        direction: direction.normalize(),
        angular_diameter_deg: 0.0,
    }
}

/// The corners of `b`.
fn corners(b: &Aabb) -> Vec<Vec3> {
    (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            )
        })
        .collect()
}

/// Receiver bounds of the world points `points` in `view`'s view space, computed here as the
/// receiver-bounds pass defines them: `(x, y, −z)` orthographic, `(x/−z, y/−z, −z)` perspective.
fn bounds_of(view: &LightView, points: &[Vec3]) -> ReceiverBounds {
    let perspective = matches!(view.projection, LightProjection::Perspective { .. });
    let mut b = ReceiverBounds::empty(perspective);
    for p in points {
        let v = view.view.transform_point3(*p);
        let d = -v.z;
        let q = if perspective {
            Vec3::new(v.x / d, v.y / d, d)
        } else {
            Vec3::new(v.x, v.y, d)
        };
        b.min = b.min.min(q);
        b.max = b.max.max(q);
        b.receivers += 1;
    }
    b
}

/// A grid of points over a receiver box, each corner and `n`³ interior points.
fn grid(b: &Aabb, n: usize) -> Vec<Vec3> {
    let mut points = corners(b);
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let f = |x: usize| (x as f32 + 0.5) / n as f32;
                points.push(b.min + (b.max - b.min) * Vec3::new(f(i), f(j), f(k)));
            }
        }
    }
    points
}

/// The body as the test builds it: the receiver bounds' corners in world space, and the same
/// cross-section moved to the base view's near plane (the casters' end; just behind it).
fn body_corners(view: &LightView, r: &ReceiverBounds) -> Vec<Vec3> {
    let inverse = view.view.inverse();
    let perspective = r.perspective;
    let mut out = Vec::new();
    for i in 0..4 {
        let x = if i & 1 == 0 { r.min.x } else { r.max.x };
        let y = if i & 2 == 0 { r.min.y } else { r.max.y };
        // Just behind the near plane: a point light's near plane can be 1e-4 of its far one,
        // where f32 depth is coarse (NDC z of a point on it rounds to ±1e-4 either way).
        for d in [view.near * 1.001, r.min.z, r.max.z] {
            let v = if perspective {
                Vec3::new(x * d, y * d, -d)
            } else {
                Vec3::new(x, y, -d)
            };
            out.push(inverse.transform_point3(v));
        }
    }
    out
}

/// One configuration: a light view fitted to `scene`, the receivers' box and a camera.
struct Setup {
    base: LightView,
    receivers: ReceiverBounds,
    receiver_points: Vec<Vec3>,
    camera: Camera,
    light: Light,
}

fn setup(light: Light, scene: Aabb, receivers: Aabb, camera: Camera, fit_view: bool) -> Setup {
    let fit = LightView::fit(&light, &scene).expect("fit");
    let receiver_points = grid(&receivers, 4);
    let bounds = bounds_of(&fit, &receiver_points);
    let base = if fit_view {
        LightView::fit_to_receivers(&light, &scene, &bounds).expect("receiver fit")
    } else {
        fit
    };
    Setup {
        base,
        receivers: bounds,
        receiver_points,
        camera,
        light,
    }
}

fn ground_scene() -> Aabb {
    Aabb {
        min: Vec3::new(-30.0, 0.0, -80.0),
        max: Vec3::new(30.0, 4.0, 10.0),
    }
}

/// A few configurations: tilted and overhead suns, a point light, receiver-fitted and
/// scene-fitted base views.
fn configurations() -> Vec<(&'static str, Setup)> {
    let scene = ground_scene();
    let receivers = Aabb {
        min: Vec3::new(-12.0, 0.0, -60.0),
        max: Vec3::new(12.0, 2.0, -2.0),
    };
    let eye = camera(Vec3::new(1.0, 3.0, 2.0), Vec3::new(0.0, 0.0, -20.0));
    vec![
        (
            "tilted sun, view fit",
            setup(sun(Vec3::new(0.4, -1.0, 0.3)), scene, receivers, eye, true),
        ),
        (
            "tilted sun from behind, scene fit",
            setup(
                sun(Vec3::new(0.2, -0.6, -1.0)),
                scene,
                receivers,
                eye,
                false,
            ),
        ),
        (
            "overhead sun",
            setup(sun(Vec3::NEG_Y), scene, receivers, eye, true),
        ),
        (
            "point light, view fit",
            setup(
                Light::Point {
                    position: Vec3::new(8.0, 60.0, -10.0),
                },
                scene,
                receivers,
                eye,
                true,
            ),
        ),
        (
            "point light, scene fit",
            setup(
                Light::Point {
                    position: Vec3::new(-5.0, 50.0, 15.0),
                },
                scene,
                receivers,
                eye,
                false,
            ),
        ),
    ]
}

fn run(s: &Setup, n_scale: f32) -> Warped {
    warp(&s.base, &s.camera, &s.receivers, n_scale).expect("warp")
}

#[test]
fn body_corners_map_inside_clip_space() {
    for (name, s) in configurations() {
        for n_scale in [0.05, 0.3, 1.0, 4.0, 1e6] {
            let w = run(&s, n_scale);
            assert_eq!(w.info.fallback, None, "{name}: {:?}", w.info);
            assert!(w.view.view_proj.is_finite());
            for p in body_corners(&s.base, &s.receivers) {
                let c = clip(w.view.view_proj, p);
                assert!(c.w > 0.0, "{name} n_scale {n_scale}: w = {} at {p}", c.w);
                let n = c.truncate() / c.w;
                let eps = 1e-4;
                assert!(
                    n.x.abs() <= 1.0 + eps && n.y.abs() <= 1.0 + eps,
                    "{name} n_scale {n_scale}: corner {p} at NDC {n}"
                );
                assert!(
                    (-eps..=1.0 + eps).contains(&n.z),
                    "{name} n_scale {n_scale}: corner {p} at depth {}",
                    n.z
                );
            }
        }
    }
}

#[test]
fn a_caster_lands_on_its_receivers_texel_nearer() {
    for (name, s) in configurations() {
        for n_scale in [0.1, 1.0, 10.0] {
            let w = run(&s, n_scale);
            let m = w.view.view_proj;
            for &p in &s.receiver_points {
                let towards_light = match s.light {
                    Light::Directional { direction, .. } => -direction,
                    _ => (s.base.origin - p).normalize(),
                };
                // Up to the base near plane along the ray (the body's caster end).
                let depth = (p - s.base.origin).dot(s.base.direction);
                let reach = match s.light {
                    Light::Directional { .. } => depth - s.base.near,
                    _ => (p - s.base.origin).length() * (1.0 - s.base.near / depth),
                };
                let r = texel(m, p);
                for f in [0.05, 0.5, 0.95] {
                    let q = p + towards_light * reach * f;
                    let c = texel(m, q);
                    let moved = Vec2::new(c.x - r.x, c.y - r.y).length();
                    assert!(
                        moved < 1e-2,
                        "{name} n_scale {n_scale}: caster {q} lands {moved} texels from {p}"
                    );
                    assert!(
                        c.z < r.z,
                        "{name} n_scale {n_scale}: caster depth {} not < receiver's {}",
                        c.z,
                        r.z
                    );
                }
            }
        }
    }
}

/// A sun, the camera looking along its rays (light behind the viewer), into it, and within
/// MIN_SIN_GAMMA of either: the base view itself.
#[test]
fn viewing_along_the_light_is_the_uniform_map() {
    let scene = ground_scene();
    let receivers = Aabb {
        min: Vec3::new(-10.0, 0.0, -20.0),
        max: Vec3::new(10.0, 1.0, 0.0),
    };
    let direction = Vec3::new(0.3, -1.0, 0.2).normalize();
    let centre = Vec3::new(0.0, 0.5, -10.0);
    let (t, _) = direction.any_orthonormal_pair();
    let almost = (0.5 * MIN_SIN_GAMMA).asin();
    let cases = [
        ("light behind the viewer", direction),
        ("looking into the light", -direction),
        (
            "light behind, just off axis",
            direction * almost.cos() + t * almost.sin(),
        ),
        (
            "into the light, just off axis",
            -direction * almost.cos() + t * almost.sin(),
        ),
    ];
    for (name, forward) in cases {
        let eye = camera(centre - forward * 30.0, centre);
        for fit_view in [true, false] {
            let s = setup(sun(direction), scene, receivers, eye, fit_view);
            let w = run(&s, 1.0);
            assert_eq!(
                w.info.fallback,
                Some(Fallback::ViewAlongLight),
                "{name}: {:?}",
                w.info
            );
            assert!(w.info.sin_gamma < MIN_SIN_GAMMA, "{name}");
            assert_eq!(w.view.view_proj, s.base.view_proj, "{name}");
            assert_eq!(w.view.proj, s.base.proj, "{name}");
            assert_eq!(w.view.view, s.base.view, "{name}");
        }
    }
    // A point light seen along one of its rays.
    let light = Light::Point {
        position: Vec3::new(0.0, 20.0, 0.0),
    };
    let eye = camera(Vec3::new(0.0, 10.0, -5.0), Vec3::new(0.0, 0.0, -10.0));
    let s = setup(light, scene, receivers, eye, true);
    let w = run(&s, 1.0);
    assert_eq!(w.info.fallback, Some(Fallback::ViewAlongLight));
    assert_eq!(w.view.view_proj, s.base.view_proj);
    // No receivers: nothing to focus on.
    let mut s = setup(sun(direction), scene, receivers, eye, false);
    s.receivers = ReceiverBounds::empty(false);
    let w = run(&s, 1.0);
    assert_eq!(w.info.fallback, Some(Fallback::NoReceivers));
    assert_eq!(w.view.view_proj, s.base.view_proj);
}

/// As n_scale → ∞ the texel coordinates of the body's points converge, with an error falling
/// like 1/n, to a map that is affine in world space (a sun) whose t axis follows the view
/// direction projected across the light.
#[test]
fn large_n_converges_to_the_uniform_map_in_the_warps_orientation() {
    for (name, s) in configurations() {
        let mut points = s.receiver_points.clone();
        points.extend(body_corners(&s.base, &s.receivers));
        let limit = run(&s, 1e9);
        let at = |w: &Warped| points.iter().map(|&p| texel(w.view.view_proj, p)).collect();
        let reference: Vec<Vec3> = at(&limit);
        let error = |n_scale: f32| -> f32 {
            let w = run(&s, n_scale);
            let t: Vec<Vec3> = at(&w);
            t.iter()
                .zip(&reference)
                .map(|(a, b)| Vec2::new(a.x - b.x, a.y - b.y).length())
                .fold(0.0, f32::max)
        };
        let e: Vec<f32> = [1e1, 1e2, 1e3, 1e4, 1e5]
            .iter()
            .map(|&k| error(k))
            .collect();
        eprintln!("{name}: largest texel distance from the limit at n_scale 1e1..1e5: {e:?}");
        assert!(
            e[0] > 10.0,
            "{name}: the warp at n_scale 10 barely moves: {e:?}"
        );
        // Once n is large against the body (n_scale >= 1e3 here), each decade divides it by 10.
        for k in 2..4 {
            let ratio = e[k] / e[k + 1];
            assert!(
                (8.5..11.5).contains(&ratio),
                "{name}: error per decade of n_scale {e:?} (ratio {ratio}), not 1/n"
            );
        }
        assert!(e.windows(2).all(|p| p[0] > p[1]), "{name}: {e:?}");
        assert!(e[4] < 0.5, "{name}: {e:?}");
        let Light::Directional { direction, .. } = s.light else {
            continue;
        };
        // Affine in world space: w does not vary over the body.
        let ws: Vec<f32> = points
            .iter()
            .map(|&p| clip(limit.view.view_proj, p).w)
            .collect();
        let (lo, hi) = ws
            .iter()
            .fold((f32::INFINITY, 0.0f32), |(a, b), &w| (a.min(w), b.max(w)));
        assert!((hi - lo) / lo < 1e-6, "{name}: w over the body {lo}..{hi}");
        // Texel y grows along the view direction projected across the light, texel x across it,
        // depth along the light.
        let forward = (s.camera.target - s.camera.position).normalize();
        let along = (forward - direction * forward.dot(direction)).normalize();
        let across = direction.cross(along).normalize();
        let m = limit.view.view_proj;
        let o = texel(m, Vec3::ZERO);
        let grad = |v: Vec3| texel(m, v) - o;
        let (ga, gx, gl) = (grad(along), grad(across), grad(direction));
        assert!(ga.y > 0.0 && ga.x.abs() < 1e-3 * ga.y, "{name}: along {ga}");
        assert!(gx.y.abs() < 1e-3 * gx.x.abs(), "{name}: across {gx}");
        assert!(
            gl.z > 0.0 && Vec2::new(gl.x, gl.y).length() < 1e-3,
            "{name}: light {gl}"
        );
    }
}

/// Book Eq. 4.15: with an overhead sun and n = n_opt, the perspective error
/// m̃_t ∝ (dv/dt)/z (Eq. 4.11) is the same on the warp's near plane (camera depth z_0) and far
/// plane (z_1); a weaker warp has its maximum on the near plane, a stronger one on the far
/// plane (§4.2.3).
#[test]
fn n_opt_balances_the_t_error_of_an_overhead_light() {
    let scene = Aabb {
        min: Vec3::new(-20.0, 0.0, -60.0),
        max: Vec3::new(20.0, 2.0, 0.0),
    };
    let receivers = Aabb {
        min: Vec3::new(-10.0, 0.0, -50.0),
        max: Vec3::new(10.0, 0.0, -2.0),
    };
    let eye = Camera {
        position: Vec3::new(0.0, 1.0, 0.0),
        target: Vec3::new(0.0, 1.0, -1.0),
        ..camera(Vec3::ZERO, Vec3::NEG_Z)
    };
    for fit_view in [true, false] {
        let s = setup(sun(Vec3::NEG_Y), scene, receivers, eye, fit_view);
        let w = run(&s, 1.0);
        let info = w.info;
        assert_eq!(info.fallback, None);
        assert!((info.sin_gamma - 1.0).abs() < 1e-6, "{info:?}");
        // Overhead: z_1 − z_0 = D sin γ = D (Eq. 4.17) and n_opt = D/(z1−z0)·(z0 + √(z0 z1)).
        assert!(
            ((info.z1 - info.z0) - info.depth_range).abs() < 1e-3 * info.depth_range,
            "{info:?}"
        );
        let expected = info.z0 + (info.z0 * info.z1).sqrt();
        assert!(
            (info.n_opt - expected).abs() < 1e-4 * expected,
            "{info:?}: n_opt {} != {expected}",
            info.n_opt
        );
        // The representative line: on the ground under the camera, along −z.
        let p0 = Vec3::new(0.0, 0.0, -info.z0);
        let p1 = Vec3::new(0.0, 0.0, -info.z1);
        let error_t = |w: &Warped, p: Vec3| -> f32 {
            // Wide enough that f32 texel rounding stays ~1e-4 of the difference at the far
            // plane, narrow enough that the curvature's error (h/v')² stays ~1e-5.
            let h = 0.05;
            let m = w.view.view_proj;
            let dt_dv = (texel(m, p - Vec3::Z * h).y - texel(m, p + Vec3::Z * h).y) / (2.0 * h);
            let z = (p - eye.position).dot(Vec3::NEG_Z);
            1.0 / (dt_dv * z)
        };
        // z_0 and z_1 are the warp's near and far planes: the map's t edges.
        assert!(texel(w.view.view_proj, p0).y.abs() < 1e-2);
        assert!((texel(w.view.view_proj, p1).y - SIZE).abs() < 1e-2);
        let (e0, e1) = (error_t(&w, p0), error_t(&w, p1));
        assert!(
            (e0 / e1 - 1.0).abs() < 2e-3,
            "fit_view {fit_view}: m̃_t {e0} at z0 = {}, {e1} at z1 = {}",
            info.z0,
            info.z1
        );
        let weaker = run(&s, 2.0);
        assert!(error_t(&weaker, p0) > 1.5 * error_t(&weaker, p1));
        let stronger = run(&s, 0.5);
        assert!(error_t(&stronger, p1) > 1.5 * error_t(&stronger, p0));
    }
}

#[test]
fn bad_inputs_are_errors_and_random_inputs_stay_finite() {
    let (_, s) = configurations().remove(0);
    for bad in [0.0, -1.0, f32::NAN, f32::INFINITY] {
        assert!(
            warp(&s.base, &s.camera, &s.receivers, bad).is_err(),
            "{bad}"
        );
    }
    let mut other = s.receivers;
    other.perspective = true;
    assert!(warp(&s.base, &s.camera, &other, 1.0).is_err());
    let mut blind = s.camera;
    blind.target = blind.position;
    assert!(warp(&s.base, &blind, &s.receivers, 1.0).is_err());

    // A fixed-seed LCG over lights, cameras and receiver boxes.
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 33) as f32) / (1u64 << 31) as f32
    };
    let scene = ground_scene();
    let mut warped = 0;
    for i in 0..400 {
        let mut r = |lo: f32, hi: f32| lo + (hi - lo) * next();
        let light = if i % 2 == 0 {
            sun(Vec3::new(r(-1.0, 1.0), r(-1.0, -0.05), r(-1.0, 1.0)))
        } else {
            Light::Point {
                position: Vec3::new(r(-40.0, 40.0), r(5.0, 60.0), r(-90.0, 20.0)),
            }
        };
        let a = Vec3::new(r(-30.0, 30.0), r(0.0, 4.0), r(-80.0, 10.0));
        let b = Vec3::new(r(-30.0, 30.0), r(0.0, 4.0), r(-80.0, 10.0));
        let receivers = Aabb {
            min: a.min(b),
            max: a.max(b),
        };
        let position = Vec3::new(r(-40.0, 40.0), r(0.5, 50.0), r(-90.0, 30.0));
        let target = Vec3::new(r(-30.0, 30.0), r(0.0, 4.0), r(-80.0, 10.0));
        let mut eye = camera(position, target);
        eye.near = r(0.01, 2.0);
        let s = setup(light, scene, receivers, eye, i % 3 != 0);
        let n_scale = [0.05, 1.0, 1e6][i % 3];
        let w = warp(&s.base, &s.camera, &s.receivers, n_scale).expect("warp");
        assert!(
            w.view.view_proj.is_finite() && w.view.proj.is_finite(),
            "{i}"
        );
        if w.info.fallback.is_some() {
            assert_eq!(w.view.view_proj, s.base.view_proj);
            continue;
        }
        warped += 1;
        assert!(
            w.info.n > 0.0 && w.info.n_opt.is_finite(),
            "{i}: {:?}",
            w.info
        );
        for p in body_corners(&s.base, &s.receivers) {
            // Receivers outside the base view (beyond a point light's field-of-view cap) are
            // outside the body too.
            let b = clip(s.base.view_proj, p);
            if !(b.w > 0.0 && b.x.abs() <= b.w && b.y.abs() <= b.w) {
                continue;
            }
            let c = clip(w.view.view_proj, p);
            assert!(c.w > 0.0, "{i}: w = {} at {p}: {:?}", c.w, w.info);
            let n = c.truncate() / c.w;
            assert!(
                n.x.abs() <= 1.0 + 1e-3 && n.y.abs() <= 1.0 + 1e-3 && n.z > -1e-3,
                "{i}: corner at {n}: {:?}",
                w.info
            );
        }
    }
    eprintln!("{warped} of 400 random configurations warped");
    assert!(warped > 200, "only {warped} of 400 warped");
}

// --- GPU ---
