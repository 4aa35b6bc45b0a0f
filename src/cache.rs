//! An on-disk cache of expensive, deterministic results (the ray-cast references).
//!
//! A reference costs up to a billion shadow rays on lavapipe, and the bench and repeated renders
//! ask for the same one again and again. The key is an FNV-1a hash (stable across Rust versions,
//! unlike `DefaultHasher`) of everything the result depends on: the triangles, the camera, the
//! light, the technique's name and resolved knobs, the SPIR-V it runs, and a format version. An
//! entry is a small JSON header plus raw little-endian f32 visibility, written to a temporary
//! name and renamed into place so a crash never leaves a half-written entry behind.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

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
