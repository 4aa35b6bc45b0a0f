#!/usr/bin/env python3
"""Interleaved A/B timing of `penumbra render`: the README's "interleaved runs, medians".

On a shared or CPU-rasterizer machine the speed of the whole machine drifts between runs (on the
2-core VM this project is measured on, by up to 2x within minutes), so two binaries timed one
after the other compare the machine's phases, not the code. This runs the variants in turn,
round after round (every other round in reverse order), and prints the total GPU time
(stats.json's `total_gpu_ms`, which leaves out the shared `view-samples` pass) and each pass's
as minimum / lower quartile / median over the rounds. The VM's disturbances only ever add time,
so with many rounds the minimum and the lower quartile are the steadier figures; the median
moves with the share of slow phases.

A variant is a penumbra binary, optionally with knobs after `::` (comma-separated `key=value`):

    python3 tools/ab.py scenes/teapot-rect.toml pvssm /tmp/pen_before target/release/penumbra
    python3 tools/ab.py 'grid:800000@rect' pvssm target/release/penumbra \\
        target/release/penumbra::page_raster=graphics --rounds 5 --pass cull --pass render

A variant's `technique=NAME` knob runs that technique instead of the command line's, so two
techniques' times interleave too (the README's `pvssm` against `average-maps` on the 800k grid):

    python3 tools/ab.py 'grid:800000@rect' pvssm target/release/penumbra \\
        'target/release/penumbra::technique=average-maps,samples=64,map_size=1024' --rounds 5

Copy the binary before a change to a path of its own (`cp target/release/penumbra
/tmp/pen_before`): the build overwrites target/release/penumbra.

`--light-scales 0,1,4` runs every variant at each scale of the scene's light (`penumbra render
--light-scale`: 0 is a point light at a rect light's centre, or a hard sun) in the same rounds —
the README's soft-against-hard runs:

    python3 tools/ab.py scenes/teapot-rect.toml pvssm target/release/penumbra \\
        --light-scales 0,1,2,4 --rounds 5
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def run(variant, scene, technique, frames, sets):
    variant, _, light_scale = variant.partition(" light x")
    exe, _, extra = variant.partition("::")
    knobs = [kv for kv in extra.split(",") if kv] + sets
    # A variant may name its own technique (`::technique=average-maps,samples=64`).
    technique = next((kv.split("=", 1)[1] for kv in knobs if kv.startswith("technique=")),
                     technique)
    knobs = [kv for kv in knobs if not kv.startswith("technique=")]
    with tempfile.TemporaryDirectory() as out:
        cmd = [exe, "render", scene, "--technique", technique, "--no-validation",
               "--frames", str(frames), "--out", out]
        for kv in knobs:
            cmd += ["--set", kv]
        if light_scale:
            cmd += ["--light-scale", light_scale]
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            sys.exit(f"{variant}: render failed ({done.returncode}):\n{done.stderr}")
        with open(os.path.join(out, "stats.json")) as f:
            return json.load(f)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("scene")
    p.add_argument("technique")
    p.add_argument("variants", nargs="+", help="BINARY or BINARY::key=value,key=value")
    p.add_argument("--rounds", type=int, default=4, help="runs of each variant (default 4)")
    p.add_argument("--frames", type=int, default=3, help="timed frames a run (default 3)")
    p.add_argument("--set", action="append", default=[], help="knob for every variant")
    p.add_argument("--pass", dest="passes", action="append", default=[],
                   help="report only passes whose name holds this (repeatable)")
    p.add_argument("--light-scales", default="",
                   help="comma-separated light scales to run every variant at")
    a = p.parse_args()
    if a.light_scales:
        a.variants = [f"{v} light x{x}" for v in a.variants for x in a.light_scales.split(",")]

    def shown(name):
        return not a.passes or any(s in name for s in a.passes)

    totals = {v: [] for v in a.variants}
    passes = {v: {} for v in a.variants}
    for r in range(a.rounds):
        # Odd rounds run the variants in reverse, so that none always follows the same one (a
        # run's speed may hang on what ran just before it: caches, the VM's scheduling).
        for v in (a.variants if r % 2 == 0 else a.variants[::-1]):
            s = run(v, a.scene, a.technique, a.frames, a.set)
            totals[v].append(s["total_gpu_ms"])
            for ps in s["passes"]:
                passes[v].setdefault(ps["name"], []).append(ps["gpu_ms"])
            row = " ".join(f"{ps['name']}={ps['gpu_ms']:.1f}" for ps in s["passes"]
                           if shown(ps["name"]))
            print(f"round {r} {v}: {s['total_gpu_ms']:.1f} ms  {row}", flush=True)
    def spread(ms):
        ms = sorted(ms)
        return f"{ms[0]:8.2f} {ms[len(ms) // 4]:8.2f} {statistics.median(ms):8.2f}"

    for v in a.variants:
        print(f"{v}: total min / q1 / median {spread(totals[v])} ms")
        for name, ms in passes[v].items():
            if shown(name):
                print(f"    {name:<28} {spread(ms)}")


if __name__ == "__main__":
    main()
