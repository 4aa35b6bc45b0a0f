#!/usr/bin/env python3
"""The README's `pvssm` tables from the bench's raw rows (bench.json files).

Each table is printed as Markdown from the runs the README names; the figures are the runs'
own (medians over runs where a table says so), nothing is rescaled or dropped.

    python3 tools/pvssm_tables.py main RUN1/bench.json RUN2/bench.json RUN3/bench.json
    python3 tools/pvssm_tables.py passes RUN1/bench.json ... [--grid DIAL1/bench.json ...]
    python3 tools/pvssm_tables.py dial DIAL1/bench.json DIAL2/bench.json DIAL3/bench.json
    python3 tools/pvssm_tables.py light LIGHT1/bench.json LIGHT2/bench.json ...
    python3 tools/pvssm_tables.py fixed FIXED/bench.json
    python3 tools/pvssm_tables.py antialiasing AA/antialiasing.json

`main` is the comparison with `pcss`, `cssm`, `average-maps` and the reference (the issue's
ratios per run), `passes` the paper's Table 1 (per-pass GPU ms, medians), `dial` the
800k-triangle grid's quality dial against `average-maps`, `light` the paper's Fig. 10 (point
light or hard sun against soft lights, per run), `fixed` its Table 2 (adaptive pages against one
4096² map) and `antialiasing` its Fig. 11.
"""

import argparse
import json
import statistics


def load(paths):
    return [json.load(open(p)) for p in paths]


def knob(row, name):
    for kv in row.get("label", "").split():
        k, _, v = kv.partition("=")
        if k == name:
            return v
    return None


def pen(row):
    return (row.get("error") or {}).get("penumbra_mae")


def rmse(row):
    return (row.get("error") or {}).get("rmse")


def pages(row):
    return (row.get("counters") or {}).get("allocated_pages")


def passes(row):
    return {p["name"]: p["gpu_ms"] for p in row.get("passes", [])}


def fmt(x, digits=1):
    return "—" if x is None else f"{x:.{digits}f}"


def err(x):
    return "—" if x is None else f"{x:.4f}"


def key(row):
    return (row["scene"], row["technique"], row.get("label", ""))


def by_key(runs):
    """Rows of several runs of one command, grouped by (scene, technique, knobs), in order."""
    order = []
    groups = {}
    for run in runs:
        for row in run:
            k = key(row)
            if k not in groups:
                order.append(k)
                groups[k] = []
            groups[k].append(row)
    return [(k, groups[k]) for k in order]


def times(rows):
    return [r["total_gpu_ms"] for r in rows]


def main_table(runs):
    groups = by_key(runs)
    avg = {k[0]: times(rs) for k, rs in groups if k[1] == "average-maps"}
    print("| scene | technique | knobs | GPU ms per run | median | × `average-maps` per run "
          "| penumbra MAE | RMSE | pages |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (scene, tech, label), rs in groups:
        t = times(rs)
        knobs = " ".join(kv for kv in label.split()
                         if kv.split("=")[0] in ("rho_scale", "refine_search", "samples", "skip", "terms"))
        ratio = "—"
        if tech != "average-maps" and scene in avg and len(avg[scene]) == len(t):
            ratio = " / ".join(f"{a / b:.1f}" for a, b in zip(avg[scene], t))
        print(f"| {scene} | `{tech}` | {knobs} | {' / '.join(fmt(x) for x in t)} "
              f"| {fmt(statistics.median(t))} | {ratio} | {err(pen(rs[0]))} | {err(rmse(rs[0]))} "
              f"| {pages(rs[0]) or '—'} |")


PASS_COLUMNS = [("view-samples", "view samples"), ("pvssm-lowres", "low-res map"),
                ("pvssm-shape", "shape + search"), ("pvssm-cull", "cull"),
                ("pvssm-render", "page render"), ("pvssm-filter", "filter")]


def passes_table(runs, grid_runs):
    print("| scene | " + " | ".join(c for _, c in PASS_COLUMNS)
          + " | frame | pages | filtered texels | decided lit (coarse look + search + kernel) "
            "of samples |")
    print("|---" * (len(PASS_COLUMNS) + 5) + "|")
    rows = []
    for (scene, tech, label), rs in by_key(runs):
        if tech == "pvssm" and knob(rs[0], "rho_scale") == "1" and knob(rs[0], "refine_search") == "1":
            rows.append((scene, rs))
    for (scene, tech, label), rs in by_key(grid_runs):
        if (tech == "pvssm" and knob(rs[0], "rho_scale") == "1"
                and knob(rs[0], "lowres_size") == "1024" and knob(rs[0], "antialias") == "1"):
            rows.append((scene, rs))
    for scene, rs in rows:
        ps = [passes(r) for r in rs]
        cells = [fmt(statistics.median(p.get(name, 0.0) for p in ps)) for name, _ in PASS_COLUMNS]
        c = rs[0]["counters"]
        lit = f"{c['skipped_lit']} + {c['fully_lit'] - c['skipped_lit']} + {c['kernel_lit']}"
        print(f"| {scene} | " + " | ".join(cells)
              + f" | {fmt(statistics.median(times(rs)))} | {pages(rs[0])} "
                f"| {c['filter_texels'] / 1e6:.1f} M | {lit} of {c['view_samples']} |")


def dial_table(runs):
    groups = by_key(runs)
    avg = next(times(rs) for k, rs in groups if k[1] == "average-maps")
    print("| `pvssm` knobs | GPU ms per run | × `average-maps` per run | penumbra MAE | pages |")
    print("|---|---|---|---|---|")
    for (scene, tech, label), rs in groups:
        t = times(rs)
        if tech == "average-maps":
            print(f"| `average-maps` 64 samples | {' / '.join(fmt(x) for x in t)} | — "
                  f"| {err(pen(rs[0]))} | — |")
            continue
        ratio = " / ".join(f"{a / b:.1f}" for a, b in zip(avg, t))
        print(f"| {label} | {' / '.join(fmt(x) for x in t)} | {ratio} | {err(pen(rs[0]))} "
              f"| {pages(rs[0])} |")


def light_table(runs):
    print("| scene, light | GPU ms per run | shape ms | filter ms | page render ms | pages "
          "| penumbra MAE | RMSE |")
    print("|---|---|---|---|---|---|---|---|")
    for (scene, tech, label), rs in by_key(runs):
        ps = [passes(r) for r in rs]
        med = lambda name: fmt(statistics.median(p.get(name, 0.0) for p in ps))
        print(f"| {scene} | {' / '.join(fmt(x) for x in times(rs))} | {med('pvssm-shape')} "
              f"| {med('pvssm-filter')} | {med('pvssm-render')} | {pages(rs[0])} "
              f"| {err(pen(rs[0]))} | {err(rmse(rs[0]))} |")


def fixed_table(runs):
    print("| scene, light | adaptive GPU ms | pages | penumbra MAE | fixed 4096² GPU ms | pages "
          "| penumbra MAE | kernels cut | speed-up |")
    print("|---|---|---|---|---|---|---|---|---|")
    rows = {}
    for (scene, tech, label), rs in by_key(runs):
        if knob(rs[0], "antialias") == "1" and knob(rs[0], "rho_scale") == "1":
            rows.setdefault(scene, {})[knob(rs[0], "fixed_level")] = rs[0]
    for scene, r in rows.items():
        a, f = r["-1"], r["0"]
        print(f"| {scene} | {fmt(a['total_gpu_ms'])} | {pages(a)} | {err(pen(a))} "
              f"| {fmt(f['total_gpu_ms'])} | {pages(f)} | {err(pen(f))} "
              f"| {f['counters'].get('filter_cut', 0)} "
              f"| {f['total_gpu_ms'] / a['total_gpu_ms']:.1f}× |")


def antialiasing_table(runs):
    print("| scene | candidate | GPU ms | MAE vs 32×32 | RMSE | max |")
    print("|---|---|---|---|---|---|")
    for run in runs:
        for r in run:
            print(f"| {r['scene']} | {r['candidate']} | {fmt(r['gpu_ms'])} | {r['mae']:.5f} "
                  f"| {r['rmse']:.4f} | {r['max']:.3f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("table", choices=["main", "passes", "dial", "light", "fixed", "antialiasing"])
    ap.add_argument("files", nargs="+", help="bench.json files, one per run")
    ap.add_argument("--grid", nargs="*", default=[], help="`passes`: the grid's dial runs too")
    a = ap.parse_args()
    runs = load(a.files)
    if a.table == "main":
        main_table(runs)
    elif a.table == "passes":
        passes_table(runs, load(a.grid))
    elif a.table == "dial":
        dial_table(runs)
    elif a.table == "light":
        light_table(runs)
    elif a.table == "fixed":
        fixed_table(runs)
    else:
        antialiasing_table(runs)


if __name__ == "__main__":
    main()
