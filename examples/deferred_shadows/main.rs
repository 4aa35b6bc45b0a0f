//! A host engine with penumbra as its shadow backend.
//!
//! The "engine" here owns everything Vulkan: it creates the instance (with the validation layers,
//! synchronization validation and its own message counter), picks the device, creates it, and
//! allocates its vertex buffer and G-buffer with plain `ash` and `vkAllocateMemory`. Its G-buffer
//! is what engines keep: a D32 depth buffer and an RGBA16F world-normal target, rendered by its
//! own graphics pipeline and shaders (`examples/deferred_shadows/gbuffer.{vert,frag}`). penumbra
//! reads them as they are ([`ViewSamples::from_depth`]: it unprojects the depth with the camera's
//! matrices itself). Each frame records, into one command buffer of the engine's: the G-buffer
//! pass, penumbra's shadow technique ([`ShadowRenderer::record`]) writing visibility into the
//! engine's own R32F image, and copies of depth, normals and visibility for the shading. It
//! shades on the host (`albedo × (ambient + diffuse × visibility)`, positions unprojected from the
//! depth) and writes `shaded.png` and `visibility.png`.
//!
//! penumbra picks the best soft technique the device runs, in order of preference (`pvssm`, the
//! centrepiece, then `pcss`, then `pcf-poisson`). Between passes the engine keeps its G-buffer in
//! `SHADER_READ_ONLY_OPTIMAL` and the visibility image in `GENERAL`, and tells penumbra so;
//! penumbra's recording needs no barrier from the engine on either side, and
//! synchronization validation checks that claim. At the end penumbra is dropped first, then the
//! engine destroys its own objects and the device: the validation layer's object tracker reports
//! any object penumbra left behind there.
//!
//! Run: `cargo run --release --example deferred_shadows -- [SCENE] [OUT_DIR]`
//! (defaults: `scenes/teapot-rect.toml`, `target/deferred-shadows`).

mod gbuffer;
mod host;

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use ash::vk;
use penumbra::gpu::{Image, ImageDesc};
use penumbra::passes::ViewSamples;
use penumbra::scene::Scene;
use penumbra::{Context, Engine, Error, TechniqueDesc, TechniqueKind};

use gbuffer::{
    f16_to_f32, record_gbuffer, transition, DEPTH, GBUFFER_LAYOUT, NORMALS, NORMAL_FORMAT,
    VISIBILITY,
};
use host::{begin, submit, Host, ERRORS, WARNINGS};

type Failure = Box<dyn std::error::Error>;

/// What a run produced.
#[derive(Debug)]
pub struct Report {
    /// The technique penumbra ran.
    pub technique: TechniqueKind,
    /// Frames rendered.
    pub frames: u32,
    /// Mean visibility over the view samples of the last frame.
    pub mean_visibility: f64,
    /// View samples of the last frame, and how many are in full shadow / penumbra.
    pub samples: (usize, usize, usize),
    /// NaN + infinite + out-of-range results penumbra's GPU checks counted.
    pub bad_values: u64,
    /// Validation errors and warnings over the whole run, teardown included.
    pub validation: (u32, u32),
    /// The images written.
    pub written: Vec<PathBuf>,
}

/// The preferred soft techniques, best first: the first one that builds here is used.
const PREFERENCE: [TechniqueKind; 3] = [
    TechniqueKind::Pvssm,
    TechniqueKind::Pcss,
    TechniqueKind::PcfPoisson,
];

/// Runs the engine: `frames` frames of `scene_spec` at `width`×`height`, images into `out`.
pub fn run(
    scene_spec: &str,
    width: u32,
    height: u32,
    frames: u32,
    out: &Path,
) -> Result<Report, Failure> {
    let mut scene = Scene::open(scene_spec)?;
    scene.camera.width = width;
    scene.camera.height = height;
    let mut host = Host::new()?;
    let result = render(&mut host, &scene, frames, out);
    host.destroy();
    let mut report = result?;
    report.validation = (
        ERRORS.load(Ordering::SeqCst),
        WARNINGS.load(Ordering::SeqCst),
    );
    Ok(report)
}

fn render(host: &mut Host, scene: &Scene, frames: u32, out: &Path) -> Result<Report, Failure> {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let (positions, indices) = scene.merged();
    let vertices = host.buffer(
        vk::BufferUsageFlags::VERTEX_BUFFER,
        (positions.len() * 12) as u64,
        bytemuck::cast_slice(&positions),
    )?;
    let index_buffer = host.buffer(
        vk::BufferUsageFlags::INDEX_BUFFER,
        (indices.len() * 4) as u64,
        bytemuck::cast_slice(&indices),
    )?;
    // Sampled: the engine's own deferred passes read them, and so does penumbra.
    let read = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC;
    host.image(ImageDesc::new_2d(
        vk::Format::D32_SFLOAT,
        w,
        h,
        vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | read,
    ))?; // DEPTH
    host.image(ImageDesc::new_2d(
        NORMAL_FORMAT,
        w,
        h,
        vk::ImageUsageFlags::COLOR_ATTACHMENT | read,
    ))?; // NORMALS
    host.image(ImageDesc::new_2d(
        vk::Format::R32_SFLOAT,
        w,
        h,
        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
    ))?; // VISIBILITY
    let texels = (w * h) as u64;
    // Depth (4 bytes a texel), normals (8) and visibility (4), copied back for shading.
    let readback = host.buffer(vk::BufferUsageFlags::TRANSFER_DST, texels * 16, &[])?;
    host.gbuffer_pipeline()?;
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(host.pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(1);
    let cmd = unsafe { host.device.allocate_command_buffers(&alloc) }?[0];

    // Frame 0: the G-buffer alone (penumbra fits its light view to the samples it holds), the
    // images first put in the layouts the engine keeps them in between passes.
    begin(host, cmd)?;
    let color = vk::ImageAspectFlags::COLOR;
    let mut initial = transition(
        &[(host.images[VISIBILITY].image, color)],
        vk::ImageLayout::UNDEFINED,
        vk::ImageLayout::GENERAL,
    );
    initial.extend(transition(
        &[(host.images[NORMALS].image, color)],
        vk::ImageLayout::UNDEFINED,
        GBUFFER_LAYOUT,
    ));
    initial.extend(transition(
        &[(host.images[DEPTH].image, vk::ImageAspectFlags::DEPTH)],
        vk::ImageLayout::UNDEFINED,
        GBUFFER_LAYOUT,
    ));
    unsafe {
        host.device.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&initial),
        )
    };
    record_gbuffer(
        host,
        cmd,
        scene,
        vertices,
        (index_buffer, indices.len() as u32),
    );
    submit(host, cmd)?;

    // penumbra on the engine's device, reading the engine's G-buffer, writing its image.
    let ctx = unsafe {
        Context::from_raw_with_features(
            host.entry.clone(),
            host.instance.clone(),
            host.physical,
            host.device.clone(),
            host.family,
            &host.features,
        )
    }?;
    let engine = Engine::from_context(ctx.clone());
    let general = vk::ImageLayout::GENERAL;
    let wrap = |i: usize, name: &str, layout| unsafe {
        Image::borrowed(
            &ctx,
            name,
            host.images[i].image,
            host.images[i].desc,
            layout,
        )
    };
    let view = ViewSamples::from_depth(
        &ctx,
        &scene.camera,
        wrap(DEPTH, "engine depth", GBUFFER_LAYOUT)?,
        wrap(NORMALS, "engine normals", GBUFFER_LAYOUT)?,
    )?;
    let visibility = wrap(VISIBILITY, "engine visibility", general)?;
    let prepared = engine.prepare_with_view_samples(scene, view, visibility)?;
    let mut chosen = None;
    for kind in PREFERENCE {
        match engine.renderer_for(&prepared, &TechniqueDesc::new(kind)) {
            Ok(r) => {
                chosen = Some((kind, r));
                break;
            }
            // A feature this device lacks: try the next technique.
            Err(Error::Unsupported { feature, .. }) => {
                eprintln!("{kind} unsupported here: {feature}")
            }
            Err(e) => return Err(e.into()),
        }
    }
    let (technique, mut renderer) = chosen.ok_or("no soft technique runs on this device")?;

    let mut bad_values = 0;
    let mut frame = 0;
    while frame < frames {
        begin(host, cmd)?;
        record_gbuffer(
            host,
            cmd,
            scene,
            vertices,
            (index_buffer, indices.len() as u32),
        );
        unsafe { renderer.record(cmd) }?;
        // No barrier after penumbra: it left its images in their layouts, visible to all
        // commands. The engine's copies want TRANSFER_SRC_OPTIMAL, and go back after.
        let copy = |offset: u64, aspect_mask| vk::BufferImageCopy {
            buffer_offset: offset,
            image_subresource: vk::ImageSubresourceLayers {
                aspect_mask,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            },
            image_extent: vk::Extent3D {
                width: w,
                height: h,
                depth: 1,
            },
            ..Default::default()
        };
        let to_host = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::ALL_TRANSFER)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)];
        let depth_aspect = vk::ImageAspectFlags::DEPTH;
        let src = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
        let gbuffer = [
            (host.images[DEPTH].image, depth_aspect),
            (host.images[NORMALS].image, color),
        ];
        let vis = [(host.images[VISIBILITY].image, color)];
        let mut to_src = transition(&gbuffer, GBUFFER_LAYOUT, src);
        to_src.extend(transition(&vis, general, src));
        let mut back = transition(&gbuffer, src, GBUFFER_LAYOUT);
        back.extend(transition(&vis, src, general));
        unsafe {
            let d = &host.device;
            let dst = host.buffers[readback].0;
            let barriers = |b: &[vk::ImageMemoryBarrier2<'_>]| {
                d.cmd_pipeline_barrier2(
                    cmd,
                    &vk::DependencyInfo::default().image_memory_barriers(b),
                )
            };
            barriers(&to_src);
            for (image, offset, aspect) in [
                (DEPTH, 0, depth_aspect),
                (NORMALS, texels * 4, color),
                (VISIBILITY, texels * 12, color),
            ] {
                d.cmd_copy_image_to_buffer(
                    cmd,
                    host.images[image].image,
                    src,
                    dst,
                    &[copy(offset, aspect)],
                );
            }
            barriers(&back);
            d.cmd_pipeline_barrier2(
                cmd,
                &vk::DependencyInfo::default().memory_barriers(&to_host),
            );
        }
        submit(host, cmd)?;
        // A technique whose storage this frame outgrew (`izb`'s pairs, under a huge light) is
        // rebuilt with room for it: the frame was wrong, so it is recorded again.
        if renderer.grow()? {
            continue;
        }
        let checks = renderer.checks()?;
        bad_values = checks.nan + checks.inf + checks.out_of_range;
        frame += 1;
    }
    // penumbra goes first; the engine's device lives on.
    drop(renderer);
    drop(prepared);
    drop(engine);
    drop(ctx);

    // Shade on the host: a grey albedo, a little ambient, Lambert towards the light, with world
    // positions unprojected from the depth as the engine's lighting pass would.
    let bytes = host.read(readback, (texels * 16) as usize)?;
    let word = |i: usize| [bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]];
    let half = |i: usize| f16_to_f32(u16::from_le_bytes([bytes[i], bytes[i + 1]]));
    let inverse = scene.camera.view_projection().inverse();
    let eye = scene.camera.position;
    let mut shaded = Vec::with_capacity((texels * 3) as usize);
    let mut grey = Vec::with_capacity(texels as usize);
    let (mut sum, mut samples, mut umbra, mut penumbra_count) = (0.0f64, 0usize, 0usize, 0usize);
    for i in 0..texels as usize {
        let depth = f32::from_le_bytes(word(i * 4));
        let n0 = (texels as usize) * 4 + i * 8;
        let mut n = glam::Vec3::new(half(n0), half(n0 + 2), half(n0 + 4));
        let v = f32::from_le_bytes(word((texels as usize) * 12 + i * 4));
        let rgb = if depth >= 1.0 {
            [40u8, 44, 52] // background
        } else {
            samples += 1;
            sum += f64::from(v);
            if v <= 0.0 {
                umbra += 1;
            } else if v < 1.0 {
                penumbra_count += 1;
            }
            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
            let ndc = glam::Vec2::new((x + 0.5) / w as f32, (y + 0.5) / h as f32) * 2.0 - 1.0;
            let p = inverse.project_point3(ndc.extend(depth));
            if n.dot(eye - p) < 0.0 {
                n = -n;
            }
            let to_light = match scene.light {
                penumbra::scene::Light::Directional { direction, .. } => -direction,
                other => other.centre().unwrap_or_default() - p,
            }
            .normalize_or_zero();
            let diffuse = n.dot(to_light).max(0.0);
            let c = 0.15 + 0.85 * diffuse * v.clamp(0.0, 1.0);
            [
                (c * 235.0).round() as u8,
                (c * 225.0).round() as u8,
                (c * 205.0).round() as u8,
            ]
        };
        shaded.extend_from_slice(&rgb);
        grey.push((v.clamp(0.0, 1.0) * 255.0).round() as u8);
    }
    std::fs::create_dir_all(out)?;
    let shaded_path = out.join("shaded.png");
    let visibility_path = out.join("visibility.png");
    image::RgbImage::from_raw(w, h, shaded)
        .ok_or("shaded image size")?
        .save(&shaded_path)?;
    image::GrayImage::from_raw(w, h, grey)
        .ok_or("visibility image size")?
        .save(&visibility_path)?;
    Ok(Report {
        technique,
        frames,
        mean_visibility: if samples > 0 {
            sum / samples as f64
        } else {
            0.0
        },
        samples: (samples, umbra, penumbra_count),
        bad_values,
        validation: (0, 0),
        written: vec![shaded_path, visibility_path],
    })
}

#[allow(
    dead_code,
    reason = "the test includes this file and calls `run` itself"
)]
fn main() -> Result<(), Failure> {
    let mut args = std::env::args().skip(1);
    let scene = args
        .next()
        .unwrap_or_else(|| "scenes/teapot-rect.toml".into());
    let out = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "target/deferred-shadows".into()),
    );
    let report = run(&scene, 512, 384, 3, &out)?;
    println!(
        "{} on {scene}: {} frames, {} view samples ({} umbra, {} penumbra), mean visibility {:.3}, \
         {} bad values, validation errors {} warnings {}",
        report.technique,
        report.frames,
        report.samples.0,
        report.samples.1,
        report.samples.2,
        report.mean_visibility,
        report.bad_values,
        report.validation.0,
        report.validation.1,
    );
    for p in &report.written {
        println!("wrote {}", p.display());
    }
    if report.validation != (0, 0) {
        return Err("validation reported errors or warnings".into());
    }
    Ok(())
}
