"""The figure assets/specular-chains.png: two renders of the same scene side
by side, the object's pixels only (the EXR's `object` layer, eroded by 6 px
from its edges), luminance (Rec. 709 weights of the linear R, G, B) stretched
from its 2nd to its 98th percentile, with the per-pixel relative standard
error's 99th percentile over those pixels in each title.

    python tools/plaque_pair_figure.py A/render.exr B/render.exr OUT.png "title A" "title B" "caption"

Needs numpy, scipy, Pillow and OpenEXR (the project venv, `make python`).
"""
import sys

import Imath
import numpy as np
import OpenEXR
from PIL import Image, ImageDraw, ImageFont
from scipy.ndimage import binary_erosion

FONT = "assets/fonts/DejaVuSans.ttf"


def load(path):
    f = OpenEXR.InputFile(path)
    dw = f.header()["dataWindow"]
    w, h = dw.max.x + 1, dw.max.y + 1
    chans = f.header()["channels"].keys()
    pt = Imath.PixelType(Imath.PixelType.FLOAT)
    return {c: np.frombuffer(f.channel(c, pt), dtype=np.float32).reshape(h, w) for c in chans}


def panel(path, scale=2):
    a = load(path)
    m = binary_erosion(a["object"] > 0.5, iterations=6)
    y = 0.2126 * a["R"] + 0.7152 * a["G"] + 0.0722 * a["B"]
    rel = np.sqrt(sum(a["variance." + c] / np.maximum(a[c], 1e-12) ** 2 for c in "RGB") / 3)
    p99 = np.percentile(rel[m], 99)
    ys, xs = np.where(m)
    c = y[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    mm = m[ys.min() : ys.max() + 1, xs.min() : xs.max() + 1]
    lo, hi = np.percentile(c[mm], [2, 98])
    img = np.clip((c - lo) / (hi - lo), 0, 1)
    img[~mm] = 0
    im = Image.fromarray((img * 255).astype(np.uint8)).convert("RGB")
    return im.resize((im.width * scale, im.height * scale), Image.NEAREST), p99


def main():
    if len(sys.argv) != 7:
        sys.exit(__doc__)
    a_path, b_path, out, title_a, title_b, caption = sys.argv[1:]
    (a, pa), (b, pb) = panel(a_path), panel(b_path)
    font = ImageFont.truetype(FONT, 13)
    pad = 24
    im = Image.new("RGB", (a.width + b.width + 30, max(a.height, b.height) + pad + 44), "white")
    d = ImageDraw.Draw(im)
    im.paste(a, (10, pad))
    im.paste(b, (20 + a.width, pad))
    d.text((10, 4), f"{title_a}: per-pixel error p99 {100 * pa:.0f} %", fill="black", font=font)
    d.text((20 + a.width, 4), f"{title_b}: p99 {100 * pb:.0f} %", fill="black", font=font)
    for i, line in enumerate(caption.split("\\n")):
        d.text((10, pad + max(a.height, b.height) + 6 + 18 * i), line, fill="black", font=font)
    im.save(out)


if __name__ == "__main__":
    main()
