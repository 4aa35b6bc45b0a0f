//! penumbra as a library with the caller's images: reads them in their layouts and rejects wrong
//! ones with clear errors, builds view samples from a depth G-buffer as its CPU twin and the
//! raster pass do, and counts NaN/Inf/out-of-range results on the GPU exactly as its twin does.

mod common;

use ash::vk;
use glam::Vec4;
use penumbra::cpu::visibility_checks::count_bad;
use penumbra::gpu::{Image, ImageDesc};
use penumbra::passes::{ViewSamples, VisibilityChecks};
use penumbra::{Engine, Error};

use common::knobs;
use common::library_api::small_scene;

/// An image the "caller" owns: penumbra's own `Image` stands in for the caller's allocation,
/// and `Image::borrowed` wraps its handle as a caller's image would be.
fn owned(engine: &Engine, name: &str, format: vk::Format, w: u32, h: u32) -> Image {
    let usage = vk::ImageUsageFlags::STORAGE
        | vk::ImageUsageFlags::TRANSFER_SRC
        | vk::ImageUsageFlags::TRANSFER_DST
        | vk::ImageUsageFlags::COLOR_ATTACHMENT;
    Image::new(
        engine.context(),
        name,
        ImageDesc::new_2d(format, w, h, usage),
    )
    .expect("image")
}

#[test]
fn the_callers_images_are_used_in_their_layouts_and_wrong_ones_are_clear_errors() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let scene = small_scene();
    // penumbra's own view samples, copied into "caller" images left in GENERAL.
    let reference = engine.prepare(&scene).expect("prepare");
    let mut r = engine
        .renderer(&reference, "pcf", &knobs(&[("map_size", "256")]))
        .expect("renderer");
    r.render().expect("frame");
    let expected = r.read_visibility().expect("read");
    drop(r);
    let rgba = vk::Format::R32G32B32A32_SFLOAT;
    let (w, h) = (96, 64);
    let positions = owned(&engine, "caller positions", rgba, w, h);
    let normals = owned(&engine, "caller normals", rgba, w, h);
    let visibility = owned(&engine, "caller visibility", vk::Format::R32_SFLOAT, w, h);
    let pos_bytes = ctx.read_image(&reference.view.positions).expect("read");
    let nrm_bytes = ctx.read_image(&reference.view.normals).expect("read");
    ctx.submit(None, |rec| {
        rec.upload_image(&positions, &pos_bytes)?;
        rec.upload_image(&normals, &nrm_bytes)?;
        rec.upload_image(&visibility, &vec![0u8; (w * h * 4) as usize])?;
        rec.use_image(&positions, penumbra::gpu::Access::ComputeWrite);
        rec.use_image(&normals, penumbra::gpu::Access::ComputeWrite);
        rec.use_image(&visibility, penumbra::gpu::Access::ComputeWrite);
        Ok(())
    })
    .expect("fill the caller's images");
    let borrow = |image: &Image, layout| unsafe {
        Image::borrowed(
            &ctx,
            &format!("{} (borrowed)", image.name),
            image.raw,
            image.desc,
            layout,
        )
    };
    let general = vk::ImageLayout::GENERAL;

    // Wrong layout, format, size and usage: each refused with what was expected.
    let e = borrow(&positions, vk::ImageLayout::UNDEFINED)
        .err()
        .expect("undefined layout refused");
    assert!(
        matches!(e, Error::InvalidArgument(_)) && e.to_string().contains("UNDEFINED"),
        "{e}"
    );
    let wrong_format = ViewSamples::from_images(
        &scene.camera,
        borrow(&visibility, general).expect("wrap"),
        borrow(&normals, general).expect("wrap"),
    )
    .err()
    .expect("R32F positions");
    assert!(
        wrong_format
            .to_string()
            .contains("expected R32G32B32A32_SFLOAT"),
        "{wrong_format}"
    );
    let mut wide = scene.camera;
    wide.width = 128;
    let wrong_size = ViewSamples::from_images(
        &wide,
        borrow(&positions, general).expect("wrap"),
        borrow(&normals, general).expect("wrap"),
    )
    .err()
    .expect("96x64 images for a 128-wide camera");
    assert!(
        wrong_size.to_string().contains("expected 128x64"),
        "{wrong_size}"
    );
    let mut no_storage = visibility.desc;
    no_storage.usage = vk::ImageUsageFlags::TRANSFER_SRC;
    let view = ViewSamples::from_images(
        &scene.camera,
        borrow(&positions, general).expect("wrap"),
        borrow(&normals, general).expect("wrap"),
    )
    .expect("view samples");
    let unusable = unsafe {
        Image::borrowed(
            &ctx,
            "visibility without storage",
            visibility.raw,
            no_storage,
            general,
        )
    }
    .expect("wrap");
    let e = engine
        .prepare_with_view_samples(&scene, view, unusable)
        .err()
        .expect("visibility without STORAGE");
    assert!(e.to_string().contains("lacks STORAGE"), "{e}");

    // The right images: the same visibility as penumbra's own view samples, twice (the
    // images are back in GENERAL after each recording, or validation would object).
    let view = ViewSamples::from_images(
        &scene.camera,
        borrow(&positions, general).expect("wrap"),
        borrow(&normals, general).expect("wrap"),
    )
    .expect("view samples");
    let prepared = engine
        .prepare_with_view_samples(&scene, view, borrow(&visibility, general).expect("wrap"))
        .expect("prepare on the caller's images");
    let mut renderer = engine
        .renderer(&prepared, "pcf", &knobs(&[("map_size", "256")]))
        .expect("renderer");
    for _ in 0..2 {
        renderer.render().expect("frame");
        let got = renderer.read_visibility().expect("read");
        common::assert_same_bits("caller-images", w, h, &expected, &got);
    }
    // The caller's image is still the caller's: penumbra wrote into it.
    let direct = penumbra::gpu::f32s(&ctx.read_image(&visibility).expect("read"));
    assert!(
        direct
            .iter()
            .zip(&expected)
            .all(|(a, b)| a.to_bits() == b.to_bits()),
        "the caller's own image does not hold what penumbra rendered"
    );
    drop(renderer);
    drop(prepared);
    drop(reference);
    common::assert_clean(&ctx.validation());
}

#[test]
fn gpu_visibility_checks_count_what_the_cpu_twin_counts() {
    let ctx = common::context();
    let (w, h) = (37u32, 23u32);
    let n = (w * h) as usize;
    // Every class planted, some on background (which must not count), at irregular places so a
    // workgroup-edge bug shows.
    let mut positions = vec![Vec4::new(0.0, 0.0, 0.0, 1.0); n];
    let mut visibility = vec![0.5f32; n];
    for i in 0..n {
        if i % 11 == 3 {
            positions[i].w = 0.0;
        }
        visibility[i] = match i % 7 {
            0 => f32::NAN,
            1 if i % 3 == 0 => f32::INFINITY,
            2 if i % 5 == 0 => f32::NEG_INFINITY,
            3 => -0.25,
            4 if i % 2 == 0 => 1.5,
            5 => 1.0,
            _ => (i as f32 * 0.013).fract(),
        };
    }
    let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST;
    let pos_image = Image::new(
        &ctx,
        "planted positions",
        ImageDesc::new_2d(vk::Format::R32G32B32A32_SFLOAT, w, h, usage),
    )
    .expect("image");
    let vis_image = Image::new(
        &ctx,
        "planted visibility",
        ImageDesc::new_2d(vk::Format::R32_SFLOAT, w, h, usage),
    )
    .expect("image");
    let checks = VisibilityChecks::new(&ctx, &pos_image, &vis_image).expect("checks");
    ctx.submit(None, |rec| {
        rec.upload_image(&pos_image, bytemuck::cast_slice(&positions))?;
        rec.upload_image(&vis_image, bytemuck::cast_slice(&visibility))?;
        checks.record(rec)
    })
    .expect("count");
    let gpu = checks.read(&ctx).expect("read");
    let (nan, inf, range) = count_bad(&visibility, &positions);
    assert!(nan > 0 && inf > 0 && range > 0, "every class planted");
    assert_eq!((gpu.nan, gpu.inf, gpu.out_of_range), (nan, inf, range));
    drop(checks);
    drop((pos_image, vis_image));
    common::assert_clean(&ctx.validation());
}

/// A depth image as `camera.view_projection()` writes it, from world positions (1 for
/// background): the test's own projection, not the GPU pass's set-up.
fn depth_of(camera: &penumbra::Camera, positions: &[Vec4]) -> Vec<f32> {
    let vp = camera.view_projection();
    positions
        .iter()
        .map(|p| {
            if p.w <= 0.0 {
                1.0
            } else {
                let c = vp * p.truncate().extend(1.0);
                c.z / c.w
            }
        })
        .collect()
}

#[test]
fn view_samples_from_a_depth_gbuffer_match_the_cpu_twin_and_the_raster_samples() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let scene = small_scene();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let own = engine.prepare(&scene).expect("prepare");
    let positions = own.sample_positions(&ctx).expect("positions");
    let normals = own.view.read_normals(&ctx).expect("normals");
    let depth = depth_of(&scene.camera, &positions);
    // The caller's normals: unnormalised and some facing away, which the pass must fix.
    let normal_in: Vec<Vec4> = normals
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let s = if i % 3 == 0 { -2.5 } else { 0.75 };
            (n.truncate() * s).extend(0.0)
        })
        .collect();
    let (twin_positions, twin_normals) =
        penumbra::cpu::view_samples::from_depth(&scene.camera, &depth, &normal_in);
    let extent = {
        let mut b = penumbra::scene::Aabb::EMPTY;
        for p in &own.positions {
            b.extend(*p);
        }
        b.radius()
    };
    for (format, bytes) in [
        (
            vk::Format::R32_SFLOAT,
            bytemuck::cast_slice::<f32, u8>(&depth).to_vec(),
        ),
        (
            vk::Format::D32_SFLOAT,
            bytemuck::cast_slice::<f32, u8>(&depth).to_vec(),
        ),
    ] {
        let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
        let depth_image = Image::new(&ctx, "caller depth", ImageDesc::new_2d(format, w, h, usage))
            .expect("depth");
        let normal_image = Image::new(
            &ctx,
            "caller normals",
            ImageDesc::new_2d(vk::Format::R32G32B32A32_SFLOAT, w, h, usage),
        )
        .expect("normals");
        ctx.submit(None, |rec| {
            rec.upload_image(&depth_image, &bytes)?;
            rec.upload_image(&normal_image, bytemuck::cast_slice(&normal_in))
        })
        .expect("upload");
        let view = ViewSamples::from_depth(&ctx, &scene.camera, depth_image, normal_image)
            .expect("view samples from depth");
        let visibility = owned(&engine, "visibility", vk::Format::R32_SFLOAT, w, h);
        let prepared = engine
            .prepare_with_view_samples(&scene, view, visibility)
            .expect("prepare from depth");
        let got_positions = prepared.sample_positions(&ctx).expect("read");
        let got_normals = prepared.view.read_normals(&ctx).expect("read");
        let mut worst = (0.0f32, 0.0f32);
        for i in 0..got_positions.len() {
            let (g, t) = (got_positions[i], twin_positions[i]);
            assert_eq!(g.w, t.w, "{format:?}: sample/background differs at {i}");
            worst.0 = worst.0.max((g.truncate() - t.truncate()).length() / extent);
            let (gn, tn) = (got_normals[i], twin_normals[i]);
            worst.1 = worst
                .1
                .max((gn.truncate() - tn.truncate()).abs().max_element());
            // And against the raster view samples the depth came from.
            assert_eq!(g.w, positions[i].w, "{format:?}: coverage differs at {i}");
            if g.w > 0.0 {
                let d = (g.truncate() - positions[i].truncate()).length() / extent;
                assert!(d < 1e-3, "{format:?}: pixel {i} unprojects {d} away");
                assert!(
                    (gn.truncate() - normals[i].truncate()).length() < 1e-5,
                    "normal {i}"
                );
            }
        }
        if !(worst.0 < 1e-4 && worst.1 < 1e-5) {
            // The linear view depth (normals' w) of both, scaled to the frame's range.
            let far = twin_normals.iter().map(|n| n.w).fold(1e-6f32, f32::max);
            let depth = |v: &[Vec4]| v.iter().map(|n| n.w / far).collect::<Vec<f32>>();
            common::write_diff(
                &format!("from-depth-{format:?}"),
                w,
                h,
                &depth(&twin_normals),
                &depth(&got_normals),
            );
        }
        assert!(
            worst.0 < 1e-4 && worst.1 < 1e-5,
            "{format:?}: worst vs twin {worst:?}"
        );
        // A technique on them agrees with the same technique on the raster samples.
        let set = knobs(&[("map_size", "256")]);
        let mut r = engine.renderer(&prepared, "pcf", &set).expect("renderer");
        r.render().expect("frame");
        let from_depth = r.read_visibility().expect("read");
        let mut o = engine.renderer(&own, "pcf", &set).expect("renderer");
        o.render().expect("frame");
        let raster = o.read_visibility().expect("read");
        // The two inputs differ by rounding, so `pcf`'s hard texel tests flip along shadow
        // edges: at most 1 % of the pixels on a CPU device (lavapipe: 9 of 6 144), 2 % on a GPU,
        // whose rasterizer interpolates the raster samples its own way (an NVIDIA H200: 68 of
        // the 6 144, 1.1 %).
        let percent = if ctx.info().runs_workgroups_on_cpu_threads() {
            1
        } else {
            2
        };
        let differing = from_depth
            .iter()
            .zip(&raster)
            .filter(|(a, b)| (*a - *b).abs() > 1e-3)
            .count();
        eprintln!(
            "{format:?}: {differing} of {} pixels differ",
            from_depth.len()
        );
        if differing * 100 > from_depth.len() * percent {
            common::write_diff("from-depth", w, h, &raster, &from_depth);
        }
        assert!(
            differing * 100 <= from_depth.len() * percent,
            "{format:?}: {differing} pixels differ"
        );
    }
    // The wrong input is refused with what was expected.
    let no_sampled = Image::new(
        &ctx,
        "storage-only depth",
        ImageDesc::new_2d(vk::Format::R32_SFLOAT, w, h, vk::ImageUsageFlags::STORAGE),
    )
    .expect("image");
    let normals_ok = Image::new(
        &ctx,
        "normals",
        ImageDesc::new_2d(
            vk::Format::R16G16B16A16_SFLOAT,
            w,
            h,
            vk::ImageUsageFlags::SAMPLED,
        ),
    )
    .expect("image");
    let e = ViewSamples::from_depth(&ctx, &scene.camera, no_sampled, normals_ok)
        .err()
        .expect("refused");
    assert!(e.to_string().contains("lacks SAMPLED"), "{e}");
    drop(own);
    common::assert_clean(&ctx.validation());
}
