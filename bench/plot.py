#!/usr/bin/env python3
"""Pictures of `make bench`, from bench/out/walk.json and
bench/out/rd.json (written by build/bin/mts-bench-walk):

  bench/plots/walkthrough.png   frames/s and extraction ms per frame of the
                                walkthrough (papers 000/002: the model moving
                                away, linear and exponential), strips with and
                                without coherence and a triangle list
  bench/plots/rd_<model>.png    triangles available and geometric error against
                                bytes received, Draco single-rate's point marked,
                                beside the same curves of an earlier protocol
                                (bench/baseline/rd_*.json: the figures before a
                                change to the bytes, kept to show it)

usage: bench/plot.py [OUT_DIR [PLOTS_DIR]]   (defaults bench/out, bench/plots)
Skips, saying why, when matplotlib is missing (Debian: python3-matplotlib).
"""
import json
import os
import sys

out = sys.argv[1] if len(sys.argv) > 1 else "bench/out"
plots = sys.argv[2] if len(sys.argv) > 2 else "bench/plots"

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError as e:
    print(f"plot: skipped: matplotlib is not installed ({e}); Debian: python3-matplotlib")
    sys.exit(0)


def load(name):
    try:
        with open(os.path.join(out, name)) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        print(f"plot: {name}: {e}")
        return None


os.makedirs(plots, exist_ok=True)
MODES = [("strips", "strips, coherent", "tab:blue"),
         ("strips_nocoh", "strips, from the base each frame", "tab:orange"),
         ("list", "triangle list (uploaded whole)", "tab:green")]
written = []

walk = load("walk.json")
if walk and walk.get("models"):
    models = list(walk["models"])
    fig, axes = plt.subplots(3, 2 * len(models), figsize=(6.5 * 2 * len(models), 10),
                             sharex=True, squeeze=False)
    hz = walk["hz"]
    for mi, name in enumerate(models):
        mod = walk["models"][name]
        for si, sched in enumerate(("linear", "exponential")):
            runs = mod["runs"][sched]
            col = 2 * mi + si
            ax_f, ax_e, ax_t = axes[0][col], axes[1][col], axes[2][col]
            for key, label, color in MODES:
                r = runs[key]
                t = [i / hz for i in range(len(r["extract_ms"]))]
                frame = [e + u + d for e, u, d in zip(r["extract_ms"], r["upload_ms"], r["draw_ms"])]
                fps = [1000.0 / f if f > 0 else 0 for f in frame]
                s = r["summary"]
                ax_f.plot(t, fps, color=color, lw=0.7,
                          label=f"{label}: {s['mean_fps']:.0f} fps")
                ax_e.plot(t, r["extract_ms"], color=color, lw=0.7,
                          label=f"{label}: mean {s['mean_extract_ms']:.3f}, "
                                f"max {s['max_extract_ms']:.2f} ms")
            ax_t.plot(t, runs["strips"]["triangles"], color="black", lw=1)
            ax_f.set_title(f"{name}, {sched} (moving away to {walk['far']:g}x)")
            ax_f.set_ylabel("frames/s")
            ax_e.set_ylabel("extraction ms")
            ax_e.set_yscale("symlog", linthresh=0.01)
            ax_t.set_ylabel("triangles (distance policy)")
            ax_t.set_xlabel("walkthrough time, s (simulated, 60 Hz)")
            ax_f.legend(fontsize=7, loc="upper left")
            ax_e.legend(fontsize=7, loc="upper right")
            for ax in (ax_f, ax_e, ax_t):
                ax.grid(alpha=0.3)
    fig.suptitle(f"Walkthrough of papers 000/002, {walk['width']}x{walk['height']} headless, "
                 f"{walk['renderer']}", fontsize=10)
    fig.tight_layout()
    path = os.path.join(plots, "walkthrough.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    written.append(path)
elif walk:
    print(f"plot: walkthrough skipped: {walk.get('skipped', 'no models')}")

rd = load("rd.json")
# earlier protocols' series, kept in the tree: what the bytes were before
baselines = []
base_dir = os.path.join(os.path.dirname(os.path.abspath(__file__)), "baseline")
for fn in sorted(os.listdir(base_dir)) if os.path.isdir(base_dir) else []:
    if fn.startswith("rd_") and fn.endswith(".json"):
        try:
            with open(os.path.join(base_dir, fn)) as f:
                baselines.append((fn[3:-5], json.load(f).get("models", {})))
        except (OSError, ValueError) as e:
            print(f"plot: baseline {fn}: {e}")
for name, m in (rd or {}).get("models", {}).items():
    pts = m["points"]
    b = [p["bytes"] / 1e3 for p in pts]
    fig, ax = plt.subplots(figsize=(8, 5))
    ax.plot(b, [p["triangles"] for p in pts], "o-", ms=3, color="tab:blue",
            label="mts stream: triangles available")
    # older protocols fainter and dotted, the last release dashed
    styles = [(":" if k + 1 < len(baselines) else "--", 0.3 if k + 1 < len(baselines) else 0.5)
              for k in range(len(baselines))]
    for (label, bm), (ls, al) in zip(baselines, styles):
        if name in bm:
            bp = bm[name]["points"]
            ax.plot([p["bytes"] / 1e3 for p in bp], [p["triangles"] for p in bp], ls,
                    color="tab:blue", alpha=al, label=f"protocol {label}: triangles")
    d = m["draco"]
    ax.plot([d["bytes"] / 1e3], [d["triangles"]], "s", ms=9, color="tab:red",
            label=f"Draco single-rate (cl 7): {d['bytes'] / 1e3:.1f} KB")
    ax.set_xlabel("bytes received, KB (MODEL_INFO + BASE + batches)")
    ax.set_ylabel("triangles available", color="tab:blue")
    ax.grid(alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(b, [p["rms"] for p in pts], "o-", ms=3, color="tab:purple",
             label="mts stream: RMS error / bbox diagonal")
    for (label, bm), (ls, al) in zip(baselines, styles):
        if name in bm:
            bp = bm[name]["points"]
            ax2.plot([p["bytes"] / 1e3 for p in bp], [p["rms"] for p in bp], ls,
                     color="tab:purple", alpha=al, label=f"protocol {label}: RMS error")
    ax2.plot([d["bytes"] / 1e3], [max(d["rms"], 1e-9)], "D", ms=8, color="tab:red",
             mfc="none", label="Draco: error (quantization only)")
    ax2.set_yscale("log")
    ax2.set_ylabel("symmetric RMS distance / bbox diagonal", color="tab:purple")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=8, loc="center right")
    ax.set_title(f"{name}: rate-distortion of the stream ({m['full_triangles']} triangles, "
                 f"{m['batches']} batches)")
    fig.tight_layout()
    path = os.path.join(plots, f"rd_{name}.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    written.append(path)

for p in written:
    print(f"plot: wrote {p}")
