use super::*;
use crate::cpu::test_support::Rng;
use crate::scene::Aabb;

/// A rect light 1.2 wide at height 6 over a 10 × 10 ground, 24 × 18 view samples on the
/// ground (normals up) and the light view fitted to the box.
fn ground() -> (Light, LightView, Vec<Vec4>, Vec<Vec4>, IVec2) {
    let light = Light::Rect {
        position: Vec3::new(0.3, 6.0, -0.2),
        u: Vec3::X * 1.2,
        v: Vec3::Z * 1.2,
    };
    let bounds = Aabb {
        min: Vec3::new(-5.0, 0.0, -5.0),
        max: Vec3::new(5.0, 2.0, 5.0),
    };
    let view = LightView::fit(&light, &bounds).expect("fit");
    let size = IVec2::new(24, 18);
    let mut positions = Vec::new();
    for j in 0..size.y {
        for i in 0..size.x {
            let x = -3.0 + 6.0 * (i as f32 + 0.5) / size.x as f32;
            let z = -2.5 + 5.0 * (j as f32 + 0.5) / size.y as f32;
            positions.push(Vec4::new(x, 0.0, z, 1.0));
        }
    }
    let normals = vec![Vec4::new(0.0, 1.0, 0.0, 0.0); positions.len()];
    (light, view, positions, normals, size)
}

/// Adding an occluder where the map was empty never brightens a view sample: the new texels
/// can only add patches (OR-ed, or summed), widen the shrunk region, extend gap-filled edges
/// or decide umbra. Checked bit for bit as blocks of texels at random depths in front of
/// the ground fill empty parts of the map one by one.
#[test]
fn adding_occluders_never_brightens() {
    let map_size = 64u32;
    let (light, lview, positions, normals, size) = ground();
    let view = ViewImages {
        positions: &positions,
        normals: &normals,
        size,
    };
    let n = (map_size * map_size) as usize;
    for (gap_fill, add, skip) in [
        (false, false, true),
        (true, false, false),
        (false, true, true),
    ] {
        let knobs = BitmaskKnobs {
            samples: 64,
            add,
            skip,
            receiver_plane: true,
            gap_fill,
            light_clip: false,
            max_width: 40.0,
        };
        let setup = BitmaskSetup::new(&light, &lview, map_size, 64);
        let mut depth = vec![1.0f32; n];
        let map = |d: &[f32]| {
            let m = DepthMap {
                depth: d,
                size: IVec2::splat(map_size as i32),
            };
            bitmask(&view, &positions, &m, &setup, &knobs).visibility
        };
        let mut before = map(&depth);
        assert!(before.iter().all(|&v| v == 1.0), "an empty map lights all");
        let mut rng = Rng(5 + u64::from(gap_fill) + 2 * u64::from(add));
        let mut darkened = 0;
        for _ in 0..8 {
            let corner = IVec2::new(
                ((rng.next() * 0.5 + 0.5) * 56.0) as i32,
                ((rng.next() * 0.5 + 0.5) * 56.0) as i32,
            );
            let extent = IVec2::new(
                2 + ((rng.next() * 0.5 + 0.5) * 8.0) as i32,
                2 + ((rng.next() * 0.5 + 0.5) * 8.0) as i32,
            );
            for y in corner.y..(corner.y + extent.y).min(map_size as i32) {
                for x in corner.x..(corner.x + extent.x).min(map_size as i32) {
                    let t = (y * map_size as i32 + x) as usize;
                    if depth[t] == 1.0 {
                        // A tilted block: depths vary across it.
                        depth[t] = 0.5 + 0.4 * (rng.next() * 0.5 + 0.5);
                    }
                }
            }
            let after = map(&depth);
            for (k, (a, b)) in after.iter().zip(&before).enumerate() {
                assert!(
                    a <= b,
                    "gap_fill {gap_fill}, add {add}: pixel {k} brightened {b} → {a}"
                );
                darkened += usize::from(a < b);
            }
            before = after;
        }
        assert!(darkened > 20, "only {darkened} darkened samples");
    }
}

/// The per-axis masks pick exactly the samples of a closed rectangle.
#[test]
fn rect_masks_are_the_brute_force_ones() {
    let (light, lview, ..) = ground();
    let mut rng = Rng(9);
    for n in [16, 128, 1024] {
        let pattern = Pattern::new(&light, &lview, n);
        let points = pattern.normalised();
        for _ in 0..500 {
            let a = rng.vec2(0.7) + Vec2::splat(0.5);
            let b = a + rng.vec2(0.6).abs();
            let r = Vec4::new(a.x, a.y, b.x, b.y);
            assert_eq!(
                pattern.rect_mask(r),
                brute_force_rect_mask(&points, r),
                "{n}: {r}"
            );
        }
    }
}
