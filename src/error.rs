//! The library's one error type.
//!
//! Callers can match on what went wrong: a Vulkan call's `vk::Result` (so a host engine can react
//! to `ERROR_DEVICE_LOST`), an allocation failure or memory running out where the driver commits
//! it (naming the resource and its size), a missing device feature, or bad input with the file
//! and line it came from. Nothing in the library panics on these.

use std::fmt;
use std::path::{Path, PathBuf};

use ash::vk;

/// Every error the library returns.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// `libvulkan.so.1` could not be loaded.
    #[error("cannot load the Vulkan loader: {0}")]
    Loader(String),
    /// A Vulkan call returned an error code.
    #[error("{call} failed: {result}")]
    Vulkan {
        /// The Vulkan entry point, e.g. `vkCreateBuffer`.
        call: &'static str,
        /// What it returned.
        result: vk::Result,
    },
    /// No physical device matched the request.
    #[error("no suitable Vulkan device: {0}")]
    NoDevice(String),
    /// The device lacks something a pass needs; the pass cannot run here.
    #[error("device '{device}' does not support {feature}")]
    Unsupported {
        /// Device name.
        device: String,
        /// The missing feature, extension or limit.
        feature: String,
    },
    /// gpu-allocator could not allocate memory for a named resource.
    #[error("cannot allocate memory for '{name}': {source}")]
    Allocation {
        /// The resource's debug name.
        name: String,
        /// The allocator's error.
        #[source]
        source: gpu_allocator::AllocationError,
    },
    /// Memory for a named resource ran out where the driver committed it: creating the buffer
    /// or binding its memory (a driver may allocate there, so an allocation that succeeded can
    /// still fail at the bind). Its size says how much was asked for; a smaller map or view is
    /// the usual remedy.
    #[error("out of memory for '{name}' ({}) at {call}: {result}", Bytes(*bytes))]
    OutOfMemory {
        /// The resource's debug name.
        name: String,
        /// Its size in bytes.
        bytes: u64,
        /// The Vulkan entry point, e.g. `vkBindImageMemory` or `vkCreateBuffer`.
        call: &'static str,
        /// What it returned (`ERROR_OUT_OF_DEVICE_MEMORY` or `ERROR_OUT_OF_HOST_MEMORY`).
        result: vk::Result,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Bad input: a malformed scene file or mesh, NaN geometry, a degenerate light.
    #[error("{}", Located { path, line: *line, message })]
    Input {
        /// The file the input came from (or a procedural scene's name).
        path: PathBuf,
        /// 1-based line, where known.
        line: Option<usize>,
        /// What was wrong and what was expected.
        message: String,
    },
    /// The caller handed the library something it cannot use: an image in the wrong format,
    /// size, usage or layout, or a recording that cannot be made into the caller's command
    /// buffer. The message names the object and what was expected.
    #[error("{0}")]
    InvalidArgument(String),
    /// A technique name that is not registered.
    #[error("unknown technique '{name}'; known techniques: {}", known.join(", "))]
    UnknownTechnique {
        /// The name asked for.
        name: String,
        /// Every registered name.
        known: Vec<String>,
    },
    /// A technique knob that is unknown or out of range.
    #[error("technique '{technique}': {message}")]
    Parameter {
        /// The technique.
        technique: String,
        /// What was wrong.
        message: String,
    },
    /// A shader module or pipeline could not be built from the embedded SPIR-V.
    #[error("shader '{name}': {message}")]
    Shader {
        /// The shader's name (its path under `spirv/`).
        name: String,
        /// What was wrong.
        message: String,
    },
    /// An image could not be encoded or decoded.
    #[error("{}: {message}", path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

struct Located<'a> {
    path: &'a Path,
    line: Option<usize>,
    message: &'a str,
}

impl fmt::Display for Located<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.path.display(), line, self.message),
            None => write!(f, "{}: {}", self.path.display(), self.message),
        }
    }
}

/// A size in bytes as people read it: bytes, or KiB, MiB or GiB to three decimals.
struct Bytes(u64);

impl fmt::Display for Bytes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const UNITS: [&str; 3] = ["KiB", "MiB", "GiB"];
        if self.0 < 1024 {
            return write!(f, "{} B", self.0);
        }
        let mut value = self.0 as f64 / 1024.0;
        let mut unit = 0;
        while value >= 1024.0 && unit + 1 < UNITS.len() {
            value /= 1024.0;
            unit += 1;
        }
        write!(f, "{value:.3} {}", UNITS[unit])
    }
}

impl Error {
    /// Bad input in `path`, at `line` if known.
    pub fn input(
        path: impl Into<PathBuf>,
        line: Option<usize>,
        message: impl Into<String>,
    ) -> Self {
        Error::Input {
            path: path.into(),
            line,
            message: message.into(),
        }
    }

    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Maps a `vk::Result` error into [`Error::Vulkan`] naming the call.
pub(crate) trait VkResultExt<T> {
    fn vk(self, call: &'static str) -> Result<T>;
}

impl<T> VkResultExt<T> for std::result::Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T> {
        self.map_err(|result| Error::Vulkan { call, result })
    }
}

/// Maps a failed creation or memory bind of resource `name` (`bytes` long): out-of-memory
/// results become [`Error::OutOfMemory`] naming it, any other [`Error::Vulkan`].
pub(crate) fn memory_result<T>(
    result: std::result::Result<T, vk::Result>,
    call: &'static str,
    name: &str,
    bytes: u64,
) -> Result<T> {
    result.map_err(|result| match result {
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY | vk::Result::ERROR_OUT_OF_HOST_MEMORY => {
            Error::OutOfMemory {
                name: name.to_string(),
                bytes,
                call,
                result,
            }
        }
        _ => Error::Vulkan { call, result },
    })
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn running_out_of_memory_names_the_resource_and_its_size() {
        let oom = memory_result::<()>(
            Err(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY),
            "vkBindImageMemory",
            "msm moments",
            4 << 30,
        )
        .unwrap_err();
        assert!(matches!(oom, Error::OutOfMemory { bytes, .. } if bytes == 4 << 30));
        assert_eq!(
            oom.to_string(),
            format!(
                "out of memory for 'msm moments' (4.000 GiB) at vkBindImageMemory: {}",
                vk::Result::ERROR_OUT_OF_DEVICE_MEMORY
            )
        );
        let other = memory_result::<()>(
            Err(vk::Result::ERROR_DEVICE_LOST),
            "vkBindBufferMemory",
            "b",
            1,
        )
        .unwrap_err();
        assert!(matches!(
            other,
            Error::Vulkan {
                call: "vkBindBufferMemory",
                ..
            }
        ));
        assert!(memory_result(Ok(()), "vkBindBufferMemory", "b", 1).is_ok());
        assert_eq!(Bytes(1000).to_string(), "1000 B");
        assert_eq!(Bytes(1536).to_string(), "1.500 KiB");
        assert_eq!(Bytes(3 << 20).to_string(), "3.000 MiB");
    }
}
