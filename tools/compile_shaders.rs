//! `compile-shaders`: compiles `glsl/` into `spirv/` (committed; the library embeds it).
//!
//! Run `cargo run --features shader-compiler --bin compile-shaders` after editing a shader. The
//! output is deterministic; a test recompiles everything and fails on any difference.

use std::path::PathBuf;

use anyhow::Context as _;

fn main() -> anyhow::Result<()> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let shaders = penumbra::shader_compiler::compile_all(&root.join("glsl"))?;
    let out = root.join("spirv");
    // Remove modules whose source is gone, so spirv/ mirrors glsl/ exactly.
    if out.exists() {
        std::fs::remove_dir_all(&out).with_context(|| format!("removing {}", out.display()))?;
    }
    for s in &shaders {
        let path = out.join(format!("{}.spv", s.name));
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        std::fs::write(&path, &s.spirv).with_context(|| format!("writing {}", path.display()))?;
        println!(
            "{:>7} bytes  {}",
            s.spirv.len(),
            path.strip_prefix(&root)?.display()
        );
    }
    println!("{} shaders compiled", shaders.len());
    // The embedding example's own shaders (the host engine's, not the library's): compiled the
    // same way, written next to their sources, included by the example with `include_bytes!`.
    let example = root.join("examples").join("deferred_shadows");
    for s in penumbra::shader_compiler::compile_all(&example)? {
        let path = example.join(format!("{}.spv", s.name));
        std::fs::write(&path, &s.spirv).with_context(|| format!("writing {}", path.display()))?;
        println!(
            "{:>7} bytes  {}",
            s.spirv.len(),
            path.strip_prefix(&root)?.display()
        );
    }
    Ok(())
}
