"""The GLB container for the tools that write glTF (test_scenes.py,
shrink_textures.py): one JSON chunk and one BIN chunk, each padded to 4
bytes (the JSON with spaces, the BIN with zeros), as the glTF 2.0 spec
lays them out. Standard library only.
"""
import json
import struct

JSON_CHUNK = 0x4E4F534A
BIN_CHUNK = 0x004E4942


def read_glb(path):
    """(the JSON document, the BIN chunk's bytes) of the GLB at `path`."""
    data = open(path, "rb").read()
    magic, version, _ = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        raise SystemExit(f"{path}: not a GLB 2.0 file")
    offset, doc, blob = 12, None, b""
    while offset < len(data):
        length, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8 : offset + 8 + length]
        if kind == JSON_CHUNK:
            doc = json.loads(chunk)
        elif kind == BIN_CHUNK:
            blob = chunk
        offset += 8 + length
    return doc, blob


def write_glb(path, doc, blob):
    """Writes `doc` (compact JSON) and `blob` as a GLB at `path`. The
    caller sets `buffers[0].byteLength`."""
    j = json.dumps(doc, separators=(",", ":")).encode()
    j += b" " * (-len(j) % 4)
    b = bytes(blob) + b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(j) + 8 + len(b)
    with open(path, "wb") as f:
        f.write(struct.pack("<4sII", b"glTF", 2, total))
        f.write(struct.pack("<II", len(j), JSON_CHUNK) + j)
        f.write(struct.pack("<II", len(b), BIN_CHUNK) + b)
