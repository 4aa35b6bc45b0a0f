#!/usr/bin/env python3
"""Every technique with each of its knobs at both ends of its range (or at each of its named
values), one `penumbra render` under the validation layers each, on a small scene: each run must
either render — exit 0, no NaN — or be refused with a clear error (exit 1 and an `error:` line that
names the knob, the device limit or the memory). What it looks for is the other outcomes: a
panic, a NaN, a validation error, a bare Vulkan failure, a timeout.

    python3 tools/knob_extremes.py [--binary target/release/penumbra] [--scene FILE]
        [--timeout 90] [--techniques hard,pvssm] [--out knob-extremes.txt]

The default scene is `scenes/teapot-rect.toml` at 64×48 (a copy with the camera shrunk, its
mesh path made absolute). Prints one line a run and a summary; exits 1 if any run panicked, wrote
a NaN, failed validation or failed with a bare `vk...` error. Timeouts are listed, not failed: a
16384² map of a moment technique on a CPU driver can take minutes.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile


def small_scene(repo, workdir):
    text = open(os.path.join(repo, "scenes/teapot-rect.toml")).read()
    text = text.replace('path = "teapot.obj"', f'path = "{os.path.join(repo, "scenes/teapot.obj")}"')
    text = re.sub(r"width = \d+", "width = 64", text)
    text = re.sub(r"height = \d+", "height = 48", text)
    path = os.path.join(workdir, "small.toml")
    open(path, "w").write(text)
    return path


def values(knob):
    if knob["names"]:
        return list(knob["names"])
    lo, hi = knob["min"], knob["max"]
    if knob["integer"]:
        return [int(lo), int(hi)]
    return [lo, hi]


def classify(rc, text, stats):
    """ok, refused, or a problem's name."""
    if "panicked" in text:
        return "PANIC"
    if rc == 0:
        if stats is None:
            return "NO-STATS"
        return "NAN" if stats.get("nan_count") else "ok"
    last = text.strip().splitlines()[-1] if text.strip() else ""
    if "validation" in last:
        return "VALIDATION"
    if re.search(r"\bvk[A-Z]\w* failed", last):
        return "BARE-VULKAN"
    return "refused" if last.startswith("error:") else "FAILED"


def main():
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--binary", default=os.path.join(repo, "target/release/penumbra"))
    ap.add_argument("--scene")
    ap.add_argument("--timeout", type=float, default=90)
    ap.add_argument("--techniques", help="comma-separated (default: all but the references)")
    ap.add_argument("--out", help="also write the lines here")
    args = ap.parse_args()

    work = tempfile.mkdtemp(prefix="knob-extremes-")
    scene = args.scene or small_scene(repo, work)
    listing = subprocess.run([args.binary, "techniques", "--json"], capture_output=True,
                             text=True, check=True)
    techniques = json.loads(listing.stdout)
    wanted = set(args.techniques.split(",")) if args.techniques else None
    out = open(args.out, "w") if args.out else None
    counts = {}
    for t in techniques:
        name = t["name"]
        if name.startswith("reference") or (wanted and name not in wanted):
            continue
        for knob in t["knobs"]:
            for v in values(knob):
                run_dir = os.path.join(work, "run")
                cmd = [args.binary, "render", scene, "-t", name, "--set",
                       f"{knob['name']}={v}", "--frames", "1", "--out", run_dir]
                try:
                    r = subprocess.run(cmd, capture_output=True, text=True,
                                       timeout=args.timeout)
                    text = r.stdout + r.stderr
                    stats = None
                    if r.returncode == 0:
                        try:
                            stats = json.load(open(os.path.join(run_dir, "stats.json")))
                        except (OSError, ValueError):
                            pass
                    verdict = classify(r.returncode, text, stats)
                    last = text.strip().splitlines()[-1] if text.strip() else ""
                except subprocess.TimeoutExpired:
                    verdict, last = "timeout", f"(over {args.timeout:g} s)"
                counts[verdict] = counts.get(verdict, 0) + 1
                line = f"{verdict:11} {name} {knob['name']}={v} | {last[:300]}"
                print(line, flush=True)
                if out:
                    out.write(line + "\n")
                    out.flush()
    summary = ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    print(f"summary: {summary}")
    if out:
        out.write(f"summary: {summary}\n")
    bad = {"PANIC", "NAN", "VALIDATION", "BARE-VULKAN", "FAILED", "NO-STATS"}
    sys.exit(1 if any(k in bad for k in counts) else 0)


if __name__ == "__main__":
    main()
