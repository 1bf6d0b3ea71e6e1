#!/usr/bin/env python3
"""Generate ``fixtures/reference/rawpy_IMG_5952.json``: what LibRaw (through
rawpy) makes of a real Canon EOS 30D raw file, for the RAW decoder of
``lucent-calib`` (``calib/src/raw.rs``) to be checked against.

The raw file
------------
``/usr/share/doc/rawtran/IMG_5952.CR2`` from the Debian package ``rawtran-doc``
(GPL-3+; it is *not* committed: ``scripts/install-deps.sh`` installs the
package and the tests read it from there, or skip with a message when it is
absent).  The file's SHA-256 is stored so a different file is detected.

What is stored
--------------
* ``sizes``, ``black_level_per_channel``, ``white_level``, ``raw_pattern``.
* The *visible* mosaic ``raw_image_visible`` (LibRaw's active area, no
  demosaicing), and the same mosaic scaled to [0, 1]:
  ``scaled = (raw - black[c]) / (white - black[c])`` in float64 rounded to
  float32, with ``c = raw_colors_visible`` (the colour of each CFA position) and
  LibRaw's per-channel black levels (LibRaw measures them as the integer mean
  of the masked pixels per CFA position).  No clipping.  Stored: CRC-32 (zlib)
  of the little-endian uint16 raw mosaic and of the little-endian float32
  scaled mosaic, four 16 x 16 crops of the scaled mosaic and 500 pixels at
  random positions (``random.Random(5952)``).
* Demosaiced images from ``postprocess`` in the camera's raw colour space, no
  white balance, linear, no auto brightness::

      postprocess(demosaic_algorithm=ALG, output_color=raw, use_camera_wb=False,
                  use_auto_wb=False, user_wb=[1,1,1,1], gamma=(1,1),
                  no_auto_bright=True, output_bps=16, user_flip=0,
                  adjust_maximum_thr=0, half_size=False, four_color_rgb=False)

  for ALG = LINEAR (bilinear) and AHD, as 32 x 32 crops (uint16, rows of
  [R, G, B] triples) at the four most textured tiles of a coarse grid, plus
  the full-image channel means.  LibRaw scales ``raw - black[c]`` by
  ``65535 / (white - min(black))`` before demosaicing, so a value v here is
  ``v / 65535 * (white - min(black))`` digital numbers above black.

How to run (from the repository root)::

    apt-get install rawtran-doc       # or: bash scripts/install-deps.sh
    pip install rawpy                 # 0.28.0 (LibRaw 0.22.2) made the committed file
    python3 tools/reference/rawpy_reference.py [--out fixtures/reference/rawpy_IMG_5952.json]

Versions that produced the committed file: Python 3.11.7, numpy 2.4.6,
rawpy 0.28.0 with LibRaw 0.22.2.
"""

import argparse
import hashlib
import json
import random
import sys
import zlib

import numpy as np
import rawpy

RAW = "/usr/share/doc/rawtran/IMG_5952.CR2"
TILE_RAW = 16
TILE_RGB = 32


def postprocess(path, algorithm):
    with rawpy.imread(path) as r:
        return r.postprocess(
            demosaic_algorithm=algorithm,
            output_color=rawpy.ColorSpace.raw,
            use_camera_wb=False,
            use_auto_wb=False,
            user_wb=[1.0, 1.0, 1.0, 1.0],
            gamma=(1, 1),
            no_auto_bright=True,
            output_bps=16,
            user_flip=0,
            adjust_maximum_thr=0.0,
            half_size=False,
            four_color_rgb=False,
        )


def textured_tiles(image, tile, count, margin):
    """Top-left corners (row, col), even, of the `count` tiles of a coarse grid
    with the largest standard deviation, `margin` pixels from every edge."""
    h, w = image.shape[:2]
    scores = []
    for r in range(margin, h - margin - tile, 4 * tile):
        for c in range(margin, w - margin - tile, 4 * tile):
            r0, c0 = r & ~1, c & ~1
            scores.append((float(image[r0 : r0 + tile, c0 : c0 + tile].std()), r0, c0))
    scores.sort(reverse=True)
    return [(r, c) for _, r, c in scores[:count]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--raw", default=RAW)
    ap.add_argument("--out", default="fixtures/reference/rawpy_IMG_5952.json")
    a = ap.parse_args()

    data = open(a.raw, "rb").read()
    with rawpy.imread(a.raw) as r:
        s = r.sizes
        raw = r.raw_image_visible.copy()
        colors = r.raw_colors_visible.copy()
        black = np.array(r.black_level_per_channel, dtype=np.float64)
        white = float(r.white_level)
        pattern = r.raw_pattern.tolist()
        color_desc = r.color_desc.decode()
    scaled = ((raw.astype(np.float64) - black[colors]) / (white - black[colors])).astype(np.float32)

    rng = random.Random(5952)
    h, w = raw.shape
    points = [(rng.randrange(h), rng.randrange(w)) for _ in range(500)]
    raw_tiles = [(0, 0), (h - TILE_RAW, w - TILE_RAW)] + textured_tiles(scaled, TILE_RAW, 2, 64)

    out = {
        "generator": "tools/reference/rawpy_reference.py",
        "versions": {"rawpy": rawpy.__version__, "libraw": ".".join(map(str, rawpy.libraw_version)), "numpy": np.__version__, "python": sys.version.split()[0]},
        "file": {"name": a.raw.split("/")[-1], "bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()},
        "sizes": {k: getattr(s, k) for k in s._fields},
        "color_desc": color_desc,
        "raw_pattern": pattern,
        "black_level_per_channel": [int(b) for b in black],
        "white_level": int(white),
        "mosaic": {
            "height": h,
            "width": w,
            "crc32_raw_u16le": zlib.crc32(raw.astype("<u2").tobytes()),
            "crc32_scaled_f32le": zlib.crc32(scaled.astype("<f4").tobytes()),
            "tiles": [
                {"row": r0, "col": c0, "values": [[float(v) for v in row] for row in scaled[r0 : r0 + TILE_RAW, c0 : c0 + TILE_RAW]]}
                for r0, c0 in raw_tiles
            ],
            "points": [[r0, c0, float(scaled[r0, c0])] for r0, c0 in points],
        },
        "demosaic": {},
    }

    for name, alg in (("linear", rawpy.DemosaicAlgorithm.LINEAR), ("ahd", rawpy.DemosaicAlgorithm.AHD)):
        rgb = postprocess(a.raw, alg)
        if name == "linear":
            tiles = textured_tiles(rgb.astype(np.float64).mean(axis=2), TILE_RGB, 4, 64)
        out["demosaic"][name] = {
            "height": rgb.shape[0],
            "width": rgb.shape[1],
            "scale_dn_per_unit": (white - black.min()) / 65535.0,
            "channel_means": [float(rgb[:, :, c].mean()) for c in range(3)],
            "tiles": [
                {"row": r0, "col": c0, "rgb": rgb[r0 : r0 + TILE_RGB, c0 : c0 + TILE_RGB].reshape(TILE_RGB, -1).tolist()}
                for r0, c0 in tiles
            ],
        }

    with open(a.out, "w") as f:
        json.dump(out, f, separators=(",", ":"))
        f.write("\n")
    print(f"wrote {a.out}: mosaic {w}x{h}, black {out['black_level_per_channel']}, white {int(white)}")


if __name__ == "__main__":
    main()
