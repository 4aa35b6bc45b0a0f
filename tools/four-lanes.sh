#!/usr/bin/env bash
# The test binaries whose shaders use subgroup operations, run on a device with 4-lane
# subgroups: lavapipe at a 128-bit native vector width (LP_NATIVE_VECTOR_WIDTH=128; the default
# on an AVX2 host is 256 bits, 8 lanes, the only width CI and the README's figures see).
#
#     bash tools/four-lanes.sh                 # the default binaries below
#     bash tools/four-lanes.sh izb pvssm       # just these
#
# Why under valgrind (`--tool=none`, no memory checking, ~27x slower): on this project's
# AVX-512 build host, lavapipe 25.0.7 at 128 bits crashes in its own code (a segfault or a
# corrupted heap inside libvulkan_lvp.so, in `hard` on teapot-rect as in most
# tests that draw a shadow map, with or without threads: LP_NUM_THREADS=0 crashes every time);
# valgrind's CPU has no AVX-512 and the same binaries run clean. GALLIUM_NOSSE=1 also avoids the
# crash but changes lavapipe's arithmetic (38 tests fail at 8 lanes as at 4), so it cannot tell
# a subgroup bug from a rounding difference. Prints one line per binary and exits non-zero if
# any failed. Two binaries at a time; about 5 minutes for the default list on 2 cores, after the build.
set -uo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
export LP_NATIVE_VECTOR_WIDTH=128

command -v valgrind > /dev/null || { echo "four-lanes: needs valgrind (apt-get install valgrind)" >&2; exit 2; }
lanes=$(valgrind --tool=none -q vulkaninfo 2> /dev/null | awk '/^\tsubgroupSize /{print $3; exit}')
if [ "$lanes" != 4 ]; then
    echo "four-lanes: lavapipe reports subgroupSize '$lanes' at 128 bits, not 4" >&2
    exit 2
fi

names=("$@")
if [ ${#names[@]} -eq 0 ]; then
    # Every test binary whose shaders hold a subgroup operation (pvssm's 4x2 pixel blocks, izb's
    # shuffles and sums, the pages' bin counts, receivers' counts, the scans, the raster count).
    names=(pvssm pvssm_pages pvssm_search pvssm_knobs page_raster izb receivers kernels_scan
        kernels_raster)
fi

out=$(mktemp -d)
cargo test --no-run --message-format=json 2> /dev/null |
    python3 tools/test_binaries.py --named "${names[@]}" > "$out/binaries"
if [ "$(wc -l < "$out/binaries")" -ne ${#names[@]} ]; then
    echo "four-lanes: found $(wc -l < "$out/binaries") of ${#names[@]} test binaries" >&2
    exit 2
fi

# shellcheck disable=SC2016
xargs -P2 -L1 sh -c 'valgrind --tool=none -q "$1" --test-threads 1 > "$2/$0.log" 2>&1;
    echo "$0 rc=$? $(grep -h "^test result" "$2/$0.log")"' < <(sed "s|\$| $out|" "$out/binaries") |
    tee "$out/summary"
echo "logs in $out"
! grep -qv " rc=0 " "$out/summary"
