"""Traces the rays dumped by `cargo run --release --example bench -- SCENE --dump-rays DIR`
with Embree (pip install embreex numpy), on 2 threads, as occlusion queries.

Usage: python3 tools/embree_compare.py DIR [threads]
Prints rays/s and how many rays are occluded (compare with the bench's obvhs line).
"""
import threading
import time

from toolargs import parser, path

ap = parser(__doc__)
ap.add_argument('dir', type=path, help='the folder of --dump-rays')
ap.add_argument('threads', nargs='?', type=int, default=2, help='Embree threads (default 2)')
args = ap.parse_args()

import numpy as np  # noqa: E402 (after the arguments, so --help needs no Embree)
from embreex import rtcore_scene as rtcs  # noqa: E402
from embreex.mesh_construction import TriangleMesh  # noqa: E402

d, threads = args.dir, args.threads
tris = np.fromfile(f"{d}/tris.f32", dtype=np.float32).reshape(-1, 3, 3)
rays = np.fromfile(f"{d}/rays.f32", dtype=np.float32).reshape(-1, 10)
t = time.perf_counter()
scene = rtcs.EmbreeScene()
TriangleMesh(scene, tris)
origins = np.ascontiguousarray(rays[:, 0:3])
dirs = np.ascontiguousarray(rays[:, 3:6])
dists = np.ascontiguousarray(rays[:, 6])
scene.run(origins[:1], dirs[:1], dists=dists[:1], query="OCCLUDED")  # commit/build
build = time.perf_counter() - t

parts = np.array_split(np.arange(len(rays)), threads)
results = [None] * threads


def work(k):
    idx = parts[k]
    results[k] = scene.run(origins[idx], dirs[idx], dists=dists[idx], query="OCCLUDED")


def run():
    ts = [threading.Thread(target=work, args=(k,)) for k in range(threads)]
    t0 = time.perf_counter()
    for x in ts:
        x.start()
    for x in ts:
        x.join()
    return time.perf_counter() - t0


run()  # warm
secs = run()
occluded = sum(int(np.count_nonzero(np.asarray(r) != -1)) for r in results)
hit = np.concatenate([np.asarray(r) != -1 for r in results])
below = (rays[:, 3:6] * rays[:, 7:10]).sum(axis=1) <= 0
print(f"occluded with the horizon rule (as baked): {int(np.count_nonzero(hit | below))} of {len(rays)}")
try:
    ours = np.fromfile(f"{d}/occluded_obvhs.u8", dtype=np.uint8).astype(bool)
    print(f"rays where embree and aobake disagree: {int(np.count_nonzero(ours != (hit | below)))}")
except FileNotFoundError:
    pass
print(f"embree: {len(rays)} rays, {occluded} occluded, {secs:.3f} s, {len(rays) / secs / 1e6:.2f} Mrays/s ({threads} threads), build+commit {build:.3f} s")
