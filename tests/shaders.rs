//! The committed SPIR-V is what the GLSL compiles to, valid, and reflects as the Rust side
//! expects. Recompiling needs the `shader-compiler` feature (Debian's libshaderc); the README's
//! test command enables it.

use ash::vk;
use penumbra::gpu::{shader_interface, shader_names};

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
}

#[test]
fn malformed_spirv_is_an_error_not_a_panic() {
    use penumbra::gpu::reflect::{reflect, words_from_bytes};
    assert!(words_from_bytes("x", &[1, 2, 3]).is_err());
    assert!(reflect("x", &[0xdead_beef, 0, 0, 0, 0]).is_err());
    // A truncated instruction: word count runs past the end.
    assert!(reflect("x", &[0x0723_0203, 0x0001_0500, 0, 10, 0, (9 << 16) | 15]).is_err());
}
