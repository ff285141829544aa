#!/usr/bin/env python3
"""The project's engine view against the independent checker on the same points.

Reads the CSV of `probes/engine_view_points` (the project's points, reference and lookups) and the GLB of the same
bake, and splits the difference of the two figures into its parts: the checker's lookups of the written textures at
the same UVs, and the checker's Embree reference at the same points with its own origin offset (1e-4 of the scene's
diagonal) and with the project's.

    python3 tools/engine_view_compare.py POINTS.csv OUT.glb [RAYS]
"""
import os
import sys

from toolargs import parser, path

import numpy as np

EVAL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "tools", "eval")
sys.path.insert(0, EVAL)
import aoeval as ae  # noqa: E402
from seamcheck import bilinear, layers  # noqa: E402


def rmse(e):
    return float(np.sqrt(np.mean(e ** 2)))


def main():
    ap = parser(__doc__)
    ap.add_argument("points", type=path, help="the CSV of probes/engine_view_points")
    ap.add_argument("glb", type=path, help="the GLB of the same bake")
    ap.add_argument("rays", nargs="?", type=int, default=2048, help="reference rays a point (default 2048)")
    args = ap.parse_args()
    csv, glb, rays = args.points, args.glb, args.rays
    d = np.genfromtxt(csv, delimiter=",", names=True)
    X = np.c_[d["x"], d["y"], d["z"]]
    N = np.c_[d["nx"], d["ny"], d["nz"]]
    G = np.c_[d["gx"], d["gy"], d["gz"]]
    uv = np.c_[d["u"], d["v"]]
    keep = d["inside"] == 0
    cls = d["class"]
    errors, warnings = [], []
    g, tri_world, baked, dist = ae.load(glb, errors, warnings)
    allv = tri_world.reshape(-1, 3)
    diag = float(np.linalg.norm(allv.max(0) - allv.min(0)))
    look = bilinear(layers(baked[0]), uv)[:, 0]
    scene = ae.build_scene(tri_world)
    print(f"{len(X)} points, {int((~keep).sum())} inside (left out); diagonal {diag:.4g}; project offset "
          f"median {np.median(d['offset']):.3g} ({np.median(d['offset']) / diag:.2g} of the diagonal)")
    out = {"project": (d["lookup_ao"], d["ref_ao"])}
    offsets = [("checker offset 1e-4 diag", 1e-4 * diag)]
    offsets += [(f"offset {f:g} diag", f * diag) for f in (3e-5, 1e-5, 1e-6)]
    offsets += [("project offset", float(np.median(d["offset"])))]
    for name, eps in offsets:
        ref, _, var, _ = ae.reference(scene, X, N, G, eps, dist, rays, 0, os.cpu_count() or 1)
        out[name] = (look, ref)
        print(f"  reference {name}: mean AO {ref[keep].mean():.4f}, SE {np.sqrt(var[keep].mean()):.4f}")
    print(f"  lookups: project vs checker at the same UVs: max |diff| {np.abs(look - d['lookup_ao'])[keep].max():.4f}")
    for name, (lk, ref) in out.items():
        e = (lk - ref)[keep]
        c = cls[keep]
        print(f"  {name:28s} AO RMSE all {rmse(e):.4f} interior {rmse(e[c == 0]):.4f} border {rmse(e[c > 0]):.4f}"
              f" bias {e.mean():+.4f}")
    diff = (out["project"][1] - out["checker offset 1e-4 diag"][1])[keep]
    print(f"  project reference - checker reference: mean {diff.mean():+.4f}, RMS {rmse(diff):.4f}")


if __name__ == "__main__":
    main()
