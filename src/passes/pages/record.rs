//! Recording a frame's page passes: compaction, allocation, culling into bins, drawing.

use super::{
    ComputeDrawer, GroupedDraw, LargeDraw, PageDrawer, VirtualPages, SLOT_CLEAR_GROUP,
    WALK_CLUSTERS, WALK_COVER_TEXELS,
};
use crate::error::Result;
use crate::gpu::{Access, Recorder, SLOT_VIEWPORTS};
use crate::kernels::scan::ScanKind;
use crate::passes::CLUSTER_TRIANGLES;
use crate::shader_types::PagesPush;

impl VirtualPages<'_> {
    /// Clears the page table and the refinement flags for a frame's marks (record before the
    /// technique marks pages).
    pub fn record_clear(&self, rec: &mut Recorder<'_>) {
        rec.fill(&self.table, 0);
        rec.fill(&self.refine_flags, 0);
        rec.fill(&self.entry_bands, 0);
    }

    /// Records compaction, allocation, culling and rendering of the marked pages, each as its
    /// own timed pass `<name>-compact|allocate|cull|render`.
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let name = self.name;
        let entries = self.desc.entries() as u32;
        rec.pass(&format!("{name}-compact"), |rec| {
            self.compact.record(rec, &self.compact_binding)?;
            if let Some((pipeline, set)) = &self.ancestors {
                rec.dispatch(pipeline, set, &self.push, [entries, 1, 1])?;
                self.compact.record(rec, &self.compact_binding)?;
            }
            Ok(())
        })?;
        rec.pass(&format!("{name}-allocate"), |rec| {
            rec.fill(&self.counters, 0);
            rec.fill(&self.level_info, 0);
            let (pipeline, set) = &self.allocate;
            rec.dispatch(pipeline, set, &self.push, [entries, 1, 1])
        })?;
        rec.pass(&format!("{name}-cull"), |rec| self.record_cull(rec))?;
        rec.pass(&format!("{name}-render"), |rec| self.record_render(rec))
    }

    /// Records the refinement round as one timed pass `<name>-refine`: the pages marked in
    /// [`VirtualPages::refine_flags`] (after [`VirtualPages::record`]) are compacted, allocated
    /// into the slots round 0 left (coarse first; the rest overflow, counted), binned and drawn
    /// into the atlas without disturbing round 0's pages. A lookup afterwards sees both rounds.
    pub fn record_refine(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.pass(&format!("{}-refine", self.name), |rec| {
            self.record_refine_untimed(rec)
        })
    }

    fn record_refine_untimed(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let round = PagesPush {
            round: 1,
            ..self.push
        };
        self.compact.record(rec, &self.refine_compact_binding)?;
        let entries = self.desc.entries() as u32;
        rec.dispatch(
            &self.allocate.0,
            &self.refine_allocate,
            &round,
            [entries, 1, 1],
        )?;
        self.record_bins(rec, &round)?;
        self.record_draws(rec, &round, false)
    }

    fn record_cull(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.fill(&self.bin_count, 0);
        rec.fill(&self.bin_cursor, 0);
        self.record_bins(rec, &self.push)
    }

    /// Bins `push.round`'s pages and writes its draws: appended in one walk for the compute
    /// raster (`glsl/pages/bin.comp` mode 2), counted, scanned and scattered for the rasterizer's
    /// per-level draws.
    fn record_bins(&self, rec: &mut Recorder<'_>, push: &PagesPush) -> Result<()> {
        let triangles = self.push.triangles;
        if self.desc.cluster_skip {
            let (cluster_pipeline, cluster_set) = &self.cluster_levels;
            let clusters = triangles.div_ceil(CLUSTER_TRIANGLES);
            rec.dispatch(cluster_pipeline, cluster_set, push, [clusters, 1, 1])?;
        } else {
            rec.fill(&self.cluster_mask, u32::MAX);
        }
        let (pipeline, set) = &self.bin;
        let (draw_pipeline, draw_set) = &self.draw_args;
        let threads = self.desc.pool_pages.max(self.push.levels);
        if let PageDrawer::Compute(drawer) = &self.render {
            // Appended unordered (the compute raster takes them so), and a tiny triangle's page
            // covered by the walk itself (bin.comp's cover_here) for a triangle of at most this
            // many of its texels, never one the page raster would leave to the rasterizer. The
            // depths are made ready before the walk: the round's slots cleared (slot_clear.comp:
            // only those, not the pool), after, for round 1, the atlas's (which holds the
            // earlier round's listed triangles too, which the copy back after the page raster
            // would otherwise overwrite; where the buffer is the atlas, it holds them already).
            if push.round == 1 && !matches!(drawer.large, LargeDraw::None) {
                rec.copy_image_to_buffer(self.atlas_image()?, &self.depth_bits);
            }
            let (clear_pipeline, clear_set) = &drawer.clear;
            // A workgroup a slot, within a dispatch's guaranteed count (the shader strides on).
            let groups = self.desc.pool_pages.min(crate::kernels::scan::MAX_GROUPS);
            let slots = groups * SLOT_CLEAR_GROUP;
            rec.dispatch(clear_pipeline, clear_set, push, [slots, 1, 1])?;
            let cover = WALK_COVER_TEXELS.min(self.desc.raster_split);
            let append = PagesPush {
                mode: 2 | (cover << 8),
                ..*push
            };
            // A workgroup (CLUSTER_TRIANGLES invocations) per WALK_CLUSTERS clusters.
            let groups = triangles.div_ceil(WALK_CLUSTERS * CLUSTER_TRIANGLES);
            rec.dispatch(pipeline, set, &append, [groups * CLUSTER_TRIANGLES, 1, 1])?;
            if push.round == 0 {
                // Bins past their capacity: their pairs counted per level (mode 4), the levels
                // that fit chosen coarse first, and those binned again (mode 3); the two walks
                // are empty dispatches when the bins fit.
                let (fit_pipeline, fit_set) = &self.bin_fit;
                let (later_pipeline, later_set) = &self.bin_later;
                let slots = [self.desc.pool_pages, 1, 1];
                let fit = |mode| PagesPush { mode, ..*push };
                let walk = |mode: u32| PagesPush {
                    mode: mode | (cover << 8),
                    ..*push
                };
                rec.dispatch(fit_pipeline, fit_set, &fit(0), [1, 1, 1])?;
                let args = &self.rewalk_args;
                rec.dispatch_indirect(later_pipeline, later_set, &walk(4), args, 0)?;
                rec.dispatch(fit_pipeline, fit_set, &fit(1), slots)?;
                rec.dispatch_indirect(later_pipeline, later_set, &walk(3), args, 0)?;
            }
            return rec.dispatch(draw_pipeline, draw_set, &append, [threads, 1, 1]);
        }
        rec.dispatch(pipeline, set, push, [triangles, 1, 1])?;
        self.scan
            .record(rec, &self.scan_binding, ScanKind::Exclusive)?;
        rec.dispatch(draw_pipeline, draw_set, push, [threads, 1, 1])?;
        let scatter = PagesPush { mode: 1, ..*push };
        rec.dispatch(pipeline, set, &scatter, [triangles, 1, 1])
    }

    fn record_render(&self, rec: &mut Recorder<'_>) -> Result<()> {
        self.record_draws(rec, &self.push, true)
    }

    /// Draws `push.round`'s pages into the atlas, clearing it first (round 0) or keeping it.
    fn record_draws(&self, rec: &mut Recorder<'_>, push: &PagesPush, clear: bool) -> Result<()> {
        let (pipeline, set) = match &self.render {
            PageDrawer::Graphics(pipeline, set) => (pipeline, set),
            PageDrawer::Compute(drawer) => {
                let ComputeDrawer {
                    pipeline,
                    set,
                    large,
                    group_count,
                    ..
                } = drawer.as_ref();
                // (The depths were cleared or taken from the atlas before the walk, which
                // writes them too: record_bins.)
                // The round's 12 words of `raster_args`: dispatch and entry range, then (word 8)
                // the listed entries' draw.
                let offset = 48 * u64::from(push.round);
                // (Where the buffer is the atlas nothing may be listed, not even an entry
                // whose two near-clipped pieces' boxes hold more than page_size² texels.)
                let split = PagesPush {
                    mode: match large {
                        LargeDraw::None => u32::MAX,
                        _ => self.desc.raster_split,
                    },
                    ..*push
                };
                rec.fill(group_count, 0);
                rec.dispatch_indirect(pipeline, set, &split, &self.raster_args, offset)?;
                let (listed, listed_set) = match large {
                    LargeDraw::None => return Ok(()),
                    LargeDraw::Viewports(grouped) => {
                        return self.record_grouped(rec, push, grouped)
                    }
                    LargeDraw::Clipped(listed, listed_set) => (listed, listed_set),
                };
                let atlas = self.atlas_image()?;
                rec.copy_buffer_to_image(&self.depth_bits, atlas);
                rec.use_set(listed_set);
                rec.use_buffer(&self.raster_args, Access::IndirectRead);
                rec.continue_rendering(atlas);
                let result = rec.draw_indirect(
                    listed,
                    listed_set,
                    push,
                    &self.raster_args,
                    offset + 32,
                    None,
                );
                rec.end_rendering();
                return result;
            }
        };
        rec.use_set(set);
        rec.use_buffer(&self.draws, Access::IndirectRead);
        let atlas = self.atlas_image()?;
        if clear {
            rec.begin_rendering(&[], (atlas, 1.0));
        } else {
            rec.continue_rendering(atlas);
        }
        let bias = self.desc.bias;
        let mut result = Ok(());
        for level in 0..self.push.levels {
            let scale = (1u32 << level) as f32;
            let depth_bias = [bias.constant * scale, bias.slope, bias.clamp * scale];
            let draw = push.round * push.levels + level;
            result = rec.draw_indirect(
                pipeline,
                set,
                push,
                &self.draws,
                16 * u64::from(draw),
                Some(depth_bias),
            );
            if result.is_err() {
                break;
            }
        }
        rec.end_rendering();
        result
    }

    /// The compute raster's listed entries in groups of `SLOT_VIEWPORTS` slots, each group one
    /// indirect draw whose viewports and scissors are its slots' squares of the atlas (after the
    /// page raster's depths are copied into it).
    fn record_grouped(
        &self,
        rec: &mut Recorder<'_>,
        push: &PagesPush,
        grouped: &GroupedDraw,
    ) -> Result<()> {
        let (groups_pipeline, groups_set) = &grouped.groups;
        rec.dispatch(groups_pipeline, groups_set, push, [1, 1, 1])?;
        let (scatter_pipeline, scatter_set) = &grouped.scatter;
        rec.dispatch_indirect(
            scatter_pipeline,
            scatter_set,
            push,
            &grouped.scatter_args,
            0,
        )?;
        let atlas = self.atlas_image()?;
        rec.copy_buffer_to_image(&self.depth_bits, atlas);
        rec.use_set(&grouped.set);
        rec.use_buffer(&grouped.draws, Access::IndirectRead);
        rec.continue_rendering(atlas);
        let (page, cols) = (self.desc.page_size, self.desc.atlas_cols());
        let mut result = Ok(());
        for group in 0..self.desc.pool_pages.div_ceil(SLOT_VIEWPORTS) {
            // Slots past the pool (in the last group) draw nothing: any square will do.
            let rects: Vec<[u32; 4]> = (0..SLOT_VIEWPORTS)
                .map(|i| {
                    let slot = (group * SLOT_VIEWPORTS + i).min(self.desc.pool_pages - 1);
                    [slot % cols * page, slot / cols * page, page, page]
                })
                .collect();
            rec.set_viewport_rects(&rects);
            result = rec.draw_indirect(
                &grouped.pipeline,
                &grouped.set,
                push,
                &grouped.draws,
                16 * u64::from(group),
                None,
            );
            if result.is_err() {
                break;
            }
        }
        rec.end_rendering();
        result
    }
}
