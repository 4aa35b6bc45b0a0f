//! GLSL → SPIR-V with shaderc, deterministically (feature `shader-compiler`).
//!
//! Used by the `compile-shaders` tool, which writes `spirv/`, and by the test that recompiles
//! every shader and fails if a committed module differs. Shaders target Vulkan 1.2 (SPIR-V 1.5):
//! Vulkan 1.3 targets emit `LocalSizeId`, which would need `maintenance4` on every device.
//! Every `.comp`, `.vert` and `.frag` under `glsl/` except `glsl/include/` is a shader; its
//! module goes to the same relative path under `spirv/` with `.spv` appended.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// One compiled shader.
pub struct CompiledShader {
    /// Path relative to `glsl/`, e.g. `pcf/pcf.comp`.
    pub name: String,
    /// The SPIR-V bytes.
    pub spirv: Vec<u8>,
}

fn collect(dir: &Path, root: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in entries {
        let path = entry.map_err(|e| Error::io(dir, e))?.path();
        if path.is_dir() {
            if path != root.join("include") {
                collect(&path, root, out)?;
            }
        } else if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("comp" | "vert" | "frag")
        ) {
            out.push(path);
        }
    }
    Ok(())
}

/// Compiles every shader under `glsl_root`, in sorted order.
pub fn compile_all(glsl_root: &Path) -> Result<Vec<CompiledShader>> {
    let mut files = Vec::new();
    collect(glsl_root, glsl_root, &mut files)?;
    files.sort();
    let compiler = shaderc::Compiler::new().map_err(|e| Error::Shader {
        name: "shaderc".into(),
        message: e.to_string(),
    })?;
    let include_dir = glsl_root.join("include");
    files
        .iter()
        .map(|path| {
            let rel = path
                .strip_prefix(glsl_root)
                .unwrap_or(path)
                .to_string_lossy()
                .replace('\\', "/");
            let source = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
            let kind = match path.extension().and_then(|e| e.to_str()) {
                Some("vert") => shaderc::ShaderKind::Vertex,
                Some("frag") => shaderc::ShaderKind::Fragment,
                _ => shaderc::ShaderKind::Compute,
            };
            let shader_error = |message: String| Error::Shader {
                name: rel.clone(),
                message,
            };
            let mut options =
                shaderc::CompileOptions::new().map_err(|e| shader_error(e.to_string()))?;
            options.set_target_env(
                shaderc::TargetEnv::Vulkan,
                shaderc::EnvVersion::Vulkan1_2 as u32,
            );
            options.set_target_spirv(shaderc::SpirvVersion::V1_5);
            options.set_optimization_level(shaderc::OptimizationLevel::Performance);
            options.set_warnings_as_errors();
            let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
            let include_dir = include_dir.clone();
            options.set_include_callback(move |requested, _ty, _from, _depth| {
                for base in [&dir, &include_dir] {
                    let candidate = base.join(requested);
                    if let Ok(content) = std::fs::read_to_string(&candidate) {
                        return Ok(shaderc::ResolvedInclude {
                            // A name relative to glsl/ keeps the output free of absolute paths.
                            resolved_name: requested.to_string(),
                            content,
                        });
                    }
                }
                Err(format!("cannot find include '{requested}'"))
            });
            let artifact = compiler
                .compile_into_spirv(&source, kind, &rel, "main", Some(&options))
                .map_err(|e| shader_error(e.to_string()))?;
            Ok(CompiledShader {
                name: rel.clone(),
                spirv: artifact.as_binary_u8().to_vec(),
            })
        })
        .collect()
}
