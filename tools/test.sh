#!/usr/bin/env bash
# The README's test command: set up, then build and run every test with the validation layers
# (each test asserts zero validation errors and warnings), the shader up-to-date check, clippy
# and rustfmt; then the tests once more with every fused multiply-add rounded once. nextest
# runs each test in its own process when installed; cargo test otherwise.
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
# nextest does not run doctests: the crate-level example (an engine, a renderer, three frames).
cargo test --doc --features shader-compiler
# Smoke runs of the CLI as a user would: a render compared with the ground truth, and the quick
# benches (every technique on every bundled scene against the reference; every compute
# primitive) and the quick stress suite, all under validation.
out="$(mktemp -d)"
penumbra() { cargo run --quiet --features shader-compiler --bin penumbra -- "$@"; }
penumbra render scenes/teapot-rect.toml --technique pcf --frames 1 --compare-to reference \
  --reference-samples 4 --cache-dir "$out/cache" --out "$out/render"
test -s "$out/render/stats.json" && test -s "$out/render/error.png"
penumbra bench --quick --cache-dir "$out/cache" --out "$out/bench"
test -s "$out/bench/bench.csv" && test -s "$out/bench/pareto.png"
penumbra bench --suite kernels --quick --out "$out/kernels"
test -s "$out/kernels/kernels.json"
# The stress suite's CI subset: every row within its bound, 0 NaN/Inf (exits non-zero otherwise).
penumbra stress --quick --cache-dir "$out/cache" --out "$out/stress"
test -s "$out/stress/stress.json"
rm -rf "$out"
# The suite again as a GPU that fuses multiply-adds runs it: every Fma in spirv/, every product
# with the sum that takes it unless `precise`, rounded once (lavapipe rounds each), and dot,
# m * v, cross, length, normalize and mix as chains of fused multiply-adds, so
# code whose result hangs on that fails here rather than on a GPU, as essm's box mean did on an
# H200. Then with the chains from their last term, the order Mesa's SPIR-V front end writes
# m * v in (the page raster's twin failed that way before transform_point). Last: it rewrites
# spirv/ (restored after) and so rebuilds the tests.
python3 tools/fused_fma.py
python3 tools/fused_fma.py --reverse
