//! The scene's triangles on the GPU: one position stream and one index list for all meshes,
//! and the world boxes of consecutive runs of [`CLUSTER_TRIANGLES`] triangles (clusters), made
//! once here on the CPU, which the virtual pages' culling walk projects to skip the levels a
//! whole cluster cannot reach (`glsl/pages/cluster_levels.comp`).

use ash::vk;
use glam::Vec3;

use crate::error::{Error, Result};
use crate::gpu::{Buffer, Context};
use crate::scene::Scene;

/// Triangles of a cluster: consecutive in the index list, one workgroup of the culling walk
/// (`glsl/pages/bin.glsl`, `cluster_levels.comp`).
pub const CLUSTER_TRIANGLES: u32 = 64;

/// Vertex and index buffers of a whole scene.
pub struct SceneGeometry {
    /// Positions, `vec3` tightly packed.
    pub vertices: Buffer,
    /// Triangle-list indices.
    pub indices: Buffer,
    /// Number of indices.
    pub index_count: u32,
    /// Number of vertices.
    pub vertex_count: u32,
    /// Per cluster, its triangles' world-space box: minimum then maximum corner, each a `vec4`
    /// (w = 0).
    pub cluster_boxes: Buffer,
}

impl SceneGeometry {
    /// Uploads every mesh of `scene`.
    pub fn upload(ctx: &Context, scene: &Scene) -> Result<SceneGeometry> {
        let (positions, indices) = scene.merged();
        Self::from_triangles(ctx, &positions, &indices)
    }

    /// Uploads a triangle list.
    pub fn from_triangles(ctx: &Context, positions: &[Vec3], indices: &[u32]) -> Result<Self> {
        if indices.is_empty() || indices.len() % 3 != 0 {
            return Err(Error::input(
                "scene",
                None,
                format!("{} indices is not a non-empty triangle list", indices.len()),
            ));
        }
        // The GPU would read out of bounds on a bad index, and a NaN vertex poisons every depth
        // test it touches: reject both here, for callers that bypass the scene loader.
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::input(
                "scene",
                None,
                format!("vertex {i} is not finite: {:?}", positions[i]),
            ));
        }
        if let Some(i) = indices.iter().position(|&i| i as usize >= positions.len()) {
            return Err(Error::input(
                "scene",
                None,
                format!(
                    "index {} (triangle {}) refers past the {} vertices",
                    indices[i],
                    i / 3,
                    positions.len()
                ),
            ));
        }
        let index_count = u32::try_from(indices.len())
            .map_err(|_| Error::input("scene", None, "more than 2^32 indices".to_string()))?;
        let flat: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
        let boxes = cluster_boxes(positions, indices);
        let cluster_boxes = ctx.buffer_with(
            "scene cluster boxes",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &boxes,
        )?;
        let vertices = ctx.buffer_with(
            "scene vertices",
            vk::BufferUsageFlags::VERTEX_BUFFER | vk::BufferUsageFlags::STORAGE_BUFFER,
            &flat,
        )?;
        let indices = ctx.buffer_with(
            "scene indices",
            vk::BufferUsageFlags::INDEX_BUFFER | vk::BufferUsageFlags::STORAGE_BUFFER,
            indices,
        )?;
        Ok(SceneGeometry {
            vertices,
            indices,
            index_count,
            vertex_count: positions.len() as u32,
            cluster_boxes,
        })
    }
}

/// The world box of each run of [`CLUSTER_TRIANGLES`] triangles of `indices` (the last run may
/// be shorter), as `[min.x, min.y, min.z, 0, max.x, max.y, max.z, 0]` per cluster. The indices
/// must be in range (checked by the caller).
pub fn cluster_boxes(positions: &[Vec3], indices: &[u32]) -> Vec<f32> {
    indices
        .chunks(3 * CLUSTER_TRIANGLES as usize)
        .flat_map(|run| {
            let (lo, hi) = run.iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), &i| {
                    let p = positions[i as usize];
                    (lo.min(p), hi.max(p))
                },
            );
            [lo.x, lo.y, lo.z, 0.0, hi.x, hi.y, hi.z, 0.0]
        })
        .collect()
}
