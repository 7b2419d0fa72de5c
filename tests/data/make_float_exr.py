#!/usr/bin/env python3
"""Writes the small float OpenEXR fixtures of hl.env.float_files with an
OpenEXR writer other than haarlight's own (PyPI's OpenEXR module:
`pip install OpenEXR`). Not run by the tests; the files are committed.

Each is a 32 x 16 map of 32-bit float R, G, B, ZIP-compressed:
  pixel (x, y) = (x + 32 y) * 0.001234567 * (1, 2, 3), computed in double
  and rounded to float, except pixel (20, 10), a sun beyond the half-float
  range: (1e5, 2e5, 3e5).
  float_scanline_sun.exr  scanline
  float_tiled_sun.exr     tiled, 16 x 16 tiles
  float_tiled.exr         tiled, the sun at (3e4, 2e4, 1e4) (within half)
"""
import numpy as np
import OpenEXR

W, H = 32, 16


def pixels(sun):
    y, x = np.mgrid[0:H, 0:W]
    base = (x + 32.0 * y) * 0.001234567
    rgb = np.stack([base * k for k in (1.0, 2.0, 3.0)], axis=-1).astype(np.float32)
    rgb[10, 20, :] = sun
    return rgb


def write(name, rgb, tiled):
    header = {"compression": OpenEXR.ZIP_COMPRESSION}
    if tiled:
        header["type"] = OpenEXR.tiledimage
        tiles = OpenEXR.TileDescription()
        tiles.xSize, tiles.ySize, tiles.mode = 16, 16, OpenEXR.ONE_LEVEL
        header["tiles"] = tiles
    else:
        header["type"] = OpenEXR.scanlineimage
    channels = {c: np.ascontiguousarray(rgb[:, :, k]) for k, c in enumerate("RGB")}
    OpenEXR.File(header, channels).write(name)


write("float_scanline_sun.exr", pixels((1e5, 2e5, 3e5)), False)
write("float_tiled_sun.exr", pixels((1e5, 2e5, 3e5)), True)
write("float_tiled.exr", pixels((3e4, 2e4, 1e4)), True)
