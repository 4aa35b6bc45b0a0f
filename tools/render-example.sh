#!/usr/bin/env bash
# The README's first command: set up, then render a bundled scene with PCF into out/teapot-rect.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo run --release --bin penumbra -- render scenes/teapot-rect.toml --technique pcf --out out/teapot-rect
echo "wrote out/teapot-rect: shaded.png, visibility.png/.exr, positions.exr, stats.json"
