//! Every push-constant block in the committed SPIR-V matches its `#[repr(C)]` Rust twin member
//! by member (name, offset, size), as reflected from the SPIR-V, and every shader with a block
//! has a twin here.

mod common;

use penumbra::gpu::reflect::compare_push_layout;
use penumbra::gpu::{shader_interface, shader_names};

use common::push_twins::{kernel_twins, twin, Twin};

/// Every shader with a push-constant block and its Rust twin.
fn push_twins() -> Vec<(Vec<&'static str>, Twin)> {
    use penumbra::shader_types::*;
    use penumbra::techniques::cssm::{CssmPreparePush, CssmPush};
    use penumbra::techniques::essm::{EssmBuildPush, EssmPush};
    use penumbra::techniques::{
        filtered::FilteredPush, pcss::PcssPush, savsm::SavsmPush, vssm::VssmPush,
    };
    let mut twins = vec![
        (
            vec!["passes/light_depth.vert"],
            twin!(LightDepthPush { light_view_proj }),
        ),
        (
            vec!["izb/footprint.comp", "izb/args.comp"],
            twin!(penumbra::techniques::izb::IzbPush { phase }),
        ),
        (
            vec!["atty/receivers.comp"],
            twin!(penumbra::techniques::atty::AttyPush { phase }),
        ),
        (
            vec!["bitmask/bitmask.comp", "bitmask/bitmask_gap_fill.comp"],
            twin!(penumbra::techniques::bitmask::BitmaskPush { group }),
        ),
        (
            vec![
                "passes/view_samples.vert",
                "passes/view_samples.frag",
                "passes/view_samples_faces.frag",
            ],
            twin!(ViewSamplesPush {
                view_proj,
                eye,
                forward
            }),
        ),
        (
            vec!["view_samples/from_depth.comp"],
            twin!(FromDepthPush {
                inv_view_proj,
                eye,
                forward,
                view_size,
                pad0,
                pad1
            }),
        ),
        (
            vec!["receivers/prepare.comp"],
            twin!(ReceiversPush {
                light_position,
                light_u,
                light_v,
                view_origin,
                view_direction,
                view_size,
                kind,
                light_clip,
                normal_offset,
                evaluate_horizon,
                write_lookup,
                pad
            }),
        ),
        (
            vec!["receivers/finish.comp", "receivers/finish_lanes.comp"],
            twin!(ReceiversFinishPush {
                view_size,
                scale,
                pad
            }),
        ),
        (
            vec!["kernels/copy.comp", "kernels/copy_u64.comp"],
            twin!(penumbra::kernels::roofline::CopyPush {
                count,
                row,
                pad0,
                pad1
            }),
        ),
        (
            vec!["cascades/depth_histogram.comp"],
            twin!(penumbra::techniques::cascades::DepthHistogramPush {
                light_view,
                view_size,
                perspective,
                pad,
                turn,
                pad2
            }),
        ),
        (
            vec!["caster_cull/tiles.comp"],
            twin!(CasterTilesPush {
                view_size,
                tile_count
            }),
        ),
        (
            vec!["caster_cull/test.comp"],
            twin!(CasterTestPush {
                light_position,
                light_u,
                light_v,
                triangles,
                tile_count,
                eps,
                kind,
                per_triangle,
                pad0,
                pad1,
                pad2
            }),
        ),
        (
            vec!["receiver_bounds/project.comp"],
            twin!(ReceiverBoundsPush {
                light_view,
                view_size,
                perspective,
                pad
            }),
        ),
        (
            vec!["pcf/pcf.comp"],
            twin!(PcfPush {
                light_view_proj,
                view_size,
                map_size,
                mode,
                kernel,
                receiver_plane,
                pad
            }),
        ),
        (
            vec!["pcf_poisson/pcf_poisson.comp"],
            twin!(PcfPoissonPush {
                light_view_proj,
                view_size,
                map_size,
                taps,
                radius,
                receiver_plane,
                pad
            }),
        ),
        (
            vec!["pcf_coverage/pcf_coverage.comp"],
            twin!(PcfCoveragePush {
                light_view_proj,
                view_size,
                map_size,
                kernel,
                receiver_plane,
                pad
            }),
        ),
        (
            vec!["average_maps/accumulate.comp"],
            twin!(AverageMapsPush {
                light_view_proj,
                light_sample,
                view_size,
                map_size,
                samples,
                first,
                last,
                light_clip
            }),
        ),
        (
            vec!["pcss/blocker_search.comp", "pcss/filter.comp"],
            twin!(PcssPush {
                light_view_proj,
                view_size,
                map_size,
                max_level,
                light_size,
                near,
                far,
                perspective,
                skip,
                search_taps,
                filter_taps,
                min_kernel,
                max_width,
                receiver_plane,
                blocker_depth
            }),
        ),
        (
            vec![
                "savsm/moments.comp",
                "savsm/moments_staged.comp",
                "savsm/lookup.comp",
            ],
            twin!(SavsmPush {
                light_view_proj,
                view_size,
                map_size,
                rows_per_band,
                near,
                far,
                perspective,
                kernel,
                min_variance,
                bleed_reduction,
                pad
            }),
        ),
        (
            vec!["cssm/prepare.comp"],
            twin!(CssmPreparePush {
                light_view_proj,
                view_size,
                map_size,
                near,
                far,
                perspective,
                pad
            }),
        ),
        (
            vec!["cssm/encode.comp", "cssm/lookup.comp"],
            twin!(CssmPush {
                view_size,
                map_size,
                pad,
                near,
                far,
                perspective,
                term,
                flags,
                depth_range,
                offset,
                remap,
                weight,
                scale,
                light_size,
                min_kernel,
                max_width
            }),
        ),
        (
            vec![
                "pages/allocate.comp",
                "pages/ancestors.comp",
                "pages/bin.comp",
                "pages/bin_fit.comp",
                "pages/bin_lanes.comp",
                "pages/bin_later.comp",
                "pages/cluster_levels.comp",
                "pages/draws.comp",
                "pages/page_depth.vert",
                "pages/page_depth_grouped.vert",
                "pages/page_depth_listed.vert",
                "pages/page_raster.comp",
                "pages/slot_clear.comp",
                "pages/slot_groups.comp",
                "pages/slot_scatter.comp",
            ],
            twin!(PagesPush {
                light_view_proj,
                virtual_size,
                page_size,
                levels,
                pool_pages,
                atlas_cols,
                triangles,
                capacity,
                mode,
                round,
                bias_constant,
                bias_slope,
                bias_clamp,
                atlas_quads,
                cull_back_faces,
                pad1,
                pad2
            }),
        ),
        (
            vec!["pvssm/lowres_mip.comp"],
            twin!(PvssmMipPush {
                src_offset,
                dst_offset,
                dst_size,
                centre
            }),
        ),
        (
            vec!["pvssm/root_strides.comp", "pvssm/root_strides_texels.comp"],
            twin!(PvssmStridesPush {
                page_size,
                atlas_cols
            }),
        ),
        (
            vec![
                "pvssm/shape.comp",
                "pvssm/filter.comp",
                "pvssm/filter_texels.comp",
            ],
            twin!(PvssmPush {
                light_view_proj,
                view_size,
                virtual_size,
                page_size,
                levels,
                atlas_cols,
                lowres_size,
                options,
                light_size,
                near,
                far,
                perspective,
                rho_scale,
                max_search,
                search_bias
            }),
        ),
        (
            vec![
                "rmsm/mark.comp",
                "rmsm/edges.comp",
                "rmsm/edges_texels.comp",
                "rmsm/lookup.comp",
                "rmsm/lookup_texels.comp",
            ],
            twin!(RmsmPush {
                light_view_proj,
                view_size,
                virtual_size,
                page_size,
                levels,
                atlas_cols,
                filter_mode,
                lod_bias,
                refine,
                pad
            }),
        ),
        (
            vec![
                "vssm/moments.comp",
                "vssm/moments_staged.comp",
                "vssm/lookup.comp",
            ],
            twin!(VssmPush {
                light_view_proj,
                view_size,
                map_size,
                rows_per_band,
                near,
                far,
                perspective,
                subdivision,
                light_size,
                min_kernel,
                max_width,
                min_variance,
                max_level,
                receiver_plane,
                split_regions
            }),
        ),
        (
            vec!["essm/encode.comp", "essm/lookup.comp"],
            twin!(EssmPush {
                light_view_proj,
                view_size,
                map_size,
                levels,
                near,
                far,
                perspective,
                exponent,
                light_size,
                min_kernel,
                max_width,
                receiver_plane,
                pad
            }),
        ),
        (
            vec!["essm/build.comp"],
            twin!(EssmBuildPush {
                src_offset,
                dst_offset,
                src_width,
                dst_width,
                dst_height,
                axis,
                pad
            }),
        ),
        (
            vec![
                "filtered/encode.comp",
                "filtered/encode_rg.comp",
                "filtered/encode_r.comp",
                "filtered/blur.comp",
                "filtered/blur_rg.comp",
                "filtered/blur_r.comp",
                "filtered/encode_staged.comp",
                "filtered/encode_staged_rg.comp",
                "filtered/encode_staged_r.comp",
                "filtered/blur_staged.comp",
                "filtered/blur_staged_rg.comp",
                "filtered/blur_staged_r.comp",
                "filtered/reconstruct.comp",
                "filtered/reconstruct_rg.comp",
                "filtered/reconstruct_r.comp",
            ],
            twin!(FilteredPush {
                light_view_proj,
                view_size,
                map_size,
                mode,
                near,
                far,
                perspective,
                radius,
                box_filter,
                channel_info,
                terms,
                flags,
                params
            }),
        ),
        (
            vec!["reference/reference.comp"],
            twin!(penumbra::reference::ReferencePush {
                light_position,
                light_u,
                light_v,
                view_size,
                kind,
                samples,
                inv_samples,
                offset,
                t_far,
                single_layer,
                jitter,
                triangle_count,
                first_cell,
                cell_count
            }),
        ),
    ];
    twins.extend(kernel_twins());
    twins
}

#[test]
fn every_push_struct_matches_its_reflected_block_member_by_member() {
    let twins = push_twins();
    let mut problems = Vec::new();
    for name in shader_names() {
        let (_, i) = shader_interface(name).expect("reflect");
        if i.push_constant_size > 0 && !twins.iter().any(|(s, _)| s.contains(&name)) {
            problems.push(format!(
                "{name}: push-constant block without a Rust twin here"
            ));
        }
    }
    for (shaders, (ty, fields, size)) in &twins {
        for &shader in shaders {
            let (_, i) = shader_interface(shader).expect("reflect");
            assert!(
                !i.push_constant_members.is_empty(),
                "{shader} reflects no push-constant members"
            );
            for p in compare_push_layout(&i, fields, *size) {
                problems.push(format!("{shader} vs {ty}: {p}"));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}
