#!/usr/bin/env python3
"""The README's measured tables, from the bench's own output (so every figure there comes from a
named command):

    python3 tools/readme_tables.py receivers DIR   # DIR from `penumbra bench --set light_clip=0,1`
    python3 tools/readme_tables.py soft DIR        # DIR from the soft-shadow bench (README)
    python3 tools/readme_tables.py virtual DIR     # DIR from the virtual-map bench (README)
    python3 tools/readme_tables.py izb DIR...      # DIRs from the irregular z-buffer benches
    python3 tools/readme_tables.py backprojection A B C  # the atty/bitmask benches (README)
    python3 tools/readme_tables.py resolution DIR...    # the hard-shadow resolution benches
    python3 tools/readme_tables.py stress DIR           # DIR from `penumbra stress`
    python3 tools/readme_tables.py skipping DIR         # DIR from `bench --suite skipping`
    python3 tools/readme_tables.py selection DIR        # DIR from `bench --suite selection`
    python3 tools/readme_tables.py reuse DIR            # DIR from `bench --suite reuse`
    python3 tools/readme_tables.py scaling DIR          # DIR from `bench --suite scaling`
    python3 tools/readme_tables.py temporal DIR         # DIR from `bench --suite temporal`
    python3 tools/readme_tables.py moved A B            # two stress.json or two bench.csv

(The `pvssm` section's tables come from tools/pvssm_tables.py.)

`receivers`: per technique, the configuration with clipping on that has the lowest penumbra MAE
on teapot-rect (lowest RMSE on spot-point), with the same configuration's clip-off figures and
the light leak of docs/bench-full-lavapipe-2026-11-22.csv. `soft`: per scene (and light scale),
per technique and map size, the configuration with the lowest penumbra MAE, its error against
both references and its pass times; then `vssm` at subdivision 4 under each pair of
`split_regions` and `receiver_plane_bias`, and `essm` per exponent with `receiver_plane_bias` 0
and 1; then the skip table (skip.csv). `virtual`: per scene, every
`hard` and `rmsm` run and the best `pcf-coverage` per map size (by RMSE), with misclassification
(also against `hard` at 2048²), memory and pages, from bench.json; then rmsm's passes.
`izb`: per scene of each DIR, every run (failures with their reason) with time, error, pairs,
tests and the izb passes, from bench.json.
`backprojection`: from A (every filter-based technique) and B (atty and bitmask over their
knobs), per scene the best penumbra MAE against the single-layer reference of each technique and
whether bitmask at 256 samples beats them all; from B and C every run with its passes, both references' errors, Atty's shadow MAE and
the skip counters.
`resolution`: per scene of the DIRs, every run with time, misclassified, RMSE, the sampling
error's median, p95 and under-sampled fraction, and memory (MiB), from bench.csv.
`stress`: technique × case MAE against the reference (`refused` where the input was refused as
the case asks, `*` on a `known` row, `FAIL` on a failed one), the NaN/Inf/out-of-range totals,
then every `known` row with its reason, from stress.json.
`skipping`: technique × scene, the speed-up of skipping on over off and the share of view samples
it decided without the full work, then the largest number of pixels that differed, from
skipping.json.
`reuse`: per technique, over the scenes of reuse.json, the median host (calling-thread) CPU
milliseconds of the first frame, the second and a rebuilt renderer, the largest second/first
ratio, the median process CPU milliseconds of the first and second frames, and what the second
frames created (device allocations + objects, summed).
`selection`: every held-out scene with the features, the pick, its predicted and measured error
and time, and the slowest candidate within the budget, then the median pick's measured time, from
selection.json.
`scaling`: per technique, the growth exponent k and the time at both ends of each sweep
(triangles, view samples, light size), from scaling.json.
`temporal`: technique (and knobs) × scene, flicker / flicker in shadow (×10⁻³) and the MAE,
then the reference's own motion per scene, from temporal.json.
`moved`: of the rows with an MAE in both runs (stress.json rows by case, technique and knobs;
bench.csv rows by scene, light scale, label and technique), how many moved by more than 10⁻⁹
from A to B and the three that moved most (the README's runs under tools/fused_fma.py).
"""
import csv
import json
import math
import statistics
import sys
from pathlib import Path

OLD = Path(__file__).resolve().parent.parent / "docs" / "bench-full-lavapipe-2026-11-22.csv"


def rows(path):
    with open(path, newline="") as f:
        return [r for r in csv.DictReader(f) if not r.get("failure")]


def num(r, key):
    try:
        return float(r[key])
    except (KeyError, TypeError, ValueError):
        return None


def knobs(label, drop):
    parts = [p for p in label.split() if p.split("=")[0] not in drop]
    return " ".join(parts) or "defaults"


def fmt(v, digits):
    return "—" if v is None else f"{v:.{digits}f}"


def receivers(directory):
    data = rows(Path(directory) / "bench.csv")
    old = rows(OLD) if OLD.exists() else []
    old_leak = {(r["scene"], r["technique"], r["label"]): num(r, "light_leak") for r in old}
    order = []
    for r in data:
        if r["technique"] not in order:
            order.append(r["technique"])
    for scene, metric in (("teapot-rect", "penumbra_mae"), ("spot-point", "rmse")):
        print(f"\n{scene} (best {metric} with light_clip=1)\n")
        if metric == "penumbra_mae":
            print("| technique | best knobs on teapot-rect | GPU ms | penumbra MAE | — clip off "
                  "| RMSE | misclassified | light leak | — clip off | — 2026-11-22 | FLIP "
                  "| memory B / map texel |")
            print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        else:
            print("| technique | best knobs on spot-point | GPU ms | RMSE | — clip off "
                  "| misclassified | light leak | — clip off | — 2026-11-22 |")
            print("|---|---|---|---|---|---|---|---|---|")
        for t in order:
            on = [r for r in data if r["scene"] == scene and r["technique"] == t
                  and "light_clip=1" in r["label"].split() and num(r, metric) is not None]
            if not on:
                continue
            best = min(on, key=lambda r: num(r, metric))
            label = knobs(best["label"], {"light_clip"})
            off = next((r for r in data if r["scene"] == scene and r["technique"] == t
                        and "light_clip=0" in r["label"].split()
                        and knobs(r["label"], {"light_clip"}) == label), None)
            leak_old = old_leak.get((scene, t, label if label != "defaults" else "defaults"))
            g = lambda r, k: None if r is None else num(r, k)
            if metric == "penumbra_mae":
                print(f"| `{t}` | {label} | {fmt(num(best, 'total_gpu_ms'), 1)} "
                      f"| {fmt(num(best, 'penumbra_mae'), 3)} | {fmt(g(off, 'penumbra_mae'), 3)} "
                      f"| {fmt(num(best, 'rmse'), 3)} | {fmt(num(best, 'misclassified'), 3)} "
                      f"| {fmt(num(best, 'light_leak'), 3)} | {fmt(g(off, 'light_leak'), 3)} "
                      f"| {fmt(leak_old, 3)} | {fmt(num(best, 'flip'), 4)} "
                      f"| {fmt(num(best, 'memory_bytes_per_texel'), 1)} |")
            else:
                print(f"| `{t}` | {label} | {fmt(num(best, 'total_gpu_ms'), 1)} "
                      f"| {fmt(num(best, 'rmse'), 3)} | {fmt(g(off, 'rmse'), 3)} "
                      f"| {fmt(num(best, 'misclassified'), 3)} "
                      f"| {fmt(num(best, 'light_leak'), 3)} | {fmt(g(off, 'light_leak'), 3)} "
                      f"| {fmt(leak_old, 3)} |")


def passes(r, prefix):
    out = []
    for part in (r.get("passes") or "").split(";"):
        if "=" in part:
            name, ms = part.split("=")
            if name.startswith(prefix):
                out.append(f"{name[len(prefix):]} {float(ms):.0f}")
    return ", ".join(out)


def soft(directory):
    data = rows(Path(directory) / "bench.csv")
    single = next((k for k in (data[0].keys() if data else []) if k.startswith("penumbra_mae@")),
                  None)
    scenes = []
    for r in data:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
    for scene in scenes:
        print(f"\n{scene}\n")
        print("| technique | map | best knobs | GPU ms | passes (ms) | penumbra MAE "
              f"| {single or 'single-layer'} | RMSE | light leak |")
        print("|---|---|---|---|---|---|---|---|---|")
        here = [r for r in data if r["scene"] == scene and num(r, "penumbra_mae") is not None]
        order = []
        for r in here:
            key = (r["technique"], r["label"].split("map_size=")[-1].split()[0]
                   if "map_size=" in r["label"] else "")
            if key not in order:
                order.append(key)
        for t, size in order:
            cands = [r for r in here if r["technique"] == t and f"map_size={size}" in r["label"]]
            best = min(cands, key=lambda r: (num(r, "penumbra_mae"), num(r, "total_gpu_ms") or 0))
            prefix = t + "-"
            print(f"| `{t}` | {size} | {knobs(best['label'], {'map_size'})} "
                  f"| {fmt(num(best, 'total_gpu_ms'), 1)} | {passes(best, prefix)} "
                  f"| {fmt(num(best, 'penumbra_mae'), 4)} "
                  f"| {fmt(num(best, single) if single else None, 4)} "
                  f"| {fmt(num(best, 'rmse'), 4)} | {fmt(num(best, 'light_leak'), 4)} |")
    vssm_rules(data, single)
    essm_filter(data, single)
    skip = Path(directory) / "skip.csv"
    if skip.exists():
        print("\nskip\n")
        print("| scene | knobs | skip off ms | skip on ms | speed-up | samples skipped "
              "| pixels differing |")
        print("|---|---|---|---|---|---|---|")
        for r in rows(skip):
            print(f"| {r['scene']} | {r['label']} | {fmt(num(r, 'ms_skip_off'), 1)} "
                  f"| {fmt(num(r, 'ms_skip_on'), 1)} | {fmt(num(r, 'speedup'), 2)}× "
                  f"| {fmt(100 * num(r, 'skipped_fraction'), 1)} % | {r['differing_pixels']} |")


def knob_table(data, single, technique, fixed, columns, title):
    """Per scene, a cell per column (header, knob sets): each knob set's row of `technique` among
    those whose label holds every knob of `fixed`, as penumbra MAE (single-layer reference's) /
    GPU ms, several joined by →, "—" for none."""
    here = [r for r in data if r["technique"] == technique
            and set(fixed) <= set(r["label"].split()) and num(r, "penumbra_mae") is not None]
    if not here:
        return
    print(f"\n{title}\n")
    print("| scene | " + " | ".join(header for header, _ in columns) + " |")
    print("|---" * (1 + len(columns)) + "|")
    scenes = []
    for r in here:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])

    def cell(scene, want):
        row = next((r for r in here if r["scene"] == scene
                    and set(want) <= set(r["label"].split())), None)
        if row is None:
            return "—"
        return (f"{fmt(num(row, 'penumbra_mae'), 4)} "
                f"({fmt(num(row, single) if single else None, 4)}) / "
                f"{fmt(num(row, 'total_gpu_ms'), 0)}")

    for scene in scenes:
        cells = [" → ".join(cell(scene, want) for want in sets) for _, sets in columns]
        print(f"| {scene} | " + " | ".join(cells) + " |")


def essm_filter(data, single):
    """`essm` at map 1024 and no normal offset, per scene and exponent: the paper's filter (one
    ESM test at the sample's depth over the box, `receiver_plane_bias=0`) → the test per
    rip-map block at the receiver plane's depth (the default)."""
    exponents = sorted({float(k.split("=")[1]) for r in data if r["technique"] == "essm"
                        for k in r["label"].split() if k.startswith("exponent=")})
    columns = [(f"c = {c:g}", [[f"exponent={c:g}", f"receiver_plane_bias={plane}"]
                               for plane in ("0", "1")]) for c in exponents]
    knob_table(data, single, "essm", ["map_size=1024", "normal_offset=0"], columns,
               "essm at map 1024, normal_offset=0: penumbra MAE (single-layer ref.) / GPU ms, "
               "one depth (the paper's) → per block at the receiver plane (the default)")


def vssm_rules(data, single):
    """`vssm` at subdivision 4, map 1024 and no normal offset, per scene: the paper's rule (split
    only where Chebyshev does not apply, one receiver depth) against the receiver plane, every
    mixed region split, and both (the defaults)."""
    rules = [("0", "0", "paper's rule"), ("0", "1", "receiver plane"),
             ("1", "0", "mixed regions split"), ("1", "1", "both (defaults)")]
    columns = [(name, [[f"split_regions={split}", f"receiver_plane_bias={plane}"]])
               for split, plane, name in rules]
    knob_table(data, single, "vssm", ["subdivision=4", "map_size=1024", "normal_offset=0"],
               columns, "vssm at subdivision=4, map 1024, normal_offset=0: penumbra MAE "
               "(single-layer ref.) / GPU ms")


def virtual(directory):
    data = [r for r in json.loads((Path(directory) / "bench.json").read_text())
            if "error" in r]
    err = lambda r, k: r["error"].get(k)
    ctr = lambda r, k: r.get("counters", {}).get(k)
    scenes = []
    for r in data:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
    for scene in scenes:
        here = [r for r in data if r["scene"] == scene]
        base = next((r for r in here if r["technique"] == "hard"
                     and r["label"] == "map_size=2048"), None)
        print(f"\n{scene} ({here[0]['width']}x{here[0]['height']})\n")
        print("| technique | knobs | GPU ms | misclassified | ÷ hard 2048² | RMSE "
              "| penumbra MAE | memory MiB | pages (+ refinement) | fallbacks |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        rows_out = [r for r in here if r["technique"] in ("hard", "rmsm")]
        for size in ("1024", "2048"):
            cands = [r for r in here if r["technique"] == "pcf-coverage"
                     and f"map_size={size}" in r["label"].split()]
            if cands:
                rows_out.append(min(cands, key=lambda r: err(r, "rmse")))
        for r in rows_out:
            ratio = (err(r, "misclassified") / err(base, "misclassified")
                     if base and err(base, "misclassified") else None)
            pages = ctr(r, "allocated_pages")
            refine = ctr(r, "refine_allocated_pages")
            pages_txt = "—" if pages is None else (
                f"{pages}" + (f" + {refine}" if refine else ""))
            print(f"| `{r['technique']}` | {r['label']} | {fmt(r.get('total_gpu_ms'), 1)} "
                  f"| {fmt(err(r, 'misclassified'), 5)} | {fmt(ratio, 2)} "
                  f"| {fmt(err(r, 'rmse'), 4)} | {fmt(err(r, 'penumbra_mae'), 4)} "
                  f"| {fmt(r['memory_bytes'] / 2**20, 1)} | {pages_txt} "
                  f"| {ctr(r, 'fallback_lookups') if pages is not None else '—'} |")
    print("\nrmsm passes (ms)\n")
    names = ["mark", "compact", "allocate", "cull", "render", "edges", "refine", "lookup"]
    print("| scene | knobs | " + " | ".join(names) + " | total |")
    print("|---|---|" + "---|" * (len(names) + 1))
    for r in data:
        if r["technique"] != "rmsm":
            continue
        ms = {p["name"][len("rmsm-"):]: p.get("gpu_ms") for p in r.get("passes", [])
              if p["name"].startswith("rmsm-")}
        print(f"| {r['scene']} | {r['label']} | "
              + " | ".join(fmt(ms.get(n), 1) for n in names)
              + f" | {fmt(r.get('total_gpu_ms'), 1)} |")


def izb(directories):
    for directory in directories:
        data = json.loads((Path(directory) / "bench.json").read_text())
        print(f"\n{directory}\n")
        print("| scene | view | triangles | technique | knobs | GPU ms | bin / footprint / test / "
              "resolve ms | penumbra MAE | RMSE | misclassified | pairs | sample tests "
              "| ray tests | memory MiB |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for r in data:
            e = r.get("error", {})
            c = r.get("counters", {})
            ms = {p["name"]: p.get("gpu_ms") for p in r.get("passes", [])}
            izb_passes = " / ".join(fmt(ms.get(n), 1) for n in ("bin", "footprint", "test",
                                                                  "resolve"))
            if r.get("failure"):
                print(f"| {r['scene']} | {r['width']}x{r['height']} | {r['triangles']} "
                      f"| `{r['technique']}` | {r['label']} | failed: {r['failure'][:60]} "
                      "| | | | | | | | |")
                continue
            is_izb = r["technique"].startswith("izb")
            print(f"| {r['scene']} | {r['width']}x{r['height']} | {r['triangles']} "
                  f"| `{r['technique']}` | {r['label']} | {fmt(r.get('total_gpu_ms'), 1)} "
                  f"| {izb_passes if is_izb else '—'} | {fmt(e.get('penumbra_mae'), 4)} "
                  f"| {fmt(e.get('rmse'), 4)} | {fmt(e.get('misclassified'), 5)} "
                  f"| {c.get('pairs', '—')} | {c.get('sample_tests', '—')} "
                  f"| {c.get('ray_tests', '—')} | {fmt(r['memory_bytes'] / 2**20, 1)} |")


FILTER_BASED = ("pcf", "pcf-poisson", "pcf-coverage", "vsm", "esm", "evsm", "msm", "csm", "savsm",
                "pcss", "cssm", "vssm", "essm", "pvssm")


def backprojection(a, b, c):
    # The filter-based rows from A, the back-projection rows from B (same scenes, references).
    mine = ("atty", "bitmask")
    data = [r for r in rows(Path(a) / "bench.csv") if r["technique"] not in mine]
    data += [r for r in rows(Path(b) / "bench.csv") if r["technique"] in mine]
    single = next(k for k in data[0].keys() if k.startswith("penumbra_mae@"))
    for scene in dict.fromkeys(r["scene"] for r in data):
        here = [r for r in data if r["scene"] == scene and num(r, single) is not None]
        best = {}
        for r in here:
            t = r["technique"]
            if t not in best or num(r, single) < num(best[t], single):
                best[t] = r
        print(f"\n{scene}: best {single} per technique\n")
        print(f"| technique | knobs | {single} | penumbra MAE | GPU ms |")
        print("|---|---|---|---|---|")
        for t, r in sorted(best.items(), key=lambda kv: num(kv[1], single)):
            print(f"| `{t}` | {knobs(r['label'], {'map_size'})} | {fmt(num(r, single), 4)} "
                  f"| {fmt(num(r, 'penumbra_mae'), 4)} | {fmt(num(r, 'total_gpu_ms'), 1)} |")
        bm = [r for r in here if r["technique"] == "bitmask" and "samples=256" in r["label"]]
        filters = [num(r, single) for t, r in best.items() if t in FILTER_BASED]
        if bm and filters:
            mine = min(num(r, single) for r in bm)
            verdict = "lower" if mine < min(filters) else "NOT lower"
            print(f"\nbitmask (256 samples) {mine:.4f}: {verdict} than every filter-based "
                  f"technique (best {min(filters):.4f})")
    for directory in (b, c):
        data = json.loads((Path(directory) / "bench.json").read_text())
        refs = [k for k in data[0].keys() if k.startswith("penumbra_mae@")] if data else []
        print(f"\n{directory}\n")
        print("| scene | technique | knobs | GPU ms | passes (ms) | penumbra MAE | "
              + " | ".join(refs) + " | shadow MAE (Atty) | RMSE | skipped lit / umbra | patches |")
        print("|---|---|---|---|---|---|" + "---|" * len(refs) + "---|---|---|---|")
        for r in data:
            if r.get("failure"):
                print(f"| {r['scene']} | `{r['technique']}` | {r['label']} | failed: "
                      f"{r['failure'][:60]} |")
                continue
            e = r.get("error", {})
            cnt = r.get("counters", {})
            ps = ", ".join(f"{p['name'].split('-', 1)[-1]} {p['gpu_ms']:.0f}"
                           for p in r.get("passes", [])
                           if p["name"].startswith(r["technique"]) and p.get("gpu_ms") is not None)
            print(f"| {r['scene']} | `{r['technique']}` | {r['label']} "
                  f"| {fmt(r.get('total_gpu_ms'), 1)} | {ps} | {fmt(e.get('penumbra_mae'), 4)} | "
                  + " | ".join(fmt(r.get(k), 4) for k in refs)
                  + f" | {fmt(e.get('shadow_mae'), 4)} | {fmt(e.get('rmse'), 4)} "
                  f"| {cnt.get('skipped_lit', '—')} / {cnt.get('skipped_umbra', '—')} "
                  f"| {cnt.get('patches', '—')} |")


def resolution(directories):
    data = []
    for d in directories:
        data.extend(rows(Path(d) / "bench.csv"))
    scenes = []
    for r in data:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
    for scene in scenes:
        print(f"\n`{scene}`:\n")
        print("| technique | knobs | GPU ms | misclassified | RMSE | m median | m p95 | m > 1 | MiB |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in data:
            if r["scene"] != scene:
                continue
            mem = num(r, "memory_bytes")
            label = knobs(r["label"], ())
            for i, name in enumerate(["pssm", "sdsm", "uniform", "log"]):
                label = label.replace(f"partition={i}", f"partition={name}")
            print(
                f"| `{r['technique']}` | {label} | {fmt(num(r, 'total_gpu_ms'), 1)} "
                f"| {fmt(num(r, 'misclassified'), 5)} | {fmt(num(r, 'rmse'), 4)} "
                f"| {fmt(num(r, 'aliasing_median'), 3)} | {fmt(num(r, 'aliasing_p95'), 3)} "
                f"| {fmt(num(r, 'aliasing_undersampled'), 3)} "
                f"| {fmt(None if mem is None else mem / 2**20, 1)} |"
            )


def stress(directory):
    d = json.loads((Path(directory) / "stress.json").read_text())
    cases, table = [], {}
    for r in d["rows"]:
        if r["case"] not in cases:
            cases.append(r["case"])
        if r["mae"] is None:
            cell = "refused" if r["pass"] else "FAIL: " + (r["error"] or "?")
        else:
            cell = fmt(r["mae"], 3)
            if not r["pass"]:
                cell = "FAIL " + cell
            elif r["bound"].startswith("known"):
                cell += "*"
        table.setdefault(r["technique"], {})[r["case"]] = cell
    bad = sum(r["nan_count"] + r["inf_count"] + r["out_of_range_count"] for r in d["rows"])
    print(
        f"{len(d['rows'])} rows, {d['failed']} failed, NaN + Inf + out-of-range values in all "
        f"rows: {bad}; {d['width']}x{d['height']}, references {d['reference_samples']}² samples, "
        f"{d['seconds']:.0f} s on {d['device']} ({d['driver']}).\n"
    )
    print("| technique | " + " | ".join(f"`{c}`" for c in cases) + " |")
    print("|---|" + "---|" * len(cases))
    for t, row in table.items():
        print(f"| `{t}` | " + " | ".join(row.get(c, "") for c in cases) + " |")
    print()
    for r in d["rows"]:
        if r["bound"].startswith("known"):
            print(f"- `{r['case']}` × `{r['technique']}` (MAE {r['mae']:.3f}): {r['bound']}")


def skipping(directory):
    d = json.loads((Path(directory) / "skipping.json").read_text())
    scenes, table, diff = [], {}, {}
    for r in d["rows"]:
        if r["scene"] not in scenes:
            scenes.append(r["scene"])
        frac = r["skipped_samples"] / max(r["view_samples"], 1)
        # The caster skip decides every sample without the technique (its rows are bounded by
        # their mean |dV|, not by differing pixels: the technique's own error on a lit scene).
        caster = r.get("counters_on", {}).get("caster_skip") == 1
        if caster:
            frac = 1.0
        mark = "†" if caster else ""
        if "hard_path_taken" in r:
            # The opt-in hard path's own rows: taken (a light too small for a penumbra) or not
            # (then bit-identical); bounded by mean |dV| where taken.
            k = (r["technique"], r["off_knobs"])
            if r["hard_path_taken"]:
                cell = f"{r['speedup']:.2f}× (100 %)‡"
                diff[k] = max(diff.get(k, 0), r["mean_abs_diff"])
            else:
                cell = "not taken"
                diff.setdefault(k, 0)
            table.setdefault(k, {})[r["scene"]] = cell
            continue
        if r.get("speedup") is None:
            cell = f"— ({100 * frac:.0f} %){mark}"
        else:
            cell = f"{r['speedup']:.2f}× ({100 * frac:.0f} %){mark}"
        table.setdefault((r["technique"], r["off_knobs"]), {})[r["scene"]] = cell
        if "differing_pixels" in r and not caster:
            k = (r["technique"], r["off_knobs"])
            diff[k] = max(diff.get(k, 0), r["differing_pixels"])
    print(f"{d['device']} ({d['driver']}), {d['frames']} timed frames per run.\n")
    print("| technique | off | " + " | ".join(f"`{s}`" for s in scenes) + " | pixels differing (most) |")
    print("|---|---|" + "---|" * len(scenes) + "---|")
    for (t, off), row in table.items():
        if (t, off) not in diff:
            d_cell = "—"
        elif "hard_path" in off:
            d_cell = f"mean \\|ΔV\\| {diff[(t, off)]:.4f}‡"
        else:
            d_cell = str(diff[(t, off)])
        print(f"| `{t}` | {off} | " + " | ".join(row.get(s, "") for s in scenes) + f" | {d_cell} |")


def scaling(directory):
    d = json.loads((Path(directory) / "scaling.json").read_text())
    print("| technique | k triangles | ms, 1k → 1M | k view samples | ms, 256² → 2048² | k light "
          "| ms, ×0.25 → ×4 |")
    print("|---|---|---|---|---|---|---|")
    for t in sorted(d["exponents"]):
        cells = []
        for sweep in ("triangles", "resolution", "light"):
            pts = sorted((r["x"], r["gpu_ms"]) for r in d["rows"]
                         if r["technique"] == t and r["sweep"] == sweep and r.get("gpu_ms"))
            k = d["exponents"][t].get(sweep)
            span = f"{pts[0][1]:.0f} → {pts[-1][1]:.0f}" if pts else "—"
            cells += [fmt(k, 2), span]
        print(f"| `{t}` | " + " | ".join(cells) + " |")


def reuse(directory):
    import statistics
    d = json.loads((Path(directory) / "reuse.json").read_text())
    by = {}
    for r in d["rows"]:
        by.setdefault(r["technique"], []).append(r)
    scenes = sorted({r["scene"] for r in d["rows"]})
    passed = sum(1 for r in d["rows"] if r["pass"])
    print(f"{passed} of {len(d['rows'])} rows meet the claim; {len(scenes)} scenes; {d['device']} ({d['driver']}).\n")
    print("| technique | host ms: first, compiling | first, pipelines kept | second | rebuilt | second/first (compiling) | pipelines compiled | process ms: first, compiling | second | created by second frames |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    med = lambda rows, step, key: statistics.median(r[step][key] for r in rows) if rows else None
    cell = lambda v, fmt: "—" if v is None else format(v, fmt)
    for t, rows in by.items():
        # The rows whose first step compiled pipelines (a technique's first scene) against the
        # rows whose first step found them kept by the context.
        cold = [r for r in rows if r.get("compiled_pipelines", 1) > 0]
        warm = [r for r in rows if r.get("compiled_pipelines", 1) == 0]
        ratio = max((r["second_over_first_thread_cpu"] for r in cold), default=None)
        created = sum(r["second_frame_allocations"] + r["second_frame_objects"] for r in rows)
        compiled = sum(r.get("compiled_pipelines", 0) for r in rows)
        print(
            f"| `{t}` | {cell(med(cold, 'first', 'thread_cpu_ms'), '.1f')} | "
            f"{cell(med(warm, 'first', 'thread_cpu_ms'), '.1f')} | {med(rows, 'second', 'thread_cpu_ms'):.1f} | "
            f"{med(rows, 'rebuilt', 'thread_cpu_ms'):.1f} | {cell(ratio, '.3f')} | {compiled} | "
            f"{cell(med(cold, 'first', 'process_cpu_ms'), '.0f')} | {med(rows, 'second', 'process_cpu_ms'):.0f} | {created} |"
        )


def selection(directory):
    d = json.loads((Path(directory) / "selection.json").read_text())
    print(
        f"{d['met']} of {d['held_out']} held-out picks within {d['max_error']} measured, "
        f"{d['not_slower']} of {d['held_out']} not slower than the slowest candidate within it; "
        f"{d['calibration_rows']} calibration rows; {d['device']}.\n"
    )
    print("| held-out scene | light ° | px | penumbra share | picked | predicted | measured | ms | fastest within budget (ms) | slowest within budget (ms) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in d["rows"]:
        f = r["features"]
        pick = r["choice"]["picked"]
        m = next(x for x in r["measured"] if x["candidate"] == pick["candidate"])
        within = [x for x in r["measured"] if x["error"] <= d["max_error"]]
        slow = max(within, key=lambda x: x["gpu_ms"]) if within else None
        slow_cell = f"`{slow['candidate']}` ({slow['gpu_ms']:.0f})" if slow else "none"
        fast = min(within, key=lambda x: x["gpu_ms"]) if within else None
        fast_cell = f"`{fast['candidate']}` ({fast['gpu_ms']:.0f})" if fast else "none"
        print(
            f"| {r['scene']} | {math.degrees(f['light_angle']):.1f} | {f['light_pixels']:.0f} | "
            f"{f['penumbra_fraction']:.2f} | `{pick['candidate']}` | {pick['error']:.4f} | "
            f"{m['error']:.4f}{'' if r['meets'] else ' (misses)'} | {m['gpu_ms']:.0f} | {fast_cell} | {slow_cell} |"
        )
    picked = [next(x["gpu_ms"] for x in r["measured"]
                   if x["candidate"] == r["choice"]["picked"]["candidate"]) for r in d["rows"]]
    print(f"\nMedian pick: {statistics.median(picked):.1f} ms GPU (measured).")


def temporal(directory):
    rows = json.loads((Path(directory) / "temporal.json").read_text())
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    runs = list(dict.fromkeys((r["technique"], r["label"]) for r in rows))
    by = {(r["scene"], r["technique"], r["label"]): r for r in rows}
    print("| technique | " + " | ".join(f"{s}: flicker / in shadow (×10⁻³), MAE" for s in scenes) + " |")
    print("|---|" + "---|" * len(scenes))
    for t, label in runs:
        cells = []
        for s in scenes:
            r = by.get((s, t, label))
            if r is None:
                cells.append("")
            elif r.get("error"):
                cells.append("refused")
            else:
                cells.append(f"{1e3 * r['flicker']:.3f} / {1e3 * r['flicker_shadow']:.2f}, {r['mae']:.4f}")
        name = f"`{t}`" if label == "defaults" else f"`{t}` {label}"
        print(f"| {name} | " + " | ".join(cells) + " |")
    print()
    for s in scenes:
        ok = [r for r in rows if r["scene"] == s and not r.get("error")]
        if ok:
            r = ok[0]
            print(f"{s}: the reference's mean |ΔR| {1e3 * r['motion_ref']:.3f} ×10⁻³, "
                  f"{r['positions']} positions, {r['step_mrad']} mrad a step")


def moved(a, b):
    def load(path):
        if path.endswith(".json"):
            return {(r["case"], r["technique"], json.dumps(r.get("knobs"), sort_keys=True)):
                    r["mae"] for r in json.load(open(path))["rows"]}
        with open(path, newline="") as f:
            return {(r["scene"], r["light_scale"], r["label"], r["technique"]):
                    float(r["mae"]) if r["mae"] else None for r in csv.DictReader(f)}
    before, after = load(a), load(b)
    both = [(abs(after[k] - v), k) for k, v in before.items()
            if v is not None and after.get(k) is not None]
    both.sort(reverse=True)
    print(f"{sum(1 for d, _ in both if d > 1e-9)} of {len(both)} rows moved by more than 1e-9; "
          f"rows only in one run: {len(set(before) ^ set(after))}")
    for d, k in both[:3]:
        print(f"  {d:.3g}  {' / '.join(k)}")


# Each command's function and how many directories it takes (None: one or more, as a list).
COMMANDS = {
    "receivers": (receivers, 1),
    "soft": (soft, 1),
    "virtual": (virtual, 1),
    "izb": (izb, None),
    "backprojection": (backprojection, 3),
    "resolution": (resolution, None),
    "stress": (stress, 1),
    "skipping": (skipping, 1),
    "selection": (selection, 1),
    "reuse": (reuse, 1),
    "scaling": (scaling, 1),
    "temporal": (temporal, 1),
    "moved": (moved, 2),
}

if __name__ == "__main__":
    name, dirs = (sys.argv[1], sys.argv[2:]) if len(sys.argv) > 2 else (None, [])
    function, count = COMMANDS.get(name, (None, 0))
    if function is None or (count is not None and len(dirs) != count):
        sys.exit(__doc__)
    function(dirs) if count is None else function(*dirs)
