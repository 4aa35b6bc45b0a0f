//! An on-disk cache of expensive, deterministic results (the ray-cast references).
//!
//! A reference costs up to a billion shadow rays on lavapipe, and the bench and repeated renders
//! ask for the same one again and again. The key is an FNV-1a hash (stable across Rust versions,
//! unlike `DefaultHasher`) of what the result depends on: the triangles, the camera, the light,
//! the technique's name and resolved knobs, every embedded SPIR-V module, the device and driver
//! ([`DeviceIdentity`]: another GPU or driver version may round differently), the source text
//! of the host code that builds the BVH, sets up the rays and the view samples
//! ([`HOST_SOURCES`], embedded at build time, so editing it needs no manual version bump), and a
//! format version. Not covered: the Rust toolchain and dependency versions (`glam`'s matrix
//! code), and host code outside [`HOST_SOURCES`]. An entry is a small JSON header plus raw
//! little-endian f32 visibility, written to a temporary name and renamed into place so a crash
//! never leaves a half-written entry behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::gpu::DeviceInfo;

/// Host-side source files whose code shapes a reference result, with their text as compiled
/// into this binary: the BVH build and ray setup (`src/reference/`), scene merging and camera
/// matrices (`src/scene/mod.rs`), the view-sample pass and geometry upload (`src/passes/`), and
/// the engine that prepares and renders (`src/engine.rs`). Their hash is part of every key
/// ([`host_code_hash`]), so any edit to them recomputes the references.
pub const HOST_SOURCES: [(&str, &str); 6] = [
    ("src/reference/mod.rs", include_str!("reference/mod.rs")),
    ("src/reference/bvh.rs", include_str!("reference/bvh.rs")),
    ("src/scene/mod.rs", include_str!("scene/mod.rs")),
    (
        "src/passes/view_samples.rs",
        include_str!("passes/view_samples.rs"),
    ),
    ("src/passes/geometry.rs", include_str!("passes/geometry.rs")),
    ("src/engine.rs", include_str!("engine.rs")),
];

/// The hash of `sources` (name and text of each, in order).
pub fn hash_sources(sources: &[(&str, &str)]) -> u64 {
    let mut h = Fnv64::default();
    for (name, text) in sources {
        h.write_str(name);
        h.write_str(text);
    }
    h.finish()
}

/// The hash of [`HOST_SOURCES`].
pub fn host_code_hash() -> u64 {
    hash_sources(&HOST_SOURCES)
}

/// What identifies the device and driver a result was computed on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceIdentity<'a> {
    /// `deviceName`.
    pub name: &'a str,
    /// `vendorID`.
    pub vendor_id: u32,
    /// `deviceID`.
    pub device_id: u32,
    /// `driverVersion`.
    pub driver_version: u32,
    /// Driver name and info (carries e.g. Mesa's and LLVM's versions).
    pub driver: &'a str,
}

impl<'a> DeviceIdentity<'a> {
    /// The identity of a queried device.
    pub fn of(info: &'a DeviceInfo) -> Self {
        DeviceIdentity {
            name: &info.name,
            vendor_id: info.vendor_id,
            device_id: info.device_id,
            driver_version: info.driver_version,
            driver: &info.driver,
        }
    }
}

/// Bumped whenever the entry format or the meaning of a cached result changes.
const FORMAT_VERSION: u64 = 1;

/// FNV-1a, 64 bit.
#[derive(Clone, Copy, Debug)]
pub struct Fnv64(u64);

impl Default for Fnv64 {
    fn default() -> Self {
        let mut h = Fnv64(0xcbf2_9ce4_8422_2325);
        h.write(&FORMAT_VERSION.to_le_bytes());
        h
    }
}

impl Fnv64 {
    /// Mixes in bytes.
    pub fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    /// Mixes in a string with its length (so "ab","c" ≠ "a","bc").
    pub fn write_str(&mut self, s: &str) {
        self.write(&(s.len() as u64).to_le_bytes());
        self.write(s.as_bytes());
    }

    /// Mixes in the environment a result was computed in: the device and driver, and the hash
    /// of the host code that shapes it ([`host_code_hash`]).
    pub fn write_environment(&mut self, device: &DeviceIdentity<'_>, host_code: u64) {
        self.write_str(device.name);
        self.write(&device.vendor_id.to_le_bytes());
        self.write(&device.device_id.to_le_bytes());
        self.write(&device.driver_version.to_le_bytes());
        self.write_str(device.driver);
        self.write(&host_code.to_le_bytes());
    }

    /// The hash.
    pub fn finish(&self) -> u64 {
        self.0
    }
}

/// The default cache directory: `$PENUMBRA_CACHE_DIR`, else `$XDG_CACHE_HOME/penumbra`, else
/// `$HOME/.cache/penumbra`; `None` when none is set.
pub fn default_dir() -> Option<PathBuf> {
    let env = |k: &str| {
        std::env::var_os(k)
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
    };
    env("PENUMBRA_CACHE_DIR")
        .or_else(|| env("XDG_CACHE_HOME").map(|d| d.join("penumbra")))
        .or_else(|| env("HOME").map(|d| d.join(".cache").join("penumbra")))
}

/// A cached frame: the header (any JSON) and the visibility.
pub struct Entry {
    /// Whatever the writer stored (the frame's stats).
    pub header: serde_json::Value,
    /// Visibility, row-major.
    pub visibility: Vec<f32>,
}

fn entry_path(dir: &Path, name: &str, key: u64) -> PathBuf {
    dir.join(format!("{name}-{key:016x}.bin"))
}

/// Reads an entry; `Ok(None)` when absent. A corrupt entry is treated as absent (and will be
/// overwritten), not as an error: the cache is an optimisation.
pub fn load(dir: &Path, name: &str, key: u64, expected_len: usize) -> Result<Option<Entry>> {
    let path = entry_path(dir, name, key);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(Error::io(path, e)),
    };
    let Some(split) = bytes.iter().position(|&b| b == b'\n') else {
        return Ok(None);
    };
    let Ok(header) = serde_json::from_slice::<serde_json::Value>(&bytes[..split]) else {
        return Ok(None);
    };
    let body = &bytes[split + 1..];
    if body.len() != expected_len * 4 {
        return Ok(None);
    }
    let visibility = body
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(Some(Entry { header, visibility }))
}

/// Writes an entry atomically (temporary file, then rename).
pub fn store(
    dir: &Path,
    name: &str,
    key: u64,
    header: &serde_json::Value,
    v: &[f32],
) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let path = entry_path(dir, name, key);
    let tmp = path.with_extension(format!("tmp{}", std::process::id()));
    let write = || -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&tmp)?);
        f.write_all(header.to_string().as_bytes())?;
        f.write_all(b"\n")?;
        for x in v {
            f.write_all(&x.to_le_bytes())?;
        }
        f.flush()?;
        drop(f);
        std::fs::rename(&tmp, &path)
    };
    write().map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        Error::io(&path, e)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn device(name: &'static str) -> DeviceIdentity<'static> {
        DeviceIdentity {
            name,
            vendor_id: 0x10005,
            device_id: 0,
            driver_version: 1,
            driver: "llvmpipe: Mesa 22.3.6 (LLVM 15.0.6)",
        }
    }

    fn key(device: &DeviceIdentity<'_>, host_code: u64) -> u64 {
        let mut h = Fnv64::default();
        h.write_str("the same scene, light, technique and knobs");
        h.write_environment(device, host_code);
        h.finish()
    }

    #[test]
    fn key_changes_with_the_device_and_driver() {
        let base = device("llvmpipe (LLVM 15.0.6, 256 bits)");
        let host = host_code_hash();
        let k = key(&base, host);
        assert_eq!(k, key(&base, host), "the key is deterministic");
        let others = [
            device("AMD Radeon RX 7900"),
            DeviceIdentity {
                vendor_id: 0x1002,
                ..base
            },
            DeviceIdentity {
                device_id: 0x744c,
                ..base
            },
            DeviceIdentity {
                driver_version: 2,
                ..base
            },
            DeviceIdentity {
                driver: "llvmpipe: Mesa 24.0.0 (LLVM 17.0.6)",
                ..base
            },
        ];
        for other in &others {
            assert_ne!(key(other, host), k, "{other:?}");
        }
    }

    #[test]
    fn key_changes_with_the_host_code() {
        let d = device("llvmpipe");
        let mut edited = HOST_SOURCES;
        let bvh = edited
            .iter()
            .position(|(name, _)| *name == "src/reference/bvh.rs")
            .expect("the BVH build is covered");
        assert!(
            edited
                .iter()
                .any(|(name, _)| *name == "src/reference/mod.rs"),
            "the ray setup is covered"
        );
        let changed = format!("{}\n// a change to the BVH build", edited[bvh].1);
        edited[bvh].1 = &changed;
        assert_ne!(hash_sources(&edited), host_code_hash());
        assert_ne!(key(&d, hash_sources(&edited)), key(&d, host_code_hash()));
        // The embedded text is the file as compiled, not a placeholder.
        assert!(HOST_SOURCES[bvh].1.contains("pub struct Bvh"));
    }
}
