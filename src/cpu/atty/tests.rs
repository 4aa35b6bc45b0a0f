use super::*;
use crate::cpu::test_support::Rng;
use crate::scene::Aabb;
use glam::{DMat4, DVec3, DVec4};

/// A 1.2 × 1.2 rect light at height 6 facing down over a 10 × 10 ground, the light view
/// fitted to the box up to height 2, and `w × h` view samples on the ground (normals up).
fn ground(w: i32, h: i32) -> (Light, LightView, Vec<Vec4>, Vec<Vec4>, IVec2) {
    let light = Light::Rect {
        position: Vec3::new(0.0, 6.0, 0.0),
        u: Vec3::X * 1.2,
        v: Vec3::Z * 1.2,
    };
    let bounds = Aabb {
        min: Vec3::new(-5.0, 0.0, -5.0),
        max: Vec3::new(5.0, 2.0, 5.0),
    };
    let view = LightView::fit(&light, &bounds).expect("fit");
    let mut positions = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let x = -2.0 + 4.0 * (i as f32 + 0.5) / w as f32;
            let z = -1.7 + 3.4 * (j as f32 + 0.5) / h as f32;
            positions.push(Vec4::new(x, 0.0, z, 1.0));
        }
    }
    let normals = vec![Vec4::new(0.0, 1.0, 0.0, 0.0); positions.len()];
    (light, view, positions, normals, IVec2::new(w, h))
}

/// Where the ray through map position `texel` (texels) meets the plane y = `height`, and the
/// map depth there, in f64.
fn on_plane(view: &LightView, n: u32, texel: [f64; 2], height: f64) -> (DVec3, f64) {
    let m = DMat4::from_cols_array(&view.view_proj.to_cols_array().map(f64::from));
    let inv = m.inverse();
    let ndc = [
        2.0 * texel[0] / n as f64 - 1.0,
        2.0 * texel[1] / n as f64 - 1.0,
    ];
    let at = |z: f64| {
        let p = inv * DVec4::new(ndc[0], ndc[1], z, 1.0);
        p.truncate() / p.w
    };
    let (a, b) = (at(0.0), at(1.0));
    let s = (height - a.y) / (b.y - a.y);
    let world = a + (b - a) * s;
    let c = m * world.extend(1.0);
    (world, c.z / c.w)
}

/// A depth map holding the plane y = `height` where the ray through a texel's centre meets it
/// inside x ∈ `xs`, z ∈ `zs`, empty (1.0) elsewhere.
fn rect_map(view: &LightView, n: u32, height: f64, xs: [f64; 2], zs: [f64; 2]) -> Vec<f32> {
    let mut depth = vec![1.0f32; (n * n) as usize];
    for y in 0..n {
        for x in 0..n {
            let (p, d) = on_plane(view, n, [x as f64 + 0.5, y as f64 + 0.5], height);
            if p.x >= xs[0] && p.x <= xs[1] && p.z >= zs[0] && p.z <= zs[1] {
                depth[(y * n + x) as usize] = d as f32;
            }
        }
    }
    depth
}

fn knobs(skip: bool) -> AttyKnobs {
    AttyKnobs {
        skip,
        receiver_plane: false,
        same_surface: 0.02,
        max_width: 128.0,
    }
}

/// The receivers' map is the brute-force one: per texel the nearest and farthest depth bits
/// of the samples binned into it and the lowest pixel index at exactly each; a texel without
/// samples reads NONE.
#[test]
fn receivers_map_is_the_brute_force_one() {
    let (light, view, mut positions, _, _) = ground(37, 29);
    let mut rng = Rng(11);
    for p in &mut positions {
        // Heights in [0, 1.5), some duplicated exactly, some background.
        *p += Vec4::new(0.0, (rng.next() * 0.5 + 0.5) * 1.5, 0.0, 0.0);
        if rng.next() > 0.8 {
            p.w = 0.0;
        }
    }
    positions[5] = positions[4];
    let n = 32;
    let setup = AttySetup::new(&light, &view, n);
    let rm = receiver_map(&positions, &setup);
    let size = IVec2::splat(n as i32);
    let mut occupied = 0;
    for k in 0..(n * n) as usize {
        let binned: Vec<(u32, u32)> = positions
            .iter()
            .enumerate()
            .filter(|(_, p)| p.w > 0.0)
            .filter_map(|(i, p)| {
                let c = shadow_coord(view.view_proj, p.xyz(), size);
                let t = c.xy().floor().as_ivec2().min(size - 1);
                (inside_map(c, size) && (t.y * n as i32 + t.x) as usize == k)
                    .then_some((i as u32, c.z.max(0.0).to_bits()))
            })
            .collect();
        let Some(near) = binned.iter().map(|b| b.1).min() else {
            assert_eq!((rm.near_pixel[k], rm.far_pixel[k]), (NONE, NONE));
            continue;
        };
        occupied += 1;
        let far = binned.iter().map(|b| b.1).max().expect("non-empty");
        let lowest = |bits: u32| binned.iter().filter(|b| b.1 == bits).map(|b| b.0).min();
        assert_eq!(rm.near_bits[k], near);
        assert_eq!(rm.far_bits[k], far);
        assert_eq!(Some(rm.near_pixel[k]), lowest(near));
        assert_eq!(Some(rm.far_pixel[k]), lowest(far));
    }
    assert!(occupied > 100, "only {occupied} texels occupied");
}

/// A flat rectangle parallel to the light (book §6.2.1; Soler and Sillion's exact case):
/// its patches tile it, so each layer's sum is the fraction of the light the whole
/// rectangle hides from the layer's representative — the product of two interval overlaps,
/// computed here in world space and f64 from the rasterised rectangle's extent. Within 10⁻⁵
/// (f32 sums of up to a few hundred areas; measured 10⁻⁶), with skipping on and off; the receivers span
/// lit, penumbra and umbra.
#[test]
fn flat_occluder_sums_to_the_exact_overlap() {
    let n = 128u32;
    let (light, view, positions, normals, size) = ground(48, 40);
    let depth = rect_map(&view, n, 2.0, [-0.9, 0.7], [-0.6, 0.8]);
    let map = DepthMap {
        depth: &depth,
        size: IVec2::splat(n as i32),
    };
    // The rasterised rectangle's world extent: its texels' outer edges on y = 2.
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for y in 0..n {
        for x in 0..n {
            if depth[(y * n + x) as usize] < 1.0 {
                for (dx, dy) in [(0.0, 0.0), (1.0, 1.0)] {
                    let (p, _) = on_plane(&view, n, [x as f64 + dx, y as f64 + dy], 2.0);
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
        }
    }
    // A light point (l, 6) sees (p, 0) through y = 2 at p + (l − p)/3: inside [lo, hi] for
    // l ∈ [3 lo − 2p, 3 hi − 2p], against the light's [−0.6, 0.6].
    let exact = |p: Vec4| {
        let overlap = |a: f64, b: f64, q: f64| {
            let (a, b) = (3.0 * a - 2.0 * q, 3.0 * b - 2.0 * q);
            (b.min(0.6) - a.max(-0.6)).max(0.0) / 1.2
        };
        overlap(lo.x, hi.x, p.x as f64) * overlap(lo.z, hi.z, p.z as f64)
    };
    let view_images = ViewImages {
        positions: &positions,
        normals: &normals,
        size,
    };
    let setup = AttySetup::new(&light, &view, n);
    let mut classes = [0; 3];
    let mut worst = 0.0f64;
    for skip in [false, true] {
        let out = atty(&view_images, &map, None, &setup, &knobs(skip));
        let (rm, ssm) = (&out.receivers, &out.ssm);
        let texels = (n * n) as usize;
        for layer in 0..2 {
            for k in 0..texels {
                let pix = [rm.near_pixel[k], rm.far_pixel[k]][layer];
                let occ = ssm.occlusion[layer * texels + k];
                if pix == NONE || occ < 0.0 {
                    continue;
                }
                let e = exact(positions[pix as usize]);
                worst = worst.max((occ as f64 - e).abs());
                assert!(
                    (occ as f64 - e).abs() < 1e-5,
                    "skip {skip}: texel {k} layer {layer}: {occ} vs exact {e}"
                );
                classes[if e <= 0.0 {
                    0
                } else if e >= 1.0 {
                    1
                } else {
                    2
                }] += 1;
            }
        }
    }
    eprintln!("(lit, umbra, penumbra) layers {classes:?}, max |sum − exact| = {worst:e}");
    assert!(classes.iter().all(|&c| c > 50), "classes {classes:?}");
}

/// Skipping changes no bit; two sides (a back map of random depths behind the front) never
/// lighten; an empty map lights everything; the counters describe the image.
#[test]
fn skip_is_exact_and_two_sides_never_lighten() {
    let n = 64u32;
    let (light, view, positions, normals, size) = ground(40, 32);
    let mut front = rect_map(&view, n, 1.5, [-1.2, 0.3], [-0.9, 0.4]);
    let mut rng = Rng(23);
    // Tilt a block of it and add a second, lower one.
    for d in front.iter_mut() {
        if *d < 1.0 {
            *d -= 0.02 * (rng.next() * 0.5 + 0.5);
        }
    }
    let low = rect_map(&view, n, 0.6, [0.5, 1.4], [0.2, 1.1]);
    for (d, l) in front.iter_mut().zip(&low) {
        *d = d.min(*l);
    }
    let back: Vec<f32> = front
        .iter()
        .map(|&d| {
            if d < 1.0 && rng.next() > -0.5 {
                d + 0.05 * (rng.next() * 0.5 + 0.5)
            } else {
                0.0
            }
        })
        .collect();
    let view_images = ViewImages {
        positions: &positions,
        normals: &normals,
        size,
    };
    let setup = AttySetup::new(&light, &view, n);
    fn at(depth: &[f32], n: u32) -> DepthMap<'_> {
        DepthMap {
            depth,
            size: IVec2::splat(n as i32),
        }
    }
    let (front_map, back_map) = (at(&front, n), at(&back, n));
    for receiver_plane in [false, true] {
        let k = |skip: bool| AttyKnobs {
            receiver_plane,
            ..knobs(skip)
        };
        let off = atty(&view_images, &front_map, None, &setup, &k(false));
        let on = atty(&view_images, &front_map, None, &setup, &k(true));
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&off.visibility), bits(&on.visibility));
        assert!(on.counters[6] > 0 && off.counters[6] == 0);
        assert!(
            off.counters[3] > 0 && off.counters[4] > 0,
            "{:?}",
            off.counters
        );
        let two = atty(&view_images, &front_map, Some(&back_map), &setup, &k(true));
        let mut darker = 0;
        for (a, b) in off.visibility.iter().zip(&two.visibility) {
            assert!(*b <= *a + 1e-6, "two sides lighten {a} → {b}");
            darker += usize::from(*b < *a - 1e-3);
        }
        assert!(darker > 0, "the back map changes nothing");
        for out in [&off, &two] {
            let counted = [out.counters[2], out.counters[3], out.counters[4]];
            let mut own = [0; 3];
            for v in &out.visibility {
                own[if *v >= 1.0 {
                    0
                } else if *v <= 0.0 {
                    1
                } else {
                    2
                }] += 1;
            }
            assert_eq!(counted, own);
        }
    }
    let empty = vec![1.0f32; (n * n) as usize];
    let lit = atty(&view_images, &at(&empty, n), None, &setup, &knobs(true));
    assert!(lit.visibility.iter().all(|&v| v == 1.0));
    assert_eq!(lit.counters[9], 0);
}
