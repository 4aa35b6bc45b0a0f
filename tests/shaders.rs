//! The committed SPIR-V is what the GLSL compiles to, valid, and reflects as the Rust side
//! expects: the interfaces of a few shaders as declared, malformed SPIR-V an error, and the
//! push-constant layout check catching reordered and missing fields (every push block against
//! its Rust twin: `tests/shaders_push.rs`). Recompiling needs the `shader-compiler` feature
//! (Debian's libshaderc); the README's test command enables it.

mod common;

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4};
use penumbra::gpu::reflect::compare_push_layout;
use penumbra::gpu::{shader_interface, shader_names};

use common::push_twins::twin;

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

/// The one specialization constant the shaders declare is div_rn.glsl's `PLAIN_DIVISION`, under
/// the ID every pipeline maps ([`penumbra::gpu::DIVISION_CONSTANT_ID`]): a shader that divides
/// through `div_rn` or `share_count` and declared another ID would silently keep the correction.
#[test]
fn every_specialization_constant_is_the_division_constant() {
    const OP_DECORATE: u32 = 71;
    const SPEC_ID: u32 = 1;
    let mut declaring = 0;
    for name in shader_names() {
        let bytes = penumbra::gpu::shader_spirv(name).expect("spirv");
        let words = penumbra::gpu::reflect::words_from_bytes(name, bytes).expect("words");
        let mut i = 5;
        let mut ids = Vec::new();
        while i < words.len() {
            let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
            if op == OP_DECORATE && count >= 4 && words[i + 2] == SPEC_ID {
                ids.push(words[i + 3]);
            }
            i += count.max(1);
        }
        assert!(
            ids.iter()
                .all(|&id| id == penumbra::gpu::DIVISION_CONSTANT_ID),
            "{name}: specialization constant IDs {ids:?}"
        );
        declaring += usize::from(!ids.is_empty());
    }
    // shadow_map.glsl's projection includes it: most techniques' lookups.
    assert!(
        declaring > 20,
        "{declaring} shaders declare the division constant"
    );
}
