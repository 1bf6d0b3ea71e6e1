# %% [markdown]
# # From a recipe to a compared render, in Python
#
# optics → BSSRDF slice → render → compare with the `lucent` module and the
# shipped fixtures: the IOL1068-09 recipe (PDMS spheres in polycarbonate)
# and the dense plaque scene with its Mitsuba 3 reference render
# (`fixtures/reference/render/plaque_dense_*.exr`, mean and variance of the
# mean), which stands in for the photo here.
#
# Run it as a script after `make python` (from the repository root):
#
#     .venv-py/bin/python docs/python_example.py [--out DIR] [--fast] [--show]
#
# or cell by cell (`# %%`) in an editor that understands them. It writes
# slice.png, render.png, photo.png, difference.png, overview.png (all four
# side by side) and metrics.json into
# DIR (default lucent-out/python_example) and prints the metrics. `--fast`
# (or the environment variable LUCENT_EXAMPLE_FAST=1) takes tiny settings,
# seconds in all; python/tests/test_example.py runs it so. Needs Python ≥
# 3.11 (tomllib) and OpenEXR (in python/requirements.txt) for the reference.

# %%
import argparse
import json
import os
import struct
import tomllib
import zlib
from pathlib import Path

import numpy as np
import OpenEXR

import lucent

REPO = Path(__file__).resolve().parents[1]
RECIPE = REPO / "fixtures/samples/IOL1068-09.toml"
SCENE = REPO / "fixtures/render/plaque_dense.toml"
REFERENCE = REPO / "fixtures/reference/render/plaque_dense"

parser = argparse.ArgumentParser(description="optics → BSSRDF slice → render → compare with lucent")
parser.add_argument("--out", type=Path, default=Path("lucent-out/python_example"))
parser.add_argument("--fast", action="store_true", default=os.environ.get("LUCENT_EXAMPLE_FAST") == "1")
parser.add_argument("--show", action="store_true", help="show the pictures in a matplotlib window")
args = parser.parse_args()
OUT = args.out
OUT.mkdir(parents=True, exist_ok=True)
# Tiny settings for the test, else a few seconds to a minute per step.
SETTINGS = (
    dict(wavelengths=[450.0, 550.0, 650.0], slice_pixels=21, slice_paths=3000, spp=4)
    if args.fast
    else dict(wavelengths=np.arange(380.0, 781.0, 10.0), slice_pixels=101, slice_paths=300_000, spp=256)
)


def write_png(path: Path, image: np.ndarray) -> None:
    """An 8-bit PNG of an H × W (grey) or H × W × 3 (RGB) array of values in [0, 1]."""
    a = np.clip(np.round(np.asarray(image) * 255.0), 0, 255).astype(np.uint8)
    h, w = a.shape[:2]
    colour = 2 if a.ndim == 3 else 0
    rows = b"".join(b"\x00" + a[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    header = struct.pack(">IIBBBBB", w, h, 8, colour, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows))
                     + chunk(b"IEND", b""))


def srgb(linear: np.ndarray) -> np.ndarray:
    """Linear values → sRGB-encoded values in [0, 1]."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def read_rgb_exr(path: Path) -> np.ndarray:
    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = {k: v.pixels for k, v in f.channels().items()}
    return np.stack([ch["R"], ch["G"], ch["B"]], axis=-1).astype(np.float32)


# %% [markdown]
# ## 1. Recipe → optical properties
# The recipe as a dict (the TOML file's keys): every function that takes a
# recipe takes a path or such a dict. Here with 0.5 instead of 0.65 wt-% of
# PDMS. `wavelengths_nm` is a grid; μs, μa [1/m] and g per wavelength.

# %%
with open(RECIPE, "rb") as f:
    recipe = tomllib.load(f)
recipe["particles"][0]["weight_percent"] = 0.5
o = lucent.optics(recipe, wavelengths_nm=SETTINGS["wavelengths"], phase_entries=181)
for w, mu_s, mu_a, g in list(zip(o.wavelengths_nm, o.mu_s, o.mu_a, o.g))[:: max(1, len(o.wavelengths_nm) // 5)]:
    print(f"{w:5.0f} nm  μs {mu_s:9.1f} {o.units['mu_s']}  μa {mu_a:7.3f} {o.units['mu_a']}  g {g:.4f}")

# %% [markdown]
# ## 2. A BSSRDF slice of the slab
# The same dict at one wavelength (`wavelength_nm`), light at 45°, camera
# at 0°: f_ssr [1/(m² sr)] over the surface, saved log-scaled as slice.png.

# %%
s = lucent.bssrdf(recipe, wavelength_nm=550.0, theta_i=45.0, theta_o=0.0, pixels=SETTINGS["slice_pixels"],
                  pixel_mm=0.2, paths=SETTINGS["slice_paths"], seed=1)
print(f"slice {s['slice'].shape}: sum {s['sum']:.4e} ± {s['sum_std_error']:.1e} 1/(m² sr), "
      f"{s['paths']} paths, μs {s['optical_properties']['mu_s_per_m']:.1f} 1/m")
positive = s["slice"][s["slice"] > 0]
floor = positive.min() if positive.size else 1.0
log = np.log10(np.maximum(s["slice"], floor))
slice_display = (log - log.min()) / max(np.ptp(log), 1e-12)
write_png(OUT / "slice.png", slice_display)

# %% [markdown]
# ## 3. A render of the twin
# The dense plaque scene at its camera's 64 × 48 pixels. `spp` is a number
# (the samples per pixel), `spp_per_pixel` each pixel's count, `variance`
# the variance of each pixel's mean.

# %%
r = lucent.render(SCENE, spp=SETTINGS["spp"], seed=7)
print(f"render {r['mean'].shape}: {r['spp']} spp, {r['samples']} samples in {r['wall_s']:.2f} s")

# %% [markdown]
# ## 4. Compare with the "photo"
# The reference render of the same scene by Mitsuba 3 plays the photo, with
# its variance. Given both variances, `compare` removes the expected noise
# from the error (the model RMSE, as `lucent compare` computes it for
# files): a twin that matches reads a model RMSE near 0 however few samples
# it took; the plain RMSE reads the noise.

# %%
photo = read_rgb_exr(Path(f"{REFERENCE}_mean.exr"))
photo_var = read_rgb_exr(Path(f"{REFERENCE}_var.exr"))
on_plaque = r["object"] >= 0.5
m = lucent.compare(photo, r["mean"], photo_variance=photo_var, render_variance=r["variance"])
p = lucent.compare(photo, r["mean"], mask=on_plaque, photo_variance=photo_var, render_variance=r["variance"])
for name, res in [("whole image", m), ("plaque only", p)]:
    a, n = res["as_calibrated"], res["noise"]["total"]
    print(f"{name}: RMSE {a['rmse']:.4e}, SSIM Y {a['ssim']['Y']:.4f}, relative error {100 * a['relative_error']:.2f} %; "
          f"model RMSE {n['model_rmse']:.4e} [{n['ci95'][0]:.4e}, {n['ci95'][1]:.4e}], noise floor {n['noise_floor']:.4e}")
for note in m["notes"] + p["notes"]:
    print("note:", note)

exposure = 1.0 / np.percentile(photo.max(axis=-1), 99)
write_png(OUT / "photo.png", srgb(exposure * photo))
write_png(OUT / "render.png", srgb(exposure * r["mean"]))
# Luminance difference render − photo: grey 0.5 = none, ± the 99th percentile = 0 / 1.
difference = (r["mean"] - photo) @ np.array([0.1769, 0.8124, 0.0107])
span = max(np.percentile(np.abs(difference), 99), 1e-12)
write_png(OUT / "difference.png", 0.5 + 0.5 * np.clip(difference / span, -1, 1))
(OUT / "metrics.json").write_text(json.dumps({"whole_image": m, "plaque": p}, indent=1))

# %% [markdown]
# ## 5. Look at them
# overview.png puts the slice, the photo, the render and the difference side
# by side (nearest-neighbour enlarged to one height); `--show` opens it in a
# matplotlib window, and in a notebook the last cell's figure shows inline.

# %%
def enlarge(image: np.ndarray, height: int) -> np.ndarray:
    """Nearest-neighbour enlargement of an H × W (× 3) image in [0, 1] to `height` rows, as RGB."""
    rgb = image if image.ndim == 3 else np.repeat(image[..., None], 3, axis=-1)
    k = max(1, height // rgb.shape[0])
    return np.repeat(np.repeat(rgb, k, axis=0), k, axis=1)


panels = [("slice", slice_display), ("photo", srgb(exposure * photo)), ("render", srgb(exposure * r["mean"])),
          ("difference", 0.5 + 0.5 * np.clip(difference / span, -1, 1))]
height = 8 * photo.shape[0]
big = [enlarge(np.asarray(image, dtype=np.float64), height) for _, image in panels]
rows = max(b.shape[0] for b in big)
gap = np.ones((rows, 8, 3))
overview = np.concatenate(
    [np.concatenate([np.pad(b, ((0, rows - b.shape[0]), (0, 0), (0, 0)), constant_values=1.0), gap], axis=1)
     for b in big], axis=1)
write_png(OUT / "overview.png", overview)
if args.show:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(4 * len(panels), 3.5))
    for ax, (name, image) in zip(axes, panels):
        ax.imshow(np.clip(image, 0, 1), cmap="gray" if np.ndim(image) == 2 else None, interpolation="nearest")
        ax.set_title(name)
        ax.axis("off")
    plt.show()
print("written:", ", ".join(str(OUT / n) for n in ["slice.png", "photo.png", "render.png", "difference.png",
                                                    "overview.png", "metrics.json"]))
