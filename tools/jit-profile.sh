#!/usr/bin/env bash
# Where lavapipe spends a shader's time: samples the JIT-compiled code of a running `penumbra
# render` with perf, then disassembles the hottest region with gdb while the process still runs
# (lavapipe's LLVM code has no symbols, and it is gone when the process exits), each instruction
# with its sample count. The method by which this project found GLSL's int(float) compiled to
# scalar code per SIMD lane (glsl/include/small_int.glsl), as a script; with it, izb-soft's test
# pass read as vector code throughout, bound by register spills rather than one slow construct.
#
# Needs perf and gdb (`apt-get install linux-perf gdb`) and the right to attach to the process
# (kernel.yama.ptrace_scope 0, or root). Usage:
#
#     bash tools/jit-profile.sh OUTDIR target/release/penumbra render scenes/bunny-rect.toml \
#         --technique izb-soft --no-validation --frames 80 --out /tmp/render
#
# Give enough frames that the render outlives the warm-up and the sampling (`WARMUP` and
# `SECONDS_SAMPLED`, 14 and 8 s by default). Writes OUTDIR/annot.txt (the hot region, one
# instruction a line with its samples first: `sort -n -r OUTDIR/annot.txt | head -50`) and
# OUTDIR/pages.txt (the hottest 4 KiB pages of code, the share of all samples in each).
set -euo pipefail

out=${1:?usage: jit-profile.sh OUTDIR PENUMBRA_BINARY ARGS...}
shift
exe=${1:?usage: jit-profile.sh OUTDIR PENUMBRA_BINARY ARGS...}
for tool in perf gdb python3; do
    command -v "$tool" > /dev/null || { echo "jit-profile: $tool is not installed" >&2; exit 1; }
done
mkdir -p "$out"
"$@" > "$out/run.log" 2>&1 &
pid=$!
trap 'kill "$pid" 2> /dev/null || true' EXIT
sleep "${WARMUP:-14}"
kill -0 "$pid" 2> /dev/null || { echo "jit-profile: the render ended before sampling (more --frames)" >&2; exit 1; }
perf record -o "$out/perf.data" -F 4000 -p "$pid" -- sleep "${SECONDS_SAMPLED:-8}" \
    > "$out/perf.log" 2>&1 || { echo "jit-profile: perf record failed: $out/perf.log" >&2; exit 1; }
perf script -i "$out/perf.data" -F ip 2> /dev/null | awk '{print $1}' > "$out/ips.txt"
# The hot region: the hottest code page, grown page by page on either side while the next page
# holds at least 1 % of the samples (one shader's code is contiguous; others lie elsewhere).
read -r lo hi < <(python3 - "$out" <<'PY'
import sys
from collections import Counter
out = sys.argv[1]
ips = [int(l, 16) for l in open(out + "/ips.txt") if l.strip()]
pages = Counter(ip >> 12 for ip in ips)
with open(out + "/pages.txt", "w") as f:
    for page, n in pages.most_common(20):
        f.write(f"{page << 12:#x} {100 * n / len(ips):5.1f} %\n")
top = pages.most_common(1)[0][0]
lo, hi = top, top
while pages.get(lo - 1, 0) >= 0.01 * len(ips):
    lo -= 1
while pages.get(hi + 1, 0) >= 0.01 * len(ips):
    hi += 1
print(f"{lo << 12:#x} {(hi + 1) << 12:#x}")
PY
)
gdb -p "$pid" -batch -ex "disassemble $lo,$hi" > "$out/dis.txt" 2> /dev/null || true
python3 - "$out" <<'PY'
import re
import sys
from collections import Counter
out = sys.argv[1]
hits = Counter(int(l, 16) for l in open(out + "/ips.txt") if l.strip())
rows = []
for line in open(out + "/dis.txt"):
    m = re.match(r"\s*0x([0-9a-f]+)", line)
    if m:
        rows.append(f"{hits.get(int(m.group(1), 16), 0):6d} {line.rstrip()}")
open(out + "/annot.txt", "w").write("\n".join(rows) + "\n")
inside = sum(int(r.split()[0]) for r in rows)
total = sum(hits.values())
print(f"jit-profile: {len(rows)} instructions in the hot region, {100 * inside / max(total, 1):.0f} %"
      f" of {total} samples; see {out}/annot.txt and {out}/pages.txt")
PY
