//! The light-view depth pass against the CPU rasterizer, texel by texel, at small sizes.
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-texel arrays by index"
)]

mod common;

use glam::Vec3;
use penumbra::cpu::raster::rasterize_depth;
use penumbra::gpu::f32s;
use penumbra::passes::{DepthBias, LightView, SceneGeometry, ShadowMap, ShadowMapDesc};
use penumbra::scene::{Aabb, Light};

/// Three overlapping triangles at different heights over a ground quad, both windings.
fn known_scene() -> (Vec<Vec3>, Vec<u32>) {
    let positions = vec![
        // ground quad at y = 0
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(2.0, 0.0, -2.0),
        Vec3::new(2.0, 0.0, 2.0),
        Vec3::new(-2.0, 0.0, 2.0),
        // a tilted triangle
        Vec3::new(-1.0, 0.5, -1.0),
        Vec3::new(1.2, 1.0, -0.3),
        Vec3::new(-0.2, 0.8, 1.1),
        // a flat one above, clockwise
        Vec3::new(0.0, 1.4, 0.0),
        Vec3::new(-0.9, 1.4, 0.6),
        Vec3::new(0.7, 1.4, 0.9),
        // a steep one crossing the others
        Vec3::new(0.3, 0.1, -1.5),
        Vec3::new(0.4, 1.9, -0.2),
        Vec3::new(1.5, 0.2, 0.4),
    ];
    let indices = vec![0, 2, 1, 0, 3, 2, 4, 5, 6, 7, 8, 9, 10, 11, 12];
    (positions, indices)
}

fn check(light: Light, size: u32) {
    let ctx = common::context();
    let (positions, indices) = known_scene();
    let mut bounds = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };
    for p in &positions {
        bounds.min = bounds.min.min(*p);
        bounds.max = bounds.max.max(*p);
    }
    let view = LightView::fit(&light, &bounds).expect("light view");
    let geometry = SceneGeometry::from_triangles(&ctx, &positions, &indices).expect("geometry");
    let map = ShadowMap::new(
        &ctx,
        view,
        ShadowMapDesc {
            size,
            bias: DepthBias::default(),
        },
    )
    .expect("shadow map");
    ctx.submit(None, |rec| map.record(rec, &geometry))
        .expect("render");
    let gpu = f32s(&ctx.read_image(&map.depth).expect("readback"));
    let snap = 1.0 / (1u32 << ctx.info().sub_pixel_precision_bits.min(16)) as f32;
    let cpu = rasterize_depth(&positions, &indices, view.view_proj, size, size, snap);

    let mut mismatches = 0;
    let mut covered = 0;
    let mut checked = 0;
    for i in 0..gpu.len() {
        if cpu.uncertain[i] {
            continue;
        }
        checked += 1;
        if cpu.depth[i] < 1.0 {
            covered += 1;
        }
        if (gpu[i] - cpu.depth[i]).abs() > 1e-6 + snap * cpu.slope[i] {
            mismatches += 1;
        }
    }
    assert!(
        checked > (size * size * 9 / 10) as usize,
        "too many uncertain texels"
    );
    assert!(
        covered > (size * size / 16) as usize,
        "the scene covers too little of the map: {covered}"
    );
    if mismatches > 0 {
        let dir = common::write_diff(
            &format!("shadow-map-{}", light.kind()),
            size,
            size,
            &cpu.depth,
            &gpu,
        );
        panic!("{mismatches} of {checked} texels differ by more than 1e-6 + snap · slope; images in {}", dir.display());
    }
    drop((map, geometry));
    common::assert_clean(&ctx.validation());
}

#[test]
fn perspective_map_matches_cpu_raster() {
    check(
        Light::Point {
            position: Vec3::new(0.5, 5.0, 0.8),
        },
        64,
    );
}

#[test]
fn orthographic_map_matches_cpu_raster() {
    check(
        Light::Directional {
            direction: Vec3::new(-0.3, -1.0, -0.2).normalize(),
            angular_diameter_deg: 0.0,
        },
        96,
    );
}

#[test]
fn rect_light_map_matches_cpu_raster() {
    check(
        Light::Rect {
            position: Vec3::new(-1.0, 4.0, 0.0),
            u: Vec3::new(0.5, 0.0, 0.0),
            v: Vec3::new(0.0, 0.0, 0.5),
        },
        128,
    );
}
