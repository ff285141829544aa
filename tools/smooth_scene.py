#!/usr/bin/env python3
"""A generated scene of large smooth charts: three smooth-shaded spheres and a
torus resting on a floor (positions and normals only; aobake unwraps it).

    python3 tools/smooth_scene.py OUT.glb

Issue 38's check that scenes with large smooth charts lose nothing to the
border fit (docs/measurements/engine-view-levers.md). No dependencies beyond the standard library.
"""
import json
import math
import struct

from toolargs import parser, path


def sphere(cx, cy, cz, r, nu=48, nv=24):
    pos, nrm, idx = [], [], []
    for j in range(nv + 1):
        v = math.pi * j / nv
        for i in range(nu + 1):
            u = 2 * math.pi * i / nu
            n = (math.sin(v) * math.cos(u), math.cos(v), math.sin(v) * math.sin(u))
            nrm.append(n)
            pos.append((cx + r * n[0], cy + r * n[1], cz + r * n[2]))
    for j in range(nv):
        for i in range(nu):
            a = j * (nu + 1) + i
            b = a + nu + 1
            idx += [a, a + 1, b, a + 1, b + 1, b]
    return pos, nrm, idx


def torus(cx, cy, cz, big, small, nu=64, nv=24):
    pos, nrm, idx = [], [], []
    for j in range(nv + 1):
        v = 2 * math.pi * j / nv
        for i in range(nu + 1):
            u = 2 * math.pi * i / nu
            n = (math.cos(v) * math.cos(u), math.sin(v), math.cos(v) * math.sin(u))
            c = (big * math.cos(u), 0.0, big * math.sin(u))
            nrm.append(n)
            pos.append((cx + c[0] + small * n[0], cy + small * n[1], cz + c[2] + small * n[2]))
    for j in range(nv):
        for i in range(nu):
            a = j * (nu + 1) + i
            b = a + nu + 1
            idx += [a, b, a + 1, a + 1, b, b + 1]
    return pos, nrm, idx


def floor(size):
    s = size
    pos = [(-s, 0, -s), (s, 0, -s), (s, 0, s), (-s, 0, s)]
    return pos, [(0, 1, 0)] * 4, [0, 2, 1, 0, 3, 2]


def main(out):
    parts = [
        floor(4.0),
        sphere(-1.2, 1.0, 0.0, 1.0),
        sphere(1.1, 0.6, 0.4, 0.6),
        sphere(0.2, 0.35, -1.3, 0.35),
        torus(0.3, 0.3, 1.6, 0.8, 0.3),
    ]
    blob = bytearray()
    views, accessors, meshes, nodes = [], [], [], []
    for k, (pos, nrm, idx) in enumerate(parts):
        prim = {}
        for name, data, fmt, typ in (
            ("POSITION", pos, "3f", "VEC3"),
            ("NORMAL", nrm, "3f", "VEC3"),
            ("indices", idx, "I", "SCALAR"),
        ):
            start = len(blob)
            flat = [c for p in data for c in (p if isinstance(p, tuple) else (p,))]
            blob += struct.pack("<%d%s" % (len(flat), fmt[-1]), *flat)
            while len(blob) % 4:
                blob += b"\0"
            views.append({"buffer": 0, "byteOffset": start, "byteLength": len(flat) * 4})
            acc = {
                "bufferView": len(views) - 1,
                "componentType": 5126 if fmt[-1] == "f" else 5125,
                "count": len(data),
                "type": typ,
            }
            if name == "POSITION":
                acc["min"] = [min(p[i] for p in pos) for i in range(3)]
                acc["max"] = [max(p[i] for p in pos) for i in range(3)]
            accessors.append(acc)
            if name == "indices":
                prim["indices"] = len(accessors) - 1
            else:
                prim.setdefault("attributes", {})[name] = len(accessors) - 1
        meshes.append({"primitives": [prim]})
        nodes.append({"mesh": k})
    doc = {
        "asset": {"version": "2.0", "generator": "aobake tools/smooth_scene.py"},
        "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes)))}],
        "nodes": nodes,
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": len(blob)}],
    }
    js = json.dumps(doc).encode()
    while len(js) % 4:
        js += b" "
    total = 12 + 8 + len(js) + 8 + len(blob)
    with open(out, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, total))
        f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
        f.write(struct.pack("<II", len(blob), 0x004E4942) + bytes(blob))


if __name__ == "__main__":
    ap = parser(__doc__)
    ap.add_argument("output", type=path, help="the GLB to write")
    main(ap.parse_args().output)
