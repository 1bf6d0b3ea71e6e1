#!/usr/bin/env python3
"""Mitsuba 3 reference render of a translucent plaque on a checkerboard.

Writes ``fixtures/reference/render/plaque_dense_{mean,var}.exr``,
``plaque_dense.json`` and ``plaque_dense_preview.png`` (plus an 8x enlarged
copy ``plaque_dense_preview_x8.png``).  With ``--scene plaque_envmap`` the same
scene is lit by a 32x16 equirectangular map instead (written first as
``env_32x16.exr``); the outputs are then ``plaque_envmap_*``.

How to run (from the repository root)::

    pip install mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6
    apt-get install libllvm19          # Debian bookworm: 1:19.1.7-3~deb12u1
    nice python3 tools/reference/mitsuba_render.py              # 64 x 512 spp, ~18 min on 2 busy cores
    nice python3 tools/reference/mitsuba_render.py --passes 4 --spp 64 --out-dir /tmp/x

Package versions used for the committed files
---------------------------------------------
Python 3.11.7, mitsuba 3.9.1, drjit 1.5.0, numpy 2.4.6, variant
``llvm_ad_rgb`` on Debian's libLLVM 19.1.7 (``DRJIT_LIBLLVM_PATH`` is set to
``/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1`` when that file exists and the
variable is unset; LLVM 15 crashes).  ``--variant scalar_rgb`` needs no LLVM.
The script refuses other mitsuba/drjit versions unless
``--allow-other-version`` is given.

The scene (metres, right-handed, z up) -- see ``SCENE`` below
------------------------------------------------------------
* Pinhole camera at (0, -0.14, 0.16) looking at (0, 0, 0.004), up +z,
  vertical field of view 36 deg, 64 x 48 pixels, box filter of one pixel
  (each pixel is the mean radiance over its square), row 0 at the top,
  +x to the right.
* One-sided Lambertian board z = 0, x, y in [-0.1, 0.1], facing +z; squares of
  0.02 m, i = floor((x+0.1)/0.02), j = floor((y+0.1)/0.02); reflectance A if
  i + j is even, B if odd (Mitsuba ``checkerboard`` on a ``rectangle`` with
  ``to_uv = scale(5, 5)``: the rectangle's uv is ((x/0.1 + 1)/2, (y/0.1 + 1)/2),
  and the texture gives ``color0`` where both fractional parts of uv are on the
  same side of 0.5).
* Plaque: the 12-triangle ``cube`` (outward normals) mapped onto
  x in [-0.03, 0.03], y in [-0.02, 0.02], z in [0.001, 0.00735]; smooth
  dielectric 1.5 / 1.0; homogeneous interior medium, sigma_s = (1200, 1500,
  1800) /m, sigma_a = (30, 15, 8) /m, Henyey-Greenstein g = 0.8.
* Constant environment radiance (1.0, 0.9, 0.8); nothing else emits.

Integrator
----------
Both ``volpath`` and ``volpathmis`` are unbiased for this scene (no depth
limit: ``max_depth = -1``; Russian roulette only after depth 100000, i.e.
never in practice).  The medium's extinction differs per channel, and
``volpath`` samples free flights with one channel and re-weights the other two
by the ratio of transmittances: after the hundreds of scattering events in the
plaque those weights are heavy-tailed (fireflies), the red channel's variance
at equal time was 30 times that of ``volpathmis``, and a per-pixel variance
estimated from a few passes is then unreliable.  ``volpathmis`` (Miller et al.
2019 spectral MIS) weights with the average pdf of the three channels, which
bounds the weights.  Hence ``--integrator volpathmis`` is the default; the
expectation is the same, the JSON records which one was used.

Statistics
----------
``--passes K`` independent renders with seeds ``seed0 + k`` (``--spp S``
each).  The mean EXR is the average of the K images; the variance EXR is the
variance OF THE MEAN, ``sum_k (I_k - mean)^2 / (K - 1) / K``.  A renderer with
N samples per pixel should then differ from the mean by
``sqrt(var_of_mean * K * S / N + var_of_mean)`` per pixel and channel (one
standard deviation); with K passes the variance estimate itself has K - 1
degrees of freedom.
"""

import argparse
import json
import math
import os
import platform
import sys
import tempfile
import time

EXPECTED = {"mitsuba": "3.9.1", "drjit": "1.5.0"}
LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))
OUT_DIR = os.path.join(REPO, "fixtures", "reference", "render")

SIGMA_S = [1200.0, 1500.0, 1800.0]
SIGMA_A = [30.0, 15.0, 8.0]

SCENE = {
    "units": "metres; world right-handed, z up",
    "camera": {
        "type": "pinhole",
        "origin": [0.0, -0.14, 0.16],
        "target": [0.0, 0.0, 0.004],
        "up": [0.0, 0.0, 1.0],
        "fov_y_degrees": 36.0,
        "width": 64,
        "height": 48,
        "pixel_filter": "box, one pixel (pixel value = mean radiance over the pixel square)",
        "image_orientation": "row 0 at the top; world +z up and +x to the right in the image",
    },
    "board": {
        "plane_z": 0.0,
        "x_range": [-0.1, 0.1],
        "y_range": [-0.1, 0.1],
        "facing": "+z, one-sided Lambertian (black from below)",
        "square_size": 0.02,
        "index": "i = floor((x + 0.1) / 0.02), j = floor((y + 0.1) / 0.02)",
        "reflectance_even": [0.80, 0.75, 0.70],
        "reflectance_odd": [0.05, 0.08, 0.12],
        "rule": "reflectance_even when i + j is even (the square at corner (-0.1, -0.1)), reflectance_odd when odd",
    },
    "plaque": {
        "shape": "closed box, 12 triangles, outward normals",
        "x_range": [-0.03, 0.03],
        "y_range": [-0.02, 0.02],
        "z_range": [0.001, 0.00735],
        "boundary": "smooth dielectric",
        "int_ior": 1.5,
        "ext_ior": 1.0,
    },
    "medium": {
        "type": "homogeneous, inside the plaque",
        "sigma_s_per_m": SIGMA_S,
        "sigma_a_per_m": SIGMA_A,
        "sigma_t_per_m": [s + a for s, a in zip(SIGMA_S, SIGMA_A)],
        "albedo": [s / (s + a) for s, a in zip(SIGMA_S, SIGMA_A)],
        "phase": {"type": "henyey-greenstein", "g": 0.8},
    },
    "environment": {"type": "constant", "radiance": [1.0, 0.9, 0.8]},
    "other_emitters": "none",
    "colour": "RGB, channels independent",
}

# The optional environment map (--scene plaque_envmap): ENV_W x ENV_H pixels.
ENV_W, ENV_H = 32, 16
ENV_CONVENTION = (
    "pixel (x, y) covers u in [x/W, (x+1)/W), v in [y/H, (y+1)/H); direction of (u, v) is "
    "d = (sin(theta) cos(2 pi u), -sin(theta) sin(2 pi u), cos(theta)), theta = pi v "
    "(row 0 = zenith +z, u = 0 along +x, u increasing clockwise seen from above); "
    "nearest-pixel lookup; at infinity"
)


def setup(variant, threads, allow_other_version):
    """Import mitsuba/drjit with LLVM 19, check versions, set the variant."""
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(LLVM19):
        os.environ["DRJIT_LIBLLVM_PATH"] = LLVM19
    import drjit as dr
    import mitsuba as mi

    found = {"mitsuba": mi.__version__, "drjit": dr.__version__}
    if found != EXPECTED and not allow_other_version:
        sys.exit(f"found {found}, expected {EXPECTED} (--allow-other-version)")
    mi.set_variant(variant)
    if threads:
        dr.set_thread_count(threads)
    return mi, dr


def loaded_llvm():
    try:
        with open("/proc/self/maps") as f:
            libs = sorted({l.split()[-1] for l in f if "libLLVM" in l})
        return libs[0] if libs else None
    except OSError:
        return None


def rgb(v):
    return {"type": "rgb", "value": [float(x) for x in v]}


def scene_dict(mi, spp, integrator="volpathmis", env="constant", env_path=None, board_only=False,
               sensor=None, rr_depth=100000):
    """The scene as a Mitsuba dict.  ``env`` is 'constant' or 'envmap'; ``rr_depth``:
    the path depth where Russian roulette starts (the references: 100000, i.e. none)."""
    T = mi.ScalarTransform4f
    cam = SCENE["camera"]
    board = SCENE["board"]
    pl = SCENE["plaque"]
    med = SCENE["medium"]
    half = board["x_range"][1]
    n_squares = round(2 * half / board["square_size"])  # 10 squares along x and y
    assert n_squares % 2 == 0
    d = {
        "type": "scene",
        "integrator": {"type": integrator, "max_depth": -1, "rr_depth": rr_depth},
        "sensor": sensor or {
            "type": "perspective",
            "fov": cam["fov_y_degrees"],
            "fov_axis": "y",
            "near_clip": 0.001,
            "far_clip": 10 * ENV_RADIUS,  # beyond the environment sphere of plaque_envmap
            "to_world": T().look_at(origin=cam["origin"], target=cam["target"], up=cam["up"]),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {
                "type": "hdrfilm",
                "width": cam["width"],
                "height": cam["height"],
                "rfilter": {"type": "box"},
                "pixel_format": "rgb",
                "component_format": "float32",
                "sample_border": False,
            },
        },
        # rectangle: [-1, 1]^2 at z = 0, normal +z, uv = ((x+1)/2, (y+1)/2).
        # checkerboard: color0 where frac(u') and frac(v') are on the same side of 0.5, u' = 5 u.
        "board": {
            "type": "rectangle",
            "to_world": T().scale([half, half, 1.0]),
            "bsdf": {
                "type": "diffuse",
                "reflectance": {
                    "type": "checkerboard",
                    "color0": rgb(board["reflectance_even"]),
                    "color1": rgb(board["reflectance_odd"]),
                    "to_uv": T().scale([n_squares / 2, n_squares / 2, 1.0]),
                },
            },
        },
    }
    if not board_only:
        (x0, x1), (y0, y1), (z0, z1) = pl["x_range"], pl["y_range"], pl["z_range"]
        d["plaque"] = {
            "type": "cube",  # [-1, 1]^3, 12 triangles, outward normals
            "to_world": T().translate([(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2])
            @ T().scale([(x1 - x0) / 2, (y1 - y0) / 2, (z1 - z0) / 2]),
            "bsdf": {"type": "dielectric", "int_ior": pl["int_ior"], "ext_ior": pl["ext_ior"]},
            "interior": {
                "type": "homogeneous",
                "sigma_t": {"type": "constvolume", "value": rgb(med["sigma_t_per_m"])},
                "albedo": {"type": "constvolume", "value": rgb(med["albedo"])},
                "scale": 1.0,
                "phase": {"type": "hg", "g": med["phase"]["g"]},
            },
        }
    if env == "constant":
        d["environment"] = {"type": "constant", "radiance": rgb(SCENE["environment"]["radiance"])}
    else:
        d["environment"] = envmap_emitter_dict(mi, env_path)
    return d


# ---------------------------------------------------------------- environment map


def make_env_map():
    """The 32x16 test map: a sky gradient plus one bright 2x2 sun (float32, rows from the zenith)."""
    import numpy as np

    img = np.zeros((ENV_H, ENV_W, 3), np.float32)
    for y in range(ENV_H):
        v = (y + 0.5) / ENV_H
        for x in range(ENV_W):
            u = (x + 0.5) / ENV_W
            if v < 0.5:  # sky: blue at the zenith, pale at the horizon, slightly brighter towards u = 0.25
                t = v / 0.5
                base = np.array([0.25 + 0.65 * t, 0.45 + 0.45 * t, 0.95 - 0.05 * t])
                base *= 1.0 + 0.3 * math.cos(2 * math.pi * (u - 0.25))
            else:  # ground below the horizon: dark brown, darker towards the nadir
                t = (v - 0.5) / 0.5
                base = np.array([0.30, 0.22, 0.15]) * (1.0 - 0.6 * t)
            img[y, x] = base
    img[4:6, 6:8] = [40.0, 38.0, 34.0]  # sun: theta in [45, 67.5) deg, u in [0.1875, 0.25)
    return img


def env_direction_to_pixel(d):
    """Our convention: the pixel (x, y) that direction d looks up (nearest pixel)."""
    x_, y_, z_ = d
    n = math.sqrt(x_ * x_ + y_ * y_ + z_ * z_)
    theta = math.acos(max(-1.0, min(1.0, z_ / n)))
    u = (math.atan2(-y_, x_) / (2 * math.pi)) % 1.0
    v = theta / math.pi
    return min(int(u * ENV_W), ENV_W - 1), min(int(v * ENV_H), ENV_H - 1)


def envmap_emitter_dict(mi, env_path):
    """Our map at infinity, as Mitsuba objects.

    Mitsuba's ``envmap`` cannot reproduce a nearest-pixel map: it interpolates
    bilinearly, puts row r at theta = pi r / (H - 1) (rows are samples at the
    poles, not cells) and averages the first and last columns.  So the map is
    instead a ``bitmap`` texture with ``filter_type = nearest`` on a large
    inward-facing ``sphere`` area emitter of radius ENV_RADIUS centred at the
    origin.  Mitsuba's sphere has uv = (phi / 2 pi, theta / pi) in its local
    frame (phi = atan2(y, x) in [0, 2 pi), theta from +z), and the bitmap
    texture's row 0 is at v = 0, so v is our v, and u_sphere = 1 - u: the
    texture is our map with its COLUMNS REVERSED (column c of the texture is
    column W - 1 - c of the map).  verify_envmap checks the result against
    our convention in 4000 directions.

    Not a mirrored sphere (to_world scale (R, -R, R)) instead: Mitsuba's
    area-emitter sampling on it returns points at -inf about once in 5000
    samples.  The direction error against a map at infinity is at most
    |p| / R for a point p in the scene (1.5e-5 rad for |p| = 0.15 m), which
    moves pixel boundaries by 1e-4 of a pixel.
    """
    import numpy as np

    T = mi.ScalarTransform4f
    ours = np.array(mi.Bitmap(env_path), dtype=np.float32)
    texture = mi.Bitmap(np.ascontiguousarray(ours[:, ::-1]), pixel_format=mi.Bitmap.PixelFormat.RGB)
    return {
        "type": "sphere",
        "to_world": T().scale(ENV_RADIUS),
        "flip_normals": True,  # emit towards the centre
        "bsdf": {"type": "diffuse", "reflectance": rgb([0.0, 0.0, 0.0])},
        "emitter": {
            "type": "area",
            "radiance": {
                "type": "bitmap",
                "bitmap": texture,
                "filter_type": "nearest",
                "wrap_mode": "clamp",
                "raw": True,
            },
        },
    }


ENV_RADIUS = 1.0e4


# ---------------------------------------------------------------- verification


def camera_basis():
    import numpy as np

    cam = SCENE["camera"]
    o = np.array(cam["origin"])
    f = np.array(cam["target"]) - o
    f /= np.linalg.norm(f)
    r = np.cross(f, cam["up"])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return o, f, r, u


def pixel_ray(px, py):
    """Independent pinhole model: direction through film position (px, py) in pixels
    (px right, py down from the top-left corner)."""
    cam = SCENE["camera"]
    o, f, r, u = camera_basis()
    W, H = cam["width"], cam["height"]
    t = math.tan(math.radians(cam["fov_y_degrees"]) / 2)
    sx = (2 * px / W - 1) * t * W / H
    sy = (1 - 2 * py / H) * t
    d = f + sx * r + sy * u
    return o, d / math.sqrt(d @ d)


def object_mask(sub=4):
    """The plaque's pixels: those where at least half of a sub x sub grid of
    pinhole rays through the pixel (``pixel_ray``) meet the plaque's box (slab
    test; the box stands on the board, so a ray meets it before the board).
    A (height, width) bool array, row 0 at the top."""
    import numpy as np

    cam, pl = SCENE["camera"], SCENE["plaque"]
    lo = np.array([pl["x_range"][0], pl["y_range"][0], pl["z_range"][0]])
    hi = np.array([pl["x_range"][1], pl["y_range"][1], pl["z_range"][1]])
    W, H = cam["width"], cam["height"]
    mask = np.zeros((H, W), dtype=bool)
    offsets = [(k + 0.5) / sub for k in range(sub)]
    for py in range(H):
        for px in range(W):
            hits = 0
            for ox in offsets:
                for oy in offsets:
                    o, d = pixel_ray(px + ox, py + oy)
                    with np.errstate(divide="ignore", invalid="ignore"):
                        t1, t2 = (lo - o) / d, (hi - o) / d
                    t_near = np.nanmax(np.minimum(t1, t2))
                    t_far = np.nanmin(np.maximum(t1, t2))
                    hits += bool(t_near <= t_far and t_far > 0)
            mask[py, px] = 2 * hits >= sub * sub
    return mask


def checker_index(x, y):
    b = SCENE["board"]
    return math.floor((x - b["x_range"][0]) / b["square_size"]), math.floor((y - b["y_range"][0]) / b["square_size"])


def verify_camera(mi, scene):
    """Mitsuba's primary rays against the independent pinhole model (pixel centres and corners)."""
    import numpy as np

    cam = SCENE["camera"]
    W, H = cam["width"], cam["height"]
    sensor = scene.sensors()[0]
    worst = 0.0
    pts = [(px, py) for px in (0.0, 0.5, 10.5, 32.0, 63.5, 64.0) for py in (0.0, 0.5, 20.5, 47.5, 48.0)]
    for px, py in pts:
        ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f(px / W, py / H), mi.Point2f(0.5, 0.5))
        dm = np.array([ray.d.x[0], ray.d.y[0], ray.d.z[0]])
        om = np.array([ray.o.x[0], ray.o.y[0], ray.o.z[0]])
        o, d = pixel_ray(px, py)
        # Mitsuba starts the ray on the near-clip plane: its origin must lie on our ray
        off = om - o
        worst = max(worst, float(np.linalg.norm(dm - d)), float(np.linalg.norm(off - (off @ d) * d)))
    if worst > 2e-6:
        sys.exit(f"camera check failed: Mitsuba rays differ from the pinhole model by {worst}")
    return {"max_difference_of_ray_direction_or_line": worst, "film_points_checked": len(pts),
            "film_points": "pixel coordinates (x right, y down) 0, 0.5, 10.5, 32, 63.5, 64 x 0, 0.5, 20.5, 47.5, 48"}


def verify_scene_geometry(mi, scene):
    """Checker reflectance at the centre of all 100 squares (rays straight down), and
    the plaque: 12 triangles, its bounding box, outward normals on all six faces."""
    import numpy as np

    b = SCENE["board"]
    n = round((b["x_range"][1] - b["x_range"][0]) / b["square_size"])
    xs, ys, ij = [], [], []
    for i in range(n):
        for j in range(n):
            xs.append(b["x_range"][0] + (i + 0.5) * b["square_size"])
            ys.append(b["y_range"][0] + (j + 0.5) * b["square_size"])
            ij.append((i, j))
    board_shape = [s for s in scene.shapes() if s.id() == "board"][0]
    refl = []
    for k in range(len(xs)):
        # straight down onto the board shape alone (the plaque is not in the way)
        si = board_shape.ray_intersect(mi.Ray3f(mi.Point3f(xs[k], ys[k], 0.5), mi.Vector3f(0, 0, -1)))
        refl.append(np.array(board_shape.bsdf().eval_diffuse_reflectance(si)).ravel())
    refl = np.array(refl)
    A, B = np.array(b["reflectance_even"]), np.array(b["reflectance_odd"])
    bad = []
    for k, (i, j) in enumerate(ij):
        want = A if (i + j) % 2 == 0 else B
        if np.max(np.abs(refl[k] - want)) > 1e-6:
            bad.append((i, j, refl[k].tolist()))
    if bad:
        sys.exit(f"checker check failed at {bad[:5]}")
    lookup = {ij[k]: refl[k] for k in range(len(ij))}
    corner_squares = {f"{i},{j}": [round(float(v), 6) for v in lookup[(i, j)]] for i, j in [(0, 0), (1, 0), (0, 1), (1, 1), (9, 0), (0, 9), (9, 9)]}

    out = {"checker_squares_checked": len(ij), "checker_reflectance_at": corner_squares}
    plaque = [s for s in scene.shapes() if s.id() == "plaque"]
    if plaque:
        p = plaque[0]
        pl = SCENE["plaque"]
        bb = p.bbox()
        lo = [bb.min.x, bb.min.y, bb.min.z]
        hi = [bb.max.x, bb.max.y, bb.max.z]
        want_lo = [pl["x_range"][0], pl["y_range"][0], pl["z_range"][0]]
        want_hi = [pl["x_range"][1], pl["y_range"][1], pl["z_range"][1]]
        err = max(abs(float(a) - c) for a, c in zip(lo + hi, want_lo + want_hi))
        if p.face_count() != 12 or err > 1e-7:
            sys.exit(f"plaque check failed: {p.face_count()} faces, bbox error {err}")
        c = [(a + b_) / 2 for a, b_ in zip(want_lo, want_hi)]
        alone = mi.load_dict({"type": "scene", "plaque": scene_dict(mi, 1)["plaque"]})  # no board in the way
        normals = {}
        for axis in range(3):
            for sgn in (-1, 1):
                o = list(c)
                o[axis] += sgn * 0.5
                dvec = [0.0, 0.0, 0.0]
                dvec[axis] = -sgn
                si = alone.ray_intersect(mi.Ray3f(mi.Point3f(*o), mi.Vector3f(*dvec)))
                nrm = [float(si.n.x[0]), float(si.n.y[0]), float(si.n.z[0])]
                want = [0.0, 0.0, 0.0]
                want[axis] = float(sgn)
                if max(abs(a - w) for a, w in zip(nrm, want)) > 1e-6:
                    sys.exit(f"plaque normal on face {axis},{sgn} is {nrm}")
                normals["xyz"[axis] + ("+" if sgn > 0 else "-")] = nrm
        out["plaque"] = {"faces": int(p.face_count()), "bbox_max_error": err, "outward_normals": normals}
    return out


def verify_board_top_view(mi, spp=4096):
    """Render the board alone from straight above (orthographic, one pixel per square,
    image up = +y, right = +x) and compare each pixel with reflectance x environment."""
    import numpy as np

    T = mi.ScalarTransform4f
    b = SCENE["board"]
    n = round((b["x_range"][1] - b["x_range"][0]) / b["square_size"])
    half = b["x_range"][1]
    sensor = {
        "type": "orthographic",
        "to_world": T().look_at(origin=[0, 0, 1], target=[0, 0, 0], up=[0, 1, 0]) @ T().scale([half, half, 1]),
        "sampler": {"type": "independent", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": n, "height": n, "rfilter": {"type": "box"},
                 "pixel_format": "rgb", "component_format": "float32"},
    }
    scene = mi.load_dict(scene_dict(mi, spp, integrator="path", board_only=True, sensor=sensor))
    img = np.array(mi.render(scene, seed=12345, spp=spp))
    env = np.array(SCENE["environment"]["radiance"])
    A, B = np.array(b["reflectance_even"]), np.array(b["reflectance_odd"])
    worst = 0.0
    for row in range(n):
        for col in range(n):
            i, j = col, n - 1 - row  # +x right, +y up
            want = (A if (i + j) % 2 == 0 else B) * env
            worst = max(worst, float(np.max(np.abs(img[row, col] - want) / want)))
    if worst > 0.02:
        sys.exit(f"top view check failed: worst relative error {worst}")
    return {"pixels": n * n, "spp": spp, "max_relative_error_vs_reflectance_times_env": worst,
            "bottom_left_pixel_square_0_0": img[n - 1, 0].round(4).tolist(),
            "pixel_right_of_it_square_1_0": img[n - 1, 1].round(4).tolist(),
            "pixel_above_it_square_0_1": img[n - 2, 0].round(4).tolist()}


def verify_image_orientation(mean):
    """Classify board pixels of the rendered image as bright (A) or dark (B) and compare
    with the checker seen through the independent pinhole model, and with its mirror image."""
    import numpy as np

    cam = SCENE["camera"]
    b = SCENE["board"]
    pl = SCENE["plaque"]
    W, H = cam["width"], cam["height"]
    lum = mean @ np.array([0.2126, 0.7152, 0.0722])

    def squares_seen(mirror):
        out = {}
        for py in range(H):
            for px in range(W):
                seen = set()
                ok = True
                for fx, fy in [(0.5, 0.5), (0.02, 0.02), (0.98, 0.02), (0.02, 0.98), (0.98, 0.98)]:
                    qx = (W - px - 1 + fx) if mirror else (px + fx)
                    o, d = pixel_ray(qx, py + fy)
                    if d[2] >= 0:
                        ok = False
                        break
                    t = -o[2] / d[2]
                    x, y = o[0] + t * d[0], o[1] + t * d[1]
                    if not (b["x_range"][0] < x < b["x_range"][1] and b["y_range"][0] < y < b["y_range"][1]):
                        ok = False
                        break
                    # keep well away from the plaque (its shadow and the light it scatters)
                    if -0.05 < x < 0.05 and -0.045 < y < 0.035:
                        ok = False
                        break
                    seen.add(checker_index(x, y))
                if ok and len(seen) == 1:
                    i, j = seen.pop()
                    out[(px, py)] = (i + j) % 2 == 0
        return out

    result = {}
    for name, mirror in (("as_rendered", False), ("mirrored_left_right", True)):
        seen = squares_seen(mirror)
        agree = sum(1 for (px, py), even in seen.items() if (lum[py, px] > 0.3) == even)
        result[name] = {"pixels_inside_one_square": len(seen), "agree": agree}
    r = result["as_rendered"]
    if r["agree"] != r["pixels_inside_one_square"] or r["agree"] < 100:
        sys.exit(f"image orientation check failed: {result}")
    if result["mirrored_left_right"]["agree"] > 0.8 * result["mirrored_left_right"]["pixels_inside_one_square"]:
        sys.exit(f"image orientation check inconclusive: {result}")
    return result


def verify_background(mean, env_img=None):
    """Pixels that see only the environment (their centre and four corners miss the board, and
    for a map all five look up the same map pixel) must equal that radiance (no noise there)."""
    import numpy as np

    cam = SCENE["camera"]
    b = SCENE["board"]
    W, H = cam["width"], cam["height"]
    worst, n = 0.0, 0
    for py in range(H):
        for px in range(W):
            looks = set()
            for fx, fy in [(0.5, 0.5), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]:
                o, d = pixel_ray(px + fx, py + fy)
                if d[2] < 0:
                    t = -o[2] / d[2]
                    x, y = o[0] + t * d[0], o[1] + t * d[1]
                    if b["x_range"][0] - 0.01 < x < b["x_range"][1] + 0.01 and b["y_range"][0] - 0.01 < y < b["y_range"][1] + 0.01:
                        looks.add("board")
                        break
                looks.add(env_direction_to_pixel(d) if env_img is not None else "env")
            if len(looks) != 1 or "board" in looks:
                continue
            want = np.array(SCENE["environment"]["radiance"]) if env_img is None else env_img[looks.pop()[::-1]]
            worst = max(worst, float(np.max(np.abs(mean[py, px] - want) / want)))
            n += 1
    if n == 0 or worst > 1e-5:
        sys.exit(f"background check failed: {n} pixels, worst relative error {worst}")
    return {"pixels_seeing_one_environment_value": n, "max_relative_error": worst}


def verify_envmap(mi, env_path, env_img):
    """Evaluate the Mitsuba environment in many directions and compare with our convention."""
    import numpy as np

    scene = mi.load_dict({"type": "scene", "environment": envmap_emitter_dict(mi, env_path)})
    sph = scene.shapes()[0]
    rng = np.random.default_rng(7)
    dirs = [(0, 0, 1), (0, 0, -1), (1, 0, 0), (0, 1, 0), (-1, 0, 0), (0, -1, 0), (1, -1, 0.2), (1, -0.2, 0.9)]
    # the sun's centre and the centres of a few named pixels
    named = []
    for x, y in [(6, 4), (7, 5), (0, 0), (31, 15), (8, 3), (16, 8)]:
        u, v = (x + 0.5) / ENV_W, (y + 0.5) / ENV_H
        th, ph = math.pi * v, 2 * math.pi * u
        dirs.append((math.sin(th) * math.cos(ph), -math.sin(th) * math.sin(ph), math.cos(th)))
        named.append((x, y))
    dirs += [tuple(v) for v in rng.normal(size=(4000, 3))]
    keep, want = [], []
    skipped = 0
    for d in dirs:
        d = np.array(d, float)
        d /= np.linalg.norm(d)
        # skip directions within 1e-3 pixel of a pixel boundary (float32 round-off decides there)
        u = (math.atan2(-d[1], d[0]) / (2 * math.pi)) % 1.0
        v = math.acos(max(-1, min(1, d[2]))) / math.pi
        fu, fv = (u * ENV_W) % 1.0, (v * ENV_H) % 1.0
        if min(fu, 1 - fu) < 1e-3 or (min(fv, 1 - fv) < 1e-3 and 0 < v < 1):
            skipped += 1
            continue
        x, y = env_direction_to_pixel(d)
        keep.append(d)
        want.append(env_img[y, x])
    keep, want = np.array(keep), np.array(want, float)
    ray = mi.Ray3f(mi.Point3f(0.0, 0.0, 0.0),
                   mi.Vector3f(*[np.ascontiguousarray(keep[:, k], np.float32) for k in range(3)]))
    si = scene.ray_intersect(ray)
    got = np.array(sph.emitter().eval(si), float).reshape(3, -1).T
    if not np.all(np.array(si.is_valid())):
        sys.exit("environment sphere missed")
    worst = float(np.max(np.abs(got - want) / np.maximum(want, 1e-6)))
    checked = len(keep)
    # the same from a point off the centre, as seen by the scene (direction error |p| / R)
    p0 = np.array([0.1, -0.1, 0.05])
    ray2 = mi.Ray3f(mi.Point3f(*[float(c) for c in p0]),
                    mi.Vector3f(*[np.ascontiguousarray(keep[:, k], np.float32) for k in range(3)]))
    got2 = np.array(sph.emitter().eval(scene.ray_intersect(ray2)), float).reshape(3, -1).T
    off_centre_mismatch = int(np.sum(np.any(np.abs(got2 - want) > 1e-5 * np.maximum(want, 1e-6), axis=1)))
    if worst > 1e-5:
        sys.exit(f"environment map check failed: worst relative error {worst}")
    return {"directions_checked": checked, "skipped_near_pixel_boundaries": skipped,
            "max_relative_error": worst, "named_pixels_checked": [list(p) for p in named],
            "from_point_0.1_-0.1_0.05_directions_with_another_pixel": off_centre_mismatch}


NON_FINITE = (
    "volpathmis multiplies the emitter's sample weight (0) by its pdf (inf) when an emitter sample lands exactly on "
    "a pole of the sphere emitter (a 2D sample coordinate of exactly 0, probability 2^-23 per light sample), so such "
    "a path is NaN and spoils its pixel in that mi.render call. Those pixel-chunks are left out: the pixel's pass "
    "value is the mean of its finite chunks. The event has measure zero; leaving out a chunk that had one (under "
    "1e-4 of them) changes the expectation by far less than the standard error. The constant environment never does this."
)


def call_sizes(spp, chunk_spp):
    """``spp`` samples per pixel as the spp of successive mi.render calls of at most ``chunk_spp``."""
    sizes = []
    while spp > 0:
        sizes.append(min(spp, chunk_spp))
        spp -= sizes[-1]
    return sizes


def render_in_calls(mi, scene, sizes, seed, label):
    """The mean image of one mi.render call per entry of ``sizes`` (its spp),
    seeds ``seed``, ``seed + 1``, ...; a pixel whose call gave a non-finite
    value leaves that call out (see NON_FINITE).  Returns the image, the
    number of pixels left out of each call and the next unused seed; exits
    (naming ``label``) if some pixel lost more than half of its samples."""
    import numpy as np

    H, W = SCENE["camera"]["height"], SCENE["camera"]["width"]
    acc = np.zeros((H, W, 3))
    weight = np.zeros((H, W, 1))
    dropped = []
    for s in sizes:
        part = np.array(mi.render(scene, seed=seed, spp=s), dtype=np.float64)  # forces evaluation
        ok = np.all(np.isfinite(part), axis=2, keepdims=True)
        dropped.append(int(np.sum(~ok)))
        acc += np.where(ok, part, 0.0) * s
        weight += ok * s
        seed += 1
    if np.any(weight < 0.5 * sum(sizes)):
        sys.exit(f"{label}: more than half of a pixel's samples were in non-finite chunks")
    return acc / weight, dropped, seed


# ---------------------------------------------------------------- outputs


def srgb_encode(x):
    import numpy as np

    x = np.clip(x, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def write_png(mi, path, linear, enlarge=1):
    import numpy as np

    img = np.round(srgb_encode(linear) * 255.0).astype(np.uint8)
    if enlarge > 1:
        img = np.repeat(np.repeat(img, enlarge, axis=0), enlarge, axis=1)
    mi.Bitmap(np.ascontiguousarray(img), pixel_format=mi.Bitmap.PixelFormat.RGB).write(path)


def write_exr(mi, path, img):
    import numpy as np

    arr = np.ascontiguousarray(img.astype(np.float32))
    mi.Bitmap(arr, pixel_format=mi.Bitmap.PixelFormat.RGB).write(path)
    back = mi.Bitmap(path)
    names = [back.struct_()[k].name for k in range(back.channel_count())]
    if names != ["R", "G", "B"] or not np.array_equal(np.array(back), arr):
        sys.exit(f"{path} did not read back ({names})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", choices=["plaque_dense", "plaque_envmap"], default="plaque_dense")
    ap.add_argument("--passes", type=int, default=64)
    ap.add_argument("--spp", type=int, default=512, help="samples per pixel of each pass")
    ap.add_argument("--chunk-spp", type=int, default=None,
                    help="spp of one mi.render call; default 1024 (plaque_dense), 64 (plaque_envmap)")
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--integrator", choices=["volpathmis", "volpath"], default="volpathmis")
    ap.add_argument("--out-dir", default=OUT_DIR)
    ap.add_argument("--allow-other-version", action="store_true")
    args = ap.parse_args()

    mi, dr = setup(args.variant, args.threads, args.allow_other_version)
    import numpy as np

    os.makedirs(args.out_dir, exist_ok=True)
    name = args.scene
    env = "constant"
    env_path = None
    scene_params = json.loads(json.dumps(SCENE))
    verification = {}
    if name == "plaque_envmap":
        env = "envmap"
        env_img = make_env_map()
        env_path = os.path.join(args.out_dir, f"env_{ENV_W}x{ENV_H}.exr")
        write_exr(mi, env_path, env_img)
        scene_params["environment"] = {
            "type": "equirectangular map at infinity",
            "file": f"fixtures/reference/render/env_{ENV_W}x{ENV_H}.exr",
            "width": ENV_W,
            "height": ENV_H,
            "convention": ENV_CONVENTION,
            "content": "sky gradient above the horizon, dark ground below, 2x2 sun of radiance (40, 38, 34) at pixels x 6-7, y 4-5",
            "mitsuba_realisation": f"the map with its columns reversed as a bitmap texture (filter_type nearest, raw) on an inward-facing (flip_normals) sphere area emitter of radius {ENV_RADIUS:g} m centred at the origin, to_world = scale({ENV_RADIUS:g}); sphere uv = (atan2(y, x) / 2pi, theta / pi), so texture u = 1 - u",
        }
        verification["envmap"] = verify_envmap(mi, env_path, env_img)
        print("envmap:", verification["envmap"], flush=True)

    scene = mi.load_dict(scene_dict(mi, args.spp, args.integrator, env, env_path))
    verification["camera"] = verify_camera(mi, scene)
    verification.update(verify_scene_geometry(mi, scene))
    verification["board_top_view"] = verify_board_top_view(mi)
    print("checks:", json.dumps(verification), flush=True)

    if args.chunk_spp is None:
        args.chunk_spp = 1024 if name == "plaque_dense" else 64
    chunks = call_sizes(args.spp, args.chunk_spp)
    H, W = SCENE["camera"]["height"], SCENE["camera"]["width"]
    sums = np.zeros((H, W, 3))
    sumsq = np.zeros((H, W, 3))
    pass_times = []
    seed = args.seed0
    dropped = []
    load_before = os.getloadavg()
    wall0, cpu0 = time.perf_counter(), time.process_time()
    for k in range(args.passes):
        w, c = time.perf_counter(), time.process_time()
        img, lost, seed = render_in_calls(mi, scene, chunks, seed, f"pass {k}")
        dropped += lost
        sums += img
        sumsq += img * img
        pass_times.append({"pass": k, "wall_seconds": round(time.perf_counter() - w, 3),
                           "cpu_seconds": round(time.process_time() - c, 3)})
        print(f"pass {k + 1}/{args.passes}: {pass_times[-1]}", flush=True)
    wall = time.perf_counter() - wall0
    cpu = time.process_time() - cpu0
    load_after = os.getloadavg()

    K = args.passes
    mean = sums / K
    var_of_mean = np.maximum(sumsq - K * mean * mean, 0.0) / (K - 1) / K
    if not np.all(np.isfinite(mean)) or not np.all(np.isfinite(var_of_mean)):
        sys.exit("non-finite pixels")

    if env == "constant":
        verification["image_orientation"] = verify_image_orientation(mean)
        print("orientation:", verification["image_orientation"], flush=True)
    verification["background"] = verify_background(mean, None if env == "constant" else env_img)
    print("background:", verification["background"], flush=True)

    write_exr(mi, os.path.join(args.out_dir, f"{name}_mean.exr"), mean)
    write_exr(mi, os.path.join(args.out_dir, f"{name}_var.exr"), var_of_mean)
    write_png(mi, os.path.join(args.out_dir, f"{name}_preview.png"), mean)
    write_png(mi, os.path.join(args.out_dir, f"{name}_preview_x8.png"), mean, enlarge=8)

    total_spp = K * args.spp
    pixels = H * W
    info = {
        "scene": name,
        "scene_parameters": scene_params,
        "software": {
            "python": platform.python_version(),
            "mitsuba": mi.__version__,
            "drjit": dr.__version__,
            "numpy": np.__version__,
            "variant": args.variant,
            "libllvm": loaded_llvm(),
        },
        "integrator": {"type": args.integrator, "max_depth": -1, "rr_depth": 100000,
                       "note": "no depth limit; Russian roulette only beyond depth 100000"},
        "sampler": "independent",
        "seeds": f"mi.render seeds {args.seed0}..{seed - 1}, one per render call, {len(chunks)} call(s) of {chunks} spp per pass",
        "passes": K,
        "spp_per_pass": args.spp,
        "total_spp": total_spp,
        "wall_seconds": round(wall, 3),
        "cpu_seconds": round(cpu, 3),
        "threads": int(dr.thread_count()),
        "samples_per_cpu_second": round(pixels * total_spp / cpu, 1),
        "load_average_before_after": [round(load_before[0], 2), round(load_after[0], 2)],
        "timing_note": "run under nice on a shared 2-core machine; the first pass includes JIT compilation; cpu_seconds is time.process_time() of the whole process (all Dr.Jit worker threads)",
        "non_finite_pixel_chunks": {"chunk_spp": args.chunk_spp, "chunks": len(dropped) * H * W,
                                    "dropped": int(sum(dropped)), "note": NON_FINITE},
        "per_pass": pass_times,
        "image_mean_rgb": [float(v) for v in mean.mean(axis=(0, 1))],
        "mean_var_of_mean_rgb": [float(v) for v in var_of_mean.mean(axis=(0, 1))],
        "max_var_of_mean_rgb": [float(v) for v in var_of_mean.max(axis=(0, 1))],
        "files": {
            "mean": f"{name}_mean.exr (RGB float32, {W}x{H}, mean radiance per pixel)",
            "var": f"{name}_var.exr (RGB float32, variance of the mean = sample variance across passes / passes)",
            "preview": f"{name}_preview.png (sRGB, exposure 1, clipped), {name}_preview_x8.png (same, 8x nearest)",
        },
        "checks": verification,
    }
    with open(os.path.join(args.out_dir, f"{name}.json"), "w") as f:
        json.dump(info, f, indent=1)
        f.write("\n")
    print(json.dumps({k: info[k] for k in ("total_spp", "wall_seconds", "cpu_seconds", "samples_per_cpu_second",
                                           "image_mean_rgb", "mean_var_of_mean_rgb")}))


if __name__ == "__main__":
    main()
