#!/usr/bin/env bash
# `izb-soft` at 64 light samples against the ray-cast reference at 8 x 8, the same light samples,
# on the two rect-light scenes with the light at x1 to x100: the GPU ms of one frame of each, and
# whether their visibility images are byte-identical (they should be: `tests/izb.rs` holds
# izb-soft at N^2 samples to the reference's N x N). Where the BVH's rays beat the view-sample
# mapping. Run from the repository's root after `cargo build --release`:
#
#     bash tools/izb_crossover.sh > FILE
set -euo pipefail
cd "$(dirname "$0")/.."
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
ms() { tail -1 | grep -o "[0-9.]* ms GPU"; }
for scene in teapot-rect bunny-rect; do
  for scale in 1 3 10 30 100; do
    common=(--light-scale "$scale" --no-validation --frames 1)
    r=$(target/release/penumbra render "scenes/$scene.toml" -t reference --set samples=8 \
      --no-cache "${common[@]}" --out "$dir/r" 2>&1 | ms)
    i=$(target/release/penumbra render "scenes/$scene.toml" -t izb-soft --set samples=64 \
      "${common[@]}" --out "$dir/i" 2>&1 | ms)
    cmp -s "$dir/r/visibility.exr" "$dir/i/visibility.exr" && same=identical || same=differ
    echo "$scene x$scale reference(8x8) $r | izb-soft(64) $i | $same"
  done
done
