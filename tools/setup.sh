#!/usr/bin/env bash
# Installs what penumbra needs on Debian bookworm (Vulkan loader and headers, lavapipe, the
# validation layers, shaderc/glslang/SPIRV-Tools for the shader compiler and its test, a font
# for plots) and a Rust toolchain if none is present. Idempotent; needs root (or sudo).
set -euo pipefail

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

packages=(
  libvulkan1 libvulkan-dev mesa-vulkan-drivers vulkan-validationlayers vulkan-tools
  glslc glslang-tools libshaderc-dev spirv-tools
  build-essential pkg-config ca-certificates curl
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if ! command -v cargo >/dev/null 2>&1; then
  if [ -x "$HOME/.cargo/bin/cargo" ]; then
    export PATH="$HOME/.cargo/bin:$PATH"
  else
    echo "setup: installing Rust (rustup, stable)"
    curl -sSf https://sh.rustup.rs | sh -s -- -y --profile minimal
    export PATH="$HOME/.cargo/bin:$PATH"
  fi
fi

# The device must be visible to the loader (lavapipe on a machine without a GPU).
if ! vulkaninfo --summary >/dev/null 2>&1; then
  echo "setup: vulkaninfo finds no Vulkan device" >&2
  exit 1
fi
echo "setup: ok ($(vulkaninfo --summary 2>/dev/null | grep -m1 deviceName | sed 's/.*= //'))"
