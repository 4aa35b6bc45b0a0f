//! The sampling-error measure (`src/sampling_error.rs`, book Ch. 3): the analytic Jacobian
//! against central differences of the test's own ray casts on a flat receiver (a directional and
//! a perspective light grid), the components multiplying back to m, the projection component at
//! normal incidence, the book's uniform storage factor for an overhead directional light
//! (notes §1.4), and — on the GPU under validation — m scaling as 1/`map_size` and the summary
//! being present exactly for the shadow-map techniques.

mod common;

use glam::{DMat4, DVec3, DVec4, Mat4, Vec3, Vec4};
use penumbra::sampling_error::{sample_error, sampling_error, SampleError, SamplingGrid};
use penumbra::scene::Camera;

/// Largest relative difference between the analytic G (and m) and central differences with
/// step `H` pixels: the maps are smooth (projective) so the O(H²) truncation is ~1e-8 here; the
/// rest is f64 rounding of the f32 matrices' inverse.
const FD_TOLERANCE: f64 = 1e-5;
/// Central-difference step in pixels.
const H: f64 = 1e-2;

fn camera(width: u32, height: u32) -> Camera {
    Camera {
        position: Vec3::new(0.7, 4.0, 5.5),
        target: Vec3::new(0.2, 0.0, -0.3),
        up: Vec3::Y,
        fov_y_deg: 50.0,
        width,
        height,
        near: 0.1,
        far: 50.0,
    }
}

/// A directional light's grid (orthographic) and a spot light's (perspective) over the plane.
fn grids() -> [(&'static str, SamplingGrid); 2] {
    let ortho = Mat4::orthographic_rh(-6.0, 6.0, -6.0, 6.0, 0.5, 30.0)
        * Mat4::look_at_rh(Vec3::new(3.0, 10.0, 2.0), Vec3::ZERO, Vec3::Y);
    let persp = Mat4::perspective_rh(1.4, 1.0, 0.5, 30.0)
        * Mat4::look_at_rh(Vec3::new(-3.0, 5.0, 1.5), Vec3::ZERO, Vec3::Y);
    [
        (
            "directional",
            SamplingGrid {
                view_proj: ortho,
                size: glam::UVec2::splat(1024),
            },
        ),
        (
            "perspective",
            SamplingGrid {
                view_proj: persp,
                size: glam::UVec2::splat(512),
            },
        ),
    ]
}

/// The test's own camera ray through continuous pixel coordinates (pixel centres at .5), by
/// unprojecting the far plane through the inverse of the camera's view-projection — the
/// shader's `pixel_on_plane` construction, not the module's basis vectors.
fn ray(camera: &Camera, x: f64, y: f64) -> (DVec3, DVec3) {
    let inv = camera.view_projection().as_dmat4().inverse();
    let ndc = DVec4::new(
        x / f64::from(camera.width) * 2.0 - 1.0,
        y / f64::from(camera.height) * 2.0 - 1.0,
        1.0,
        1.0,
    );
    let q = inv * ndc;
    let eye = camera.position.as_dvec3();
    (eye, q.truncate() / q.w - eye)
}

fn hit(camera: &Camera, x: f64, y: f64, p: DVec3, n: DVec3) -> DVec3 {
    let (e, d) = ray(camera, x, y);
    e + d * (n.dot(p - e) / n.dot(d))
}

fn texel(m: DMat4, size: glam::UVec2, w: DVec3) -> [f64; 2] {
    let c = m * w.extend(1.0);
    let s = size.as_dvec2();
    [(c.x / c.w * 0.5 + 0.5) * s.x, (c.y / c.w * 0.5 + 0.5) * s.y]
}

/// Pixels per texel from a texels-per-pixel matrix: the longer column of its inverse.
fn m_of(g: [[f64; 2]; 2]) -> f64 {
    let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
    (g[1][1].hypot(g[1][0]) / det.abs()).max(g[0][1].hypot(g[0][0]) / det.abs())
}

#[test]
fn analytic_jacobian_matches_central_differences_on_a_plane() {
    let camera = camera(96, 64);
    let n = DVec3::new(0.2, 1.0, 0.3).normalize();
    let p0 = DVec3::new(0.1, -0.2, 0.05);
    for (what, grid) in grids() {
        let vp = grid.view_proj.as_dmat4();
        let mut checked = 0;
        for py in (0..camera.height).step_by(5) {
            for px in (0..camera.width).step_by(7) {
                let (x, y) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
                let (_, d) = ray(&camera, x, y);
                if n.dot(p0 - camera.position.as_dvec3()) / n.dot(d) <= 0.0 {
                    continue;
                }
                let p = hit(&camera, x, y, p0, n);
                if grid.texel(p.as_vec3()).is_none() {
                    continue;
                }
                let e = sample_error(&camera, (px, py), p.as_vec3(), n.as_vec3(), &grid);
                assert!(!e.degenerate(), "{what} ({px},{py}) degenerate");
                let t =
                    |dx: f64, dy: f64| texel(vp, grid.size, hit(&camera, x + dx, y + dy, p0, n));
                let (xp, xm, yp, ym) = (t(H, 0.0), t(-H, 0.0), t(0.0, H), t(0.0, -H));
                let fd = [
                    [(xp[0] - xm[0]) / (2.0 * H), (yp[0] - ym[0]) / (2.0 * H)],
                    [(xp[1] - xm[1]) / (2.0 * H), (yp[1] - ym[1]) / (2.0 * H)],
                ];
                let scale = fd.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
                for (r, (analytic, differences)) in e.g.iter().zip(&fd).enumerate() {
                    for (c, (a, d)) in analytic.iter().zip(differences).enumerate() {
                        let diff = (a - d).abs() / scale;
                        assert!(
                            diff < FD_TOLERANCE,
                            "{what} ({px},{py}) G[{r}][{c}] analytic {a} vs differences {d} ({diff:e})"
                        );
                    }
                }
                let m_fd = m_of(fd);
                let rel = (e.m - m_fd).abs() / m_fd;
                assert!(
                    rel < FD_TOLERANCE,
                    "{what} ({px},{py}) m {} vs {m_fd} ({rel:e})",
                    e.m
                );
                // The components multiply back to m.
                let back = e.projection * e.perspective;
                assert!(
                    (back - e.m).abs() <= 1e-12 * e.m,
                    "{what}: {back} vs {}",
                    e.m
                );
                checked += 1;
            }
        }
        assert!(checked > 60, "{what}: only {checked} samples checked");
    }
}

#[test]
fn projection_component_is_one_at_normal_incidence() {
    // Camera straight above the plane y = 0, odd size so the centre pixel's ray is the axis.
    let camera = Camera {
        position: Vec3::new(0.0, 5.0, 0.0),
        target: Vec3::ZERO,
        up: Vec3::Z,
        fov_y_deg: 40.0,
        width: 33,
        height: 33,
        near: 0.1,
        far: 20.0,
    };
    let overhead = [
        Mat4::orthographic_rh(-4.0, 4.0, -4.0, 4.0, 0.5, 20.0)
            * Mat4::look_at_rh(Vec3::new(0.0, 9.0, 0.0), Vec3::ZERO, Vec3::Z),
        Mat4::perspective_rh(1.0, 1.0, 0.5, 20.0)
            * Mat4::look_at_rh(Vec3::new(0.0, 7.0, 0.0), Vec3::ZERO, Vec3::Z),
    ];
    for view_proj in overhead {
        let grid = SamplingGrid {
            view_proj,
            size: glam::UVec2::splat(256),
        };
        let e = sample_error(&camera, (16, 16), Vec3::ZERO, Vec3::Y, &grid);
        assert!(
            (e.projection - 1.0).abs() < 1e-9,
            "projection {}",
            e.projection
        );
        assert!((e.perspective - e.m).abs() < 1e-9 * e.m);
        // A tilted receiver at the same point: cos ψ_eye / cos ψ_light = 1 still (both along the
        // axis), and the components still multiply back.
        let n = Vec3::new(0.3, 1.0, 0.0).normalize();
        let e = sample_error(&camera, (16, 16), Vec3::ZERO, n, &grid);
        assert!((e.projection - 1.0).abs() < 1e-6, "{}", e.projection);
        assert!((e.projection * e.perspective - e.m).abs() <= 1e-12 * e.m);
    }
    // A sun at 60° from the normal with the eye along it: cos ψ_eye / cos ψ_light = 1 / cos 60°.
    let sun = Mat4::orthographic_rh(-4.0, 4.0, -4.0, 4.0, 0.5, 40.0)
        * Mat4::look_at_rh(
            Vec3::new(
                10.0 * 60f32.to_radians().sin(),
                10.0 * 60f32.to_radians().cos(),
                0.0,
            ),
            Vec3::ZERO,
            Vec3::Z,
        );
    let grid = SamplingGrid {
        view_proj: sun,
        size: glam::UVec2::splat(256),
    };
    let e = sample_error(&camera, (16, 16), Vec3::ZERO, Vec3::Y, &grid);
    assert!((e.projection - 2.0).abs() < 1e-5, "{}", e.projection);
}

/// Notes §1.4: for an overhead directional light and a viewer looking horizontally, a uniform
/// map fitted to the view frustum needs S = (z_f/z_n)(z_f/z_n − 1)/(2 tan θ) times the pixel count
/// (Eq. 4.25): 865 159 for z_n = 1, z_f = 1000, 2θ = 60°. Reproduced from the perspective
/// components at the near plane's centre (where m̃ is largest), S = (r_t/r_j)·M_t·(r_s/r_i)·M_s,
/// on a receiver whose projection component is 1 (its normal halfway between eye and light).
#[test]
fn uniform_storage_factor_of_an_overhead_directional_light() {
    let (z_n, z_f) = (1.0f32, 1000.0f32);
    let size = 513u32; // odd: the centre pixel's ray is the view axis
    let camera = Camera {
        position: Vec3::ZERO,
        target: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        fov_y_deg: 60.0,
        width: size,
        height: size,
        near: z_n,
        far: z_f,
    };
    let tan = (30f64).to_radians().tan();
    let half_width = (f64::from(z_f) * tan) as f32; // aspect 1
                                                    // Looking down −y, light x = world x, light y = world −z: s spans the far plane's width, t
                                                    // the depth range [z_n, z_f].
                                                    // (t starts a hair before z_n so the near-plane sample is inside the window, not on its
                                                    // edge: dv/dt changes by 1e-6.)
    let light = Mat4::orthographic_rh(-half_width, half_width, z_n - 1e-3, z_f, 1.0, 20.0)
        * Mat4::look_at_rh(Vec3::new(0.0, 10.0, 0.0), Vec3::ZERO, Vec3::NEG_Z);
    let r = 2048u32;
    let grid = SamplingGrid {
        view_proj: light,
        size: glam::UVec2::splat(r),
    };
    let p = Vec3::new(0.0, 0.0, -z_n);
    let n = Vec3::new(0.0, 1.0, 1.0).normalize();
    assert!(grid.texel(p).is_some());
    let c = size / 2;
    let e: SampleError = sample_error(&camera, (c, c), p, n, &grid);
    assert!((e.projection - 1.0).abs() < 1e-6, "{}", e.projection);
    let ratio = f64::from(r) / f64::from(size);
    let s = ratio * e.columns[0] * ratio * (e.columns[1] / e.projection);
    let (zn, zf) = (f64::from(z_n), f64::from(z_f));
    let book = (zf / zn) * (zf / zn - 1.0) / (2.0 * tan);
    assert!(
        (s - book).abs() < 1e-3 * book,
        "storage factor {s} vs the book's {book}"
    );
    // And the same map over the far plane's centre samples it 1000× finer in s.
    let far = Vec3::new(0.0, 0.0, -z_f * 0.999);
    let ef = sample_error(&camera, (c, c), far, n, &grid);
    assert!((e.columns[0] / ef.columns[0] - 999.0).abs() < 0.1);
}

#[test]
fn first_grid_charged_and_outside_counted() {
    let camera = camera(48, 32);
    let n = DVec3::Y;
    let [(_, wide), _] = grids();
    // A grid over a small window only, given first (the finer one).
    let narrow = SamplingGrid {
        view_proj: Mat4::orthographic_rh(-0.5, 0.5, -0.5, 0.5, 0.5, 30.0)
            * Mat4::look_at_rh(Vec3::new(0.0, 10.0, 0.0), Vec3::ZERO, Vec3::Z),
        size: glam::UVec2::splat(4096),
    };
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for py in 0..camera.height {
        for px in 0..camera.width {
            let (x, y) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
            let (e, d) = ray(&camera, x, y);
            let p = hit(&camera, x, y, DVec3::ZERO, n);
            // In front of the eye, near enough, and some background.
            let keep = n.dot(-e) / n.dot(d) > 0.0 && p.length() < 20.0 && (px + py) % 9 != 0;
            positions.push(if keep {
                p.as_vec3().extend(1.0)
            } else {
                Vec4::ZERO
            });
            normals.push(n.as_vec3().extend(0.0));
        }
    }
    let (map, summary) = sampling_error(&camera, &positions, &normals, &[narrow, wide]);
    let s = summary.expect("summary");
    let (mut in_narrow, mut in_wide, mut outside, mut background) = (0u64, 0u64, 0u64, 0u64);
    for (i, p) in positions.iter().enumerate() {
        if p.w <= 0.0 {
            background += 1;
            assert_eq!(map[i], 0.0);
            continue;
        }
        let pixel = (i as u32 % camera.width, i as u32 / camera.width);
        let w = p.truncate();
        let expected = if narrow.texel(w).is_some() {
            in_narrow += 1;
            sample_error(&camera, pixel, w, Vec3::Y, &narrow).m as f32
        } else if wide.texel(w).is_some() {
            in_wide += 1;
            sample_error(&camera, pixel, w, Vec3::Y, &wide).m as f32
        } else {
            outside += 1;
            0.0
        };
        assert_eq!(map[i], expected, "pixel {pixel:?}");
    }
    assert!(in_narrow > 0 && in_wide > 0 && outside > 0 && background > 0);
    assert_eq!(s.samples, in_narrow + in_wide);
    assert_eq!(s.outside, outside);
    let mut charged: Vec<f32> = map.iter().copied().filter(|&m| m > 0.0).collect();
    charged.sort_by(f32::total_cmp);
    assert_eq!(
        s.median,
        charged[(charged.len() as f64 * 0.5).ceil() as usize - 1]
    );
    let under = charged.iter().filter(|&&m| m > 1.0).count() as f64 / charged.len() as f64;
    assert_eq!(s.undersampled, under);
}

/// `SampleFootprints` (the camera's half computed once, for `cascades`' thirteen tile shapes): each
/// sample's m in the first grid that holds it is `sample_error`'s, bit for bit, for three sets of
/// grids over the same footprints; samples no grid holds are left out, and a degenerate sample
/// (zero normal) gives +∞ as `sample_error` does.
#[test]
fn footprints_give_sample_errors_bits() {
    let camera = camera(40, 30);
    let [(_, wide), (_, persp)] = grids();
    let narrow = SamplingGrid {
        view_proj: Mat4::orthographic_rh(-0.5, 0.5, -0.5, 0.5, 0.5, 30.0)
            * Mat4::look_at_rh(Vec3::new(0.0, 10.0, 0.0), Vec3::ZERO, Vec3::Z),
        size: glam::UVec2::new(2048, 1024),
    };
    let mut samples = Vec::new();
    for py in 0..camera.height {
        for px in 0..camera.width {
            let (x, y) = (f64::from(px) + 0.5, f64::from(py) + 0.5);
            let p = hit(&camera, x, y, DVec3::ZERO, DVec3::Y).as_vec3();
            // Tilted normals, and a zero one now and then.
            let n = match (px + 3 * py) % 7 {
                0 => Vec3::ZERO,
                k => Vec3::new(0.1 * k as f32, 1.0, -0.05 * k as f32),
            };
            samples.push(((px, py), p, n));
        }
    }
    let footprints = penumbra::sampling_error::SampleFootprints::new(&camera, samples.clone());
    for grids in [vec![narrow, wide], vec![persp], vec![narrow, persp, wide]] {
        let expected: Vec<f32> = samples
            .iter()
            .filter_map(|&(pixel, p, n)| {
                let g = grids.iter().find(|g| g.texel(p).is_some())?;
                Some(sample_error(&camera, pixel, p, n, g).m as f32)
            })
            .collect();
        let got = footprints.first_grid_m(&grids);
        assert!(expected.len() > 100 && expected.len() < samples.len());
        assert!(expected.iter().any(|m| m.is_infinite()));
        let bits = |v: &[f32]| v.iter().map(|m| m.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&expected), bits(&got), "{} grids", grids.len());
    }
}

/// On the GPU under validation: `hard` at map sizes 256 and 512 gives per-sample maps in ratio
/// exactly 2 (the window test and the derivative scale by the size exactly); the summary is in
/// `FrameStats` for `hard`, `pcf` and `pcss`, and absent for `izb`, which has no map.
#[test]
fn gpu_frames_carry_the_map_and_scale_with_map_size() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes@rect"))
        .expect("prepare");
    let render = |technique: &str, set: &[(&str, &str)]| {
        engine
            .render(&prepared, technique, &common::knobs(set), 1)
            .expect(technique)
    };
    let coarse = render("hard", &[("map_size", "256")]);
    let fine = render("hard", &[("map_size", "512")]);
    let (a, b) = (
        coarse.aliasing.as_ref().expect("hard has a map"),
        fine.aliasing.as_ref().expect("hard has a map"),
    );
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    let mut charged = 0;
    for (i, p) in positions.iter().enumerate() {
        if p.w <= 0.0 {
            assert_eq!((a[i], b[i]), (0.0, 0.0), "background pixel {i}");
            continue;
        }
        assert_eq!(
            a[i] == 0.0,
            b[i] == 0.0,
            "pixel {i}: charged at one size only"
        );
        if a[i] > 0.0 && a[i].is_finite() {
            let ratio = a[i] / b[i];
            assert!((ratio - 2.0).abs() < 1e-5, "pixel {i}: ratio {ratio}");
            charged += 1;
        }
    }
    assert!(
        charged > positions.len() / 4,
        "only {charged} samples charged"
    );
    let (sa, sb) = (
        coarse.stats.sampling_error.clone().expect("summary"),
        fine.stats.sampling_error.clone().expect("summary"),
    );
    assert!((sa.median / sb.median - 2.0).abs() < 1e-5);
    assert_eq!(sa.samples, sb.samples);
    assert!(sa.undersampled >= sb.undersampled);
    // The summary survives JSON (FrameStats is what the cache and stats.json carry).
    let json = serde_json::to_value(&coarse.stats).expect("json");
    assert!(json["sampling_error"]["median"].is_number());
    let back: penumbra::FrameStats = serde_json::from_value(json).expect("back");
    assert_eq!(back.sampling_error, Some(sa));
    for technique in ["pcf", "pcss"] {
        let f = render(technique, &[]);
        assert!(f.aliasing.is_some(), "{technique}");
        let s = f.stats.sampling_error.expect(technique);
        assert!(s.samples > 0 && s.median > 0.0, "{technique}: {s:?}");
    }
    let izb = render("izb", &[]);
    assert!(izb.aliasing.is_none() && izb.stats.sampling_error.is_none());
    common::assert_clean(&engine.context().validation());
}
