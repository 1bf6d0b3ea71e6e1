#!/usr/bin/env python3
"""Reference image pairs and their SSIM / RMSE for `lucent compare`.

Writes into fixtures/reference/compare/ (run from the repository root):

  base.exr      64 x 48 RGB, float32: a smooth pattern (sinusoids and
                Gaussian blobs per channel) plus Gaussian noise (sigma 0.02)
  shifted.exr   the pattern evaluated at (x - 1.5, y + 0.75) plus new noise
  contrast.exr  0.5 + 0.6 (base - 0.5), then x 0.9: lower contrast, darker
  mask.png      8-bit grey, 255 inside an ellipse and a rectangle, 0 outside
  reference.json  per pair: skimage SSIM per channel, their mean, SSIM of
                the luminance, numpy RMSE (total, per channel), mean
                absolute error, relative error, with and without the mask

SSIM is scikit-image's
  structural_similarity(x, y, gaussian_weights=True, sigma=1.5,
                        use_sample_covariance=False, data_range=R)
on float64 copies of the float32 pixels (skimage computes in float32 when
given float32, which would limit the agreement to ~1e-7 of the variances).
Per channel it is called on each 2-D plane; "ssim_mean" is their mean (what
channel_axis=-1 returns, checked here). Luminance is
Y = 0.1769 R + 0.8124 G + 0.0107 B, the Y row of the CIE 1931 RGB -> XYZ
matrix (lucent_colour::spaces::RgbSpace::CieRgb), in float64.

With a mask, the SSIM is the mean of skimage's full SSIM map (full=True)
over the mask pixels that lie inside skimage's crop (pad = (11 - 1) // 2 = 5
pixels from every border, as skimage crops before its mean); RMSE and the
errors are over all mask pixels.

    pip install scikit-image==0.26.0 numpy==2.4.6 scipy==1.17.1 OpenEXR==3.5.3 pillow==13.0.0
    python3 tools/reference/skimage_ssim.py
"""

import argparse
import json
import os
import sys

import numpy as np
import OpenEXR
import scipy
import skimage
from PIL import Image
from skimage.metrics import structural_similarity

VERSIONS = {"scikit-image": "0.26.0", "numpy": "2.4.6"}
OUT = "fixtures/reference/compare"
W, H = 64, 48
LUMA = np.array([0.1769, 0.8124, 0.0107])  # Y row of CIE RGB -> XYZ
SEED = 2004


def pattern(xs, ys):
    """Smooth RGB pattern in about [0.05, 0.9], shape (H, W, 3)."""
    out = np.empty(xs.shape + (3,))
    for c, (fx, fy, bx, by, amp) in enumerate(
        [(0.11, 0.07, 20.0, 15.0, 0.35), (0.05, 0.13, 40.0, 30.0, 0.30), (0.17, 0.04, 50.0, 10.0, 0.25)]
    ):
        blob = np.exp(-((xs - bx) ** 2 + (ys - by) ** 2) / (2 * 8.0**2))
        out[..., c] = 0.45 + 0.2 * np.sin(fx * xs + 0.5 * c) * np.cos(fy * ys) + amp * blob - 0.1 * c * blob
    return out


def write_exr(path, rgb32):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": rgb32}) as f:
        f.write(path)
    with OpenEXR.File(path) as f:
        back = f.channels()["RGB"].pixels
    assert back.dtype == np.float32 and np.array_equal(back, rgb32), path


def ssim(a, b, data_range, full=False):
    return structural_similarity(
        a, b, gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=data_range, full=full
    )


def metrics(photo32, render32, data_range, mask=None):
    p = photo32.astype(np.float64)
    r = render32.astype(np.float64)
    pad = (11 - 1) // 2
    planes = {"R": (p[..., 0], r[..., 0]), "G": (p[..., 1], r[..., 1]), "B": (p[..., 2], r[..., 2]), "Y": (p @ LUMA, r @ LUMA)}
    out = {"data_range": data_range, "ssim": {}}
    if mask is None:
        for k, (a, b) in planes.items():
            out["ssim"][k] = float(ssim(a, b, data_range))
        joint = structural_similarity(
            p, r, gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=data_range, channel_axis=-1
        )
        out["ssim_mean_rgb"] = float(np.mean([out["ssim"][k] for k in "RGB"]))
        assert abs(joint - out["ssim_mean_rgb"]) < 1e-15, (joint, out["ssim_mean_rgb"])
        sel = np.ones(p.shape[:2], dtype=bool)
    else:
        sel = mask
        inner = np.zeros_like(mask)
        inner[pad:-pad, pad:-pad] = True
        for k, (a, b) in planes.items():
            _, smap = ssim(a, b, data_range, full=True)
            out["ssim"][k] = float(smap[mask & inner].mean(dtype=np.float64))
            # Sanity: without a mask the same recipe is skimage's number.
            assert abs(smap[pad:-pad, pad:-pad].mean(dtype=np.float64) - ssim(a, b, data_range)) < 1e-15
        out["ssim_mean_rgb"] = float(np.mean([out["ssim"][k] for k in "RGB"]))
        out["ssim_pixels"] = int((mask & inner).sum())
    d = (r - p)[sel]  # (n, 3)
    out["pixels"] = int(sel.sum())
    out["rmse"] = float(np.sqrt(np.mean(d**2)))
    out["rmse_channels"] = {k: float(np.sqrt(np.mean(d[:, i] ** 2))) for i, k in enumerate("RGB")}
    out["mean_abs_error"] = float(np.mean(np.abs(d)))
    out["relative_error"] = float(np.sum(np.abs(d)) / np.sum(np.abs(p[sel])))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--allow-other-version", action="store_true")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    found = {"scikit-image": skimage.__version__, "numpy": np.__version__}
    if found != VERSIONS and not args.allow_other_version:
        sys.exit(f"expected {VERSIONS}, found {found} (or pass --allow-other-version)")
    os.makedirs(args.out, exist_ok=True)

    rng = np.random.default_rng(SEED)
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    base = (pattern(xs, ys) + rng.normal(0.0, 0.02, (H, W, 3))).astype(np.float32)
    shifted = (pattern(xs - 1.5, ys + 0.75) + rng.normal(0.0, 0.02, (H, W, 3))).astype(np.float32)
    contrast = (0.9 * (0.5 + 0.6 * (base.astype(np.float64) - 0.5))).astype(np.float32)
    ell = ((xs - 24.0) / 18.0) ** 2 + ((ys - 22.0) / 14.0) ** 2 <= 1.0
    rect = (xs >= 44) & (xs < 60) & (ys >= 30) & (ys < 46)
    mask = ell | rect

    images = {"base.exr": base, "shifted.exr": shifted, "contrast.exr": contrast}
    for name, img in images.items():
        write_exr(os.path.join(args.out, name), img)
    Image.fromarray((mask * 255).astype(np.uint8), mode="L").save(os.path.join(args.out, "mask.png"))
    back = np.asarray(Image.open(os.path.join(args.out, "mask.png")))
    assert np.array_equal(back != 0, mask)

    pairs = [
        ("shifted", "base.exr", "shifted.exr", None, 1.0),
        ("contrast", "base.exr", "contrast.exr", None, 1.0),
        ("contrast_range_2.5", "base.exr", "contrast.exr", None, 2.5),
        ("shifted_masked", "base.exr", "shifted.exr", "mask.png", 1.0),
        ("identical", "base.exr", "base.exr", None, 1.0),
    ]
    cases = []
    for name, photo, render, mask_name, data_range in pairs:
        m = metrics(images[photo], images[render], data_range, mask if mask_name else None)
        cases.append({"name": name, "photo": photo, "render": render, "mask": mask_name, **m})
        print(f"{name:20s} SSIM Y {m['ssim']['Y']:.6f}  RGB {m['ssim_mean_rgb']:.6f}  RMSE {m['rmse']:.6f}")

    doc = {
        "generator": "tools/reference/skimage_ssim.py",
        "call": "skimage.metrics.structural_similarity(x, y, gaussian_weights=True, sigma=1.5, "
        "use_sample_covariance=False, data_range=R) on float64 planes",
        "luminance": "Y = 0.1769 R + 0.8124 G + 0.0107 B (CIE 1931 RGB -> XYZ, Y row)",
        "masked_ssim": "mean of the full SSIM map over mask pixels inside the 5-pixel border crop",
        "relative_error": "sum |render - photo| / sum |photo|",
        "versions": {
            "python": sys.version.split()[0],
            "scikit-image": skimage.__version__,
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "OpenEXR": OpenEXR.__version__,
        },
        "size": [W, H],
        "seed": SEED,
        "cases": cases,
    }
    with open(os.path.join(args.out, "reference.json"), "w") as f:
        json.dump(doc, f, indent=2)
        f.write("\n")


if __name__ == "__main__":
    main()
