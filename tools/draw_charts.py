#!/usr/bin/env python3
"""Draw the charts of an aobake output's lightmap atlas: each chart (triangles
joined by shared lightmap vertices) filled in a colour of its own on black, one
PNG per lightmap image.

    python3 tools/draw_charts.py OUT.glb PNG [--eval-dir ../shared/tools/eval]

Reads the file with the independent checker's reader (`aoeval.load`, so it
needs that tool's Python environment: `../shared/tools/eval/setup.sh`). Prints
the image size and the number of charts drawn.
"""
import argparse
import os
import sys

import numpy as np
from PIL import Image, ImageDraw


def charts(tris):
    """Per triangle, its chart: union-find over shared vertex indices."""
    parent = np.arange(tris.max() + 1 if len(tris) else 0)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b, c in tris:
        ra, rb, rc = root(a), root(b), root(c)
        parent[rb] = ra
        parent[root(rc)] = ra
    return np.array([root(t[0]) for t in tris])


def colour(key):
    h = (int(key) * 2654435761) & 0xFFFFFFFF
    return (64 + (h & 0xBF), 64 + ((h >> 8) & 0xBF), 64 + ((h >> 16) & 0xBF))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("glb")
    ap.add_argument("png")
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--eval-dir", default=os.path.join(here, "..", "..", "shared", "tools", "eval"))
    a = ap.parse_args()
    sys.path.insert(0, a.eval_dir)
    import aoeval as ae

    errors, warnings = [], []
    _, _, baked, _ = ae.load(a.glb, errors, warnings)
    if errors:
        sys.exit("draw_charts: " + "; ".join(errors[:3]))
    images = {}
    for bk in baked:
        images.setdefault(bk.occ[3], []).append(bk)
    for k, (src, bks) in enumerate(sorted(images.items(), key=lambda e: str(e[0]))):
        h, w = bks[0].occ[0].shape[:2]
        img = Image.new("RGB", (w, h))
        draw = ImageDraw.Draw(img)
        count = 0
        for m, bk in enumerate(bks):
            of = charts(bk.tris)
            count += len(np.unique(of))
            pts = bk.uv[bk.tris] * np.array([w, h])
            for t, key in zip(pts, of):
                draw.polygon([tuple(p) for p in t], fill=colour(key * 131 + m))
        out = a.png if len(images) == 1 else a.png.replace(".png", f"-{k}.png")
        img.save(out)
        print(f"{out}: {w}x{h}, {count} charts")


if __name__ == "__main__":
    main()
