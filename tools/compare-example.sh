#!/usr/bin/env bash
# The README's first command: set up, build, then run every technique on a bundled scene against
# the ray-cast reference and write out/teapot-rect/index.html (contact sheet, error table, Pareto
# chart). The reference is cached (~/.cache/penumbra), so a second run takes about a minute less.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
cargo build --release --bin penumbra
./target/release/penumbra compare scenes/teapot-rect.toml --out out/teapot-rect "$@"
echo "open out/teapot-rect/index.html (contact-sheet.png, errors.csv, pareto.png beside it)"
