//! Texel-buffer views (`Buffer::texel_view`): a view of a buffer too small for one texel is a
//! clear error, not an empty-range view; a valid one is made and dropped under validation.
//! (The `maxTexelBufferElements` check is not exercised: it would take a buffer of 2^27+ texels.)

mod common;

use ash::vk;
use penumbra::gpu::Buffer;
use penumbra::Error;

fn texel_buffer(ctx: &penumbra::Context, bytes: u64) -> Buffer {
    Buffer::storage_with(
        ctx,
        "texels",
        bytes,
        vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
    )
    .expect("buffer")
}

#[test]
fn a_view_needs_a_whole_texel() {
    let ctx = common::context();
    {
        let small = texel_buffer(&ctx, 8);
        match small.texel_view(vk::Format::R32G32B32A32_SFLOAT, 16) {
            Err(Error::Unsupported { feature, .. }) => {
                assert!(feature.contains("hold no 16-byte texel"), "{feature}")
            }
            Err(e) => panic!("wrong error: {e}"),
            Ok(_) => panic!("a view of 8 bytes as 16-byte texels was made"),
        }
        let buffer = texel_buffer(&ctx, 64);
        let view = buffer
            .texel_view(vk::Format::R32G32B32A32_SFLOAT, 16)
            .expect("a four-texel view");
        drop(view);
    }
    common::assert_clean(&ctx.validation());
}
