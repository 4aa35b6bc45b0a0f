//! `pcss`: percentage-closer soft shadows (Fernando 2005; book §6.5.3) with the exact
//! texel-coverage filter of PVSSM §4.1 and min/max work skipping (book §6.5.4, App. D.2).
//!
//! Per frame:
//!
//! 1. the D32 [`ShadowMap`] from the light's centre;
//! 2. with `skip = nbuffer`, an [`NBuffer`] of it (exact min and max depth over any texel
//!    rectangle, 8 B per texel per level); with `skip = pyramid` (the default), a
//!    [`MinMaxPyramid`] (min and max over a superset of the rectangle: the cells of the finest
//!    level covering it with at most 4 cells per axis; 2.7 B per texel, a fifth of the N-buffer's
//!    build time, but it classifies fewer samples, so with the exhaustive search the N-buffer
//!    gives the faster frame — measured in the README);
//! 3. `glsl/pcss/blocker_search.comp`, per view sample at map position x and light-view distance
//!    z_y: the search region is the light's footprint at the near plane,
//!    w_s = [`soft_light`]`(z_y, near)` — the light-pyramid cross-section w_light·(z_y − z_n)/z_y
//!    in texels — centred at x. z_avg is the mean distance of its blocking texels (texels nearer
//!    the light than the sample), each weighted by its area inside the region (`search_taps = 0`,
//!    continuous as the region moves) or over an n×n grid of point taps (`search_taps = n`). No
//!    blocker: lit, V = 1 (PCSS's own early out). With `blocker_depth = silhouette` a second walk
//!    over the same texels or taps averages only the silhouette's (blockers beside one that does
//!    not block, at least a quarter of z_avg's distance from the receiver: `pvssm`'s rule), the
//!    plain mean where none is left — a rounded caster's top, nearer the light than the
//!    silhouette that bounds its shadow, no longer widens the penumbra (README: teapot-rect
//!    penumbra MAE 0.029 → 0.020 with 8×8 taps);
//! 4. `glsl/pcss/filter.comp`: the filter w_f = `soft_light(z_y, z_avg)` =
//!    w_light·(z_y − z_avg)/(z_y·z_avg) in texels (Eqs. 6.9 and 6.10 combined), evaluated with
//!    `pcf-coverage`'s exact texel-coverage box (`glsl/include/coverage.glsl`) or, with
//!    `filter_taps = n` and w_f > n, an n×n grid of bilinear tests.
//!
//! Both widths are clamped to [`MIN_KERNEL`, `MAX_WIDTH`]: a point light gives `min_kernel`,
//! `pcf-coverage` with that kernel.
//!
//! **Work skipping, identical output.** With skipping on, the search pass first asks the
//! structure for (min, max) over the region's texels grown by one texel on each side (the farthest a
//! bilinear filter tap reaches past the region's texels), and compares them with the range of
//! depths the sample's texels are tested at (its depth z, or with receiver-plane bias the plane's
//! depths at the grown region's corner texels: the plane is linear and float rounding monotone,
//! so no texel's depth falls outside the corners'). If min ≥ the highest, no texel the search or
//! the filter reads can block: the search would find no blocker and return V = 1. If max < the
//! lowest and the grown region lies inside the map (texels off the map read as the far plane,
//! lit), every texel blocks: the search finds blockers, the filter box lies inside the region
//! (w_f ≤ w_s because the footprint is monotone in the blocker distance and z_avg ≥ near), so
//! every filter test is 0 and V = 0. Either way the shortcut writes the value the full path
//! would have, **bit for bit** (the tests check it). Counters `skipped_lit`, `skipped_umbra`
//! count the shortcuts; `lit`, `umbra`, `penumbra` count the written values. A superset's
//! (min, max) only classifies less, never differently. Skipping costs the structure's build
//! (N-buffer levels up to [`MAX_SKIP_LEVEL`]) and saves the search — (w_s + 1)² texel reads
//! exhaustively, n² with a grid — wherever it classifies.
//!
//! It classifies receivers that face the light: a region of teapot-rect's ground (parallel to
//! the rect light) holds depths at or behind the sample's. A receiver tilted against the map
//! (plane-boxes' oblique light) straddles its own region — part of its surface is nearer the
//! light than z, part farther, and with receiver-plane bias each texel is behind *its own*
//! plane depth but not behind the plane's highest depth over the region — so min/max cannot
//! classify it, and such views run the full search (measured in the README's skip table).
//!
//! **Loop lengths.** The exhaustive search and filter read up to (`max_width` + 1)² texels in
//! one loop nest. lavapipe stops any loop after 65 535 iterations per SIMD group (see
//! `crate::reference`), so the exhaustive modes reject `max_width` above
//! [`EXHAUSTIVE_MAX_WIDTH`] with a clear error rather than return a truncated sum.
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`, `skipped_lit`,
//! `skipped_umbra`, `clamped` (search regions wider than `max_width`), `plane_fallback`
//! (receiver-plane bias asked for, no same-plane neighbour: one depth used). CPU twin:
//! [`crate::cpu::pcss`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4, Vec2};

use super::pcf::shadow_map_desc;
use super::soft_light::{soft_light, MAX_WIDTH, MIN_KERNEL};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, BIAS_KNOBS,
    SHADOW_MAP_KNOBS,
};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder};
use crate::kernels::minmax::MinMaxPyramid;
use crate::kernels::nbuffer::{level_bindings, NBuffer, MAX_LEVEL};
use crate::passes::{SceneGeometry, ShadowMap};

/// Counter names, in the shaders' slot order.
pub const COUNTER_NAMES: [&str; 9] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "skipped_lit",
    "skipped_umbra",
    "clamped",
    "plane_fallback",
];

/// The highest N-buffer level built for skipping: windows of 32 texels, so a region of the
/// default `max_width` (128) takes at most 5 × 5 lookups, at 40 B per map texel.
pub const MAX_SKIP_LEVEL: u32 = 5;

/// The widest `max_width` the exhaustive search or filter accepts: (200 + 2)² texel reads stay
/// under lavapipe's 65 535 loop iterations.
pub const EXHAUSTIVE_MAX_WIDTH: f32 = 200.0;

/// The widest `max_width` an exhaustive search with `blocker_depth = silhouette` accepts: its
/// second walk over the region doubles the loop passes, 2·(170 + 2)² of lavapipe's 65 535.
pub const SILHOUETTE_MAX_WIDTH: f32 = 170.0;

const KNOBS: [Knob; 11] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    Knob {
        name: "search_taps",
        summary: "blocker search: 0 every texel of the region (area-weighted), n an n x n grid",
        default: KnobDefault::Value(0.0),
        min: 0.0,
        max: 64.0,
        integer: true,
        names: &[],
    },
    Knob {
        name: "filter_taps",
        summary: "filter: 0 exact texel coverage, n an n x n bilinear grid once wider than n",
        default: KnobDefault::Value(0.0),
        min: 0.0,
        max: 64.0,
        integer: true,
        names: &[],
    },
    Knob {
        name: "skip",
        summary: "classify regions by min/max depth first (same output, less work): off, by an \
                  N-buffer (exact), or by a min/max pyramid (a superset; cheaper to build)",
        default: KnobDefault::Value(2.0),
        min: 0.0,
        max: 2.0,
        integer: true,
        names: &["off", "nbuffer", "pyramid"],
    },
    Knob {
        name: "receiver_plane_bias",
        summary: "1: test every texel at the receiver plane's depth under it; 0: one depth",
        default: KnobDefault::Value(1.0),
        min: 0.0,
        max: 1.0,
        integer: true,
        names: &[],
    },
    Knob {
        name: "blocker_depth",
        summary: "z_avg: the average of every blocker of the search, or of the silhouette's \
                  (blockers beside one that does not block, away from the receiver's own \
                  surface; a second walk over the region)",
        default: KnobDefault::Value(0.0),
        min: 0.0,
        max: 1.0,
        integer: true,
        names: &["average", "silhouette"],
    },
    MIN_KERNEL,
    MAX_WIDTH,
];

/// `pcss`: percentage-closer soft shadows.
pub const PCSS: TechniqueInfo = TechniqueInfo {
    name: "pcss",
    summary: "percentage-closer soft shadows: blocker search, exact-coverage filter, skipping",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Pcss::new(setup, params)?)),
};

/// The push-constant block of `glsl/pcss/pcss.glsl`, shared by both passes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PcssPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map width and height.
    pub map_size: i32,
    /// The N-buffer's highest level.
    pub max_level: i32,
    /// The light's footprint factor per map axis ([`super::soft_light::SoftLight::size`]).
    pub light_size: Vec2,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// 1 for a perspective light view.
    pub perspective: i32,
    /// 1: N-buffer classification first.
    pub skip: i32,
    /// Search grid side (0: exhaustive).
    pub search_taps: i32,
    /// Filter grid side (0: exact coverage).
    pub filter_taps: i32,
    /// Floor on the widths, texels.
    pub min_kernel: f32,
    /// Cap on the widths, texels.
    pub max_width: f32,
    /// 1: receiver-plane depth per texel.
    pub receiver_plane: i32,
    /// 0: z_avg over every blocker; 1: over the silhouette's.
    pub blocker_depth: i32,
}

/// The skip classification's structure (the `skip` knob).
// One a renderer, built once: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
enum MinMax<'a> {
    Off,
    NBuffer(NBuffer<'a>),
    Pyramid(MinMaxPyramid<'a>),
}

impl MinMax<'_> {
    /// The images of the levels built above the source, level 1 first.
    fn levels(&self) -> Vec<&Image> {
        match self {
            MinMax::Off => Vec::new(),
            MinMax::NBuffer(n) => (1..=n.max_level).filter_map(|l| n.level(l)).collect(),
            MinMax::Pyramid(p) => (1..p.sizes.len() as u32)
                .filter_map(|l| p.level(l))
                .collect(),
        }
    }

    fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        match self {
            MinMax::Off => Ok(()),
            MinMax::NBuffer(n) => n.record(rec),
            MinMax::Pyramid(p) => p.record(rec),
        }
    }
}

struct Pcss<'a> {
    ctx: Context,
    // Field order is drop order: the N-buffer and the sets refer to the map's depth image, which
    // is dropped last (see `new`).
    minmax: MinMax<'a>,
    search_set: DescriptorSet,
    filter_set: DescriptorSet,
    search: Pipeline,
    filter: Pipeline,
    counters: Buffer,
    _blocker: Image,
    _unused_levels: Image,
    push: PcssPush,
    geometry: &'a SceneGeometry,
    /// The knobs it was built with (what [`Technique::retune`] compares against).
    built: Params,
    shadow_map: Box<ShadowMap>,
}

fn parameter(message: String) -> Error {
    Error::Parameter {
        technique: PCSS.name.into(),
        message,
    }
}

/// The knobs that only change [`PcssPush`]: retunable in place (with the bias).
const PUSH_KNOBS: [&str; 6] = [
    "blocker_depth",
    "search_taps",
    "filter_taps",
    "min_kernel",
    "max_width",
    "receiver_plane_bias",
];

/// [`PUSH_KNOBS`] from `params`, checked together: (search taps, filter taps, min kernel,
/// max width, receiver plane).
fn push_knobs(params: &Params) -> Result<(i32, i32, f32, f32, i32)> {
    let search_taps = params.u32("search_taps")? as i32;
    let filter_taps = params.u32("filter_taps")? as i32;
    let min_kernel = params.f32("min_kernel")?;
    let max_width = params.f32("max_width")?;
    let receiver_plane = params.u32("receiver_plane_bias")? as i32;
    if min_kernel > max_width {
        return Err(parameter(format!(
            "min_kernel = {min_kernel} exceeds max_width = {max_width}"
        )));
    }
    if search_taps == 0 && params.u32("blocker_depth")? == 1 && max_width > SILHOUETTE_MAX_WIDTH {
        return Err(parameter(format!(
            "max_width = {max_width} with an exhaustive search and blocker_depth = \
             silhouette: at most {SILHOUETTE_MAX_WIDTH} texels (its two walks over the region \
             must fit software drivers' 65 535 loop iterations); set search_taps, or a smaller \
             max_width"
        )));
    }
    if (search_taps == 0 || filter_taps == 0) && max_width > EXHAUSTIVE_MAX_WIDTH {
        return Err(parameter(format!(
            "max_width = {max_width} with an exhaustive search or filter: at most \
             {EXHAUSTIVE_MAX_WIDTH} texels (software drivers stop loops after 65 535 \
             iterations); set search_taps and filter_taps, or a smaller max_width"
        )));
    }
    Ok((
        search_taps,
        filter_taps,
        min_kernel,
        max_width,
        receiver_plane,
    ))
}

impl<'a> Pcss<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let skip = params.u32("skip")? as i32;
        let (search_taps, filter_taps, min_kernel, max_width, receiver_plane) = push_knobs(params)?;
        let shadow_map = Box::new(ShadowMap::new(
            ctx,
            *setup.light_view,
            shadow_map_desc(params)?,
        )?);
        let size = shadow_map.desc.size;
        let light = soft_light(setup.light, setup.light_view, size)?;
        // SAFETY: the N-buffer borrows the depth image only to tie it to the image's life (its
        // sets name it). The map is boxed, so its address survives moves of `Pcss`; it is never
        // replaced, and it is declared last, so it is dropped after everything referring to it.
        let depth: &'a Image = unsafe { &*(&shadow_map.depth as *const Image) };
        let minmax = match skip {
            0 => MinMax::Off,
            1 => MinMax::NBuffer(NBuffer::new(ctx, depth, Some(MAX_SKIP_LEVEL))?),
            _ => MinMax::Pyramid(MinMaxPyramid::new(ctx, depth)?),
        };
        let usage = vk::ImageUsageFlags::STORAGE;
        let blocker = Image::new(
            ctx,
            "pcss blocker distance",
            ImageDesc::new_2d(
                vk::Format::R32_SFLOAT,
                setup.view.width,
                setup.view.height,
                usage,
            ),
        )?;
        let counters = Buffer::storage(ctx, "pcss counters", (COUNTER_NAMES.len() * 4) as u64)?;
        let search = Pipeline::compute(ctx, "pcss/blocker_search.comp")?;
        let filter = Pipeline::compute(ctx, "pcss/filter.comp")?;

        // Levels the shader never reads (none built, or above the highest) are still bound: to
        // the highest level, or to a 1×1 pair when nothing is built.
        let levels = minmax.levels();
        let built = levels.len() as u32;
        if built > MAX_LEVEL {
            return Err(parameter(format!(
                "{built} min/max levels, at most {MAX_LEVEL}"
            )));
        }
        let unused_levels = crate::kernels::nbuffer::minmax_image(ctx, "pcss unused levels", 1, 1)?;
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
            Binding::Image(&blocker),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
            Binding::Image(&setup.view.normals),
            Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
        ];
        bindings.extend(level_bindings(&levels, &unused_levels, &shadow_map.sampler));
        let search_set = DescriptorSet::new(ctx, &search, &bindings)?;
        let filter_set = DescriptorSet::new(ctx, &filter, &bindings[..6])?;
        let push = PcssPush {
            light_view_proj: setup.light_view.view_proj,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            map_size: size as i32,
            max_level: built as i32,
            light_size: light.size,
            near: setup.light_view.near,
            far: setup.light_view.far,
            perspective: light.perspective as i32,
            skip,
            search_taps,
            filter_taps,
            min_kernel,
            max_width,
            receiver_plane,
            blocker_depth: params.u32("blocker_depth")? as i32,
        };
        Ok(Pcss {
            ctx: ctx.clone(),
            minmax,
            search_set,
            filter_set,
            search,
            filter,
            counters,
            _blocker: blocker,
            _unused_levels: unused_levels,
            push,
            geometry: setup.geometry,
            built: params.clone(),
            shadow_map,
        })
    }
}

impl Technique for Pcss<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        let view = [
            self.push.view_size.x as u32,
            self.push.view_size.y as u32,
            1,
        ];
        if !matches!(self.minmax, MinMax::Off) {
            rec.begin_pass("pcss-minmax")?;
            self.minmax.record(rec)?;
        }
        rec.begin_pass("pcss-blocker-search")?;
        rec.fill(&self.counters, 0);
        rec.dispatch(&self.search, &self.search_set, &self.push, view)?;
        rec.begin_pass("pcss-filter")?;
        rec.dispatch(&self.filter, &self.filter_set, &self.push, view)?;
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        super::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }

    fn retune(&mut self, params: &Params) -> Result<bool> {
        let allowed: Vec<&str> = BIAS_KNOBS.iter().chain(&PUSH_KNOBS).copied().collect();
        if !super::only_changed(&self.built, params, &allowed) {
            return Ok(false);
        }
        let (search_taps, filter_taps, min_kernel, max_width, receiver_plane) = push_knobs(params)?;
        self.shadow_map
            .set_bias(&self.ctx, shadow_map_desc(params)?.bias)?;
        self.push = PcssPush {
            search_taps,
            filter_taps,
            min_kernel,
            max_width,
            receiver_plane,
            blocker_depth: params.u32("blocker_depth")? as i32,
            ..self.push
        };
        self.built = params.clone();
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::size_of;

    #[test]
    fn push_size_matches_the_shaders() {
        assert_eq!(size_of::<PcssPush>(), 128);
        for shader in ["pcss/blocker_search.comp", "pcss/filter.comp"] {
            let declared = shader_interface(shader).expect("embedded").1;
            assert_eq!(
                declared.push_constant_size as usize,
                size_of::<PcssPush>(),
                "{shader}"
            );
        }
    }
}
