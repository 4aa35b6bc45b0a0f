#!/usr/bin/env python3
"""How well a calibration table predicts its own candidates' times, three ways, leaving each
scene out (its rows predicted from the others' three nearest, as src/selection/calibration.rs does):

    python3 tools/selection_time_check.py calibration/lavapipe.json

A: the neighbours' times scaled by view samples alone (the selection before 2026-12-07);
B: and by the triangle ratio to the power of the candidate's growth exponent, from any count;
C: and by that ratio with counts under the growth pairs' fewest counted as that many (the
   selection's `TriangleGrowth`). Prints the median, the 90th percentile and the worst three of
|ln(predicted / measured)| over every (candidate, scene) row. The exponent is recomputed
without the left-out scene, as `Calibration::triangle_growth` would on the others' rows.
"""
import json
import math
import sys


def vector(f):
    ln = lambda x, floor: math.log(max(x, 0.0) + floor)
    return [2 * ln(f["light_angle"], 1e-3), ln(f["light_pixels"], 0.5),
            2 * ln(f["penumbra_fraction"], 1e-2), ln(f["depth_span"], 1e-2),
            0.5 * ln(f["triangles"], 1.0), 0.5 * ln(f["view_samples"], 1.0)]


def growth(rows):
    """(exponent, from): src/selection/calibration.rs's triangle_growth over these rows (it takes every row
    with a time and triangles, whatever its error)."""
    rows = [r for r in rows if r["gpu_ms"] > 0 and r["features"]["triangles"] > 0]
    slopes, low = [], []
    per_sample = lambda r: r["gpu_ms"] / max(r["features"]["view_samples"], 1)
    for i, a in enumerate(rows):
        for b in rows[i + 1:]:
            ratio = b["features"]["triangles"] / a["features"]["triangles"]
            va, vb = vector(a["features"]), vector(b["features"])
            va[4] = vb[4] = 0.0
            if max(ratio, 1 / ratio) >= 4.0 and math.dist(va, vb) <= 0.5:
                slopes.append(math.log(per_sample(b) / per_sample(a)) / math.log(ratio))
                low.append(min(a["features"]["triangles"], b["features"]["triangles"]))
    if not slopes:
        return 0.0, 0
    slopes.sort()
    m = len(slopes) // 2
    median = slopes[m] if len(slopes) % 2 else 0.5 * (slopes[m - 1] + slopes[m])
    return min(max(median, 0.0), 1.0), min(low)


def predict(features, rows, model, k, low):
    near = sorted(rows, key=lambda r: math.dist(vector(features), vector(r["features"])))[:3]
    total = 0.0
    for r in near:
        t = r["gpu_ms"] * max(features["view_samples"], 1) / max(r["features"]["view_samples"], 1)
        n, nr = features["triangles"], r["features"]["triangles"]
        if model == "B":
            t *= (max(n, 1) / max(nr, 1)) ** k
        if model == "C":
            t *= (max(n, low, 1) / max(nr, low, 1)) ** k
        total += t
    return total / len(near)


def main(path):
    table = json.load(open(path))
    every = [r for r in table["rows"] if r["gpu_ms"] > 0]
    # The rows a prediction's neighbours come from (Calibration::nearest): a time and an error.
    rows = [r for r in every if math.isfinite(r["error"])]
    candidates = sorted({r["candidate"] for r in rows})
    print(f"{path}: {len(rows)} rows, {len(candidates)} candidates")
    for model in "ABC":
        errors = []
        for c in candidates:
            own = [r for r in rows if r["candidate"] == c]
            for r in own:
                others = [x for x in own if x["scene"] != r["scene"]]
                if not others:
                    continue
                k, low = growth([x for x in every
                                 if x["candidate"] == c and x["scene"] != r["scene"]])
                p = predict(r["features"], others, model, k, low)
                errors.append((abs(math.log(p / r["gpu_ms"])), c, r["scene"]))
        errors.sort()
        n = len(errors)
        worst = ", ".join(f"{e:.2f} {c} on {s}" for e, c, s in errors[-3:])
        print(f"{model}: median {errors[n // 2][0]:.3f}, 90th percentile "
              f"{errors[int(0.9 * n)][0]:.3f}; worst {worst}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
