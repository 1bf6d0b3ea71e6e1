#!/usr/bin/env python3
"""Mitsuba 3 on the scene of ``tools/reference/slab_column.py``, in two length
units: how much Mitsuba's answer depends on the scale of the scene.

The scene: a 2 m x 2 m x 6.35 mm box (the infinite slab at its centre), 1 mm
above a Lambertian floor of reflectance 0.5, homogeneous medium sigma_t 3015 /m,
albedo 3000/3015, Henyey-Greenstein g = 0.9, smooth dielectric 1.5 / 1.0,
uniform sky of radiance 1; a 32 x 32 pinhole camera 0.13 m above the centre
looking straight down (field of view 1 deg). ``--unit 1`` describes it in
metres, ``--unit 1000`` in millimetres (every length times 1000, sigma_t over
1000): the same physical scene.

Why it matters: Mitsuba spawns every ray from a surface at
(1 + max|p|) * 1500 * 2^-24 scene units off the surface along the normal
(``Interaction::offset_p``, ``math::RayEpsilon``): 89 um near the origin of a
scene in metres, 0.27 of this medium's mean free path, skipped without
extinction at every refraction into the medium and every internal
reflection; in millimetres it is 0.7 um. Measured (3 Dec 2026, scalar_rgb,
volpathmis, 4 passes of 256 spp): 0.41019 in metres, 0.41266 in millimetres,
against 0.41174 +- 0.00012 from the float64 brute force and 0.41188 +- 0.00023
from lucent.

    pip install mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6
    python3 tools/reference/mitsuba_column.py --unit 1 --spp 256 --passes 4
    python3 tools/reference/mitsuba_column.py --unit 1000 --spp 256 --passes 4

Prints the mean over the image of each pass and the running mean with the
standard error from the spread of the passes.
"""

import argparse
import time

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--passes", type=int, default=4)
    ap.add_argument("--integrator", default="volpathmis")
    ap.add_argument("--unit", type=float, default=1.0, help="scene units per metre (1000: millimetres)")
    a = ap.parse_args()
    import mitsuba as mi

    mi.set_variant(a.variant)
    T = mi.ScalarTransform4f
    u = a.unit

    def scene(seed):
        return mi.load_dict({
            "type": "scene",
            "integrator": {"type": a.integrator, "max_depth": -1, "rr_depth": 100000},
            "sensor": {
                "type": "perspective", "fov": 1.0, "fov_axis": "y",
                "near_clip": 0.001 * u, "far_clip": 100.0 * u,
                "to_world": T().look_at(origin=[0, 0, 0.13 * u], target=[0, 0, 0], up=[0, 1, 0]),
                "sampler": {"type": "independent", "sample_count": a.spp, "seed": seed},
                "film": {"type": "hdrfilm", "width": 32, "height": 32, "rfilter": {"type": "box"},
                         "pixel_format": "rgb"},
            },
            "env": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}},
            "floor": {"type": "rectangle", "to_world": T().scale([2.0 * u, 2.0 * u, 1.0]),
                      "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}},
            "slab": {
                "type": "cube",
                "to_world": T().translate([0, 0, (0.001 + 0.00635 / 2) * u]).scale([u, u, 0.00635 / 2 * u]),
                "bsdf": {"type": "dielectric", "int_ior": 1.5, "ext_ior": 1.0},
                "interior": {"type": "homogeneous", "sigma_t": 3015.0 / u, "albedo": 3000.0 / 3015.0,
                             "phase": {"type": "hg", "g": 0.9}},
            },
        })

    means = []
    t0 = time.time()
    for k in range(a.passes):
        img = np.array(mi.render(scene(1000 + k), spp=a.spp), dtype=np.float64)
        means.append(img.mean())
        m = np.array(means)
        se = m.std(ddof=1) / np.sqrt(len(m)) if len(m) > 1 else float("nan")
        print(f"pass {k}: {means[-1]:.6f}; mean {m.mean():.6f} ± {se:.6f} ({time.time() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
