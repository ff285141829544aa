#!/usr/bin/env python3
"""Writes the generated test scenes of assets/generated/ (byte-for-byte the
same on every run: tests/assets.rs checks the committed files against it).

    python3 tools/test_scenes.py OUT_DIR

They stand in for shared scenes whose licenses keep them out of the
repository, each with the property its test needs:

- courtyard.glb: for Dabrovic Sponza. An open courtyard with a two-storey
  colonnade (smooth columns on plinths under capitals, arches, a gallery
  floor), walls and a floor: 24 meshes with TEXCOORD_0 and no TEXCOORD_1,
  contact lines at every foot and capital, smooth surfaces cut into many
  charts, so that a small page size spreads one surface over several pages.
- cad_instances.glb: for the 2CylinderEngine: CAD scale (millimetres,
  about 700 units across), 77 nodes in a hierarchy with rotations and
  scales, 24 meshes of which 12 are referenced by several nodes, positions
  and normals only.
- dense_detail.glb: for the city diorama: one mesh of 24 primitives and
  about 46,000 triangles of small boxes and pipes, no UVs at all, every
  material double-sided and one BLEND.
- gpu_instancing.glb: one mesh drawn only through EXT_mesh_gpu_instancing
  (ten instances), which aobake refuses.

No dependencies beyond the standard library.
"""
import math
import os
import struct

from glb import write_glb
from toolargs import parser, path


class Mesh:
    """Triangles with normals and, optionally, TEXCOORD_0."""

    def __init__(self):
        self.pos, self.nrm, self.uv, self.idx = [], [], [], []

    def add(self, pos, nrm, uv, idx):
        base = len(self.pos)
        self.pos += pos
        self.nrm += nrm
        self.uv += uv
        self.idx += [base + i for i in idx]
        return self


def box(c, h):
    """Axis-aligned box at centre c with half sizes h, flat faces, UVs in
    world units."""
    m = Mesh()
    for axis in range(3):
        for sign in (-1, 1):
            u, v = [(a) for a in range(3) if a != axis]
            pos, nrm, uv = [], [], []
            for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                p = [0.0, 0.0, 0.0]
                p[axis] = c[axis] + sign * h[axis]
                p[u] = c[u] + su * h[u]
                p[v] = c[v] + sv * h[v]
                pos.append(tuple(p))
                n = [0.0, 0.0, 0.0]
                n[axis] = float(sign)
                nrm.append(tuple(n))
                uv.append((p[u], p[v]))
            # Counter-clockwise seen from outside: u x v is +x, -y, +z.
            outward = sign * (-1 if axis == 1 else 1) > 0
            idx = [0, 1, 2, 0, 2, 3] if outward else [0, 2, 1, 0, 3, 2]
            m.add(pos, nrm, uv, idx)
    return m


def grid(rows, cols):
    """Two triangles per cell of a (rows + 1) x (cols + 1) vertex grid,
    row-major, counter-clockwise with u along a row and v across rows."""
    idx = []
    for j in range(rows):
        for i in range(cols):
            a = j * (cols + 1) + i
            b = a + cols + 1
            idx += [a, b, a + 1, a + 1, b, b + 1]
    return idx


def cylinder(base, r, height, seg=32, rings=8):
    """A smooth-shaded open cylinder standing on `base`."""
    m = Mesh()
    pos, nrm, uv = [], [], []
    for j in range(rings + 1):
        y = base[1] + height * j / rings
        for i in range(seg + 1):
            a = 2 * math.pi * i / seg
            n = (math.cos(a), 0.0, math.sin(a))
            pos.append((base[0] + r * n[0], y, base[2] + r * n[2]))
            nrm.append(n)
            uv.append((r * a, y))
    return m.add(pos, nrm, uv, grid(rings, seg))


def arch(cx, cy, z0, z1, r_in, r_out, seg=24):
    """A half-annulus arch in the x-y plane from z0 to z1: its smooth
    intrados (underside), its extrados and two flat faces."""
    m = Mesh()
    # Intrados and extrados: smooth, normals toward the opening and away.
    for r, s in ((r_in, -1.0), (r_out, 1.0)):
        pos, nrm, uv, idx = [], [], [], []
        for i in range(seg + 1):
            a = math.pi * i / seg
            n = (math.cos(a) * s, math.sin(a) * s, 0.0)
            for z in (z0, z1):
                pos.append((cx + r * math.cos(a), cy + r * math.sin(a), z))
                nrm.append(n)
                uv.append((r * a, z))
        for i in range(seg):
            a, b = 2 * i, 2 * i + 2
            idx += [a, a + 1, b, a + 1, b + 1, b] if s < 0 else [a, b, a + 1, a + 1, b, b + 1]
        m.add(pos, nrm, uv, idx)
    # Front and back: flat rings.
    for z, s in ((z0, -1.0), (z1, 1.0)):
        pos, nrm, uv, idx = [], [], [], []
        for i in range(seg + 1):
            a = math.pi * i / seg
            for r in (r_in, r_out):
                pos.append((cx + r * math.cos(a), cy + r * math.sin(a), z))
                nrm.append((0.0, 0.0, s))
                uv.append((pos[-1][0], pos[-1][1]))
        for i in range(seg):
            a, b = 2 * i, 2 * i + 2
            idx += [a, b, a + 1, a + 1, b, b + 1] if s < 0 else [a, a + 1, b, a + 1, b + 1, b]
        m.add(pos, nrm, uv, idx)
    return m


def torus(r_major, r_minor, seg=24, sides=12):
    m = Mesh()
    pos, nrm, uv = [], [], []
    for j in range(sides + 1):
        b = 2 * math.pi * j / sides
        for i in range(seg + 1):
            a = 2 * math.pi * i / seg
            n = (math.cos(a) * math.cos(b), math.sin(b), math.sin(a) * math.cos(b))
            c = (r_major * math.cos(a), 0.0, r_major * math.sin(a))
            pos.append((c[0] + r_minor * n[0], c[1] + r_minor * n[1], c[2] + r_minor * n[2]))
            nrm.append(n)
            uv.append((i / seg, j / sides))
    return m.add(pos, nrm, uv, grid(sides, seg))


def merged(parts):
    m = Mesh()
    for p in parts:
        m.add(p.pos, p.nrm, p.uv, p.idx)
    return m


class Glb:
    """A GLB writer: one buffer, a view per accessor, 4-byte aligned."""

    def __init__(self):
        self.doc = {"asset": {"version": "2.0", "generator": "aobake tools/test_scenes.py"},
                    "scene": 0, "scenes": [{"nodes": []}], "nodes": [], "meshes": [],
                    "materials": [], "accessors": [], "bufferViews": [],
                    "buffers": [{"byteLength": 0}]}
        self.bin = bytearray()

    def accessor(self, fmt, rows, kind, ctype, target, minmax=False):
        while len(self.bin) % 4:
            self.bin.append(0)
        start = len(self.bin)
        for r in rows:
            self.bin += struct.pack(fmt, *(r if isinstance(r, tuple) else (r,)))
        view = {"buffer": 0, "byteOffset": start, "byteLength": len(self.bin) - start}
        if target:
            view["target"] = target
        self.doc["bufferViews"].append(view)
        acc = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": ctype,
               "count": len(rows), "type": kind}
        if minmax:
            acc["min"] = [min(r[k] for r in rows) for k in range(3)]
            acc["max"] = [max(r[k] for r in rows) for k in range(3)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, name, **extra):
        mat = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0]}}
        mat.update(extra)
        self.doc["materials"].append(mat)
        return len(self.doc["materials"]) - 1

    def primitive(self, m, material, uv=True):
        # Rounded, so that a last-bit difference of one libm's sin from
        # another's does not change the file.
        def r6(rows):
            return [tuple(round(x, 6) + 0.0 for x in row) for row in rows]
        attrs = {"POSITION": self.accessor("<3f", r6(m.pos), "VEC3", 5126, 34962, minmax=True),
                 "NORMAL": self.accessor("<3f", r6(m.nrm), "VEC3", 5126, 34962)}
        if uv:
            attrs["TEXCOORD_0"] = self.accessor("<2f", r6(m.uv), "VEC2", 5126, 34962)
        big = len(m.pos) > 65535
        ind = self.accessor("<I" if big else "<H", m.idx, "SCALAR", 5125 if big else 5123, 34963)
        return {"attributes": attrs, "indices": ind, "material": material}

    def mesh(self, name, prims):
        self.doc["meshes"].append({"name": name, "primitives": prims})
        return len(self.doc["meshes"]) - 1

    def node(self, root=True, **fields):
        self.doc["nodes"].append(fields)
        n = len(self.doc["nodes"]) - 1
        if root:
            self.doc["scenes"][0]["nodes"].append(n)
        return n

    def write(self, path):
        while len(self.bin) % 4:
            self.bin.append(0)
        self.doc["buffers"][0]["byteLength"] = len(self.bin)
        write_glb(path, self.doc, self.bin)


def courtyard(path):
    g = Glb()
    stone = g.material("stone")
    parts = []
    # Floor 24 x 14, walls 8 high around it.
    parts.append(("floor", box((0, -0.1, 0), (12, 0.1, 7))))
    parts.append(("wall_north", box((0, 4, -7.2), (12.4, 4, 0.2))))
    parts.append(("wall_south", box((0, 4, 7.2), (12.4, 4, 0.2))))
    parts.append(("wall_east", box((12.2, 4, 0), (0.2, 4, 7))))
    parts.append(("wall_west", box((-12.2, 4, 0), (0.2, 4, 7))))
    # Two colonnades (z = -4 and z = 4) of 7 columns each, both storeys.
    for side, z in (("north", -4.5), ("south", 4.5)):
        shafts, plinths, capitals, arches = [], [], [], []
        for storey, (y0, h) in enumerate(((0.0, 2.4), (4.0, 2.4))):
            r = 0.32 if storey == 0 else 0.24
            for k in range(7):
                x = -9 + 3 * k
                plinths.append(box((x, y0 + 0.15, z), (r + 0.15, 0.15, r + 0.15)))
                shafts.append(cylinder((x, y0 + 0.3, z), r, h - 0.6))
                capitals.append(box((x, y0 + h - 0.15, z), (r + 0.2, 0.15, r + 0.2)))
                if k < 6:
                    arches.append(arch(x + 1.5, y0 + h, z - 0.3, z + 0.3, 1.5 - r - 0.2, 1.5 - r + 0.15))
        parts.append((f"columns_{side}", merged(shafts)))
        parts.append((f"plinths_{side}", merged(plinths)))
        parts.append((f"capitals_{side}", merged(capitals)))
        parts.append((f"arches_{side}", merged(arches)))
        # The gallery floor between the storeys, from the colonnade to the wall.
        zc = (z + (-7 if z < 0 else 7)) / 2
        parts.append((f"gallery_{side}", box((0, 4.0 - 0.12, zc), (10.5, 0.12, abs(z - zc) + 0.4))))
        parts.append((f"parapet_{side}", box((0, 4.0 + 0.45, z + (0.3 if z < 0 else -0.3)), (10.5, 0.45, 0.08))))
    # A fountain in the middle: a ring basin on a drum, and four benches.
    ring = torus(1.2, 0.22, seg=48, sides=16)
    ring.pos = [(x, y + 0.55, z) for x, y, z in ring.pos]
    parts.append(("fountain_ring", ring))
    parts.append(("fountain_drum", cylinder((0, 0, 0), 1.0, 0.55, seg=48, rings=4)))
    parts.append(("fountain_spout", cylinder((0, 0, 0), 0.15, 1.6, seg=16, rings=4)))
    for k, (x, zb) in enumerate(((-5, -1.5), (5, -1.5), (-5, 1.5), (5, 1.5))):
        parts.append((f"bench_{k}", merged([box((x, 0.45, zb), (1.2, 0.06, 0.3)),
                                             box((x - 1.0, 0.2, zb), (0.08, 0.2, 0.25)),
                                             box((x + 1.0, 0.2, zb), (0.08, 0.2, 0.25))])))
    for name, m in parts:
        mesh = g.mesh(name, [g.primitive(m, stone)])
        g.node(name=name, mesh=mesh)
    g.write(path)


def quat(axis, angle):
    s = math.sin(angle / 2)
    return [round(axis[0] * s, 6), round(axis[1] * s, 6), round(axis[2] * s, 6), round(math.cos(angle / 2), 6)]


def cad_instances(path):
    g = Glb()
    steel = g.material("steel")
    meshes = []
    # 24 parts in millimetres: bolts, rings, blocks, shafts and plates.
    for k in range(24):
        kind = k % 4
        if kind == 0:
            m = merged([cylinder((0, 0, 0), 6 + k % 3, 30 + 2 * k, seg=16, rings=2),
                        box((0, 3, 0), (10, 3, 10))])
        elif kind == 1:
            m = torus(20 + k, 4 + k % 5, seg=32, sides=10)
        elif kind == 2:
            m = merged([box((0, 0, 0), (40 + k, 25, 30)), box((0, 30, 0), (20, 5, 20))])
        else:
            m = cylinder((0, -60, 0), 12, 120 + k, seg=24, rings=6)
        meshes.append(g.mesh(f"part_{k}", [g.primitive(m, steel, uv=False)]))
    # An engine block frame with two banks of assemblies; parts 0-11 repeat.
    root = g.node(name="engine", scale=[1.0, 1.0, 1.0], children=[])
    children = []
    for bank in range(2):
        b = g.node(root=False, name=f"bank_{bank}", translation=[-300.0 + 600.0 * bank, 0.0, 0.0],
                   rotation=quat((0, 0, 1), (0.3 if bank else -0.3)), children=[])
        children.append(b)
        bank_children = []
        for a in range(6):
            asm = g.node(root=False, name=f"assembly_{bank}_{a}",
                         translation=[0.0, 0.0, -125.0 + 50.0 * a],
                         rotation=quat((1, 0, 0), 0.2 * a), children=[])
            bank_children.append(asm)
            kids = []
            for p in range(5):
                mesh = meshes[(a * 2 + p) % 12] if p < 3 else meshes[12 + (bank * 6 + a + p) % 12]
                kids.append(g.node(root=False, name=f"part_{bank}_{a}_{p}", mesh=mesh,
                                   translation=[0.0, 40.0 * p - 80.0, 0.0],
                                   scale=[1.0 + 0.1 * (p % 2), 1.0, 1.0]))
            g.doc["nodes"][asm]["children"] = kids
        g.doc["nodes"][b]["children"] = bank_children
    # The crankshaft and the flywheel, straight under the root.
    children.append(g.node(root=False, name="crankshaft", mesh=meshes[3],
                           rotation=quat((0, 0, 1), math.pi / 2), scale=[1.0, 5.5, 1.0]))
    children.append(g.node(root=False, name="flywheel", mesh=meshes[5],
                           translation=[0.0, -120.0, 0.0], rotation=quat((0, 0, 1), math.pi / 2),
                           scale=[3.0, 3.0, 3.0]))
    g.doc["nodes"][root]["children"] = children
    g.write(path)


def dense_detail(path):
    g = Glb()
    prims = []
    for p in range(24):
        mat = g.material(f"detail_{p}", doubleSided=True)
        if p == 23:
            g.doc["materials"][mat]["alphaMode"] = "BLEND"
            g.doc["materials"][mat]["pbrMetallicRoughness"]["baseColorFactor"] = [0.6, 0.7, 0.9, 0.4]
        parts = []
        # A block of the diorama: a tower of greebles and pipes on a slab.
        ox, oz = (p % 6) * 1.0 - 2.5, (p // 6) * 1.0 - 1.5
        parts.append(box((ox, 0.02, oz), (0.48, 0.02, 0.48)))
        for k in range(60):
            a = (p * 61 + k * 37) % 97 / 97.0
            b = (p * 17 + k * 53) % 89 / 89.0
            c = (p * 29 + k * 11) % 83 / 83.0
            x, z = ox - 0.4 + 0.8 * a, oz - 0.4 + 0.8 * b
            if k % 3 == 2:
                parts.append(cylinder((x, 0.04, z), 0.015 + 0.02 * c, 0.1 + 0.5 * a, seg=12, rings=3))
            else:
                parts.append(box((x, 0.04 + 0.05 * c, z), (0.02 + 0.05 * b, 0.05 * c + 0.01, 0.02 + 0.04 * a)))
        prims.append(g.primitive(merged(parts), mat, uv=False))
    g.node(name="diorama", mesh=g.mesh("diorama", prims))
    g.write(path)


def gpu_instancing(path):
    g = Glb()
    mesh = g.mesh("crate", [g.primitive(box((0, 0, 0), (0.5, 0.5, 0.5)), g.material("crate"), uv=False)])
    t = g.accessor("<3f", [(1.5 * k, 0.0, 0.0) for k in range(10)], "VEC3", 5126, None)
    g.node(name="crates", mesh=mesh, extensions={"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": t}}})
    g.doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    g.doc["extensionsRequired"] = ["EXT_mesh_gpu_instancing"]
    g.write(path)


def main():
    ap = parser(__doc__)
    ap.add_argument("out_dir", nargs="?", default="assets/generated", type=path,
                    help="the folder to write them in (default: assets/generated)")
    out = ap.parse_args().out_dir
    os.makedirs(out, exist_ok=True)
    courtyard(os.path.join(out, "courtyard.glb"))
    cad_instances(os.path.join(out, "cad_instances.glb"))
    dense_detail(os.path.join(out, "dense_detail.glb"))
    gpu_instancing(os.path.join(out, "gpu_instancing.glb"))


if __name__ == "__main__":
    main()
