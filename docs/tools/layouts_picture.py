#!/usr/bin/env python3
"""Draws the map layouts haarlight reads (docs/CONVENTIONS.md, "Map
layouts") with the same sky in each: colour by direction (red towards +X,
green +Y, blue +Z, darker towards the opposite axes), a white grid every
30 degrees of longitude and latitude, and the axes named where they land.
Used for docs/img/layouts.png. Needs Pillow and numpy.

    layouts_picture.py OUT.png
"""
import sys

import numpy as np
from PIL import Image, ImageDraw

S = 96  # a cube face's side; the other layouts are sized to match


def colour(d):
    """Colour of unit directions d (..., 3), with the 30-degree grid."""
    c = 0.15 + 0.85 * np.clip(d, 0, 1) + 0.25 * np.clip(-d, 0, 1)[..., [1, 2, 0]]
    lon = np.degrees(np.arctan2(d[..., 2], d[..., 0]))
    lat = np.degrees(np.arcsin(np.clip(d[..., 1], -1, 1)))
    grid = (np.abs((lon + 15) % 30 - 15) < 0.6) | (np.abs((lat + 15) % 30 - 15) < 0.6)
    c[grid] = 1.0
    return (np.clip(c, 0, 1) * 255).astype(np.uint8)


def equirect():
    h, w = 2 * S, 4 * S
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    th, ph = np.pi * v, 2 * np.pi * (u - 0.5)
    d = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1)
    return colour(d)


def angular():
    n = 4 * S // 2 * 1  # the disc's diameter: as tall as the cross
    y, x = np.meshgrid((np.arange(n) + 0.5) / n, (np.arange(n) + 0.5) / n, indexing="ij")
    u, v = 2 * x - 1, 1 - 2 * y
    r = np.hypot(u, v)
    a = np.pi * np.minimum(r, 1)
    s = np.where(r > 0, np.sin(a) / np.maximum(r, 1e-9), 0)
    d = np.stack([np.cos(a), v * s, u * s], -1)
    img = colour(d)
    img[r > 1] = 40
    return img


FACES = {  # name: (centre, right, up)
    "+X": ((1, 0, 0), (0, 0, 1), (0, 1, 0)), "-Z": ((0, 0, -1), (1, 0, 0), (0, 1, 0)),
    "+Z": ((0, 0, 1), (-1, 0, 0), (0, 1, 0)), "-X": ((-1, 0, 0), (0, 0, -1), (0, 1, 0)),
    "+Y": ((0, 1, 0), (0, 0, 1), (-1, 0, 0)), "-Y": ((0, -1, 0), (0, 0, 1), (1, 0, 0)),
    "-X flipped": ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
}


def face(name):
    f, r, u = (np.array(x, float) for x in FACES[name])
    t, s = np.meshgrid(1 - 2 * (np.arange(S) + 0.5) / S, 2 * (np.arange(S) + 0.5) / S - 1, indexing="ij")
    d = f + s[..., None] * r + t[..., None] * u
    return colour(d / np.linalg.norm(d, axis=-1, keepdims=True))


def cross(cells, cols, rows):
    img = np.full((rows * S, cols * S, 3), 40, np.uint8)
    for name, (c, r) in cells.items():
        img[r * S:(r + 1) * S, c * S:(c + 1) * S] = face(name)
    return img


def label(draw, x, y, text):
    draw.text((x + 1, y + 1), text, fill=(0, 0, 0))
    draw.text((x, y), text, fill=(255, 255, 255))


def main():
    out = sys.argv[1]
    eq = equirect()
    ang = angular()
    ch = cross({"-Z": (0, 1), "+X": (1, 1), "+Z": (2, 1), "-X": (3, 1), "+Y": (1, 0), "-Y": (1, 2)}, 4, 3)
    cv = cross({"-Z": (0, 1), "+X": (1, 1), "+Z": (2, 1), "+Y": (1, 0), "-Y": (1, 2), "-X flipped": (1, 3)}, 3, 4)
    pad, top = 12, 22
    panels = [("equirectangular 2:1", eq), ("angular map 1:1", ang), ("horizontal cross 4:3", ch),
              ("vertical cross 3:4", cv)]
    width = sum(p.shape[1] for _, p in panels) + pad * (len(panels) + 1)
    height = max(p.shape[0] for _, p in panels) + top + pad
    canvas = Image.new("RGB", (width, height), (24, 24, 24))
    draw = ImageDraw.Draw(canvas)
    x = pad
    for title, p in panels:
        canvas.paste(Image.fromarray(p), (x, top))
        label(draw, x, 4, title)
        if p is eq:
            for name, u, v in (("+X", 0.5, 0.5), ("-X", 0.0, 0.5), ("+Z", 0.75, 0.5), ("-Z", 0.25, 0.5),
                               ("+Y (top row)", 0.38, 0.02), ("-Y (bottom row)", 0.36, 0.9)):
                label(draw, x + int(u * p.shape[1]) + 2, top + int(v * p.shape[0]), name)
        elif p is ang:
            n = p.shape[0]
            for name, u, v in (("+X", 0.5, 0.5), ("+Z", 0.8, 0.5), ("-Z", 0.12, 0.5), ("+Y", 0.5, 0.15),
                               ("-Y", 0.5, 0.82), ("-X (rim)", 0.02, 0.02)):
                label(draw, x + int(u * n), top + int(v * n), name)
        else:
            cells = ({"-Z": (0, 1), "+X": (1, 1), "+Z": (2, 1), "-X": (3, 1), "+Y": (1, 0), "-Y": (1, 2)}
                     if p is ch else
                     {"-Z": (0, 1), "+X": (1, 1), "+Z": (2, 1), "+Y": (1, 0), "-Y": (1, 2), "-X flipped": (1, 3)})
            for name, (c, r) in cells.items():
                label(draw, x + c * S + 4, top + r * S + 4, name.replace(" flipped", " (upside down)"))
        x += p.shape[1] + pad
    canvas.save(out)


if __name__ == "__main__":
    main()
