#!/usr/bin/env python3
"""Copies a GLB with every embedded image scaled down to at most SIZE pixels
on its longer side, re-encoded in its own format (PNG stays PNG, with its
alpha; JPEG stays JPEG, so an RGB JPEG cut-out keeps its lost alpha). The
JSON, the geometry and every other buffer view keep their bytes; only the
views behind images shrink and the views after them move.

    python3 tools/shrink_textures.py IN.glb OUT.glb [--size 64] [--normal-size 512]

How the test scenes in assets/ were made from their sources (CREDITS.md):
aobake does not read textures, so its tests lose nothing, and a clone stays
small. Normal maps keep more (--normal-size): the importers' browser tests
check that they move the relit light. Needs Pillow (the checker's
environment has it).
"""
import io

from glb import read_glb, write_glb
from toolargs import parser, path
from PIL import Image


def shrink(blob, mime, size):
    image = Image.open(io.BytesIO(blob))
    image.load()
    scale = size / max(image.size)
    if scale < 1:
        new = (max(1, round(image.width * scale)), max(1, round(image.height * scale)))
        image = image.resize(new, Image.LANCZOS)
    out = io.BytesIO()
    if mime == "image/jpeg":
        image.convert("RGB").save(out, "JPEG", quality=85)
    else:
        image.save(out, "PNG", optimize=True)
    return out.getvalue()


def main():
    ap = parser(__doc__)
    ap.add_argument("input", type=path)
    ap.add_argument("output", type=path)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--normal-size", type=int, default=512)
    args = ap.parse_args()
    doc, blob = read_glb(args.input)
    views = doc.get("bufferViews", [])
    textures = doc.get("textures", [])
    normal_images = {
        textures[m["normalTexture"]["index"]].get("source")
        for m in doc.get("materials", [])
        if "normalTexture" in m
    }
    replaced = {}
    for i, image in enumerate(doc.get("images", [])):
        if "bufferView" in image:
            v = views[image["bufferView"]]
            start = v.get("byteOffset", 0)
            raw = blob[start : start + v["byteLength"]]
            size = args.normal_size if i in normal_images else args.size
            replaced[image["bufferView"]] = shrink(raw, image.get("mimeType", "image/png"), size)
    # Views keep their order and their offsets' alignment (8 bytes covers
    # every component type and the spec's 4-byte rule).
    out = b""
    for i, v in enumerate(views):
        if v.get("buffer", 0) != 0:
            continue
        start = v.get("byteOffset", 0)
        bytes_ = replaced.get(i, blob[start : start + v["byteLength"]])
        out += b"\0" * (-len(out) % 8)
        v["byteOffset"] = len(out)
        v["byteLength"] = len(bytes_)
        out += bytes_
    doc["buffers"][0]["byteLength"] = len(out)
    write_glb(args.output, doc, out)


if __name__ == "__main__":
    main()
