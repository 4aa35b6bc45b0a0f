//! Embeds the committed SPIR-V, and links Debian's static glslang / SPIRV-Tools archives when the
//! `shader-compiler` feature is on.
//!
//! `spirv/` is walked into `OUT_DIR/embedded_spirv.rs`, a table of `include_bytes!`, so adding a
//! shader needs no hand-kept list and linking users need no shader compiler.
//!
//! Debian's shared `libshaderc.so` is under-linked and its `libshaderc_combined.a` holds only
//! shaderc's own objects, so the `shaderc` crate's `prefer-static-linking` needs the glslang and
//! SPIRV-Tools archives named explicitly (see ENV.md). Building shaderc from source costs ~10
//! minutes of CI, which is what this avoids. Nothing is written outside `OUT_DIR`.

use std::path::{Path, PathBuf};

fn collect(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect(&path, out);
        } else if path.extension().is_some_and(|e| e == "spv") {
            out.push(path);
        }
    }
}

fn embed_spirv() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let spirv = root.join("spirv");
    println!("cargo:rerun-if-changed={}", spirv.display());
    let mut files = Vec::new();
    collect(&spirv, &mut files);
    files.sort();
    let mut table = String::from("/// Every committed shader: (path under glsl/, SPIR-V bytes).\n");
    table.push_str("pub(crate) static EMBEDDED_SPIRV: &[(&str, &[u8])] = &[\n");
    for f in &files {
        println!("cargo:rerun-if-changed={}", f.display());
        let rel = f
            .strip_prefix(&spirv)
            .unwrap_or(f)
            .to_string_lossy()
            .replace('\\', "/");
        let name = rel.trim_end_matches(".spv");
        table.push_str(&format!(
            "    ({name:?}, include_bytes!({:?})),\n",
            f.display().to_string()
        ));
    }
    table.push_str("];\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default()).join("embedded_spirv.rs");
    if let Err(e) = std::fs::write(&out, table) {
        println!("cargo:warning=cannot write {}: {e}", out.display());
    }
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    embed_spirv();
    println!("cargo:rerun-if-env-changed=SHADERC_LIB_DIR");
    if std::env::var_os("CARGO_FEATURE_SHADER_COMPILER").is_none() {
        return;
    }
    let dir = std::env::var("SHADERC_LIB_DIR")
        .unwrap_or_else(|_| "/usr/lib/x86_64-linux-gnu".to_string());
    println!("cargo:rustc-link-search=native={dir}");
    for lib in [
        "glslang",
        "MachineIndependent",
        "GenericCodeGen",
        "OSDependent",
        "OGLCompiler",
        "SPIRV",
        "SPIRV-Tools-opt",
        "SPIRV-Tools",
    ] {
        if std::path::Path::new(&dir)
            .join(format!("lib{lib}.a"))
            .exists()
        {
            println!("cargo:rustc-link-lib=static={lib}");
        }
    }
    println!("cargo:rustc-link-lib=dylib=stdc++");
}
