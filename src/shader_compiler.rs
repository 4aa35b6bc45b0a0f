//! GLSL → SPIR-V with shaderc, deterministically (feature `shader-compiler`).
//!
//! Used by the `compile-shaders` tool, which writes `spirv/`, and by the test that recompiles
//! every shader and fails if a committed module differs. Shaders target Vulkan 1.2 (SPIR-V 1.5):
//! Vulkan 1.3 targets emit `LocalSizeId`, which would need `maintenance4` on every device.
//! Every `.comp`, `.vert` and `.frag` under `glsl/` except `glsl/include/` is a shader; its
//! module goes to the same relative path under `spirv/` with `.spv` appended.
//!
//! The optimizer strips every debug name. The push-constant block's member names are put back
//! (taken from an unoptimized compile of the same source, which keeps them) so the reflector can
//! match each member with its `#[repr(C)]` Rust twin by name; nothing else is kept.

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
            let compile = |level: shaderc::OptimizationLevel| -> Result<Vec<u32>> {
                let mut options =
                    shaderc::CompileOptions::new().map_err(|e| shader_error(e.to_string()))?;
                options.set_target_env(
                    shaderc::TargetEnv::Vulkan,
                    shaderc::EnvVersion::Vulkan1_2 as u32,
                );
                options.set_target_spirv(shaderc::SpirvVersion::V1_5);
                options.set_optimization_level(level);
                options.set_warnings_as_errors();
                let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
                let include_dir = include_dir.clone();
                options.set_include_callback(move |requested, _ty, _from, _depth| {
                    for base in [&dir, &include_dir] {
                        let candidate = base.join(requested);
                        if let Ok(content) = std::fs::read_to_string(&candidate) {
                            return Ok(shaderc::ResolvedInclude {
                                // A name relative to glsl/ keeps the output free of absolute
                                // paths.
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
                Ok(artifact.as_binary().to_vec())
            };
            let mut words = compile(shaderc::OptimizationLevel::Performance)?;
            if push_block_struct(&words).is_some() {
                let named = compile(shaderc::OptimizationLevel::Zero)?;
                words = graft_push_member_names(&words, &named).map_err(shader_error)?;
            }
            Ok(CompiledShader {
                name: rel.clone(),
                spirv: words.iter().flat_map(|w| w.to_le_bytes()).collect(),
            })
        })
        .collect()
}

const OP_MEMBER_NAME: u32 = 6;
const OP_TYPE_POINTER: u32 = 32;
const OP_VARIABLE: u32 = 59;
const SC_PUSH_CONSTANT: u32 = 9;
/// Opcodes that precede the debug-name section in a module's logical layout: capabilities,
/// extensions, imports, memory model, entry points, execution modes, and the debug section
/// itself (strings, sources, names).
const BEFORE_ANNOTATIONS: [u32; 13] = [17, 10, 11, 14, 15, 16, 331, 7, 4, 3, 2, 5, 6];

/// Splits a module (after its 5-word header) into instructions; `None` if malformed.
fn instructions(words: &[u32]) -> Option<Vec<&[u32]>> {
    let mut out = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        if count == 0 || i + count > words.len() {
            return None;
        }
        out.push(&words[i..i + count]);
        i += count;
    }
    Some(out)
}

/// The struct type id of the module's push-constant block, if it has one.
fn push_block_struct(words: &[u32]) -> Option<u32> {
    let ins = instructions(words)?;
    let pointer = ins.iter().find_map(|i| {
        (i[0] & 0xffff == OP_VARIABLE && i.len() >= 4 && i[3] == SC_PUSH_CONSTANT).then(|| i[1])
    })?;
    ins.iter().find_map(|i| {
        (i[0] & 0xffff == OP_TYPE_POINTER && i.len() >= 4 && i[1] == pointer).then(|| i[3])
    })
}

/// Copies the `OpMemberName`s of the push-constant block from `named` (an unoptimized compile
/// of the same source) into `optimized`, retargeted to its block struct and placed where the
/// logical layout puts debug names (before the first annotation).
fn graft_push_member_names(
    optimized: &[u32],
    named: &[u32],
) -> std::result::Result<Vec<u32>, String> {
    let malformed = || "malformed SPIR-V from shaderc".to_string();
    let target = push_block_struct(optimized).ok_or_else(malformed)?;
    let source = push_block_struct(named)
        .ok_or_else(|| "the unoptimized module has no push-constant block".to_string())?;
    let names: Vec<Vec<u32>> = instructions(named)
        .ok_or_else(malformed)?
        .into_iter()
        .filter(|i| i[0] & 0xffff == OP_MEMBER_NAME && i.len() >= 4 && i[1] == source)
        .map(|i| {
            let mut i = i.to_vec();
            i[1] = target;
            i
        })
        .collect();
    let ins = instructions(optimized).ok_or_else(malformed)?;
    let at = ins
        .iter()
        .position(|i| !BEFORE_ANNOTATIONS.contains(&(i[0] & 0xffff)))
        .unwrap_or(ins.len());
    let mut out = optimized[..5].to_vec();
    for i in &ins[..at] {
        out.extend_from_slice(i);
    }
    for n in &names {
        out.extend_from_slice(n);
    }
    for i in &ins[at..] {
        out.extend_from_slice(i);
    }
    Ok(out)
}
