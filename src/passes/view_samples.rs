//! The camera view-sample pass: per pixel, the world position and camera-facing normal of the
//! nearest surface, and its linear view depth. Every technique shades these same samples, so
//! every technique is compared with the ground truth on the same points.
//!
//! Two RGBA32F targets: `positions` (xyz world, w = 1 for a sample, 0 for background — the
//! clear value) and `normals` (xyz unit normal facing the camera, w linear depth along the view
//! direction). Full f32 so a receiver's depth reprojected into the light is not quantized.
//!
//! The normal is the face's: on a device with `geometryShader` (which gives fragment shaders
//! `gl_PrimitiveID`) the cross product of the pixel's triangle's edges, read from the scene's
//! buffers, for the pixels whose neighbours lie closer than 2⁻¹² of their distance from the
//! origin; elsewhere, and on other devices, the cross product of the interpolated position's
//! screen derivatives — the same plane, but only as exact as the f32 positions are far apart:
//! noise where neighbouring pixels are a few f32 steps apart (`glsl/passes/view_samples.glsl`;
//! the stress suite's `dense-cell`). Reading `gl_PrimitiveID` costs lavapipe's fragment stage
//! even where no pixel needs it (the pass 1.2–1.6× slower on `grid:800000@rect`, measured with
//! the variant forced, medians of five interleaved runs), so
//! [`ViewSamples::for_scene`] takes that variant only when the camera's view of the scene may
//! hold such pixels ([`may_be_denser_than_f32`]).

use ash::vk;
use glam::{IVec2, Vec3, Vec4};
use std::sync::Mutex;

use super::SceneGeometry;
use crate::error::{Error, Result};
use crate::gpu::{
    f32s, Access, Binding, Context, DescriptorSet, GraphicsDesc, Image, ImageDesc, Pipeline,
    Recorder, Sampler,
};
use crate::scene::{Aabb, Camera};
use crate::shader_types::{FromDepthPush, ViewSamplesPush};

const SAMPLE_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

/// The view-sample images and the pipeline that renders them, or the caller's own images of the
/// same layout ([`ViewSamples::from_images`]).
pub struct ViewSamples {
    /// The raster pipeline and depth buffer; `None` for the caller's images, which penumbra
    /// reads but never renders.
    raster: Option<(Pipeline, Image)>,
    /// With face normals from `gl_PrimitiveID`: the scene's buffers bound for the fragment
    /// shader, made by the last [`ViewSamples::record`] (it holds the set until the next, by
    /// which time that submission has completed).
    faces: Option<Mutex<Option<DescriptorSet>>>,
    /// For the caller's depth and normal G-buffer: the pass that unprojects it into
    /// `positions` and `normals` at the start of each frame.
    from_depth: Option<FromDepth>,
    /// xyz world position, w = 1 for a sample and 0 for background.
    pub positions: Image,
    /// xyz normal facing the camera, w linear view depth.
    pub normals: Image,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl ViewSamples {
    /// Creates the targets for `camera`'s resolution, with face normals from `gl_PrimitiveID`
    /// wherever the pixels are denser than f32 resolves, if the device has `geometryShader`.
    pub fn new(ctx: &Context, camera: &Camera) -> Result<ViewSamples> {
        Self::with_faces(ctx, camera, ctx.info().geometry_shader)
    }

    /// [`ViewSamples::new`] for a view of a scene within `bounds`: the face-normal variant only
    /// where some pixel may need it (a pixel at view depth z spans z · 2 tan(fov/2) / height).
    pub fn for_scene(ctx: &Context, camera: &Camera, bounds: &Aabb) -> Result<ViewSamples> {
        let faces = ctx.info().geometry_shader && may_be_denser_than_f32(camera, bounds);
        Self::with_faces(ctx, camera, faces)
    }

    fn with_faces(ctx: &Context, camera: &Camera, faces: bool) -> Result<ViewSamples> {
        let pipeline = Pipeline::graphics(
            ctx,
            &GraphicsDesc {
                vertex: "passes/view_samples.vert",
                fragment: Some(if faces {
                    "passes/view_samples_faces.frag"
                } else {
                    "passes/view_samples.frag"
                }),
                color_formats: &[SAMPLE_FORMAT, SAMPLE_FORMAT],
                depth_format: vk::Format::D32_SFLOAT,
                depth_bias: false,
                vertex_input: true,
                cull_mode: vk::CullModeFlags::NONE,
                depth_compare: vk::CompareOp::LESS_OR_EQUAL,
                viewports: 1,
            },
        )?;
        let (w, h) = (camera.width, camera.height);
        let color_usage = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::STORAGE
            | vk::ImageUsageFlags::TRANSFER_SRC;
        let depth = Image::new(
            ctx,
            "view depth",
            ImageDesc::new_2d(
                vk::Format::D32_SFLOAT,
                w,
                h,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            ),
        )?;
        Ok(ViewSamples {
            raster: Some((pipeline, depth)),
            faces: faces.then(|| Mutex::new(None)),
            from_depth: None,
            positions: Image::new(
                ctx,
                "view positions",
                ImageDesc::new_2d(SAMPLE_FORMAT, w, h, color_usage),
            )?,
            normals: Image::new(
                ctx,
                "view normals",
                ImageDesc::new_2d(SAMPLE_FORMAT, w, h, color_usage),
            )?,
            width: w,
            height: h,
        })
    }

    /// View samples the caller rendered: `positions` (xyz world position, w > 0 for a sample and
    /// 0 for background) and `normals` (xyz unit normal facing the camera, w linear view depth),
    /// both RGBA32F with `STORAGE` usage and `camera`'s size — usually [`Image::borrowed`]
    /// wrappers of the caller's G-buffer. Anything else is an [`Error::InvalidArgument`] naming
    /// the image and what was expected.
    pub fn from_images(camera: &Camera, positions: Image, normals: Image) -> Result<ViewSamples> {
        for image in [&positions, &normals] {
            check_image(image, SAMPLE_FORMAT, camera.width, camera.height)?;
        }
        Ok(ViewSamples {
            raster: None,
            faces: None,
            from_depth: None,
            positions,
            normals,
            width: camera.width,
            height: camera.height,
        })
    }

    /// View samples from the caller's depth and normal G-buffer: `depth` (D32_SFLOAT or
    /// R32_SFLOAT, as `camera.view_projection()` writes it: 0..1, cleared to 1 for background)
    /// and `normals` (xyz a world-space normal of any length and either facing, in
    /// R32G32B32A32_SFLOAT, R16G16B16A16_SFLOAT or _SNORM, or R8G8B8A8_SNORM), both with
    /// `SAMPLED` usage and `camera`'s size. Each frame first unprojects them into penumbra's own
    /// positions and normals (`glsl/view_samples/from_depth.comp`, CPU twin
    /// [`crate::cpu::view_samples::from_depth`]), which is what the techniques then read.
    pub fn from_depth(
        ctx: &Context,
        camera: &Camera,
        depth: Image,
        normals: Image,
    ) -> Result<ViewSamples> {
        let (w, h) = (camera.width, camera.height);
        let sampled = vk::ImageUsageFlags::SAMPLED;
        let why = "the pass reads it with texelFetch";
        check_input(
            &depth,
            &[vk::Format::D32_SFLOAT, vk::Format::R32_SFLOAT],
            (w, h),
            sampled,
            why,
        )?;
        check_input(
            &normals,
            &[
                SAMPLE_FORMAT,
                vk::Format::R16G16B16A16_SFLOAT,
                vk::Format::R16G16B16A16_SNORM,
                vk::Format::R8G8B8A8_SNORM,
            ],
            (w, h),
            sampled,
            why,
        )?;
        let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
        let out_positions = Image::new(
            ctx,
            "view positions (from depth)",
            ImageDesc::new_2d(SAMPLE_FORMAT, w, h, usage),
        )?;
        let out_normals = Image::new(
            ctx,
            "view normals (from depth)",
            ImageDesc::new_2d(SAMPLE_FORMAT, w, h, usage),
        )?;
        let pipeline = Pipeline::compute(ctx, "view_samples/from_depth.comp")?;
        let sampler = Sampler::nearest_border_white(ctx, "caller G-buffer sampler")?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Sampled(&depth, &sampler),
                Binding::Sampled(&normals, &sampler),
                Binding::Image(&out_positions),
                Binding::Image(&out_normals),
            ],
        )?;
        let forward = (camera.target - camera.position).normalize_or_zero();
        let push = FromDepthPush {
            inv_view_proj: camera.view_projection().inverse(),
            eye: camera.position.extend(1.0),
            forward: forward.extend(0.0),
            view_size: IVec2::new(w as i32, h as i32),
            pad0: 0,
            pad1: 0,
        };
        Ok(ViewSamples {
            raster: None,
            faces: None,
            from_depth: Some(FromDepth {
                pipeline,
                set,
                push,
                _inputs: (depth, normals, sampler),
            }),
            positions: out_positions,
            normals: out_normals,
            width: w,
            height: h,
        })
    }

    /// For view samples from a depth G-buffer ([`ViewSamples::from_depth`]): records the pass
    /// that unprojects it (what every frame starts with, outside any timed pass). Nothing for the
    /// other kinds.
    pub fn record_reconstruction(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let Some(f) = &self.from_depth else {
            return Ok(());
        };
        // Untimed, like the view-sample raster pass is outside a technique's time: it is the
        // caller's view samples' cost, shared by every technique.
        rec.dispatch(&f.pipeline, &f.set, &f.push, [self.width, self.height, 1])
    }

    /// Whether these are the caller's images ([`ViewSamples::from_images`]).
    pub fn is_external(&self) -> bool {
        self.raster.is_none()
    }

    /// Records the pass (named `view-samples`). Fails for the caller's images, which the caller
    /// renders.
    pub fn record(
        &self,
        rec: &mut Recorder<'_>,
        geometry: &SceneGeometry,
        camera: &Camera,
    ) -> Result<()> {
        let Some((pipeline, depth)) = &self.raster else {
            return Err(Error::InvalidArgument(
                "the view samples are the caller's images: the caller renders them".into(),
            ));
        };
        let faces = match &self.faces {
            Some(slot) => {
                let set = DescriptorSet::new(
                    rec.context(),
                    pipeline,
                    &[
                        Binding::Buffer(&geometry.vertices),
                        Binding::Buffer(&geometry.indices),
                    ],
                )?;
                let mut slot = slot.lock().map_err(|_| {
                    Error::InvalidArgument("the view samples' set lock was poisoned".into())
                })?;
                *slot = Some(set);
                Some(slot)
            }
            None => None,
        };
        // The guard holds the set for this recording (and until the next one replaces it).
        let set = faces.as_deref().and_then(Option::as_ref);
        rec.begin_pass("view-samples")?;
        if let Some(set) = set {
            rec.use_set(set);
        }
        rec.use_buffer(&geometry.vertices, Access::VertexInput);
        rec.use_buffer(&geometry.indices, Access::VertexInput);
        rec.begin_rendering(
            &[(&self.positions, [0.0; 4]), (&self.normals, [0.0; 4])],
            (depth, 1.0),
        );
        let forward = (camera.target - camera.position).normalize_or_zero();
        let result = rec.draw_indexed(
            pipeline,
            set,
            &geometry.vertices,
            &geometry.indices,
            geometry.index_count,
            &ViewSamplesPush {
                view_proj: camera.view_projection(),
                eye: camera.position.extend(1.0),
                forward: forward.extend(0.0),
            },
            None,
        );
        rec.end_rendering();
        rec.end_pass();
        result
    }

    /// Reads the positions back (row-major).
    pub fn read_positions(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        Ok(to_vec4(&f32s(&ctx.read_image(&self.positions)?)))
    }

    /// Reads the normals (w: linear depth) back.
    pub fn read_normals(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        Ok(to_vec4(&f32s(&ctx.read_image(&self.normals)?)))
    }
}

/// Neighbouring pixels nearer than this fraction of their distance from the origin take the
/// triangle's normal (`FACE_MIN_STEP` in `glsl/passes/view_samples.glsl`).
pub const FACE_MIN_STEP: f32 = 1.0 / 4096.0;

/// Whether some pixel of `camera`'s view of a scene within `bounds` may lie nearer its
/// neighbours than [`FACE_MIN_STEP`] of its distance from the origin (with a factor 2 of
/// margin): a pixel at view depth z spans at least z · 2 tan(fov/2) / height, the nearest
/// sample is no nearer than the box's nearest corner along the view direction (or the near
/// plane), and none is farther from the origin than the box's farthest corner.
pub fn may_be_denser_than_f32(camera: &Camera, bounds: &Aabb) -> bool {
    if bounds.is_empty() {
        return false;
    }
    let forward = (camera.target - camera.position).normalize_or_zero();
    let corners = (0..8).map(|k| {
        Vec3::new(
            if k & 1 == 0 {
                bounds.min.x
            } else {
                bounds.max.x
            },
            if k & 2 == 0 {
                bounds.min.y
            } else {
                bounds.max.y
            },
            if k & 4 == 0 {
                bounds.min.z
            } else {
                bounds.max.z
            },
        )
    });
    let (nearest, farthest) = corners.fold((f32::MAX, 0.0f32), |(n, f), q| {
        (n.min((q - camera.position).dot(forward)), f.max(q.length()))
    });
    let pixel = 2.0 * (0.5 * camera.fov_y_deg.to_radians()).tan() / camera.height.max(1) as f32;
    let span = nearest.max(camera.near) * pixel;
    // Written so that NaN (a degenerate camera) takes the exact variant.
    !matches!(
        span.partial_cmp(&(2.0 * FACE_MIN_STEP * farthest)),
        Some(std::cmp::Ordering::Greater | std::cmp::Ordering::Equal)
    )
}

/// That `image` is a storage image of `format` and `width`×`height`, as a technique binding it
/// expects; otherwise an error naming the image and what was expected.
pub(crate) fn check_image(
    image: &Image,
    format: vk::Format,
    width: u32,
    height: u32,
) -> Result<()> {
    check_input(
        image,
        &[format],
        (width, height),
        vk::ImageUsageFlags::STORAGE,
        "penumbra's compute passes bind it as a storage image",
    )
}

/// That `image` is one of `formats`, `size` and has `usage` (needed because `why`).
fn check_input(
    image: &Image,
    formats: &[vk::Format],
    size: (u32, u32),
    usage: vk::ImageUsageFlags,
    why: &str,
) -> Result<()> {
    let d = &image.desc;
    if !formats.contains(&d.format) {
        let expected = match formats {
            [one] => format!("{one:?}"),
            all => format!("one of {all:?}"),
        };
        return Err(Error::InvalidArgument(format!(
            "image '{}' is {:?}: expected {expected}",
            image.name, d.format
        )));
    }
    if (d.width, d.height) != size {
        return Err(Error::InvalidArgument(format!(
            "image '{}' is {}x{}: expected {}x{} (the camera's size)",
            image.name, d.width, d.height, size.0, size.1
        )));
    }
    if !d.usage.contains(usage) {
        return Err(Error::InvalidArgument(format!(
            "image '{}' lacks {usage:?} usage (has {:?}): {why}",
            image.name, d.usage
        )));
    }
    Ok(())
}

/// The unprojection pass of [`ViewSamples::from_depth`] and the caller's images it reads.
struct FromDepth {
    pipeline: Pipeline,
    set: DescriptorSet,
    push: FromDepthPush,
    // Read by the set every frame.
    _inputs: (Image, Image, Sampler),
}

fn to_vec4(f: &[f32]) -> Vec<Vec4> {
    f.chunks_exact(4).map(Vec4::from_slice).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(fov_y_deg: f32) -> Camera {
        Camera {
            position: Vec3::new(5.0, 7.0, 11.0),
            target: Vec3::new(1.0, 0.8, 0.0),
            up: Vec3::Y,
            fov_y_deg,
            width: 512,
            height: 384,
            near: 0.1,
            far: 100.0,
        }
    }

    /// A bundled scene's view (teapot-rect) takes the derivatives' normals; the same view
    /// narrowed to 0.002° (the stress suite's dense-cell), or moved 10⁵ units from the origin,
    /// may hold pixels denser than f32 resolves.
    #[test]
    fn only_views_denser_than_f32_take_the_face_normals() {
        let bounds = Aabb {
            min: Vec3::new(-8.0, 0.0, -8.0),
            max: Vec3::new(8.0, 3.2, 8.0),
        };
        assert!(!may_be_denser_than_f32(&camera(45.0), &bounds));
        assert!(may_be_denser_than_f32(&camera(0.002), &bounds));
        let far = Vec3::splat(1e5);
        let moved = Aabb {
            min: bounds.min + far,
            max: bounds.max + far,
        };
        let mut c = camera(45.0);
        c.position += far;
        c.target += far;
        assert!(may_be_denser_than_f32(&c, &moved));
        assert!(!may_be_denser_than_f32(&camera(45.0), &Aabb::EMPTY));
    }
}
