//! `rmsm`: resolution-matched virtual shadow maps (Lefohn et al. 2007; book §4.4), GPU-driven,
//! with a shadow-edge refinement round in the spirit of adaptive shadow maps (Fernando et al.
//! 2001).
//!
//! Every frame, each view sample asks for the mip level of a `virtual_size`² virtual map whose
//! texels match its screen footprint — the camera pixel's neighbours' rays meet the sample's
//! tangent plane, and their spread in the light's texel grid is the footprint
//! (`glsl/rmsm/rmsm.glsl`), scaled by `2^lod_bias` — and marks the page(s) its filter reads there
//! and their ancestors (`rmsm-mark`). The page machinery ([`crate::passes::pages`]) compacts the
//! marks, allocates them from a fixed pool coarse level first, bins the casters to the resident
//! pages and draws each page's own casters into the atlas (`rmsm-compact`, `-allocate`, `-cull`,
//! `-render`); no readback on the way.
//!
//! A nearest-texel test is wrong where a shadow edge passes within half a texel of the sample,
//! and matching the screen's resolution everywhere spends the pool on flat lit or shadowed areas
//! where a coarser texel gives the same answer. So a second round (`rmsm-edges`, `rmsm-refine`)
//! finds the samples whose 3×3 texels at their served level disagree — those near an edge — and
//! gives them `refine` levels finer, allocated into the slots round 0 left. On `spot-point` this
//! takes `rmsm`, with a pool of one 2048² map, from 80 to 9 misclassified samples (`hard` at
//! 2048²: 60; README); the same pool spent uniformly instead (`--set lod_bias=-2 --set
//! refine=0`) gives 41.
//!
//! The lookup (`rmsm-lookup`) reads each sample's level (its refined one at an edge) through the
//! page table, falling back level by level to the first coarser one whose pages cover its
//! filter's texels when the pool or the bins ran out: every sample gets a value, and the
//! fallbacks are counted.
//!
//! Knobs: `virtual_size`, `page_size`, `pool_pages` (the memory bound), `lod_bias`, `refine`,
//! `filter` (nearest texel, or a bilinear 2×2 whose texels may sit on different pages),
//! `tangent_plane` (compare each texel with the receiver's tangent plane under its centre),
//! `bin_factor` (bin entries per triangle, or 8 × as many per pool slot), and the depth bias
//! of a level-0 page (constant and clamp double per level). The defaults — 32768² virtual,
//! pages of 64² (finer pages waste less of the pool on the thin regions along edges than 128²
//! pages: 9 against 19 misclassified on `spot-point` with the same memory, `--set
//! page_size=128 --set pool_pages=256`), `lod_bias` −1, `refine` 4 — were measured on the
//! bundled scenes with `penumbra render SCENE --technique rmsm --compare-to reference`
//! (misclassified × samples in `stats.json`). CPU twin of the request, allocation, culling and fallback rules:
//! [`crate::cpu::rmsm`].

use glam::IVec2;

use super::{virtual_map, Knob, Params, Technique, TechniqueInfo, TechniqueSetup};
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder};
use crate::passes::pages::VirtualPages;
use crate::shader_types::RmsmPush;

/// Counter names of the view-sample passes, in the order of `glsl/rmsm/lookup.comp`'s buffer.
pub const LOOKUP_COUNTER_NAMES: [&str; 9] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "fallback_lookups",
    "footprint_met",
    "virtual_too_coarse",
    "refined_samples",
];

/// Counter names of the edge pass, in the order of `glsl/rmsm/edges.comp`'s buffer.
pub const EDGE_COUNTER_NAMES: [&str; 2] = ["edge_samples", "refine_requests"];

const PAGE_KNOBS: [Knob; 9] = virtual_map::page_knobs(32768.0, 64.0);

const KNOBS: [Knob; 16] = [
    PAGE_KNOBS[0],
    PAGE_KNOBS[1],
    PAGE_KNOBS[2],
    Knob::int(
        "lod_bias",
        "added to log2 of the footprint (negative: finer pages than the screen needs)",
        -1.0,
        -8.0,
        8.0,
    )
    .real(),
    Knob::int(
        "filter",
        "nearest: one texel; bilinear: 2x2 texels, across page borders",
        0.0,
        0.0,
        1.0,
    )
    .named(&["nearest", "bilinear"]),
    Knob::int(
        "refine",
        "levels finer for samples at a shadow edge, in a second round of pages (0: off)",
        4.0,
        0.0,
        8.0,
    ),
    virtual_map::tangent_plane_knob(0.0),
    PAGE_KNOBS[3],
    PAGE_KNOBS[4],
    PAGE_KNOBS[5],
    PAGE_KNOBS[6],
    PAGE_KNOBS[7],
    PAGE_KNOBS[8],
    super::SHADOW_MAP_KNOBS[1],
    super::SHADOW_MAP_KNOBS[2],
    super::SHADOW_MAP_KNOBS[3],
];

/// `rmsm`.
pub const RMSM: TechniqueInfo = TechniqueInfo {
    name: "rmsm",
    summary: "resolution-matched virtual shadow map: GPU page requests, pool, culled page draws",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Rmsm::new(setup, params)?)),
};

/// An `rmsm` instance: its pages and its two view-sample passes.
pub struct Rmsm<'a> {
    ctx: Context,
    /// The virtual map's page machinery (public for tests: page list, table, bins).
    pub pages: VirtualPages<'a>,
    mark: (Pipeline, DescriptorSet),
    edges: (Pipeline, DescriptorSet),
    lookup: (Pipeline, DescriptorSet),
    mark_counters: Buffer,
    edge_counters: Buffer,
    lookup_counters: Buffer,
    // Written by the edge pass, read by the lookup.
    _refine_level: Image,
    // Read by both sets.
    _camera: Buffer,
    push: RmsmPush,
    view_size: IVec2,
}

impl<'a> Rmsm<'a> {
    /// Builds the pages, the passes and their bindings.
    pub fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let desc = virtual_map::pages_desc(ctx, params)?;
        let pages = VirtualPages::new(ctx, "rmsm", setup.light_view, setup.geometry, desc)?;
        let camera_buffer =
            virtual_map::view_camera(ctx, "rmsm camera", setup, params.u32("tangent_plane")?)?;
        let mark_counters = Buffer::storage(ctx, "rmsm mark counters", 4)?;
        let lookup_counters = Buffer::storage(
            ctx,
            "rmsm lookup counters",
            4 * LOOKUP_COUNTER_NAMES.len() as u64,
        )?;
        let view = setup.view;
        let mark_pipeline = Pipeline::compute(ctx, "rmsm/mark.comp")?;
        let mark_set = DescriptorSet::new(
            ctx,
            &mark_pipeline,
            &[
                Binding::Image(&view.positions),
                Binding::Image(&view.normals),
                Binding::Image(setup.receivers),
                Binding::Buffer(&camera_buffer),
                Binding::Buffer(&pages.table),
                Binding::Buffer(&mark_counters),
            ],
        )?;
        let refine_level = Image::new(
            ctx,
            "rmsm refine levels",
            ImageDesc::new_2d(
                ash::vk::Format::R32_UINT,
                view.width,
                view.height,
                ash::vk::ImageUsageFlags::STORAGE,
            ),
        )?;
        let edge_counters = Buffer::storage(
            ctx,
            "rmsm edge counters",
            4 * EDGE_COUNTER_NAMES.len() as u64,
        )?;
        let edges_pipeline = Pipeline::compute(ctx, &pages.atlas_reader("rmsm/edges.comp"))?;
        let edges_set = DescriptorSet::new(
            ctx,
            &edges_pipeline,
            &[
                Binding::Image(&view.positions),
                Binding::Image(&view.normals),
                Binding::Image(setup.receivers),
                Binding::Buffer(&camera_buffer),
                Binding::Buffer(&pages.table),
                pages.atlas_binding(),
                Binding::Buffer(&pages.refine_flags),
                Binding::Image(&refine_level),
                Binding::Buffer(&edge_counters),
            ],
        )?;
        let lookup_pipeline = Pipeline::compute(ctx, &pages.atlas_reader("rmsm/lookup.comp"))?;
        let lookup_set = DescriptorSet::new(
            ctx,
            &lookup_pipeline,
            &[
                Binding::Image(&view.positions),
                Binding::Image(&view.normals),
                Binding::Image(setup.receivers),
                Binding::Buffer(&camera_buffer),
                Binding::Buffer(&pages.table),
                pages.atlas_binding(),
                Binding::Image(setup.visibility),
                Binding::Buffer(&lookup_counters),
                Binding::Image(&refine_level),
            ],
        )?;
        let view_size = IVec2::new(view.width as i32, view.height as i32);
        let push = RmsmPush {
            light_view_proj: setup.light_view.view_proj,
            view_size,
            virtual_size: desc.virtual_size,
            page_size: desc.page_size,
            levels: desc.levels(),
            atlas_cols: desc.atlas_cols(),
            filter_mode: params.u32("filter")?,
            lod_bias: params.f32("lod_bias")?,
            refine: params.u32("refine")?,
            pad: [0; 3],
        };
        Ok(Rmsm {
            ctx: ctx.clone(),
            pages,
            mark: (mark_pipeline, mark_set),
            edges: (edges_pipeline, edges_set),
            lookup: (lookup_pipeline, lookup_set),
            mark_counters,
            edge_counters,
            lookup_counters,
            _refine_level: refine_level,
            _camera: camera_buffer,
            push,
            view_size,
        })
    }
}

impl Technique for Rmsm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        let threads = [self.view_size.x as u32, self.view_size.y as u32, 1];
        rec.pass("rmsm-mark", |rec| {
            self.pages.record_clear(rec);
            rec.fill(&self.mark_counters, 0);
            let (pipeline, set) = &self.mark;
            rec.dispatch(pipeline, set, &self.push, threads)
        })?;
        self.pages.record(rec)?;
        if self.push.refine > 0 {
            rec.pass("rmsm-edges", |rec| {
                rec.fill(&self.edge_counters, 0);
                let (pipeline, set) = &self.edges;
                rec.dispatch(pipeline, set, &self.push, threads)
            })?;
            self.pages.record_refine(rec)?;
        }
        rec.pass("rmsm-lookup", |rec| {
            rec.fill(&self.lookup_counters, 0);
            let (pipeline, set) = &self.lookup;
            rec.dispatch(pipeline, set, &self.push, threads)
        })
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut out =
            super::read_counters(&self.ctx, &self.lookup_counters, &LOOKUP_COUNTER_NAMES)?;
        out.extend(super::read_counters(
            &self.ctx,
            &self.mark_counters,
            &["requested_pages"],
        )?);
        if self.push.refine > 0 {
            out.extend(super::read_counters(
                &self.ctx,
                &self.edge_counters,
                &EDGE_COUNTER_NAMES,
            )?);
        }
        let pages = self.pages.counters()?;
        let drawn = pages
            .iter()
            .find(|(n, _)| n == "drawn_pages")
            .map_or(0, |(_, v)| *v);
        let samples = out.first().map_or(0, |(_, v)| *v).max(1);
        let page_texels = u64::from(self.push.page_size).pow(2);
        out.extend(pages);
        // Texels of the drawn pages per view sample, in thousandths.
        out.push((
            "texels_per_sample_milli".into(),
            drawn * page_texels * 1000 / samples,
        ));
        Ok(out)
    }

    fn virtual_pages(&self) -> Option<&VirtualPages<'_>> {
        Some(&self.pages)
    }

    /// The virtual map's finest level: `virtual_size` texels a side over the light view. Every
    /// sample is charged to it, whichever level it was served from: the coarser page levels (a
    /// sample's resolution-matched level, or a fallback when the pool ran out) are not charged,
    /// so this is the error the finest level bounds from below, not the served texel's.
    fn sampling_grids(&self) -> Vec<crate::sampling_error::SamplingGrid> {
        vec![crate::sampling_error::SamplingGrid {
            view_proj: self.push.light_view_proj,
            size: glam::UVec2::splat(self.push.virtual_size),
        }]
    }
}
