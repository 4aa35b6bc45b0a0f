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
  build-essential pkg-config ca-certificates curl python3
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

# lavapipe from Mesa 25 (bookworm-backports) rather than bookworm's 22.3: the whole suite passes
# under validation on both, and 25 runs the quick bench in half the time and the compute
# kernels 1.2-3.6x faster (README, "Driver choice"). The backports source is derived from the
# machine's own Debian source (its mirror and key); if anything fails, 22.3 stays.
# PENUMBRA_MESA=debian keeps bookworm's Mesa (the README's older figures came from it).
backports_source() {
  local uri="" key=""
  if [ -f /etc/apt/sources.list.d/debian.sources ]; then
    # deb822: the stanza whose Suites has `bookworm` itself (not -security, -updates).
    read -r uri key < <(awk 'BEGIN { RS = ""; FS = "\n" }
      { u = ""; k = ""; s = 0
        for (i = 1; i <= NF; i++) {
          if ($i ~ /^URIs:/) { split($i, a, " "); u = a[2] }
          if ($i ~ /^Signed-By:/) { split($i, a, " "); k = a[2] }
          if ($i ~ /^Suites:/ && $i ~ /[ \t]bookworm([ \t]|$)/) s = 1
        }
        if (s && u != "") { print u, k; exit } }' /etc/apt/sources.list.d/debian.sources)
  fi
  if [ -z "$uri" ] && [ -f /etc/apt/sources.list ]; then
    uri=$(awk '$1 == "deb" { for (i = 2; i <= NF; i++) if ($i !~ /^\[/ && $i !~ /\]$/) {
      if ($(i + 1) == "bookworm") { print $i; exit } else break } }' /etc/apt/sources.list)
  fi
  [ -n "$uri" ] || return 1
  printf 'Types: deb\nURIs: %s\nSuites: bookworm-backports\nComponents: main\n' "$uri"
  if [ -n "$key" ]; then printf 'Signed-By: %s\n' "$key"; fi
}
if [ "${PENUMBRA_MESA:-backports}" != debian ] && grep -q '^VERSION_CODENAME=bookworm' /etc/os-release \
  && ! dpkg-query -W -f='${Version}' mesa-vulkan-drivers 2>/dev/null | grep -q bpo; then
  list=/etc/apt/sources.list.d/penumbra-bookworm-backports.sources
  if text="$(backports_source)"; then
    echo "setup: installing Mesa from bookworm-backports ($(echo "$text" | sed -n 's/^URIs: //p'))"
    if ! { echo "$text" | $SUDO tee "$list" >/dev/null && $SUDO apt-get update -qq \
      && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
        -t bookworm-backports mesa-vulkan-drivers >/dev/null; }; then
      echo "setup: bookworm-backports Mesa not installed; keeping $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers)" >&2
    fi
  else
    echo "setup: no bookworm source found to derive bookworm-backports from; keeping Mesa $(dpkg-query -W -f='${Version}' mesa-vulkan-drivers)" >&2
  fi
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
