//! The scene's triangles on the GPU: one position stream and one index list for all meshes.

use ash::vk;
use glam::Vec3;

use crate::error::{Error, Result};
use crate::gpu::{Buffer, Context};
use crate::scene::Scene;

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
        let index_count = u32::try_from(indices.len())
            .map_err(|_| Error::input("scene", None, "more than 2^32 indices".to_string()))?;
        let flat: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
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
        })
    }
}
