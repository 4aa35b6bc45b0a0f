//! `cascades`: z-partitioned shadow maps (cascaded / parallel-split shadow maps, book §4.3; SDSM,
//! Lauritzen11), the way engines ship sun shadows.
//!
//! The view's depth range is split into `count` slices (`partition`: practical `pssm` splits with
//! `lambda`, `uniform`, `log`, or `sdsm` fitted to the view samples — see
//! [`crate::passes::cascade_fit`]); each slice gets a map of at most `map_size`² texels fitted to
//! it, in the better of two orientations, all in one depth atlas (tiles in a row, wrapping into
//! rows past the device's largest image side), drawn with one viewport per tile in one rendering
//! scope. The tiles share one shape, chosen at set-up among [`cascade_fit::tile_candidates`] by
//! the view samples' p95 sampling error ([`fit`]). `snap` (on by default) rounds each window to
//! whole texels of a fixed ladder of sizes so a still scene's maps do not shimmer as the camera
//! moves.
//!
//! Per frame: with `sdsm`, the depth-histogram reduction (`glsl/cascades/depth_histogram.comp`,
//! timed as `depth-histogram`; an engine reads it back for the next frame — here the set-up runs
//! it once and fits from that, which for a still scene is the frame's own); the atlas
//! (`light-depth`), skipping the maps of cascades no view sample falls in (`cascades_skipped`,
//! SDSM only: a frustum slice cannot know); the lookup (`glsl/cascades/lookup.glsl`), finest
//! cascade first, each fading into the next over a band of `blend` texels at its tile's edge, so
//! no seam shows. `filter = hard` tests the nearest texel, `pcf` a `kernel` × `kernel` box of
//! bilinear taps as `pcf`, with each tap at the receiver plane's depth under it by default
//! ([`RECEIVER_PLANE`]; the plane's gradient taken in each cascade's own map).
//!
//! Counters: `view_samples`, `outside_light` (no cascade covers it: lit), `lit`, `umbra`,
//! `penumbra`, `blended` (in a band), `plane_fallback` (no receiver plane in the first cascade
//! used: one depth there), `cascade0`… (samples looked up first in each cascade),
//! `cascades_skipped`. CPU twin: [`crate::cpu::cascades`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, IVec4, Mat4, UVec2, Vec2, Vec4};

use crate::sampling_error::{nearest_rank, SampleFootprints, SamplingGrid};

use super::pcf::{shadow_map_desc, FILTER, KERNEL, RECEIVER_PLANE_BIAS};
use super::{Knob, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS};
use crate::error::{Error, Result};
use crate::gpu::{
    Access, Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder, Sampler,
};
use crate::passes::cascade_fit::{
    self, Cascade, DepthHistogram, FitDesc, Partition, HISTOGRAM_BINS, MAX_CASCADES,
};
use crate::passes::{
    depth_pipeline, LightProjection, LightView, MapLayer, SceneGeometry, ShadowMapDesc,
    SHADOW_MAP_FORMAT,
};
use crate::scene::{Aabb, Camera};
use crate::shader_types::LightDepthPush;

/// Counter slots the lookup writes, in order (then one per cascade, `cascade0`…).
pub const LOOKUP_COUNTERS: [&str; 7] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "blended",
    "plane_fallback",
];

/// `receiver_plane_bias` of the PCF family, used with `filter = pcf` (on by default, as for
/// `pcf`: a cascade's texels grow with its slice, and one receiver depth across a kernel of them
/// self-shadows every slope the slope bias, sized for one texel, does not cover).
pub const RECEIVER_PLANE: Knob = Knob {
    summary: "with filter = pcf, 1: per-tap receiver-plane depth from neighbouring view samples, \
              in each cascade's map (default); 0: one depth",
    ..RECEIVER_PLANE_BIAS
};

const COUNT: Knob = Knob::int("count", "number of cascades (z-partitions)", 4.0, 1.0, 8.0);

const PARTITION: Knob = Knob::int(
    "partition",
    "split placement: practical (pssm, with lambda), sample-distribution (sdsm: splits and \
     windows fitted to the view samples' depth histogram), uniform or log",
    0.0,
    0.0,
    3.0,
)
.named(&["pssm", "sdsm", "uniform", "log"]);

const LAMBDA: Knob = Knob::int(
    "lambda",
    "practical split blend: 1 logarithmic, 0 uniform (pssm and sdsm)",
    0.5,
    0.0,
    1.0,
)
.real();

const BLEND: Knob = Knob::int(
    "blend",
    "width in texels of the band at a cascade's edge where it fades into the next (0: a hard \
     switch)",
    4.0,
    0.0,
    64.0,
)
.real();

const SNAP: Knob = Knob::int(
    "snap",
    "1: windows on a fixed ladder of sizes and whole texels (no shimmer as the camera moves); 0: \
     tight windows cropped to the light view",
    1.0,
    0.0,
    1.0,
);

const KNOBS: [Knob; 12] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    COUNT,
    PARTITION,
    LAMBDA,
    BLEND,
    SNAP,
    FILTER,
    KERNEL,
    RECEIVER_PLANE,
];

/// `cascades`: z-partitioned shadow maps.
pub const CASCADES: TechniqueInfo = TechniqueInfo {
    name: "cascades",
    summary: "cascaded shadow maps: count z-partitions (pssm, sdsm, uniform, log), one map each, \
              texel-snapped, blended at the borders",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Cascades::new(setup, params)?)),
};

/// The uniform block of `glsl/cascades/lookup.glsl` (std140, 688 bytes: every member at its
/// std140 offset, which `tests/cascades.rs` checks).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CascadeParams {
    /// World → each cascade's clip space.
    pub view_proj: [Mat4; MAX_CASCADES],
    /// Tile origin x, y (texels); 1 when rendered; 1 for the last rendered cascade.
    pub tiles: [IVec4; MAX_CASCADES],
    /// Cascades, mode (0 nearest, 1 pcf), kernel (0 with mode 0), unused (the receiver plane is
    /// the pipeline's).
    pub sizes: IVec4,
    /// Blend band (texels), filter reach (texels), unused × 2.
    pub band: Vec4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Tile width and height (texels).
    pub tile: IVec2,
}

/// The push block of `glsl/cascades/depth_histogram.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct DepthHistogramPush {
    /// World → base light view.
    pub light_view: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// 1: perspective light (x and y divided by −z).
    pub perspective: i32,
    /// Padding.
    pub pad: i32,
    /// (cos, sin) of the second orientation's turn.
    pub turn: glam::Vec2,
    /// Padding.
    pub pad2: glam::Vec2,
}

/// The texels a filter reads on either side of a sample's map position: the nearest texel
/// (`kernel = 0`) stays inside for positions half a texel from the edge; a box of k bilinear taps
/// reaches k/2 texels (taps at ±(k−1)/2, each reading half a texel beyond).
pub fn filter_reach(kernel: u32) -> f32 {
    if kernel == 0 {
        0.5
    } else {
        kernel as f32 * 0.5 + 0.5
    }
}

/// Tiles per row of the atlas and rows, for `count` tiles of `tile` texels with images at most
/// `max` texels a side.
pub fn atlas_layout(count: u32, tile: UVec2, max: u32) -> Result<(u32, u32)> {
    let cols = count.min((max / tile.x.max(1)).max(1));
    let rows = count.div_ceil(cols);
    if cols * tile.x > max || rows * tile.y > max {
        return Err(Error::Parameter {
            technique: "cascades".into(),
            message: format!(
                "{count} cascades of {}x{} texels do not fit an atlas of at most {max}² texels",
                tile.x, tile.y
            ),
        });
    }
    Ok((cols, rows))
}

/// The fit's settings from the knobs.
pub fn fit_desc(params: &Params) -> Result<FitDesc> {
    let kernel = if params.u32("filter")? == 0 {
        0
    } else {
        params.u32("kernel")?
    };
    Ok(FitDesc {
        partition: Partition::from_index(params.u32("partition")?)?,
        count: params.u32("count")? as usize,
        lambda: params.f32("lambda")?,
        map_size: params.u32("map_size")?,
        margin: filter_reach(kernel) + params.f32("blend")?,
        snap: params.u32("snap")? == 1,
    })
}

/// Fits the cascades in each of [`cascade_fit::tile_candidates`] and keeps the tile shape whose
/// maps give the view samples the lowest 95th-percentile sampling error (book Ch. 3,
/// [`crate::sampling_error`]; every 4th sample of every 4th row, at most): a slice of the view
/// seen from the light is a strip whose texels want one aspect, but a receiver lit at a grazing
/// angle wants its texels along the light's foreshortened axis, which no window's shape tells.
/// The view samples are read back at set-up, like the SDSM histogram. Ties keep the earlier
/// candidate (square first).
#[allow(clippy::too_many_arguments)]
pub fn fit(
    camera: &Camera,
    scene: &Aabb,
    base: &LightView,
    turns: &[Vec2; 2],
    histogram: Option<&DepthHistogram>,
    desc: &FitDesc,
    positions: &[Vec4],
    normals: &[Vec4],
) -> Result<(Vec<Cascade>, UVec2)> {
    let width = camera.width.max(1) as usize;
    // Every fourth sample a side, their footprints on their planes once for all tile shapes.
    let picked = SampleFootprints::new(
        camera,
        positions
            .iter()
            .zip(normals)
            .enumerate()
            .filter(|(i, (p, _))| p.w > 0.0 && (i % width) % 4 == 0 && (i / width) % 4 == 0)
            .map(|(i, (p, n))| {
                let pixel = ((i % width) as u32, (i / width) as u32);
                (pixel, p.truncate(), n.truncate())
            }),
    );
    let mut best: Option<(f32, Vec<Cascade>, UVec2)> = None;
    for tile in cascade_fit::tile_candidates(desc.map_size) {
        let cascades =
            cascade_fit::fit_cascades(camera, scene, base, turns, histogram, desc, tile)?;
        let grids: Vec<SamplingGrid> = cascades
            .iter()
            .filter(|c| !c.empty)
            .map(|c| SamplingGrid {
                view_proj: c.light_view(base, turns).view_proj,
                size: tile,
            })
            .collect();
        let mut m = picked.first_grid_m(&grids);
        m.sort_by(f32::total_cmp);
        let p95 = if m.is_empty() {
            0.0
        } else {
            nearest_rank(&m, 95.0)
        };
        if best.as_ref().is_none_or(|b| p95 < b.0) {
            best = Some((p95, cascades, tile));
        }
    }
    best.map(|(_, c, t)| (c, t))
        .ok_or_else(|| Error::Parameter {
            technique: "cascades".into(),
            message: "no tile shape to try".into(),
        })
}

/// The SDSM reduction: its pipeline, bindings and the buffers it fills.
struct DepthHistogramPass {
    pipeline: Pipeline,
    set: DescriptorSet,
    words: Buffer,
    initial: Buffer,
    _edges: Buffer,
    push: DepthHistogramPush,
    edges: Vec<f32>,
    view_size: [u32; 2],
}

impl DepthHistogramPass {
    fn new(setup: &TechniqueSetup<'_>, turn: glam::Vec2) -> Result<DepthHistogramPass> {
        let ctx = setup.ctx;
        let edges = cascade_fit::histogram_edges(setup.camera.near, setup.camera.far);
        let mut padded = edges.clone();
        padded.resize((HISTOGRAM_BINS + 4) / 4 * 4, f32::INFINITY);
        let edges_buffer = ctx.buffer_with(
            "cascades histogram edges",
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            &padded,
        )?;
        let words = ctx.buffer_with(
            "cascades depth histogram",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &DepthHistogram::initial_words(),
        )?;
        // What each frame's reduction starts from, copied on the device (no staging per frame).
        let initial = ctx.buffer_with(
            "cascades depth histogram reset",
            vk::BufferUsageFlags::empty(),
            &DepthHistogram::initial_words(),
        )?;
        let pipeline = Pipeline::compute(ctx, "cascades/depth_histogram.comp")?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Image(&setup.view.positions),
                Binding::Image(&setup.view.normals),
                Binding::Buffer(&words),
                Binding::Buffer(&edges_buffer),
            ],
        )?;
        let push = DepthHistogramPush {
            light_view: setup.light_view.view,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            perspective: matches!(
                setup.light_view.projection,
                LightProjection::Perspective { .. }
            ) as i32,
            pad: 0,
            turn,
            pad2: glam::Vec2::ZERO,
        };
        Ok(DepthHistogramPass {
            pipeline,
            set,
            words,
            initial,
            _edges: edges_buffer,
            push,
            edges,
            view_size: [setup.view.width, setup.view.height],
        })
    }

    fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.copy_buffer(&self.initial, &self.words);
        let [w, h] = self.view_size;
        rec.dispatch(&self.pipeline, &self.set, &self.push, [w, h, 1])
    }

    fn read(&self, ctx: &Context) -> Result<DepthHistogram> {
        let words = crate::gpu::u32s(&ctx.read_buffer(&self.words)?);
        DepthHistogram::decode(self.edges.clone(), &words)
    }
}

/// Runs the SDSM reduction once on `setup`'s view samples, in the base light view and turned by
/// `turn`, and returns the buffer's words (see [`DepthHistogram::decode`]): for tests against the
/// CPU twin ([`crate::cpu::cascades::depth_histogram`]).
pub fn reduce_depth_histogram(setup: &TechniqueSetup<'_>, turn: glam::Vec2) -> Result<Vec<u32>> {
    let pass = DepthHistogramPass::new(setup, turn)?;
    setup.ctx.submit(None, |rec| pass.record(rec))?;
    Ok(crate::gpu::u32s(&setup.ctx.read_buffer(&pass.words)?))
}

/// A `cascades` instance.
pub struct Cascades<'a> {
    ctx: Context,
    cascades: Vec<Cascade>,
    views: Vec<LightView>,
    tiles: Vec<[u32; 2]>,
    tile: UVec2,
    desc: ShadowMapDesc,
    histogram: Option<DepthHistogramPass>,
    depth_pipeline: Pipeline,
    atlas: Image,
    _sampler: Sampler,
    _params: Buffer,
    lookup: Pipeline,
    set: DescriptorSet,
    counters: Buffer,
    view_size: [u32; 2],
    geometry: &'a SceneGeometry,
}

impl<'a> Cascades<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Cascades<'a>> {
        let ctx = setup.ctx;
        let desc = shadow_map_desc(params)?;
        let k = params.u32("count")?;
        let (d0, d1) = cascade_fit::scene_depth_range(setup.camera, &Aabb::of(setup.positions));
        let turns = cascade_fit::orientations(setup.light_view, setup.camera, d0, d1);
        let histogram = if Partition::from_index(params.u32("partition")?)? == Partition::Sdsm {
            let pass = DepthHistogramPass::new(setup, turns[1])?;
            ctx.submit(None, |rec| pass.record(rec))?;
            Some(pass)
        } else {
            None
        };
        let hist = histogram.as_ref().map(|h| h.read(ctx)).transpose()?;
        let positions = setup.host_samples.positions(ctx)?;
        let normals = setup.host_samples.normals(ctx)?;
        let (cascades, tile) = fit(
            setup.camera,
            &Aabb::of(setup.positions),
            setup.light_view,
            &turns,
            hist.as_ref(),
            &fit_desc(params)?,
            &positions,
            &normals,
        )?;
        let (cols, rows) = atlas_layout(k, tile, ctx.info().max_image_dimension_2d)?;
        let views: Vec<LightView> = cascades
            .iter()
            .map(|c| c.light_view(setup.light_view, &turns))
            .collect();
        let tiles: Vec<[u32; 2]> = (0..k)
            .map(|i| [(i % cols) * tile.x, (i / cols) * tile.y])
            .collect();

        let depth_pipeline = depth_pipeline(ctx, &desc.bias, MapLayer::Nearest)?;
        let atlas = Image::new(
            ctx,
            "cascade atlas",
            ImageDesc::new_2d(
                SHADOW_MAP_FORMAT,
                cols * tile.x,
                rows * tile.y,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC,
            ),
        )?;
        let sampler = Sampler::nearest_border_white(ctx, "cascade atlas sampler")?;

        let filter = params.u32("filter")?;
        let kernel = if filter == 0 {
            0
        } else {
            params.u32("kernel")?
        };
        let last = cascades.iter().rposition(|c| !c.empty);
        let mut block = CascadeParams::zeroed();
        for (i, (c, v)) in cascades.iter().zip(&views).enumerate() {
            block.view_proj[i] = v.view_proj;
            block.tiles[i] = IVec4::new(
                tiles[i][0] as i32,
                tiles[i][1] as i32,
                (!c.empty) as i32,
                (Some(i) == last) as i32,
            );
        }
        // The receiver plane is a pipeline of its own (below), used with the filtered lookup.
        let receiver_plane = filter != 0 && params.u32("receiver_plane_bias")? != 0;
        block.sizes = IVec4::new(k as i32, filter as i32, kernel as i32, 0);
        block.tile = tile.as_ivec2();
        block.band = Vec4::new(params.f32("blend")?, filter_reach(kernel), 0.0, 0.0);
        block.view_size = IVec2::new(setup.view.width as i32, setup.view.height as i32);
        let params_buffer = ctx.buffer_with(
            "cascades params",
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            std::slice::from_ref(&block),
        )?;
        let counters = Buffer::storage(
            ctx,
            "cascades counters",
            ((LOOKUP_COUNTERS.len() + MAX_CASCADES) * 4) as u64,
        )?;
        // The shader with RECEIVER_PLANE defined also reads the normals; a pipeline of its own,
        // so the default lookup does not compile it.
        let shader = if receiver_plane {
            "cascades/lookup_plane.comp"
        } else {
            "cascades/lookup.comp"
        };
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Sampled(&atlas, &sampler),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
            Binding::Buffer(&params_buffer),
        ];
        if receiver_plane {
            bindings.push(Binding::Image(&setup.view.normals));
        }
        let lookup = Pipeline::compute(ctx, shader)?;
        let set = DescriptorSet::new(ctx, &lookup, &bindings)?;
        Ok(Cascades {
            ctx: ctx.clone(),
            cascades,
            views,
            tiles,
            tile,
            desc,
            histogram,
            depth_pipeline,
            atlas,
            _sampler: sampler,
            _params: params_buffer,
            lookup,
            set,
            counters,
            view_size: [setup.view.width, setup.view.height],
            geometry: setup.geometry,
        })
    }

    /// The fitted cascades, finest first.
    pub fn cascades(&self) -> &[Cascade] {
        &self.cascades
    }

    /// Each cascade's light view.
    pub fn views(&self) -> &[LightView] {
        &self.views
    }

    /// The depth atlas, each cascade's tile origin in it and the tiles' size (texels).
    pub fn atlas(&self) -> (&Image, &[[u32; 2]], UVec2) {
        (&self.atlas, &self.tiles, self.tile)
    }
}

impl Technique for Cascades<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        if let Some(h) = &self.histogram {
            rec.begin_pass("depth-histogram")?;
            let r = h.record(rec);
            rec.end_pass();
            r?;
        }
        rec.begin_pass("light-depth")?;
        let g = self.geometry;
        rec.use_buffer(&g.vertices, Access::VertexInput);
        rec.use_buffer(&g.indices, Access::VertexInput);
        rec.begin_rendering(&[], (&self.atlas, 1.0));
        let bias = self.desc.bias;
        let mut result = Ok(());
        for ((c, v), t) in self.cascades.iter().zip(&self.views).zip(&self.tiles) {
            if c.empty {
                continue;
            }
            rec.set_viewport_rect(t[0], t[1], self.tile.x, self.tile.y);
            result = rec.draw_indexed(
                &self.depth_pipeline,
                None,
                &g.vertices,
                &g.indices,
                g.index_count,
                &LightDepthPush {
                    light_view_proj: v.view_proj,
                },
                Some([bias.constant, bias.slope, bias.clamp]),
            );
            if result.is_err() {
                break;
            }
        }
        rec.end_rendering();
        rec.end_pass();
        result?;
        rec.begin_pass("cascades")?;
        rec.fill(&self.counters, 0);
        let [w, h] = self.view_size;
        let r = rec.dispatch(&self.lookup, &self.set, &(), [w, h, 1]);
        rec.end_pass();
        r
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut names: Vec<String> = LOOKUP_COUNTERS.iter().map(|s| s.to_string()).collect();
        names.extend((0..MAX_CASCADES).map(|i| format!("cascade{i}")));
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let mut counters = super::read_counters(&self.ctx, &self.counters, &refs)?;
        counters.truncate(LOOKUP_COUNTERS.len() + self.cascades.len());
        let skipped = self.cascades.iter().filter(|c| c.empty).count();
        counters.push(("cascades_skipped".into(), skipped as u64));
        Ok(counters)
    }

    fn images(&self) -> Vec<(&'static str, &Image)> {
        vec![("atlas", &self.atlas)]
    }

    fn sampling_grids(&self) -> Vec<crate::sampling_error::SamplingGrid> {
        // Finest first, as the lookup composites them.
        self.cascades
            .iter()
            .zip(&self.views)
            .filter(|(c, _)| !c.empty)
            .map(|(_, v)| crate::sampling_error::SamplingGrid {
                view_proj: v.view_proj,
                size: self.tile,
            })
            .collect()
    }
}
