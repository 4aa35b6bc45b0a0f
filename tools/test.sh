#!/usr/bin/env bash
# The README's test command: set up, then build and run every test with the validation layers
# (each test asserts zero validation errors and warnings), the shader up-to-date check, clippy
# and rustfmt. nextest runs each test in its own process when installed; cargo test otherwise.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"

cargo fmt --all --check
cargo clippy --all-targets --features shader-compiler -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --lib --quiet
if command -v cargo-nextest >/dev/null 2>&1; then
  cargo nextest run --features shader-compiler --no-fail-fast
else
  cargo test --features shader-compiler --no-fail-fast
fi
# A short smoke run of the CLI on a bundled scene, as a user would.
out="$(mktemp -d)"
cargo run --quiet --features shader-compiler --bin penumbra -- render scenes/teapot-rect.toml --technique pcf --frames 1 --out "$out"
test -s "$out/stats.json"
rm -rf "$out"
