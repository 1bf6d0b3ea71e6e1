#!/usr/bin/env python3
"""Brute-force reference for the 3D tracer's region means: the radiance seen
straight down on an infinite grey slab over a Lambertian floor under a
uniform sky, by an analog Monte Carlo written from scratch in numpy.

Scene (plane-parallel, every plane infinite):

* sky: uniform radiance L_sky above the slab (and nowhere below it: the
  floor and the slab enclose the gap);
* slab: thickness d [m], homogeneous medium with scattering and absorption
  coefficients mu_s, mu_a [1/m], Henyey-Greenstein phase function g, smooth
  dielectric faces of index n (air n = 1 on both sides);
* floor: Lambertian, reflectance rho, below the slab (the gap's height does
  not matter for infinite planes).

Estimated: the radiance L leaving the top face straight up (the camera looks
straight down), in units of L_sky, with its standard error.

Method (independent of lucent's code: own sampling formulas, own Fresnel,
own geometry). Paths start at the top face going down (adjoint / importance
transport, which equals radiance transport here: the path starts and ends in
air, so the n^2 factors of radiance cancel). At every smooth face the path
reflects with the unpolarised Fresnel probability R and refracts otherwise
(weights unchanged). In the medium: free paths with density mu_t e^{-mu_t s},
at a scattering event the weight is multiplied by the albedo mu_s/mu_t and
the direction turned by an HG sample about the current one. A path that
leaves the top face collects L_sky times its weight. Below the slab a path
meets the floor: its weight is multiplied by rho and it leaves the floor in
a cosine-distributed direction upwards. Russian roulette below weight 0.1
(survival 0.5, weight doubled). Paths are run in vectorised batches; the
standard error comes from the spread over paths.

Usage (from the repository root):

    python3 tools/reference/slab_column.py --paths 20000000 \
        --out fixtures/reference/render/slab_column.json

Versions used: Python 3.11.7, numpy 2.4.6.
"""

import argparse
import json
import sys
import time

import numpy as np


def fresnel(cos_i, eta):
    """Unpolarised Fresnel reflectance for a ray with cos_i > 0 on the side
    of index n_i, eta = n_t / n_i. Total internal reflection gives 1."""
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.clip(1.0 - sin2_t, 0.0, 1.0))
    rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    r = 0.5 * (rs * rs + rp * rp)
    return np.where(tir, 1.0, r), cos_t


def hg_cos(g, u):
    """cos(theta) of a Henyey-Greenstein sample (inverse CDF)."""
    s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u)
    return np.clip((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0)


def turn(dx, dy, dz, cos_t, phi):
    """Rotate the unit direction (dx, dy, dz) by polar angle acos(cos_t) and
    azimuth phi (the classic MCML formula)."""
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    cp, sp = np.cos(phi), np.sin(phi)
    near_pole = np.abs(dz) > 0.99999
    den = np.sqrt(np.maximum(1e-300, 1.0 - dz * dz))
    nx = sin_t * (dx * dz * cp - dy * sp) / den + dx * cos_t
    ny = sin_t * (dy * dz * cp + dx * sp) / den + dy * cos_t
    nz = -sin_t * cp * den + dz * cos_t
    px = sin_t * cp
    py = sin_t * sp
    pz = np.sign(dz) * cos_t
    nx = np.where(near_pole, px, nx)
    ny = np.where(near_pole, py, ny)
    nz = np.where(near_pole, pz, nz)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    return nx / norm, ny / norm, nz / norm


def batch(rng, m, p):
    d, mu_s, mu_a, g, n, rho = p["d"], p["mu_s"], p["mu_a"], p["g"], p["n"], p["rho"]
    mu_t = mu_s + mu_a
    albedo = mu_s / mu_t
    total = np.zeros(m)
    # State: where the path is. 0 = at the top face from above (going down),
    # 1 = inside the slab at height z (0 = top, -d = bottom), 2 = at the
    # bottom face from below (going up, leaving the floor).
    where = np.zeros(m, dtype=np.int8)
    z = np.zeros(m)
    dx = np.zeros(m)
    dy = np.zeros(m)
    dz = -np.ones(m)
    w = np.ones(m)
    alive = np.ones(m, dtype=bool)
    steps = 0
    while alive.any():
        steps += 1
        # --- at the top face from above (only at the start): reflect to the sky or enter
        idx = np.flatnonzero(alive & (where == 0))
        if idx.size:
            cos_i = -dz[idx]
            r, cos_t = fresnel(cos_i, n)
            refl = rng.random(idx.size) < r
            out = idx[refl]
            total[out] += w[out]
            alive[out] = False
            into = idx[~refl]
            ct = cos_t[~refl]
            dx[into] /= n
            dy[into] /= n
            dz[into] = -ct
            z[into] = 0.0
            where[into] = 1
        # --- at the bottom face from below: reflect back to the floor or enter
        idx = np.flatnonzero(alive & (where == 2))
        if idx.size:
            cos_i = dz[idx]
            r, cos_t = fresnel(cos_i, n)
            refl = rng.random(idx.size) < r
            back = idx[refl]
            # back down to the floor: floor reflection and a new cosine direction
            w[back] *= rho
            u1, u2 = rng.random(back.size), rng.random(back.size)
            ct = np.sqrt(1.0 - u1)
            st = np.sqrt(u1)
            dx[back] = st * np.cos(2 * np.pi * u2)
            dy[back] = st * np.sin(2 * np.pi * u2)
            dz[back] = ct
            into = idx[~refl]
            ctt = cos_t[~refl]
            dx[into] /= n
            dy[into] /= n
            dz[into] = ctt
            z[into] = -d
            where[into] = 1
        # --- inside: one flight
        idx = np.flatnonzero(alive & (where == 1))
        if idx.size:
            s = -np.log(1.0 - rng.random(idx.size)) / mu_t
            zz = z[idx] + s * dz[idx]
            up_hit = zz >= 0.0
            down_hit = zz <= -d
            scat = ~(up_hit | down_hit)
            # scattering events
            si = idx[scat]
            z[si] = zz[scat]
            w[si] *= albedo
            cth = hg_cos(g, rng.random(si.size))
            phi = 2 * np.pi * rng.random(si.size)
            dx[si], dy[si], dz[si] = turn(dx[si], dy[si], dz[si], cth, phi)
            # boundary hits from inside
            bi = idx[up_hit | down_hit]
            top = zz[up_hit | down_hit] >= 0.0
            cos_i = np.abs(dz[bi])
            r, cos_t = fresnel(cos_i, 1.0 / n)
            refl = rng.random(bi.size) < r
            # reflected: mirror dz, stay inside at the face
            rb = bi[refl]
            z[rb] = np.where(top[refl], 0.0, -d)
            dz[rb] = -dz[rb]
            # transmitted through the top: the sky
            tt = bi[~refl & top]
            total[tt] += w[tt]
            alive[tt] = False
            # transmitted through the bottom: the floor, then back up
            tb = bi[~refl & ~top]
            w[tb] *= rho
            u1, u2 = rng.random(tb.size), rng.random(tb.size)
            dx[tb] = np.sqrt(u1) * np.cos(2 * np.pi * u2)
            dy[tb] = np.sqrt(u1) * np.sin(2 * np.pi * u2)
            dz[tb] = np.sqrt(1.0 - u1)
            where[tb] = 2
        # --- Russian roulette
        low = np.flatnonzero(alive & (w < 0.1))
        if low.size:
            keep = rng.random(low.size) < 0.5
            w[low[keep]] *= 2.0
            alive[low[~keep]] = False
    return total, steps


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--paths", type=int, default=2_000_000)
    ap.add_argument("--batch", type=int, default=500_000)
    ap.add_argument("--seed", type=int, default=20261203)
    ap.add_argument("--d-mm", type=float, default=6.35)
    ap.add_argument("--mu-s", type=float, default=3000.0)
    ap.add_argument("--mu-a", type=float, default=15.0)
    ap.add_argument("--g", type=float, default=0.9)
    ap.add_argument("--n", type=float, default=1.5)
    ap.add_argument("--rho", type=float, default=0.5)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    p = dict(d=a.d_mm * 1e-3, mu_s=a.mu_s, mu_a=a.mu_a, g=a.g, n=a.n, rho=a.rho)
    rng = np.random.default_rng(a.seed)
    s1 = s2 = 0.0
    done = 0
    t0 = time.time()
    while done < a.paths:
        m = min(a.batch, a.paths - done)
        tot, _ = batch(rng, m, p)
        s1 += tot.sum()
        s2 += (tot * tot).sum()
        done += m
        mean = s1 / done
        se = np.sqrt(max(0.0, s2 / done - mean * mean) / (done - 1))
        print(f"{done} paths: L/L_sky = {mean:.6f} ± {se:.6f} ({time.time() - t0:.0f} s)", file=sys.stderr)
    res = {
        "what": "radiance leaving an infinite slab straight up, over a Lambertian floor, under a uniform sky (units of the sky radiance)",
        "script": "tools/reference/slab_column.py",
        "thickness_m": p["d"],
        "mu_s_per_m": p["mu_s"],
        "mu_a_per_m": p["mu_a"],
        "g": p["g"],
        "n": p["n"],
        "floor_reflectance": p["rho"],
        "paths": done,
        "seed": a.seed,
        "radiance": mean,
        "std_error": se,
        "numpy": np.__version__,
    }
    text = json.dumps(res, indent=2)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
