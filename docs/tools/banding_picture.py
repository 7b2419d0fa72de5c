#!/usr/bin/env python3
"""Puts two renders of the same ground crop side by side, as rendered
(top) and with their contrast raised (bottom), so that contour bands
show plainly. Used for docs/img/banding-sunrise.png (docs/ACCURACY.md says
how the renders are made). Needs Pillow and numpy (pip install pillow numpy).

    banding_picture.py BEFORE.png AFTER.png OUT.png [GAIN]

GAIN (default 6) multiplies each pixel's difference from a 31-pixel box
blur of the same image, so smooth shading stays grey and steps stand out;
the same gain is used for both images.
"""
import sys

import numpy as np
from PIL import Image, ImageDraw


def box_blur(a, r):
    """Mean over a (2r+1)^2 box, edges clamped, per channel."""
    p = np.pad(a, ((r, r), (r, r), (0, 0)), mode="edge")
    c = p.cumsum(0).cumsum(1)
    c = np.pad(c, ((1, 0), (1, 0), (0, 0)))
    n = 2 * r + 1
    s = c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]
    return s / (n * n)


def raised(a, gain):
    return np.clip(128.0 + gain * (a - box_blur(a, 15)), 0, 255)


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    before, after = (np.asarray(Image.open(p).convert("RGB"), dtype=np.float64) for p in sys.argv[1:3])
    if before.shape != after.shape:
        sys.exit("the two images differ in size")
    gain = float(sys.argv[4]) if len(sys.argv) > 4 else 6.0
    h, w, _ = before.shape
    gap = 8
    out = np.full((2 * h + gap, 2 * w + gap, 3), 255.0)
    out[:h, :w] = before
    out[:h, w + gap:] = after
    out[h + gap:, :w] = raised(before, gain)
    out[h + gap:, w + gap:] = raised(after, gain)
    img = Image.fromarray(out.astype(np.uint8))
    d = ImageDraw.Draw(img)
    for x, label in ((6, "before"), (w + gap + 6, "after")):
        d.text((x, 4), label, fill=(255, 255, 255))
        d.text((x, h + gap + 4), label + ", contrast raised", fill=(0, 0, 0))
    img.save(sys.argv[3])


if __name__ == "__main__":
    main()
