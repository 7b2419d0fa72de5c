#!/usr/bin/env python3
"""Writes textured_box.gltf and textured_box.png (made here, for the
viewer's textured case and anyone trying textures): a box 2 x 1.5 x 1.2
standing on y = 0, each face its own four vertices with UVs over the whole
texture, and an 8 x 8 texture of two colours in a checker with a red
corner at the top left, so that a flipped or mirrored texture shows."""
import base64, json, struct, zlib

W = H = 8
rows = []
for y in range(H):
    r = b'\x00'  # PNG filter: none
    for x in range(W):
        if x < 2 and y < 2: c = (230, 40, 30)
        elif (x // 2 + y // 2) % 2: c = (40, 90, 220)
        else: c = (235, 225, 120)
        r += bytes(c)
    rows.append(r)


def chunk(t, d):
    return struct.pack('>I', len(d)) + t + d + struct.pack('>I', zlib.crc32(t + d) & 0xffffffff)


png = (b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', W, H, 8, 2, 0, 0, 0)) +
       chunk(b'IDAT', zlib.compress(b''.join(rows), 9)) + chunk(b'IEND', b''))
open('textured_box.png', 'wb').write(png)

# (normal, u axis, v axis) of each face
faces = [((1, 0, 0), (0, 0, -1), (0, 1, 0)), ((-1, 0, 0), (0, 0, 1), (0, 1, 0)), ((0, 1, 0), (1, 0, 0), (0, 0, -1)),
         ((0, -1, 0), (1, 0, 0), (0, 0, 1)), ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
half, centre = (1.0, 0.75, 0.6), (0, 0.75, 0)
pos, uv, idx = [], [], []
for n, u, v in faces:
    base = len(pos)
    for (a, b), (tu, tv) in zip([(-1, -1), (1, -1), (1, 1), (-1, 1)], [(0, 0), (1, 0), (1, 1), (0, 1)]):
        pos.append([centre[k] + half[k] * (n[k] + a * u[k] + b * v[k]) for k in range(3)])
        uv.append((tu, 1 - tv))  # glTF: v = 0 at the image's top
    idx += [base, base + 1, base + 2, base, base + 2, base + 3]
pb = b''.join(struct.pack('<3f', *p) for p in pos)
ub = b''.join(struct.pack('<2f', *t) for t in uv)
ib = b''.join(struct.pack('<I', i) for i in idx)
buf = pb + ub + ib
lo = [min(p[k] for p in pos) for k in range(3)]
hi = [max(p[k] for p in pos) for k in range(3)]
g = {"asset": {"version": "2.0", "generator": "haarlight tests: a textured box (tests/data/README.md)"},
     "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
     "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
     "materials": [{"name": "checker", "pbrMetallicRoughness": {"baseColorFactor": [1, 0.9, 0.8, 1],
                                                               "baseColorTexture": {"index": 0}}}],
     "textures": [{"source": 0, "sampler": 0}], "samplers": [{"magFilter": 9729, "minFilter": 9729}],
     "images": [{"uri": "textured_box.png"}],
     "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3", "min": lo, "max": hi},
                   {"bufferView": 1, "componentType": 5126, "count": len(uv), "type": "VEC2"},
                   {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
     "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pb)},
                     {"buffer": 0, "byteOffset": len(pb), "byteLength": len(ub)},
                     {"buffer": 0, "byteOffset": len(pb) + len(ub), "byteLength": len(ib)}],
     "buffers": [{"byteLength": len(buf),
                  "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}]}
open('textured_box.gltf', 'w').write(json.dumps(g, indent=1) + "\n")
