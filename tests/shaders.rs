//! The committed SPIR-V is what the GLSL compiles to, valid, and reflects as the Rust side
//! expects: every push-constant block matches its `#[repr(C)]` Rust twin member by member
//! (name, offset, size), as reflected from the SPIR-V. Recompiling needs the `shader-compiler`
//! feature (Debian's libshaderc); the README's test command enables it.

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4};
use penumbra::gpu::reflect::{compare_push_layout, RustField};
use penumbra::gpu::{shader_interface, shader_names};
use penumbra::kernels;

#[cfg(feature = "shader-compiler")]
#[test]
fn committed_spirv_is_up_to_date() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let compiled = penumbra::shader_compiler::compile_all(&root.join("glsl")).expect("compile");
    let mut stale = Vec::new();
    for s in &compiled {
        let path = root.join("spirv").join(format!("{}.spv", s.name));
        match std::fs::read(&path) {
            Ok(bytes) if bytes == s.spirv => {}
            Ok(_) => stale.push(format!("{} differs", path.display())),
            Err(_) => stale.push(format!("{} is missing", path.display())),
        }
    }
    let names: Vec<_> = shader_names().collect();
    for n in &names {
        if !compiled.iter().any(|s| s.name == *n) {
            stale.push(format!("spirv/{n}.spv has no source in glsl/"));
        }
    }
    assert!(
        stale.is_empty(),
        "run `cargo run --features shader-compiler --bin compile-shaders`:\n{}",
        stale.join("\n")
    );
}

/// The embedding example's own shaders, compiled next to their sources by `compile-shaders`.
#[cfg(feature = "shader-compiler")]
#[test]
fn the_examples_spirv_is_up_to_date() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/deferred_shadows");
    let compiled = penumbra::shader_compiler::compile_all(&dir).expect("compile");
    assert_eq!(compiled.len(), 2, "gbuffer.vert and gbuffer.frag");
    for s in &compiled {
        let path = dir.join(format!("{}.spv", s.name));
        let committed = std::fs::read(&path).unwrap_or_default();
        assert!(
            committed == s.spirv,
            "{} is stale: run `cargo run --features shader-compiler --bin compile-shaders`",
            path.display()
        );
    }
}

#[test]
fn every_module_passes_spirv_val() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut checked = 0;
    for name in shader_names() {
        let path = root.join("spirv").join(format!("{name}.spv"));
        let out = std::process::Command::new("spirv-val")
            .args(["--target-env", "vulkan1.2"])
            .arg(&path)
            .output()
            .expect("spirv-val (package spirv-tools) must be installed");
        assert!(
            out.status.success(),
            "spirv-val rejects {}: {}",
            path.display(),
            String::from_utf8_lossy(&out.stderr)
        );
        checked += 1;
    }
    assert!(checked >= 4, "only {checked} shaders embedded");
}

#[test]
fn pcf_interface_reflects_as_declared() {
    let (_, i) = shader_interface("pcf/pcf.comp").expect("reflect");
    assert_eq!(i.stage, vk::ShaderStageFlags::COMPUTE);
    assert_eq!(i.local_size, [8, 8, 1]);
    let kinds: Vec<_> = i
        .bindings
        .iter()
        .map(|b| (b.binding, b.kind, b.read_only))
        .collect();
    assert_eq!(
        kinds,
        vec![
            (0, vk::DescriptorType::STORAGE_IMAGE, true),
            (1, vk::DescriptorType::COMBINED_IMAGE_SAMPLER, true),
            (2, vk::DescriptorType::STORAGE_IMAGE, false),
            (3, vk::DescriptorType::STORAGE_BUFFER, false),
            (4, vk::DescriptorType::STORAGE_IMAGE, true),
        ]
    );
    assert_eq!(i.push_constant_size, 96);
    let members: Vec<_> = i
        .push_constant_members
        .iter()
        .map(|m| (m.name.as_str(), m.offset, m.size))
        .collect();
    assert_eq!(
        members,
        vec![
            ("light_view_proj", 0, 64),
            ("view_size", 64, 8),
            ("map_size", 72, 8),
            ("mode", 80, 4),
            ("kernel", 84, 4),
            ("receiver_plane", 88, 4),
            ("pad1", 92, 4),
        ]
    );
}

/// The izb test passes read their parameters as a uniform block and the triangles through
/// texel buffers (`samplerBuffer`, `usamplerBuffer`): the reflection must name those kinds, or
/// the descriptor sets would be built with the wrong descriptor types.
#[test]
fn izb_test_interfaces_reflect_uniform_blocks_and_texel_buffers() {
    for shader in ["izb/test_hard.comp", "izb/test_soft.comp"] {
        let (_, i) = shader_interface(shader).expect("reflect");
        // One invocation per sample of a work item: the host's item size is the shader's.
        let item = penumbra::techniques::izb::ITEM_SAMPLES;
        assert_eq!(i.local_size, [item, 1, 1], "{shader}");
        let kind = |n: u32| {
            i.bindings
                .iter()
                .find(|b| b.binding == n)
                .map(|b| (b.kind, b.read_only))
        };
        assert_eq!(
            kind(2),
            Some((vk::DescriptorType::UNIFORM_BUFFER, true)),
            "{shader}"
        );
        assert_eq!(
            kind(24),
            Some((vk::DescriptorType::UNIFORM_TEXEL_BUFFER, true)),
            "{shader}"
        );
        assert_eq!(
            kind(25),
            Some((vk::DescriptorType::UNIFORM_TEXEL_BUFFER, true)),
            "{shader}"
        );
        assert_eq!(
            kind(16).map(|k| k.0),
            Some(vk::DescriptorType::STORAGE_BUFFER)
        );
    }
}

#[test]
fn raster_interfaces_reflect_as_declared() {
    let (_, v) = shader_interface("passes/light_depth.vert").expect("reflect");
    assert_eq!(v.stage, vk::ShaderStageFlags::VERTEX);
    assert!(v.bindings.is_empty());
    assert_eq!(v.push_constant_size, 64);
    let (_, f) = shader_interface("passes/view_samples.frag").expect("reflect");
    assert_eq!(f.stage, vk::ShaderStageFlags::FRAGMENT);
    assert_eq!(f.push_constant_size, 96);
    assert!(f.bindings.is_empty());
    // The face-normal variant reads the scene's vertex and index buffers.
    let (_, f) = shader_interface("passes/view_samples_faces.frag").expect("reflect");
    assert_eq!(f.push_constant_size, 96);
    assert_eq!(f.bindings.len(), 2);
}

#[test]
fn malformed_spirv_is_an_error_not_a_panic() {
    use penumbra::gpu::reflect::{reflect, words_from_bytes};
    assert!(words_from_bytes("x", &[1, 2, 3]).is_err());
    assert!(reflect("x", &[0xdead_beef, 0, 0, 0, 0]).is_err());
    // A truncated instruction: word count runs past the end.
    assert!(reflect("x", &[0x0723_0203, 0x0001_0500, 0, 10, 0, (9 << 16) | 15]).is_err());
}

/// A Rust push struct's fields, each with `offset_of!` and its size, and the struct's size.
macro_rules! twin {
    ($ty:ty { $($field:ident),* $(,)? }) => {{
        let zero = <$ty as Zeroable>::zeroed();
        (
            stringify!($ty),
            vec![$(RustField {
                name: stringify!($field),
                offset: std::mem::offset_of!($ty, $field),
                size: std::mem::size_of_val(&zero.$field),
            }),*],
            std::mem::size_of::<$ty>(),
        )
    }};
}

type Twin = (&'static str, Vec<RustField>, usize);

/// Every shader with a push-constant block and its Rust twin.
fn push_twins() -> Vec<(Vec<&'static str>, Twin)> {
    use kernels::{compact, minmax, nbuffer, raster, reduce, sat, scan, sort};
    use penumbra::shader_types::*;
    use penumbra::techniques::cssm::{CssmPreparePush, CssmPush};
    use penumbra::techniques::essm::{EssmBuildPush, EssmPush};
    use penumbra::techniques::{
        filtered::FilteredPush, pcss::PcssPush, savsm::SavsmPush, vssm::VssmPush,
    };
    vec![
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
                bias_clamp
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
            vec!["pvssm/shape.comp", "pvssm/filter.comp"],
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
            vec!["rmsm/mark.comp", "rmsm/edges.comp", "rmsm/lookup.comp"],
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
                pad
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
        (
            vec!["kernels/compact_scatter.comp"],
            twin!(compact::CompactPush { n }),
        ),
        (
            vec![
                "kernels/compact_serial.comp",
                "kernels/compact_serial_wide.comp",
            ],
            twin!(compact::CompactSerialPush { n, phase }),
        ),
        (
            vec![
                "kernels/minmax_first.comp",
                "kernels/minmax_next.comp",
                "kernels/minmax_first_rgba.comp",
                "kernels/minmax_next_rgba.comp",
            ],
            twin!(minmax::MinMaxPush { src_size, dst_size }),
        ),
        (
            vec!["kernels/minmax_tail.comp", "kernels/minmax_tail_rgba.comp"],
            twin!(minmax::MinMaxTailPush {
                src_size,
                levels,
                pad
            }),
        ),
        (
            vec![
                "kernels/nbuffer_first.comp",
                "kernels/nbuffer_next.comp",
                "kernels/nbuffer_first_rgba.comp",
                "kernels/nbuffer_next_rgba.comp",
                "kernels/nbuffer_first_staged.comp",
                "kernels/nbuffer_next_staged.comp",
            ],
            twin!(nbuffer::NBufferBuildPush { size, step, levels }),
        ),
        (
            vec![
                "kernels/nbuffer_tile.comp",
                "kernels/nbuffer_tile_rgba.comp",
            ],
            twin!(nbuffer::NBufferTilePush { size, levels, pad }),
        ),
        (
            vec!["kernels/nbuffer_query.comp"],
            twin!(nbuffer::NBufferQueryPush {
                size,
                max_level,
                count
            }),
        ),
        (
            vec![
                "kernels/raster_conservative.comp",
                "kernels/raster_conservative_lanes.comp",
                "kernels/raster_conservative_clip.comp",
            ],
            twin!(raster::RasterPush {
                light_view_proj,
                triangles,
                map_size,
                phase,
                bias_slope,
                bias_clamp,
                centre,
                pad1,
                pad2
            }),
        ),
        (
            vec![
                "kernels/reduce_buffer.comp",
                "kernels/reduce_image.comp",
                "kernels/reduce_final.comp",
            ],
            twin!(reduce::ReducePush {
                count,
                chunk,
                width,
                pad
            }),
        ),
        (
            vec![
                "kernels/sat_rows_f32.comp",
                "kernels/sat_rows_f64.comp",
                "kernels/sat_rows_u32.comp",
                "kernels/sat_rows_u64.comp",
                "kernels/sat_rows_u32_fixed.comp",
                "kernels/sat_rows_u64_fixed.comp",
                "kernels/sat_rows_f32_wide.comp",
                "kernels/sat_rows_u32_wide.comp",
                "kernels/sat_rows_u32_fixed_wide.comp",
                "kernels/sat_rows_blocked_f32.comp",
                "kernels/sat_rows_blocked_f64.comp",
                "kernels/sat_rows_blocked_u32.comp",
                "kernels/sat_rows_blocked_u64.comp",
                "kernels/sat_rows_blocked_u32_fixed.comp",
                "kernels/sat_rows_blocked_u64_fixed.comp",
            ],
            twin!(sat::SatRowsPush {
                size,
                row0,
                rows,
                scale,
                pad
            }),
        ),
        (
            vec![
                "kernels/sat_cols_f32.comp",
                "kernels/sat_cols_f64.comp",
                "kernels/sat_cols_u32.comp",
                "kernels/sat_cols_u64.comp",
                "kernels/sat_cols_f32_wide.comp",
                "kernels/sat_cols_u32_wide.comp",
            ],
            twin!(sat::SatColsPush { size, rows, first }),
        ),
        (
            vec![
                "kernels/sat_cols_blocked_f32.comp",
                "kernels/sat_cols_blocked_f64.comp",
                "kernels/sat_cols_blocked_u32.comp",
                "kernels/sat_cols_blocked_u64.comp",
            ],
            twin!(sat::SatColsBlockedPush {
                size,
                rows,
                first,
                phase,
                chunk_rows,
                pad
            }),
        ),
        (
            vec![
                "kernels/sat_query_f32.comp",
                "kernels/sat_query_f64.comp",
                "kernels/sat_query_u32.comp",
                "kernels/sat_query_u64.comp",
            ],
            twin!(sat::SatQueryPush {
                size,
                rows_per_band,
                count
            }),
        ),
        (
            vec!["kernels/sat_row_sums.comp", "kernels/sat_mean.comp"],
            twin!(sat::SatSizePush { size }),
        ),
        (
            vec![
                "kernels/scan_block_shared.comp",
                "kernels/scan_block_subgroup.comp",
                "kernels/scan_block_serial.comp",
                "kernels/scan_block_serial_wide.comp",
                "kernels/scan_add.comp",
            ],
            twin!(scan::ScanPush {
                n,
                inclusive,
                flags,
                mode
            }),
        ),
        (
            vec![
                "kernels/sort_histogram_shared.comp",
                "kernels/sort_histogram_subgroup.comp",
                "kernels/sort_scatter_shared.comp",
                "kernels/sort_scatter_subgroup.comp",
                "kernels/sort_serial_histogram.comp",
                "kernels/sort_serial_scatter.comp",
            ],
            twin!(sort::SortPush {
                n,
                shift,
                num_blocks,
                pad
            }),
        ),
    ]
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

/// `PcfPush` with `mode` and `kernel` swapped: the same offsets by position and the same total
/// size, so only a comparison by name catches it.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct SwappedPcfPush {
    light_view_proj: Mat4,
    view_size: IVec2,
    map_size: IVec2,
    kernel: i32,
    mode: i32,
    receiver_plane: i32,
    pad: i32,
}

/// `PcfPush` without `receiver_plane` (a padding field in its place).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ShortPcfPush {
    light_view_proj: Mat4,
    view_size: IVec2,
    map_size: IVec2,
    mode: i32,
    kernel: i32,
    pad: [i32; 2],
}

#[test]
fn the_layout_check_catches_reordered_and_missing_fields() {
    let (_, pcf) = shader_interface("pcf/pcf.comp").expect("reflect");
    let (_, fields, size) = twin!(SwappedPcfPush {
        light_view_proj,
        view_size,
        map_size,
        kernel,
        mode,
        receiver_plane,
        pad
    });
    let problems = compare_push_layout(&pcf, &fields, size);
    assert_eq!(problems.len(), 2, "{problems:?}");
    assert!(problems[0].contains("'mode': GLSL offset 80 size 4, Rust offset 84"));
    assert!(problems[1].contains("'kernel': GLSL offset 84 size 4, Rust offset 80"));

    let (_, fields, size) = twin!(ShortPcfPush {
        light_view_proj,
        view_size,
        map_size,
        mode,
        kernel,
        pad
    });
    let problems = compare_push_layout(&pcf, &fields, size);
    assert_eq!(
        problems,
        vec!["GLSL member 'receiver_plane' has no Rust field".to_string()]
    );

    // A field left out of the list is caught by the size sum (Pod structs have no gaps).
    let (_, mut fields, size) = twin!(SwappedPcfPush {
        light_view_proj,
        view_size,
        map_size,
        mode,
        kernel,
        receiver_plane,
        pad
    });
    fields.pop();
    let problems = compare_push_layout(&pcf, &fields, size);
    assert!(
        problems.iter().any(|p| p.contains("list every field")),
        "{problems:?}"
    );

    // Another shader's block is not this struct's twin.
    let (_, light_depth) = shader_interface("passes/light_depth.vert").expect("reflect");
    assert!(!compare_push_layout(&light_depth, &fields, size).is_empty());
}
