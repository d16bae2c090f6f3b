#!/usr/bin/env python3
"""Writes tests/data/cow_colors.ply: tests/data/cow.off with a smooth colour
per vertex, so that every part that carries vertex colours (reader, builder,
model file, stream, renderer) has a small coloured mesh to test on.

The colour is a function of position only, so a test can recompute it: a hue
running across x (red at the smallest x, through yellow, green and cyan, to
blue at the largest) and a value rising with height (y) from 0.45 to 1. Each
channel is written as uchar (0..255, sRGB), the form MeshLab, Blender and
Open3D write. The file is ASCII so that it diffs; the positions are the
OFF's own text, unchanged.

    python3 scripts/make_colored_mesh.py [IN.off [OUT.ply]]
"""
import colorsys
import sys


def read_off(path):
    words = []
    with open(path) as f:
        for line in f:
            line = line.split("#", 1)[0]
            words.extend(line.split())
    if words[0] != "OFF":
        raise SystemExit(f"{path}: not a plain OFF file")
    nv, nf = int(words[1]), int(words[2])
    at = 4
    verts = []
    for _ in range(nv):
        verts.append(words[at:at + 3])
        at += 3
    faces = []
    for _ in range(nf):
        n = int(words[at])
        faces.append(words[at + 1:at + 1 + n])
        at += 1 + n
    return verts, faces


def color(x, y, lo, hi):
    """The colour field: hue from x, value from y; 8-bit sRGB."""
    u = (x - lo[0]) / (hi[0] - lo[0]) if hi[0] > lo[0] else 0.0
    w = (y - lo[1]) / (hi[1] - lo[1]) if hi[1] > lo[1] else 0.0
    r, g, b = colorsys.hsv_to_rgb(0.66 * u, 0.85, 0.45 + 0.55 * w)
    return tuple(int(round(c * 255)) for c in (r, g, b))


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "tests/data/cow.off"
    dst = sys.argv[2] if len(sys.argv) > 2 else "tests/data/cow_colors.ply"
    verts, faces = read_off(src)
    pts = [[float(c) for c in v] for v in verts]
    lo = [min(p[a] for p in pts) for a in range(3)]
    hi = [max(p[a] for p in pts) for a in range(3)]
    with open(dst, "w", newline="\n") as f:
        f.write("ply\nformat ascii 1.0\n")
        f.write("comment tests/data/cow.off with a colour per vertex: "
                "hue across x, value up y (scripts/make_colored_mesh.py)\n")
        f.write(f"element vertex {len(verts)}\n")
        f.write("property float x\nproperty float y\nproperty float z\n")
        f.write("property uchar red\nproperty uchar green\nproperty uchar blue\n")
        f.write(f"element face {len(faces)}\n")
        f.write("property list uchar int vertex_indices\nend_header\n")
        for v, p in zip(verts, pts):
            r, g, b = color(p[0], p[1], lo, hi)
            f.write(f"{v[0]} {v[1]} {v[2]} {r} {g} {b}\n")
        for face in faces:
            f.write(f"{len(face)} {' '.join(face)}\n")


if __name__ == "__main__":
    main()
