#!/usr/bin/env python3
"""A level of N copies of a scene side by side, for scaling benchmarks
(issue 38: the post-bake stage on 16 copies of Sponza).

    python3 tools/repeat_level.py IN.glb OUT.glb [N 16]

Each copy is the scene's root nodes (with their subtrees duplicated, the
meshes shared) under a parent translated on a grid of ceil(sqrt(N))
columns, spaced 1.2x the scene's largest extent (from the POSITION
accessors' min/max, transforms ignored). Buffers are unchanged."""
import json, math, struct

from toolargs import parser, path

ap = parser(__doc__)
ap.add_argument('input', type=path, help='the scene to copy')
ap.add_argument('output', type=path, help='the level to write')
ap.add_argument('n', nargs='?', type=int, default=16, help='how many copies (default 16)')
args = ap.parse_args()
src, dst, n = args.input, args.output, args.n
data = open(src, 'rb').read()
magic, version, length = struct.unpack_from('<III', data, 0)
assert magic == 0x46546C67, 'not a GLB'
jlen, jtype = struct.unpack_from('<II', data, 12)
doc = json.loads(data[20:20 + jlen])
rest = data[20 + jlen:]
lo, hi = [math.inf] * 3, [-math.inf] * 3
for m in doc.get('meshes', []):
    for p in m['primitives']:
        a = doc['accessors'][p['attributes']['POSITION']]
        for k in range(3):
            lo[k] = min(lo[k], a['min'][k]); hi[k] = max(hi[k], a['max'][k])
step = 1.2 * max(hi[k] - lo[k] for k in range(3))
nodes = doc['nodes']
scene = doc['scenes'][doc.get('scene', 0)]
roots = list(scene['nodes'])

def copy(i):
    node = dict(nodes[i])
    if 'children' in node:
        node['children'] = [copy(c) for c in node['children']]
    nodes.append(node)
    return len(nodes) - 1

cols = math.ceil(math.sqrt(n))
parents = []
for c in range(n):
    kids = roots if c == 0 else [copy(r) for r in roots]
    nodes.append({'name': f'copy {c}', 'translation': [step * (c % cols), 0.0, step * (c // cols)], 'children': kids})
    parents.append(len(nodes) - 1)
scene['nodes'] = parents
j = json.dumps(doc, separators=(',', ':')).encode()
j += b' ' * ((4 - len(j) % 4) % 4)
out = struct.pack('<III', magic, version, 12 + 8 + len(j) + len(rest)) + struct.pack('<II', len(j), 0x4E4F534A) + j + rest
open(dst, 'wb').write(out)
print(f'{n} copies, step {step:.3f}, {len(nodes)} nodes')
