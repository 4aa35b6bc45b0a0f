//! [`VirtualPages::new`]: the page machinery's buffers, pipelines and descriptor sets.

use ash::vk;

use super::{
    AtlasDepths, ComputeDrawer, GroupedDraw, LargeDraw, PageDrawer, PageRaster, PagesDesc,
    VirtualPages, LEVEL_PAIRS, PAGE_COUNTER_NAMES, SLOT_BIN_SHARE,
};
use crate::error::{Error, Result};
use crate::gpu::{
    Binding, Buffer, Context, DescriptorSet, GraphicsDesc, Image, ImageDesc, MemoryLocation,
    Pipeline, Sampler, SLOT_VIEWPORTS,
};
use crate::kernels::compact::Compact;
use crate::kernels::scan::Scan;
use crate::passes::{LightView, SceneGeometry, SHADOW_MAP_FORMAT};
use crate::shader_types::PagesPush;

impl<'a> VirtualPages<'a> {
    /// Creates the page machinery for `geometry` seen through `light_view`; `name` (the
    /// technique's) prefixes its passes and names it in errors.
    pub fn new(
        ctx: &Context,
        name: &'static str,
        light_view: &LightView,
        geometry: &'a SceneGeometry,
        desc: PagesDesc,
    ) -> Result<Self> {
        desc.check(ctx, name)?;
        let triangles = geometry.index_count / 3;
        // The walks but the first (bin.comp's counting and scattering modes, the later walks'
        // indirect dispatches) take a workgroup per cluster: refused here, not mid-frame.
        let clusters = triangles.div_ceil(crate::passes::CLUSTER_TRIANGLES);
        let max_groups = ctx.info().max_workgroup_count[0];
        if clusters > max_groups {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "{name}'s culling walk over {triangles} triangles ({clusters} workgroups of \
                     {}; maxComputeWorkGroupCount {max_groups})",
                    crate::passes::CLUSTER_TRIANGLES
                ),
            });
        }
        let capacity = u64::from(desc.bin_factor)
            * u64::from(triangles).max(u64::from(SLOT_BIN_SHARE) * u64::from(desc.pool_pages));
        let max_entries = u64::from(ctx.info().max_storage_buffer_range) / 8;
        let capacity = capacity.min(max_entries).min(u64::from(u32::MAX / 3));
        if capacity < u64::from(triangles) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "bins for {triangles} triangles (maxStorageBufferRange holds {max_entries})"
                ),
            });
        }
        let capacity = capacity as u32;
        let entries = desc.entries() as u32;
        let levels = desc.levels();
        let pool = desc.pool_pages;
        let storage = |name: &str, size: u64| Buffer::storage(ctx, name, size);
        let table = storage("page table", 4 * u64::from(entries))?;
        let list = storage("page list", 4 * u64::from(entries))?;
        let count = storage("page count", 4)?;
        let slot_info = storage("page slots", 16 * u64::from(pool))?;
        // Two rounds of per-level bookkeeping and draws: the requests', then the refinement's.
        let level_info = storage("page levels", 2 * 32 * u64::from(levels))?;
        let bin_count = storage("page bin counts", 4 * u64::from(pool))?;
        let bin_offset = storage("page bin offsets", 4 * u64::from(pool))?;
        // Per slot, then the append cursors of bin.comp's modes 2 and 3, bin_fit.comp's choice
        // and the pairs per level (pages_push.glsl).
        let bin_cursor = storage(
            "page bin cursors",
            4 * (u64::from(pool) + (LEVEL_PAIRS as u64) + u64::from(levels)),
        )?;
        // bin_fit.comp's dispatch of the second walk (empty unless the bins overflowed).
        let rewalk_args = Buffer::new(
            ctx,
            "page rewalk args",
            12,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let bins = storage("page bins", 8 * u64::from(capacity))?;
        // bin.comp mode 0's memo for mode 1, per triangle (the rasterizer's way of binning only;
        // appending walks once and needs none).
        let memo_size = match desc.raster {
            PageRaster::Graphics => 8 * u64::from(triangles.max(1)),
            PageRaster::Compute => 8,
        };
        let bin_memo = storage("page bin memo", memo_size)?;
        // The compute raster's depths, which the walk writes too (bin.comp's cover_here); one
        // word for the rasterizer's way, where nothing writes it.
        // Where they are the atlas itself (`atlas_in_buffer`), its readers view it as texels.
        let in_buffer = desc.atlas_in_buffer();
        let depth_bits = match desc.raster {
            PageRaster::Compute => Buffer::storage_with(
                ctx,
                "page atlas depth bits",
                desc.atlas_bytes(),
                if in_buffer {
                    vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                } else {
                    vk::BufferUsageFlags::empty()
                },
            )?,
            PageRaster::Graphics => storage("page atlas depth bits (unused)", 4)?,
        };
        let draws = Buffer::new(
            ctx,
            "page draws",
            2 * 16 * u64::from(levels),
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuOnly,
        )?;
        let counters = storage("page counters", 4 * PAGE_COUNTER_NAMES.len() as u64)?;
        let raster_args = Buffer::new(
            ctx,
            "page raster args",
            2 * 48,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let (w, h) = desc.atlas_size();
        let atlas = if in_buffer {
            AtlasDepths::Texels(depth_bits.texel_view(vk::Format::R32G32B32A32_UINT, 16)?)
        } else {
            AtlasDepths::Image(Image::new(
                ctx,
                "page atlas",
                ImageDesc::new_2d(
                    SHADOW_MAP_FORMAT,
                    w,
                    h,
                    vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                        | vk::ImageUsageFlags::SAMPLED
                        | vk::ImageUsageFlags::TRANSFER_SRC
                        | vk::ImageUsageFlags::TRANSFER_DST,
                ),
            )?)
        };
        let sampler = Sampler::nearest_border_white(ctx, "page atlas sampler")?;

        let compact = Compact::new(ctx)?;
        let compact_binding = compact.bind(&table, &list, &count, entries)?;
        let refine_flags = storage("page refine flags", 4 * u64::from(entries))?;
        let entry_bands = storage("page entry bands", 4 * u64::from(entries))?;
        let slot_bands = storage("page slot bands", 4 * u64::from(pool))?;
        let refine_list = storage("page refine list", 4 * u64::from(entries))?;
        let refine_count = storage("page refine count", 4)?;
        let refine_compact_binding =
            compact.bind(&refine_flags, &refine_list, &refine_count, entries)?;
        let scan = Scan::new(ctx)?;
        let scan_binding = scan.bind(&bin_count, &bin_offset, pool)?;
        let with_set = |shader: &str, bindings: &[Binding<'_>]| -> Result<_> {
            let pipeline = Pipeline::compute(ctx, shader)?;
            let set = DescriptorSet::new(ctx, &pipeline, bindings)?;
            Ok((pipeline, set))
        };
        let allocate = with_set(
            "pages/allocate.comp",
            &[
                Binding::Buffer(&table),
                Binding::Buffer(&list),
                Binding::Buffer(&count),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&level_info),
                Binding::Buffer(&counters),
                Binding::Buffer(&entry_bands),
                Binding::Buffer(&slot_bands),
            ],
        )?;
        let refine_allocate = DescriptorSet::new(
            ctx,
            &allocate.0,
            &[
                Binding::Buffer(&table),
                Binding::Buffer(&refine_list),
                Binding::Buffer(&refine_count),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&level_info),
                Binding::Buffer(&counters),
                Binding::Buffer(&entry_bands),
                Binding::Buffer(&slot_bands),
            ],
        )?;
        let ancestors = if desc.ancestors_on_overflow {
            Some(with_set(
                "pages/ancestors.comp",
                &[
                    Binding::Buffer(&table),
                    Binding::Buffer(&list),
                    Binding::Buffer(&count),
                    Binding::Buffer(&entry_bands),
                ],
            )?)
        } else {
            None
        };
        let clusters = triangles.div_ceil(crate::passes::CLUSTER_TRIANGLES);
        let cluster_mask = storage("page cluster levels", 4 * u64::from(clusters.max(1)))?;
        let cluster_levels = with_set(
            "pages/cluster_levels.comp",
            &[
                Binding::Buffer(&geometry.cluster_boxes),
                Binding::Buffer(&table),
                Binding::Buffer(&level_info),
                Binding::Buffer(&counters),
                Binding::Buffer(&cluster_mask),
                Binding::Buffer(&slot_bands),
            ],
        )?;
        let bin_bindings = [
            Binding::Buffer(&geometry.vertices),
            Binding::Buffer(&geometry.indices),
            Binding::Buffer(&table),
            Binding::Buffer(&level_info),
            Binding::Buffer(&bin_count),
            Binding::Buffer(&bin_offset),
            Binding::Buffer(&bin_cursor),
            Binding::Buffer(&bins),
            Binding::Buffer(&counters),
            Binding::Buffer(&bin_memo),
            Binding::Buffer(&depth_bits),
            Binding::Buffer(&cluster_mask),
            Binding::Buffer(&slot_bands),
        ];
        let bin = with_set(
            if ctx.info().subgroup_arithmetic {
                "pages/bin.comp"
            } else {
                "pages/bin_lanes.comp"
            },
            &bin_bindings,
        )?;
        // The walks after an overflow of round 0's appended bins (modes 4 and 3).
        let bin_later = with_set("pages/bin_later.comp", &bin_bindings)?;
        let bin_fit = with_set(
            "pages/bin_fit.comp",
            &[Binding::Buffer(&bin_cursor), Binding::Buffer(&rewalk_args)],
        )?;
        let draw_args = with_set(
            "pages/draws.comp",
            &[
                Binding::Buffer(&bin_count),
                Binding::Buffer(&bin_offset),
                Binding::Buffer(&table),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&level_info),
                Binding::Buffer(&draws),
                Binding::Buffer(&counters),
                Binding::Buffer(&raster_args),
                Binding::Buffer(&bin_cursor),
            ],
        )?;
        let page_graphics = GraphicsDesc {
            vertex: "pages/page_depth.vert",
            fragment: None,
            color_formats: &[],
            depth_format: SHADOW_MAP_FORMAT,
            depth_bias: true,
            vertex_input: false,
            cull_mode: vk::CullModeFlags::NONE,
            depth_compare: vk::CompareOp::LESS_OR_EQUAL,
            viewports: 1,
        };
        // The rasterizer's page draws (`page_depth*.vert`): the scene's triangles pulled by bin
        // entry into their slots, cut to the used rectangles; the compute raster's listed and
        // grouped draws read an entry list too, bound before the bands.
        let page_draw = |graphics: &GraphicsDesc, list: Option<&Buffer>| -> Result<_> {
            let pipeline = Pipeline::graphics(ctx, graphics)?;
            let mut bindings = vec![
                Binding::Buffer(&geometry.vertices),
                Binding::Buffer(&geometry.indices),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&bins),
            ];
            bindings.extend(list.map(Binding::Buffer));
            bindings.push(Binding::Buffer(&slot_bands));
            let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
            Ok((pipeline, set))
        };
        let render = match desc.raster {
            PageRaster::Graphics => {
                let (pipeline, set) = page_draw(&page_graphics, None)?;
                PageDrawer::Graphics(pipeline, set)
            }
            PageRaster::Compute => {
                // (Nothing is listed where the raster's buffer is the atlas: a word each.)
                let listed = if in_buffer { 0 } else { u64::from(capacity) };
                let large_list = storage("page raster large list", 4 * listed.max(1))?;
                let groups = u64::from(pool.div_ceil(SLOT_VIEWPORTS));
                let group_count = storage("page raster group counts", 4 * groups)?;
                let large_rank = storage("page raster listed ranks", 4 * listed.max(1))?;
                let (pipeline, set) = with_set(
                    "pages/page_raster.comp",
                    &[
                        Binding::Buffer(&geometry.vertices),
                        Binding::Buffer(&geometry.indices),
                        Binding::Buffer(&slot_info),
                        Binding::Buffer(&bins),
                        Binding::Buffer(&depth_bits),
                        Binding::Buffer(&raster_args),
                        Binding::Buffer(&large_list),
                        Binding::Buffer(&group_count),
                        Binding::Buffer(&large_rank),
                        Binding::Buffer(&slot_bands),
                    ],
                )?;
                let large = if in_buffer {
                    LargeDraw::None
                } else if desc.viewport_draw(ctx) {
                    let group_first = storage("page raster group firsts", 4 * groups)?;
                    let indirect = |name: &str, size: u64| {
                        Buffer::new(
                            ctx,
                            name,
                            size,
                            vk::BufferUsageFlags::STORAGE_BUFFER
                                | vk::BufferUsageFlags::INDIRECT_BUFFER,
                            MemoryLocation::GpuOnly,
                        )
                    };
                    let draws = indirect("page raster group draws", 16 * groups)?;
                    let scatter_args = indirect("page raster scatter args", 12)?;
                    let grouped_list =
                        storage("page raster grouped list", 4 * u64::from(capacity))?;
                    let groups_pass = with_set(
                        "pages/slot_groups.comp",
                        &[
                            Binding::Buffer(&group_count),
                            Binding::Buffer(&group_first),
                            Binding::Buffer(&draws),
                            Binding::Buffer(&scatter_args),
                        ],
                    )?;
                    let scatter = with_set(
                        "pages/slot_scatter.comp",
                        &[
                            Binding::Buffer(&bins),
                            Binding::Buffer(&large_list),
                            Binding::Buffer(&large_rank),
                            Binding::Buffer(&group_first),
                            Binding::Buffer(&raster_args),
                            Binding::Buffer(&grouped_list),
                        ],
                    )?;
                    let (draw_pipeline, draw_set) = page_draw(
                        &GraphicsDesc {
                            vertex: "pages/page_depth_grouped.vert",
                            depth_bias: false,
                            viewports: SLOT_VIEWPORTS,
                            ..page_graphics
                        },
                        Some(&grouped_list),
                    )?;
                    LargeDraw::Viewports(Box::new(GroupedDraw {
                        groups: groups_pass,
                        scatter,
                        scatter_args,
                        draws,
                        pipeline: draw_pipeline,
                        set: draw_set,
                        _buffers: [group_first, grouped_list],
                    }))
                } else {
                    let (listed, listed_set) = page_draw(
                        &GraphicsDesc {
                            vertex: "pages/page_depth_listed.vert",
                            depth_bias: false,
                            ..page_graphics
                        },
                        Some(&large_list),
                    )?;
                    LargeDraw::Clipped(listed, listed_set)
                };
                let clear = with_set(
                    "pages/slot_clear.comp",
                    &[
                        Binding::Buffer(&depth_bits),
                        Binding::Buffer(&counters),
                        Binding::Buffer(&slot_bands),
                    ],
                )?;
                let drawer = ComputeDrawer {
                    pipeline,
                    set,
                    clear,
                    large,
                    _large_list: large_list,
                    group_count,
                    _large_rank: large_rank,
                };
                PageDrawer::Compute(Box::new(drawer))
            }
        };
        let push = PagesPush {
            light_view_proj: light_view.view_proj,
            virtual_size: desc.virtual_size,
            page_size: desc.page_size,
            levels,
            pool_pages: pool,
            atlas_cols: desc.atlas_cols(),
            triangles,
            capacity,
            mode: 0,
            round: 0,
            bias_constant: desc.bias.constant,
            bias_slope: desc.bias.slope,
            bias_clamp: desc.bias.clamp,
            atlas_quads: u32::from(in_buffer),
            cull_back_faces: u32::from(desc.cull_back_faces),
            pad1: 0,
            pad2: 0,
        };
        Ok(VirtualPages {
            ctx: ctx.clone(),
            name,
            desc,
            push,
            table,
            refine_flags,
            entry_bands,
            slot_bands,
            atlas,
            sampler,
            list,
            count,
            slot_info,
            level_info,
            bin_count,
            _bin_offset: bin_offset,
            _bin_memo: bin_memo,
            depth_bits,
            bin_cursor,
            entries: bins,
            draws,
            counters,
            compact,
            compact_binding,
            refine_list,
            refine_count,
            refine_compact_binding,
            refine_allocate,
            scan,
            scan_binding,
            allocate,
            ancestors,
            bin,
            bin_later,
            bin_fit,
            rewalk_args,
            cluster_levels,
            cluster_mask,
            draw_args,
            raster_args,
            render,
            _geometry: geometry,
        })
    }
}
