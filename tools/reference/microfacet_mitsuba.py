#!/usr/bin/env python3
"""Reference values of the rough dielectric BSDF from Mitsuba 3's ``roughdielectric``.

Writes two tables into ``fixtures/reference/microfacet/`` that
``render/tests/microfacet.rs`` compares ``lucent_render::microfacet`` with:

``mitsuba_roughdielectric.csv``
    BSDF values and pdfs for GGX and Beckmann, alpha in {0.01, 0.1, 0.3, 0.7},
    eta = int_ior/ext_ior in {1.41, 1/1.41}, outgoing directions at
    0, 35 and 70 degrees above and 50 degrees below the surface, each with
    eight incident directions: six drawn by Mitsuba's own sampler (so they
    lie in the lobes) and two uniform on the sphere.  Both transport modes.
``mitsuba_albedo.csv``
    Directional albedo (mean sample weight, importance transport) with its
    standard error, for the cases where single scattering visibly loses
    energy (GGX from the dense side, GGX at alpha 0.2 and 60 degrees).

How to run (from the repository root)::

    pip install mitsuba==3.9.1 drjit==1.5.0 numpy==2.4.6
    nice python3 tools/reference/microfacet_mitsuba.py       # about 2 minutes

Versions used for the committed files: Python 3.11.7, mitsuba 3.9.1,
drjit 1.5.0, numpy 2.4.6, variant ``scalar_rgb`` (single precision, no LLVM
needed).  The script refuses other mitsuba/drjit versions unless
``--allow-other-version`` is given.

Conventions (lucent's in brackets)
----------------------------------
* Local frame, normal +z; ``eta`` = interior/exterior index, interior below
  [``eta`` = n_below/n_above: the same number].
* Mitsuba's ``si.wi`` is the direction towards the camera [``wo``]; Mitsuba's
  ``wo`` is the sampled direction [``wi``].  The columns use lucent's names.
* ``eval_cos`` is Mitsuba's ``eval``: the BSDF times |cos theta| of the
  sampled direction [``eval(wo, wi) * |wi.z|``].
* ``pdf`` is Mitsuba's ``pdf`` with ``sample_visible = true`` (lobe chosen
  with probability F, like lucent).
* Mitsuba's Beckmann Smith G1 is Walter 2007's rational approximation
  (< 0.35 % error), lucent's the exact erfc form.  So the table also records
  Mitsuba's ``g`` = G1(wo, m) G1(wi, m) and ``g1o`` = G1(wo, m) at the
  generalised half-vector m, and the test divides them out before comparing
  tightly.  Directions are written after rounding to float32 (what Mitsuba
  used), as 9 significant digits.
"""

import argparse
import csv
import math
import os
import sys

import numpy as np

PINNED = {"mitsuba": "3.9.1", "drjit": "1.5.0"}
ALPHAS = [0.01, 0.1, 0.3, 0.7]
ETAS = [1.41, 1.0 / 1.41]
WO_THETAS = [(0.0, 1), (35.0, 1), (70.0, 1), (50.0, -1)]  # (degrees, side)


def f32(x):
    return float(np.float32(x))


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    v = v / np.linalg.norm(v)
    return [f32(c) for c in v]


def half_vector(wo, wi, eta):
    """lucent's generalised half-vector (facing +z), or None."""
    wo, wi = np.asarray(wo), np.asarray(wi)
    if wo[2] * wi[2] > 0:
        etap = 1.0
    else:
        etap = eta if wo[2] > 0 else 1.0 / eta
    m = wi * etap + wo
    n = np.linalg.norm(m)
    if n == 0:
        return None
    m = m / n
    return -m if m[2] < 0 else m


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", default="fixtures/reference/microfacet")
    ap.add_argument("--allow-other-version", action="store_true")
    ap.add_argument("--albedo-samples", type=int, default=40000)
    args = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    for mod, want in (("mitsuba", PINNED["mitsuba"]), ("drjit", PINNED["drjit"])):
        have = (mi if mod == "mitsuba" else dr).__version__
        if have != want and not args.allow_other_version:
            sys.exit(f"{mod} {have} found, {want} pinned (use --allow-other-version)")
    mi.set_variant("scalar_rgb")
    os.makedirs(args.out_dir, exist_ok=True)
    rng = np.random.default_rng(20261128)

    def bsdf(dist, alpha, eta):
        return mi.load_dict(
            {"type": "roughdielectric", "distribution": dist, "alpha": alpha, "int_ior": eta, "ext_ior": 1.0}
        )

    def interaction(wo):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*wo)
        si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
        return si

    rows = []
    for dist in ("ggx", "beckmann"):
        mtype = mi.MicrofacetType.GGX if dist == "ggx" else mi.MicrofacetType.Beckmann
        for alpha in ALPHAS:
            md = mi.MicrofacetDistribution(mtype, alpha, True)
            for eta in ETAS:
                b = bsdf(dist, alpha, eta)
                for theta, side in WO_THETAS:
                    t, p = math.radians(theta), math.radians(25.0)
                    wo = unit([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), side * math.cos(t)])
                    si = interaction(wo)
                    wis = []
                    ctx = mi.BSDFContext(mi.TransportMode.Radiance)
                    tries = 0
                    while len(wis) < 6 and tries < 1000:
                        tries += 1
                        u = rng.random(3)
                        bs, w = b.sample(ctx, si, float(u[0]), mi.Point2f(float(u[1]), float(u[2])))
                        if w[0] > 0 and bs.pdf > 0:
                            wis.append(unit([bs.wo[0], bs.wo[1], bs.wo[2]]))
                    for _ in range(2):
                        v = rng.normal(size=3)
                        wis.append(unit(v))
                    for wi in wis:
                        m = half_vector(wo, wi, eta)
                        if m is None:
                            continue
                        mm = mi.Vector3f(*m)
                        g1o = float(md.smith_g1(mi.Vector3f(*wo), mm))
                        g = g1o * float(md.smith_g1(mi.Vector3f(*wi), mm))
                        for mode_name, mode in (("radiance", mi.TransportMode.Radiance), ("importance", mi.TransportMode.Importance)):
                            ctx = mi.BSDFContext(mode)
                            val = float(b.eval(ctx, si, mi.Vector3f(*wi))[0])
                            pdf = float(b.pdf(ctx, si, mi.Vector3f(*wi)))
                            rows.append([dist, alpha, repr(eta), mode_name, *wo, *wi, val, pdf, g, g1o])

    path = os.path.join(args.out_dir, "mitsuba_roughdielectric.csv")
    with open(path + ".tmp", "w", newline="") as f:
        f.write(f"# Mitsuba {mi.__version__} roughdielectric, variant scalar_rgb; see tools/reference/microfacet_mitsuba.py\n")
        wr = csv.writer(f)
        wr.writerow(["distribution", "alpha", "eta", "mode", "wo_x", "wo_y", "wo_z", "wi_x", "wi_y", "wi_z", "eval_cos", "pdf", "g", "g1o"])
        for r in rows:
            wr.writerow([f"{x:.9g}" if isinstance(x, float) else x for x in r])
    os.replace(path + ".tmp", path)
    print(f"{len(rows)} rows -> {path}")

    # Directional albedo where single scattering loses energy.
    cases = [
        ("ggx", 0.1, 1.0 / 1.41, 0.0),
        ("ggx", 0.2, 1.0 / 1.41, 0.0),
        ("ggx", 0.2, 1.0 / 1.41, 30.0),
        ("ggx", 0.2, 1.41, 60.0),
        ("beckmann", 0.2, 1.0 / 1.41, 60.0),
        ("ggx", 0.7, 1.41, 80.0),
        ("beckmann", 0.3, 1.41, 0.0),
    ]
    n = args.albedo_samples
    out = []
    ctx = mi.BSDFContext(mi.TransportMode.Importance)
    for dist, alpha, eta, theta in cases:
        b = bsdf(dist, alpha, eta)
        t = math.radians(theta)
        si = interaction(unit([math.sin(t), 0.0, math.cos(t)]))
        u = rng.random((n, 3))
        w = np.empty(n)
        for i in range(n):
            _, wt = b.sample(ctx, si, float(u[i, 0]), mi.Point2f(float(u[i, 1]), float(u[i, 2])))
            w[i] = wt[0]
        out.append([dist, alpha, repr(eta), theta, n, w.mean(), w.std(ddof=1) / math.sqrt(n)])
        print(dist, alpha, eta, theta, w.mean(), "+-", out[-1][-1])
    path = os.path.join(args.out_dir, "mitsuba_albedo.csv")
    with open(path + ".tmp", "w", newline="") as f:
        f.write(f"# Mitsuba {mi.__version__} roughdielectric directional albedo (importance), scalar_rgb; see tools/reference/microfacet_mitsuba.py\n")
        wr = csv.writer(f)
        wr.writerow(["distribution", "alpha", "eta", "theta_deg", "samples", "albedo", "stderr"])
        for r in out:
            wr.writerow([f"{x:.9g}" if isinstance(x, float) else x for x in r])
    os.replace(path + ".tmp", path)
    print(f"-> {path}")


if __name__ == "__main__":
    main()
