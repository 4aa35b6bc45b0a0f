//! `bitmask`: occlusion-bitmask soft shadows (Schwarz and Stamminger 2007; book §6.7.2), the
//! micropatch back-projection of the book's §6.7.1 with light-sample bitmasks for exact occluder
//! fusion.
//!
//! Per frame: the D32 [`ShadowMap`] from the light's centre; with `skip` on, an [`NBuffer`] of it;
//! then `glsl/bitmask/bitmask.comp`, one view sample per invocation and one dispatch per
//! 256-sample group of the mask (so lavapipe's per-dispatch loop limiter gives every group the
//! same region cap, [`loop_width`]; the groups' visible counts add up in a per-pixel buffer).
//! Each texel of the sample's search region nearer the light than the receiver plane under it
//! is a micropatch — the square
//! of the view plane it covers at its depth, parallel to the light — whose back-projection from
//! the sample onto the light is an axis-aligned rectangle (`glsl/include/backprojection.glsl`).
//! Its light samples are four table lookups: with each sample's coordinates snapped to a
//! [`TABLE_RESOLUTION`]-step grid over the light's box, `X[i]` holds the samples whose x step is
//! below i (likewise `Y`), so the rectangle's samples are `X[i1] & !X[i0] & Y[j1] & !Y[j0]` —
//! exact for the snapped pattern, whatever its shape (the book's "3 lookups" scheme in separable
//! form). The masks are OR-ed, so overlapping patches count once (occluder fusion);
//! V = popcount(front & !blocked) / n, `front` being the samples in front of the receiver's
//! tangent plane with `light_clip` on (the technique clips them itself, sample by sample, so the
//! engine does not scale its result). `combine = add` sums the patches' hidden areas instead
//! (Atty's saturation product): the classic additive back-projection, which counts overlaps
//! twice and over-darkens.
//!
//! **Pattern**: n = `samples` (a power of two, 16 to 1024) stratified cells, n_a × n_b with
//! n_a = 2^⌈log₂n / 2⌉, each jittered by a PCG hash of a fixed seed (one pattern for every
//! pixel, so one set of tables), on the rect light, or through Shirley and Chiu's concentric map
//! on the sun's disk of slopes. A point light or a hard sun is a box 2·10⁻⁷·far wide: every
//! sample at its centre, the hard shadow of the micropatches.
//!
//! **Search region and work skipping**: the light's footprint through the near plane, capped at
//! `max_width` texels (counted as `clamped`). Its (min, max) depth — from the N-buffer with
//! `skip = nbuffer`, by a scan of the region with `skip = off`; the same values, so the same
//! output bit for bit — decides three cases: min at or behind every receiver-plane depth, no
//! patch can block (`skipped_lit`: V = the front fraction without the loop); max in front of
//! every one, umbra (`skipped_umbra`: the height field covers every ray to the light; the loop's
//! patches would leave slivers of light through the gaps between patches at different depths,
//! the micropatch artefact of book §6.7.3); otherwise the region shrinks to the footprint
//! through the nearest texel (Guennebaud et al. 2006) and the patches are back-projected.
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`, `skipped_lit`,
//! `skipped_umbra`, `clamped`, `plane_fallback`, `patches` (back-projected micropatches). CPU
//! twin: [`crate::cpu::bitmask`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec4, Mat4, Vec2, Vec4};

use super::pcf::shadow_map_desc;
use super::soft_light::MAX_WIDTH;
use super::{Knob, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder, TexelView};
use crate::kernels::nbuffer::{level_bindings, NBuffer, MAX_LEVEL};
use crate::passes::{LightProjection, SceneGeometry, ShadowMap};

/// Counter names, in the shader's slot order.
pub const COUNTER_NAMES: [&str; 11] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "skipped_lit",
    "skipped_umbra",
    "clamped",
    "plane_fallback",
    "patches",
    "cut",
];

/// Steps per axis of the grid the light samples are snapped to (the tables' rows).
pub const TABLE_RESOLUTION: u32 = 1024;

/// The highest N-buffer level built for skipping (windows of 32 texels).
pub const MAX_SKIP_LEVEL: u32 = 5;

/// The widest region the loops accept: (200 + 1)² texels stay under lavapipe's 65 535 loop
/// iterations.
pub const EXHAUSTIVE_MAX_WIDTH: f32 = 200.0;

/// lavapipe's loop limiter: 65 535 loop passes per SIMD group and dispatch, shared by every loop
/// of the shader, after which every loop silently exits (see `crate::reference`).
pub const LOOP_PASSES: u32 = 65_535;

/// The widest search region (texels a side) whose loops fit [`LOOP_PASSES`] with room to spare
/// (1 000 passes for the rest of the shader). Each 256-sample group runs in its own dispatch,
/// and the limiter counts per dispatch, so the budget is one group's: `per_texel` passes a texel
/// and two a row, up to 256 for the group's front mask, and with `skip` off one a texel and two
/// a row more for the scan. The technique caps its regions here on every device, so its output
/// is the same everywhere (regions cut are counted as `clamped`): 146 texels with `skip` on at
/// every sample count. (When all groups shared one dispatch the cap fell to 72 texels at 512
/// samples and 51 at 1024, and the cut regions made 1024 samples less accurate than 256: on
/// `teapot-rect` with the light doubled, penumbra MAE 0.116 against 0.035.)
pub fn loop_width(samples: u32, skip: bool) -> f32 {
    let budget = f64::from(LOOP_PASSES) - 1000.0 - f64::from(samples.min(256));
    // p·W² + 2W + scan·(W² + 2W) ≤ budget.
    let scan = if skip { 0.0 } else { 1.0 };
    let a = per_texel() + scan;
    let b = 2.0 * (1.0 + scan);
    let w = (-b + (b * b + 4.0 * a * budget).sqrt()) / (2.0 * a);
    w.floor() as f32
}

/// Loop passes a texel costs a group's dispatch: three (the texel loop's, and entering and
/// leaving the mask's second-word branch, a loop of one pass).
fn per_texel() -> f64 {
    3.0
}

/// The push constant of `glsl/bitmask/backproject.glsl`: the dispatch's 256-sample group.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BitmaskPush {
    /// Group index, 0 ..= (samples − 1) / 256.
    pub group: i32,
}

/// The fixed seed of the pattern's jitter.
pub const PATTERN_SEED: u32 = 0x9e37_79b9;

mod pattern;
pub use pattern::{grid, light_box, unit_mapping, LightPattern};

const KNOBS: [Knob; 10] = [
    Knob {
        name: "map_size",
        summary: "shadow-map width and height in texels (its own default: a region's texels, \
                  and the cost, grow with the map's area)",
        default: super::KnobDefault::Value(1024.0),
        ..SHADOW_MAP_KNOBS[0]
    },
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    Knob::int(
        "samples",
        "light samples, a power of two from 16 to 1024 (bits per mask)",
        256.0,
        16.0,
        1024.0,
    ),
    Knob::int(
        "combine",
        "bitmask: OR the patches' sample masks; add: sum their hidden areas (over-darkens)",
        0.0,
        0.0,
        1.0,
    )
    .named(&["bitmask", "add"]),
    Knob::int(
        "skip",
        "classify regions by min/max depth from an N-buffer first (less work; a region proven \
         wholly blocked is umbra, where bare micropatches can leak through their gaps)",
        1.0,
        0.0,
        1.0,
    )
    .named(&["off", "nbuffer"]),
    Knob::int(
        "receiver_plane_bias",
        "1: test every texel at the receiver plane's depth under it; 0: one depth",
        1.0,
        0.0,
        1.0,
    ),
    Knob::int(
        "gap_fill",
        "1: a blocking patch's edges reach its blocking neighbours' back-projections (no \
         slivers of light between patches at different depths); 0: bare micropatches",
        0.0,
        0.0,
        1.0,
    ),
    MAX_WIDTH,
];

/// `bitmask`: occlusion-bitmask back-projection.
pub const BITMASK: TechniqueInfo = TechniqueInfo {
    name: "bitmask",
    summary: "back-projected shadow-map micropatches OR-ed into light-sample bitmasks",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: true,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Bitmask::new(setup, params)?)),
};

/// The uniform block of `glsl/bitmask/bitmask.glsl` (std140, 240 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct BitmaskParams {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// World → light view space.
    pub light_view: Mat4,
    /// Projection scale (x, y) and the ndc of unit coordinate 0 (x, y).
    pub scale_offset: Vec4,
    /// The light's box on its plane: lo (x, y), 1 / extent (x, y).
    pub light_box: Vec4,
    /// View width, height; map size; the N-buffer's highest level.
    pub sizes: IVec4,
    /// Near, far, max_width, unused.
    pub planes: Vec4,
    /// Perspective, skip, receiver-plane bias, light clip.
    pub modes: IVec4,
    /// Samples, 256-bit groups, table resolution, combine.
    pub samples: IVec4,
    /// Gap filling, unused × 3.
    pub options: IVec4,
}

struct Bitmask<'a> {
    ctx: Context,
    // Field order is drop order: the N-buffer and the set refer to the map's depth image, which
    // is dropped last (see `new`).
    nbuffer: Option<NBuffer<'a>>,
    set: DescriptorSet,
    pipeline: Pipeline,
    counters: Buffer,
    _views: [TexelView; 2],
    /// 256-sample groups: one dispatch each.
    groups: u32,
    _buffers: [Buffer; 4],
    _unused_levels: Image,
    view_size: [u32; 2],
    geometry: &'a SceneGeometry,
    shadow_map: Box<ShadowMap>,
}

fn parameter(message: String) -> Error {
    Error::Parameter {
        technique: BITMASK.name.into(),
        message,
    }
}

impl<'a> Bitmask<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let n = params.u32("samples")?;
        let combine = params.u32("combine")?;
        let skip = params.u32("skip")?;
        let receiver_plane = params.u32("receiver_plane_bias")?;
        let max_width = params.f32("max_width")?;
        let light_clip = params.u32("light_clip")?;
        let gap_fill = params.u32("gap_fill")?;
        if unit_mapping(setup.light_view)
            .truncate()
            .truncate()
            .cmple(Vec2::ZERO)
            .any()
        {
            return Err(parameter(
                "the light view's projection flips an axis (a negative scale)".into(),
            ));
        }
        if max_width > EXHAUSTIVE_MAX_WIDTH {
            return Err(parameter(format!(
                "max_width = {max_width}: at most {EXHAUSTIVE_MAX_WIDTH} texels (software \
                 drivers stop loops after 65 535 iterations)"
            )));
        }
        let pattern = LightPattern::new(setup.light, setup.light_view, n)?;
        let shadow_map = Box::new(ShadowMap::new(
            ctx,
            *setup.light_view,
            shadow_map_desc(params)?,
        )?);
        let size = shadow_map.desc.size;
        // SAFETY: as in `pcss`: the N-buffer borrows the boxed map's depth image, which is never
        // replaced and is dropped after everything referring to it (declared last).
        let depth: &'a Image = unsafe { &*(&shadow_map.depth as *const Image) };
        let nbuffer = skip_nbuffer(ctx, depth, skip == 1)?;
        let levels = nbuffer_levels(&nbuffer);
        let built = levels.len() as u32;
        let perspective = matches!(
            setup.light_view.projection,
            LightProjection::Perspective { .. }
        );
        let params_block = BitmaskParams {
            light_view_proj: setup.light_view.view_proj,
            light_view: setup.light_view.view,
            scale_offset: unit_mapping(setup.light_view),
            light_box: Vec4::new(pattern.lo.x, pattern.lo.y, pattern.inv.x, pattern.inv.y),
            sizes: IVec4::new(
                setup.view.width as i32,
                setup.view.height as i32,
                size as i32,
                built as i32,
            ),
            planes: Vec4::new(
                setup.light_view.near,
                setup.light_view.far,
                max_width.min(loop_width(n, skip == 1)),
                0.0,
            ),
            modes: IVec4::new(
                i32::from(perspective),
                skip as i32,
                receiver_plane as i32,
                light_clip as i32,
            ),
            samples: IVec4::new(
                n as i32,
                pattern.groups as i32,
                TABLE_RESOLUTION as i32,
                combine as i32,
            ),
            options: IVec4::new(gap_fill as i32, 0, 0, 0),
        };
        let params_buffer = ctx.buffer_with(
            "bitmask params",
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            std::slice::from_ref(&params_block),
        )?;
        let texels = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let tables = ctx.buffer_with("bitmask tables", texels, &pattern.tables)?;
        let points: Vec<[f32; 2]> = pattern.points.iter().map(|p| p.to_array()).collect();
        let samples = ctx.buffer_with("bitmask samples", texels, &points)?;
        let views = [
            tables.texel_view(vk::Format::R32G32B32A32_UINT, 16)?,
            samples.texel_view(vk::Format::R32G32_SFLOAT, 8)?,
        ];
        let counters = Buffer::storage(ctx, "bitmask counters", (COUNTER_NAMES.len() * 4) as u64)?;
        // Each sample's visible count (and hidden area) between its groups' dispatches; with one
        // group no dispatch reads it (bound all the same).
        let pixels = u64::from(setup.view.width) * u64::from(setup.view.height);
        let running_bytes = if pattern.groups > 1 {
            8 * pixels.max(1)
        } else {
            8
        };
        let running = Buffer::storage(ctx, "bitmask running counts", running_bytes)?;
        let pipeline = Pipeline::compute(
            ctx,
            if gap_fill == 1 {
                "bitmask/bitmask_gap_fill.comp"
            } else {
                "bitmask/bitmask.comp"
            },
        )?;
        let unused_levels =
            crate::kernels::nbuffer::minmax_image(ctx, "bitmask unused levels", 1, 1)?;
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Image(&setup.view.normals),
            Binding::Buffer(&params_buffer),
            Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
            Binding::Texels(&views[0]),
            Binding::Texels(&views[1]),
            Binding::Image(&setup.view.positions),
            Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
        ];
        bindings.extend(level_bindings(&levels, &unused_levels, &shadow_map.sampler));
        bindings.push(Binding::Buffer(&running));
        let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
        Ok(Bitmask {
            ctx: ctx.clone(),
            nbuffer,
            set,
            pipeline,
            counters,
            _views: views,
            groups: pattern.groups,
            _buffers: [params_buffer, tables, samples, running],
            _unused_levels: unused_levels,
            view_size: [setup.view.width, setup.view.height],
            geometry: setup.geometry,
            shadow_map,
        })
    }
}

impl Technique for Bitmask<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        if let Some(nb) = &self.nbuffer {
            rec.begin_pass("bitmask-nbuffer")?;
            nb.record(rec)?;
        }
        rec.begin_pass("bitmask-backprojection")?;
        rec.fill(&self.counters, 0);
        let [w, h] = self.view_size;
        for group in 0..self.groups {
            let push = BitmaskPush {
                group: group as i32,
            };
            rec.dispatch(&self.pipeline, &self.set, &push, [w, h, 1])?;
        }
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let counters = super::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)?;
        limiter_check(BITMASK.name, &counters)?;
        Ok(counters)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }
}

/// The N-buffer of `depth` the skip classification reads (levels up to [`MAX_SKIP_LEVEL`]),
/// when `skip` is on: shared by `bitmask` and `atty`.
pub(crate) fn skip_nbuffer<'a>(
    ctx: &Context,
    depth: &'a Image,
    skip: bool,
) -> Result<Option<NBuffer<'a>>> {
    if !skip {
        return Ok(None);
    }
    let nb = NBuffer::new(ctx, depth, Some(MAX_SKIP_LEVEL))?;
    // The shaders bind levels 1 ..= MAX_LEVEL (nbuffer.glsl); MAX_SKIP_LEVEL is far below.
    debug_assert!(nb.max_level <= MAX_LEVEL);
    Ok(Some(nb))
}

/// The levels of a skip N-buffer above its source, level 1 first (none without one): what
/// [`level_bindings`] binds.
pub(crate) fn nbuffer_levels<'b>(nbuffer: &'b Option<NBuffer<'_>>) -> Vec<&'b Image> {
    nbuffer.as_ref().map_or(Vec::new(), |nb| {
        (1..=nb.max_level).filter_map(|l| nb.level(l)).collect()
    })
}

/// Fails the frame when the shader's loop-limiter guard counted invocations cut short (`cut`):
/// their visibility is wrong.
pub(crate) fn limiter_check(technique: &str, counters: &[(String, u64)]) -> Result<()> {
    let cut = counters
        .iter()
        .find(|(k, _)| k == "cut")
        .map_or(0, |(_, v)| *v);
    if cut > 0 {
        return Err(Error::Shader {
            name: technique.to_string(),
            message: format!(
                "the driver's loop limiter cut {cut} invocations short: the frame is wrong \
                 (a smaller `max_width` or fewer `samples` shortens the loops)"
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_block_is_std140_sized() {
        assert_eq!(std::mem::size_of::<BitmaskParams>(), 240);
    }

    #[test]
    fn loop_width_fits_the_limiter() {
        for n in [16, 64, 256, 512, 1024] {
            for skip in [true, false] {
                let w = loop_width(n, skip) as f64;
                let scan = if skip { 0.0 } else { w * w + 2.0 * w };
                // One group's dispatch: its region loop, its front mask, the scan.
                let passes = per_texel() * w * w + 2.0 * w + scan;
                assert!(
                    passes + f64::from(n.min(256)) + 1000.0 <= f64::from(LOOP_PASSES),
                    "{n} {skip}"
                );
                assert!(w >= 120.0, "{n} {skip}: {w}");
            }
        }
        assert_eq!(loop_width(256, true), 146.0);
        assert_eq!(loop_width(1024, true), 146.0);
    }

    #[test]
    fn grids_multiply_to_n() {
        for n in [16, 32, 64, 128, 256, 512, 1024] {
            let (a, b) = grid(n);
            assert_eq!(a * b, n);
            assert!(a >= b && a <= 2 * b, "{n}: {a} x {b}");
        }
    }
}
