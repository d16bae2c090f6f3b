#!/usr/bin/env python3
"""Compares rate-distortion series of mts-bench-walk --rd-json at equal bytes.

usage: rd_compare.py BASE.json OTHER.json [--json OUT]

For every point of OTHER strictly between the base mesh and the full level,
BASE's geometric and colour errors are interpolated at OTHER's byte count
(linearly in bytes, on the logarithm of the error) and the ratios
OTHER / BASE taken; a model's summary is the geometric mean of the ratios
over those points (below 1: OTHER has less error for the same bytes), its
worst ratio, and the full streams' byte counts; "excess" is the geometric
ratio of the errors above each stream's full level (the grid's quantization).
"""
import json
import math
import sys


def interp(points, key, b):
    pts = sorted(points, key=lambda p: p["bytes"])
    if b <= pts[0]["bytes"]:
        return pts[0][key]
    for p, q in zip(pts, pts[1:]):
        if p["bytes"] <= b <= q["bytes"]:
            if q["bytes"] == p["bytes"] or p[key] <= 0 or q[key] <= 0:
                return q[key]
            t = (b - p["bytes"]) / (q["bytes"] - p["bytes"])
            return math.exp((1 - t) * math.log(p[key]) + t * math.log(q[key]))
    return pts[-1][key]


def compare(a, b):
    out = {}
    for name, mb in b["models"].items():
        ma = a["models"].get(name)
        if not ma:
            continue
        inner = [p for p in mb["points"] if 0 < p["level"] < mb["levels"]]
        r = {"points": len(inner), "full_bytes_base": ma["points"][-1]["bytes"],
             "full_bytes_other": mb["points"][-1]["bytes"]}
        for key in ("rms", "color_rms"):
            ratios = []
            for p in inner:
                e = interp(ma["points"], key, p["bytes"]) if key in p else None
                if e and e > 0 and p[key] > 0:
                    ratios.append(p[key] / e)
            if ratios:
                r[key + "_ratio_geomean"] = math.exp(sum(map(math.log, ratios)) / len(ratios))
                r[key + "_ratio_worst"] = max(ratios)
                r[key + "_ratio_best"] = min(ratios)
        # the geometric error above each stream's full level (the grid's
        # quantization, the same for both): a ratio of errors near that
        # floor says little about what shows
        fa, fb = ma["points"][-1]["rms"], mb["points"][-1]["rms"]
        ex = []
        for p in inner:
            e = interp(ma["points"], "rms", p["bytes"]) - fa
            if e > 0 and p["rms"] - fb > 0:
                ex.append((p["rms"] - fb) / e)
        if ex:
            r["rms_excess_ratio_geomean"] = math.exp(sum(map(math.log, ex)) / len(ex))
        out[name] = r
    return out


def main():
    args = sys.argv[1:]
    dest = None
    if "--json" in args:
        i = args.index("--json")
        dest = args[i + 1]
        del args[i:i + 2]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    with open(args[0]) as f:
        a = json.load(f)
    with open(args[1]) as f:
        b = json.load(f)
    res = compare(a, b)
    print(f"{'model':<16} {'points':>6} {'geo ratio':>9} {'worst':>6} {'excess':>6} {'colour ratio':>12} "
          f"{'worst':>6} {'best':>6} {'full B base':>11} {'full B other':>12}")
    for name, r in res.items():
        g = r.get("rms_ratio_geomean", float("nan"))
        c = r.get("color_rms_ratio_geomean", float("nan"))
        print(f"{name:<16} {r['points']:>6} {g:>9.3f} {r.get('rms_ratio_worst', float('nan')):>6.3f} "
              f"{r.get('rms_excess_ratio_geomean', float('nan')):>6.3f} "
              f"{c:>12.3f} {r.get('color_rms_ratio_worst', float('nan')):>6.3f} "
              f"{r.get('color_rms_ratio_best', float('nan')):>6.3f} {r['full_bytes_base']:>11} "
              f"{r['full_bytes_other']:>12}")
    if dest:
        with open(dest, "w") as f:
            json.dump(res, f, indent=2)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
