//! `izb`'s set-up: the light's encoding and the grid's size from the knobs, the buffers, the
//! triangles in their spatial order, the scans, and each pass's pipeline and descriptor set.

use ash::vk;
use glam::{Vec3, Vec4};

use super::knobs::{COUNTER_WORDS, GRID_DEFAULT, MIN_GRID, SOFT_GRID};
use super::params::{
    grid_map, sample_grid, soft_item_triangles, spatial_order, IzbParams, HARD_ITEM_TRIANGLES,
    ITEM_SAMPLES, SOFT_SAMPLES_PER_INVOCATION,
};
use super::{Izb, IZB, IZB_SOFT};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, DescriptorSet, MemoryLocation, Pipeline};
use crate::kernels::scan::Scan;
use crate::reference::bvh::scene_scale;
use crate::reference::{light_encoding, KIND_DIRECTIONAL, KIND_POINT, KIND_RECT};
use crate::scene::Light;
use crate::techniques::{set_for, Params, TechniqueSetup};

/// `KIND_SUN` of `glsl/izb/izb.glsl`: `izb-soft` under a sun disk (the reference's kinds are 0-2).
const KIND_SUN: i32 = 3;

impl<'a> Izb<'a> {
    pub(super) fn new(setup: &TechniqueSetup<'a>, params: &Params, soft: bool) -> Result<Izb<'a>> {
        let ctx = setup.ctx;
        let name = if soft { IZB_SOFT.name } else { IZB.name };
        let bad = |message: String| Error::Parameter {
            technique: name.to_string(),
            message,
        };
        let grid_knob = params.u32("grid")?;
        let capacity = (params.get("pair_capacity")? * 1e6).round() as u64;
        let (mut kind, centre, u, v) = light_encoding(setup.light, name)?;
        let extent = u != Vec3::ZERO || v != Vec3::ZERO;
        if kind == KIND_DIRECTIONAL && extent && soft {
            // izb-soft under a sun disk: light samples over the disk of directions.
            kind = KIND_SUN;
        } else if kind == KIND_DIRECTIONAL && extent {
            // izb under a sun disk: the hard test from its centre direction.
        } else if kind == KIND_RECT && !(soft && extent) {
            // izb, or a rect of zero extent: a point at the centre.
            kind = KIND_POINT;
        }
        // One ray per sample unless an area light is sampled: izb-soft with a point light, a
        // hard sun or a rect of zero extent runs izb's test.
        let sampled = kind == KIND_RECT || kind == KIND_SUN;
        let (na, nb) = if sampled {
            sample_grid(params.u32("samples")?)
        } else {
            (1, 1)
        };
        let words = (na * nb).div_ceil(32);
        let jitter = if soft { params.u32("jitter")? } else { 0 };
        let perspective = !matches!(setup.light, Light::Directional { .. });
        if perspective != setup.receiver_bounds.perspective && !setup.receiver_bounds.is_empty() {
            return Err(bad(
                "the receivers' bounds are not in the light's projection".into(),
            ));
        }
        let view = setup.light_view.view;
        // The rect's half extents in view space (it lies in the plane z = 0 of its own view); a
        // sun's tangent on both axes (its rays leave a sample within that of the centre's per
        // unit of depth, whichever way the disk's axes lie in the view).
        let mut half = glam::Vec2::ZERO;
        if kind == KIND_SUN {
            half = glam::Vec2::splat(u.length().max(v.length()) * (1.0 + 1e-4));
        }
        if kind == KIND_RECT {
            for (a, b) in [(0.5, 0.5), (0.5, -0.5), (-0.5, 0.5), (-0.5, -0.5)] {
                let corner = view.transform_point3(centre + u * a + v * b);
                half = half.max(corner.truncate().abs());
            }
            half *= 1.0 + 1e-4;
        }
        let scale = scene_scale(setup.positions);
        let deepest = setup.receiver_bounds.max.z;
        let floor = if perspective && deepest.is_finite() {
            1e-4 * deepest.max(1e-20)
        } else {
            0.0
        };
        let triangles = u32::try_from(setup.indices.len() / 3)
            .map_err(|_| bad("more than 2^32 triangles".into()))?;
        let (w, h) = (setup.view.width, setup.view.height);
        // Triangles eight at a time where a subgroup holds a workgroup of ITEM_SAMPLES and has
        // the operations (the soft test also ORs its lanes' kept triangles).
        let info = ctx.info();
        let batched = params.u32("triangle_batch")? == 1
            && info.subgroup_shuffle
            && info.subgroup_size >= ITEM_SAMPLES
            && (!sampled || info.subgroup_arithmetic);
        // The bin pass sums its counters over a subgroup before the atomics where the
        // device has subgroup arithmetic (on lavapipe an atomic is a loop over the SIMD lanes,
        // and the bin pass spent half its time adding its counters: bunny-rect 10.5 -> 7.3 ms).
        let sum_per_subgroup = params.u32("triangle_batch")? == 1 && info.subgroup_arithmetic;
        let grid = match grid_knob {
            0 if sampled => SOFT_GRID,
            0 => GRID_DEFAULT,
            g if g < MIN_GRID => {
                return Err(bad(format!(
                    "grid {grid_knob}: at least 8 cells a side (or 0 for the default)"
                )))
            }
            g => g,
        };
        let per_invocation = if sampled && batched {
            SOFT_SAMPLES_PER_INVOCATION
        } else {
            1
        };
        let item_triangles = if sampled {
            soft_item_triangles(na, nb, per_invocation)
        } else {
            HARD_ITEM_TRIANGLES
        };
        let izb_params = IzbParams {
            light_view: view,
            light_c: centre.extend(1.0),
            light_u: u.extend(0.0),
            light_v: v.extend(0.0),
            grid_map: grid_map(setup.receiver_bounds, grid),
            light_half: Vec4::new(half.x, half.y, floor, params.f32("ray_offset")? * scale),
            view: [w as i32, h as i32, grid as i32, kind],
            pattern: [na as i32, nb as i32, jitter as i32, words as i32],
            pattern_f: [1.0 / na as f32, 1.0 / nb as f32, 4.0 * scale + 1.0, 0.0],
            sizes: [
                triangles,
                u32::try_from(capacity).map_err(|_| bad("pair capacity too large".into()))?,
                item_triangles,
                u32::from(perspective),
            ],
            items: [ITEM_SAMPLES * per_invocation, per_invocation, 0, 0],
        };

        let storage = |label: &str, bytes: u64| Buffer::storage(ctx, label, bytes.max(4));
        let pixels = u64::from(w) * u64::from(h);
        let cells = u64::from(grid) * u64::from(grid) + 1;
        let tris = u64::from(triangles);
        let params_buffer = ctx.buffer_with(
            "izb params",
            // A uniform block: lavapipe reads it with scalar loads even inside loops and
            // branches, where a storage buffer's reads become a loop over the SIMD lanes.
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            std::slice::from_ref(&izb_params),
        )?;
        let cell_start = storage("izb cell starts", 4 * cells)?;
        let binned = storage("izb binned", 8 * pixels)?;
        let cell_samples = storage("izb cell samples", 4 * pixels)?;
        let origins = storage("izb origins", 16 * pixels)?;
        let tri_cells = storage("izb triangle cells", 4 * tris)?;
        let cell_tris = storage("izb cell triangles", 4 * cells)?;
        let cell_tri_start = storage("izb cell triangle starts", 4 * cells)?;
        let cell_cursor = storage("izb cell cursors", 4 * cells)?;
        let cell_items = storage("izb cell items", 4 * cells)?;
        let item_start = storage("izb item starts", 4 * cells)?;
        let large = storage("izb large triangles", 4 * tris)?;
        // The cells each small footprint keeps, recorded by the count for the write.
        let tri_range = storage("izb triangle ranges", 16 * tris.max(1))?;
        // Read by the test pass through texel views (below).
        let texel_storage = |label: &str, bytes: u64| {
            // At least one texel: a view of an empty scene's triangles still needs one.
            let bytes = bytes.max(16);
            Buffer::storage_with(
                ctx,
                label,
                bytes,
                vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            )
        };
        let tri_list = texel_storage("izb pairs", 4 * capacity)?;
        // Also read by the footprint pass's range walk through texel views.
        let cell_count = texel_storage("izb cell counts", 4 * cells)?;
        let cell_depth = texel_storage("izb cell depths", 4 * cells)?;
        let tri_verts = texel_storage("izb triangle vertices", 48 * tris)?;
        // Only the soft test reads them (one texel otherwise).
        let tri_bounds = texel_storage("izb triangle bounds", 16 * if sampled { tris } else { 1 })?;
        let tri_indices = ctx.buffer_with(
            "izb triangle indices (spatial order)",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &spatial_order(setup.positions, setup.indices),
        )?;
        // The test pass reads the triangles of a work item, the same for all its invocations,
        // through texel views: gathers, where storage-buffer reads in its loop would go lane
        // by lane on lavapipe (whose storage reads are scalar only outside control flow).
        let views = [
            tri_list.texel_view(vk::Format::R32_UINT, 4)?,
            tri_verts.texel_view(vk::Format::R32G32B32A32_SFLOAT, 16)?,
            tri_bounds.texel_view(vk::Format::R32G32B32A32_SFLOAT, 16)?,
            cell_count.texel_view(vk::Format::R32_UINT, 4)?,
            cell_depth.texel_view(vk::Format::R32_UINT, 4)?,
        ];
        let masks = storage("izb masks", 4 * pixels * u64::from(words))?;
        let counters = storage("izb counters", 4 * COUNTER_WORDS.len() as u64)?;
        let args = Buffer::new(
            ctx,
            "izb test dispatch",
            12,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;

        let all = [
            (0, Binding::Image(&setup.view.positions)),
            (1, Binding::Image(&setup.view.normals)),
            (2, Binding::Buffer(&params_buffer)),
            (3, Binding::Buffer(&setup.geometry.vertices)),
            (4, Binding::Buffer(&tri_indices)),
            (5, Binding::Buffer(&cell_count)),
            (6, Binding::Buffer(&cell_start)),
            (7, Binding::Buffer(&cell_depth)),
            (8, Binding::Buffer(&binned)),
            (9, Binding::Buffer(&cell_samples)),
            (10, Binding::Buffer(&origins)),
            (11, Binding::Buffer(&tri_cells)),
            (12, Binding::Buffer(&cell_tris)),
            (13, Binding::Buffer(&cell_tri_start)),
            (14, Binding::Buffer(&large)),
            (15, Binding::Buffer(&tri_list)),
            (16, Binding::Buffer(&masks)),
            (17, Binding::Buffer(&counters)),
            (18, Binding::Buffer(&args)),
            (19, Binding::Image(setup.visibility)),
            (20, Binding::Buffer(&tri_verts)),
            (21, Binding::Buffer(&cell_cursor)),
            (22, Binding::Buffer(&cell_items)),
            (23, Binding::Buffer(&item_start)),
            (24, Binding::Texels(&views[0])),
            (25, Binding::Texels(&views[1])),
            (26, Binding::Buffer(&tri_range)),
            (27, Binding::Texels(&views[2])),
            (28, Binding::Buffer(&tri_bounds)),
            (29, Binding::Texels(&views[3])),
            (30, Binding::Texels(&views[4])),
        ];
        let pass = |shader: &str| -> Result<(Pipeline, DescriptorSet)> {
            let p = Pipeline::compute(ctx, shader)?;
            let s = set_for(ctx, &p, &all)?;
            Ok((p, s))
        };
        let scan = Scan::new(ctx)?;
        let cell_len = u32::try_from(cells).map_err(|_| bad(format!("grid {grid} too large")))?;
        let cell_scan = scan.bind(&cell_count, &cell_start, cell_len)?;
        let pair_scan = scan.bind(&cell_tris, &cell_tri_start, cell_len)?;
        let item_scan = scan.bind(&cell_items, &item_start, cell_len)?;
        Ok(Izb {
            ctx: ctx.clone(),
            name,
            view_size: [w, h],
            triangles,
            bin: pass(if sum_per_subgroup {
                "izb/bin_subgroup.comp"
            } else {
                "izb/bin.comp"
            })?,
            scatter: pass("izb/scatter.comp")?,
            footprint: pass("izb/footprint.comp")?,
            args_pass: pass("izb/args.comp")?,
            // A sun disk's test is its own shader (test_soft.glsl's SUN_DISK): the rect's
            // carries none of its code.
            test: pass(match (sampled, kind == KIND_SUN, batched) {
                (true, true, true) => "izb/test_soft_sun_batched.comp",
                (true, true, false) => "izb/test_soft_sun.comp",
                (true, false, true) => "izb/test_soft_batched.comp",
                (true, false, false) => "izb/test_soft.comp",
                (false, _, true) => "izb/test_hard_batched.comp",
                (false, _, false) => "izb/test_hard.comp",
            })?,
            resolve: pass("izb/resolve.comp")?,
            scan,
            cell_scan,
            pair_scan,
            item_scan,
            grid,
            cell_count,
            cell_depth,
            tri_cells,
            cell_tris,
            cell_cursor,
            masks,
            counters,
            args,
            _views: views,
            _buffers: vec![
                params_buffer,
                cell_start,
                binned,
                cell_samples,
                origins,
                cell_tri_start,
                cell_items,
                item_start,
                large,
                tri_list,
                tri_verts,
                tri_indices,
                tri_range,
                tri_bounds,
            ],
            _visibility: setup.visibility,
        })
    }
}
