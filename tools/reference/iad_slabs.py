#!/usr/bin/env python3
"""Generate ``fixtures/reference/iad_slabs.csv``: adding-doubling reference values
for plane-parallel scattering slabs, computed with Scott Prahl's iadpython.

Purpose
-------
lucent's slab transport is checked against these rows.  Every row is one
homogeneous slab (albedo ``a``, optical thickness ``b = (mu_s + mu_a) * d``,
Henyey-Greenstein anisotropy ``g``, refractive index ``n_slab``) with air
(n = 1) above and below and NO glass slides.  For each slab the file gives

* ``ur1``, ``ut1``: total reflectance and total transmittance for a collimated
  beam at NORMAL incidence,
* ``uru``, ``utu``: total reflectance and transmittance for diffuse
  (Lambertian) irradiance from the air,
* ``specular_r = ((n-1)/(n+1))**2``: the normal-incidence Fresnel reflectance
  of the top surface,
* ``quad_pts``: the number of quadrature points of the row's values.

How to run (from the repository root)::

    pip install iadpython==0.5.3 numpy==2.4.6 scipy==1.17.1
    python3 tools/reference/iad_slabs.py                  # writes the CSV
    python3 tools/reference/iad_slabs.py --out /tmp/x.csv --no-converged-check

It takes about 15 s, mostly for the fixed-Radau convergence check (see below).

Package versions used to produce the committed CSV
--------------------------------------------------
Python 3.11.7, iadpython 0.5.3, numpy 2.4.6, scipy 1.17.1.  iadpython 0.5.3
declares only numpy as a dependency but imports scipy (``scipy.linalg``,
``scipy.special``, ``scipy.optimize``), so scipy must be installed too.  The
script refuses to run with another iadpython version unless
``--allow-other-version`` is given.

Conventions (as in iadpython 0.5.3)
-----------------------------------
* ``iadpython.Sample(a, b, g, n, n_above=1, n_below=1, quad_pts=N).rt()``
  returns ``(UR1, UT1, URU, UTU)``.  ``n_above = n_below = 1`` means "slide
  index 1", i.e. bare air/slab/air interfaces; ``b_above = b_below = 0``.
* ``UR1`` INCLUDES the specular reflection at the top surface (and the light
  that comes back unscattered after a reflection at the bottom surface);
  ``UT1`` INCLUDES the unscattered transmitted beam.  The script checks this
  with a non-scattering slab (``a = 0``) against the closed form
  ``r + (1-r)^2 r e^{-2b} / (1 - r^2 e^{-2b})`` and
  ``(1-r)^2 e^{-b} / (1 - r^2 e^{-2b})``.  To compare only the diffusely
  reflected light, subtract ``specular_r`` (strictly, that removes only the
  first-surface reflection; for a thick slab the unscattered part that
  comes back from the bottom is ``~ e^{-2b}`` and negligible).
* ``URU``/``UTU`` are for diffuse irradiance from air and include the
  Fresnel-reflected and unscattered parts too (n^2 law of radiance applied
  by iadpython).
* The phase function is Henyey-Greenstein, treated with the delta-M method
  with ``M = quad_pts`` (iadpython truncates at ``g**quad_pts``).  The
  quadrature for a mismatched slab (n != 1) is ``quad_pts/2`` Gauss points on
  ``[0, nu_c]`` plus ``quad_pts/2`` Radau points on ``[nu_c, 1]`` (``nu_c`` =
  cosine of the critical angle inside the slab); for ``n = 1`` it is one
  Radau rule with ``quad_pts`` points on ``[0, 1]``.  The Radau rules include
  ``nu = 1``, which is where the normal-incidence beam enters.
* Only normal incidence works in 0.5.3: setting ``Sample.nu_0 != 1`` makes
  ``rt()`` fail (``zero_layer`` is called with an int), so there are no
  oblique-incidence rows.

Quadrature choice
-----------------
Every slab is computed with 16, 24 and 32 points; the spread (max - min over
those three) of each quantity is written to the CSV header.

iadpython 0.5.3's ``quadrature.radau`` computes its weights from
``scipy.special.legendre(n-1).deriv(1)``, i.e. from monomial coefficients,
which loses all accuracy for large ``n``: the rule integrates polynomials of
degree <= 2n-2 with an error of 7e-12 (n = 16), 9e-9 (24), 5e-5 (32), 0.09
(40), 0.5 (64).  The nodes (found with ``brentq`` on ``eval_legendre``) are
accurate.  This is why "64 points drift by about 1 %" (a mismatched slab with
64 points uses a 32-point Radau rule) and "128 points give nonsense".  The
script therefore selects, per slab, the largest of 32, 24, 16 points whose
Radau rule integrates ``x^k`` (k <= 2m-2) on [0, 1] to better than 1e-10:
that is 32 for every mismatched slab (16-point Radau rule) and 16 for the
matched slab ``n = 1`` (where 32 points would use a 32-point Radau rule with
weights wrong by up to 3 %).

Converged-value check (diagnostic only; not written to the CSV columns):
unless ``--no-converged-check`` is given, each slab is recomputed with 64
and 96 points after temporarily replacing ``iadpython.quadrature.radau`` by
a version that keeps iadpython's nodes but uses the stable weight formula
``w_0 = 2/m^2``, ``w_i = (1 - x_i) / (m^2 P_{m-1}(x_i)^2)`` (Abramowitz &
Stegun 25.4.31).  The differences "selected - fixed96" and "fixed64 -
fixed96" are written to the CSV header; they estimate how far the selected
row is from the converged adding-doubling answer.  The patch is undone
before anything else is computed.

Checks (the script exits with an error if one fails)
-----------------------------------------------------
* ``thick_white`` (a = 1): ``|UR1 + UT1 - 1| < 1e-9`` and
  ``|URU + UTU - 1| < 1e-9``.
* ``pdms09_like``: ``UR1 = 0.420 +- 0.001`` and ``UT1 = 0.332 +- 0.001``
  (the values the project lead got with iadpython).
* every slab: ``UR1 >= specular_r``; every value in [0, 1].
* ``a = 0`` slabs (n = 1.0 and 1.4, b = 1) against the closed forms above
  (tolerance 1e-5).

Angular output
--------------
``fixtures/reference/iad_slabs_angular.csv`` is NOT written: iadpython 0.5.3
has no public API for angle-resolved reflectance or transmittance (only the
internal quadrature-point R/T matrices, at delta-M-truncated, quadrature-
dependent angles inside the slab), and it cannot do oblique incidence.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform
import sys
import warnings

import numpy as np
import scipy
import scipy.special

import iadpython
import iadpython.quadrature

EXPECTED_IADPYTHON = "0.5.3"
CANDIDATE_QUAD_PTS = (16, 24, 32)
RADAU_TOL = 1e-10  # max |sum w x^k - 1/(k+1)| for the rule to count as accurate
CONVERGED_QUAD_PTS = (64, 96)

# name, albedo, optical thickness b = (mu_s + mu_a) d, g, n_slab
SLABS = (
    ("thin_moderate", 0.9, 1.0, 0.5, 1.4),
    ("thin_forward", 0.95, 2.0, 0.8, 1.5),
    ("matched_isotropic", 0.8, 1.0, 0.0, 1.0),
    ("thick_white", 1.0, 20.0, 0.9, 1.4),
    ("pdms09_like", 0.999347, 93.36, 0.97358, 1.589),
    ("medium_mixed", 0.99, 10.0, 0.7, 1.33),
)

QUANTITIES = ("ur1", "ut1", "uru", "utu")

DEFAULT_OUT = os.path.join("fixtures", "reference", "iad_slabs.csv")


def rt(a: float, b: float, g: float, n: float, quad_pts: int) -> tuple[float, float, float, float]:
    """(UR1, UT1, URU, UTU) for air/slab/air at normal incidence; fresh Sample, no caches."""
    s = iadpython.Sample(a=a, b=b, g=g, n=n, n_above=1.0, n_below=1.0, quad_pts=quad_pts)
    assert s.nu_0 == 1.0 and s.b_above == 0 and s.b_below == 0
    ur1, ut1, uru, utu = s.rt()
    return float(ur1), float(ut1), float(uru), float(utu)


def radau_points_used(n: float, quad_pts: int) -> int:
    """Size of the Radau rule iadpython 0.5.3 builds for normal incidence (ad.update_quadrature)."""
    return quad_pts if n == 1 else quad_pts // 2


def radau_rule_error(m: int) -> float:
    """Max error of iadpython's m-point Radau rule on [0, 1] for x^k, k = 0 .. 2m-2."""
    x, w = iadpython.quadrature.radau(m, a=0, b=1)
    return max(abs(float(np.sum(w * x**k)) - 1.0 / (k + 1)) for k in range(2 * m - 1))


def specular_r(n: float) -> float:
    return ((n - 1.0) / (n + 1.0)) ** 2


@contextlib.contextmanager
def fixed_radau_weights():
    """Temporarily replace iadpython.quadrature.radau by one with stable weights (same nodes)."""
    original = iadpython.quadrature.radau

    def radau(n, a=-1, b=1):
        # original(n, -1, 1) maps its internal nodes t (ascending, t[0] = -1) to -t and flips
        # them, so it returns the nodes ascending with the fixed node at +1; undo that:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)  # from its (discarded) weights
            x = -np.flip(original(n, a=-1, b=1)[0])  # ascending, x[0] = -1
        w = np.empty(n)
        w[0] = 2.0 / n**2
        w[1:] = (1.0 - x[1:]) / (n**2 * scipy.special.eval_legendre(n - 1, x[1:]) ** 2)
        x = x * 0.5 * (a - b) + 0.5 * (b + a)
        w = w * 0.5 * (b - a)
        return np.flip(x), np.flip(w)

    iadpython.quadrature.radau = radau
    try:
        yield
    finally:
        iadpython.quadrature.radau = original


def check_unscattered() -> None:
    """a = 0: UR1/UT1 must equal the Fresnel + Beer-Lambert closed form (specular included)."""
    for n in (1.0, 1.4):
        b = 1.0
        ur1, ut1, _, _ = rt(0.0, b, 0.5, n, 16)
        r = specular_r(n)
        e2 = np.exp(-2 * b)
        want_r = r + (1 - r) ** 2 * r * e2 / (1 - r * r * e2)
        want_t = (1 - r) ** 2 * np.exp(-b) / (1 - r * r * e2)
        if abs(ur1 - want_r) > 1e-5 or abs(ut1 - want_t) > 1e-5:
            raise SystemExit(f"a=0 check failed for n={n}: UR1 {ur1} vs {want_r}, UT1 {ut1} vs {want_t}")


def fmt(x: float) -> str:
    return f"{x:.1e}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=DEFAULT_OUT, help=f"output CSV (default {DEFAULT_OUT})")
    ap.add_argument("--no-converged-check", action="store_true",
                    help="skip the 64/96-point fixed-Radau diagnostic in the header")
    ap.add_argument("--allow-other-version", action="store_true",
                    help=f"run with an iadpython other than {EXPECTED_IADPYTHON}")
    args = ap.parse_args(argv)

    if iadpython.__version__ != EXPECTED_IADPYTHON and not args.allow_other_version:
        print(f"iadpython {iadpython.__version__} found, the committed file was made with "
              f"{EXPECTED_IADPYTHON}; pass --allow-other-version to continue anyway", file=sys.stderr)
        return 2

    check_unscattered()

    radau_err = {m: radau_rule_error(m) for m in sorted({radau_points_used(n, q)
                                                          for *_, n in SLABS for q in CANDIDATE_QUAD_PTS})}

    rows, notes = [], []
    for name, a, b, g, n in SLABS:
        vals = {q: rt(a, b, g, n, q) for q in CANDIDATE_QUAD_PTS}
        ok = [q for q in CANDIDATE_QUAD_PTS if radau_err[radau_points_used(n, q)] < RADAU_TOL]
        if not ok:
            raise SystemExit(f"{name}: no candidate quadrature with an accurate Radau rule")
        q_sel = max(ok)
        sel = vals[q_sel]
        spread = [max(v[i] for v in vals.values()) - min(v[i] for v in vals.values()) for i in range(4)]

        rs = specular_r(n)
        for qn, v in zip(QUANTITIES, sel):
            if not 0.0 <= v <= 1.0:
                raise SystemExit(f"{name}: {qn} = {v} outside [0, 1]")
        if sel[0] < rs:
            raise SystemExit(f"{name}: UR1 {sel[0]} < specular {rs}")
        if name == "thick_white":
            for q, v in vals.items():
                if abs(v[0] + v[1] - 1) > 1e-9 or abs(v[2] + v[3] - 1) > 1e-9:
                    raise SystemExit(f"thick_white, {q} pts: UR1+UT1-1 = {v[0]+v[1]-1}, URU+UTU-1 = {v[2]+v[3]-1}")
        if name == "pdms09_like":
            if abs(sel[0] - 0.420) > 1e-3 or abs(sel[1] - 0.332) > 1e-3:
                raise SystemExit(f"pdms09_like: UR1 {sel[0]}, UT1 {sel[1]} do not reproduce 0.420 / 0.332")

        note = (f"# {name}: quad_pts {q_sel}; spread(16,24,32) "
                + ", ".join(f"{qn} {fmt(s)}" for qn, s in zip(QUANTITIES, spread)))
        notes.append((name, a, b, g, n, sel, note))
        rows.append((name, a, b, g, n, *sel, rs, q_sel))
        print(f"{name:18s} q={q_sel}  " + "  ".join(f"{qn}={v:.6f}" for qn, v in zip(QUANTITIES, sel))
              + f"  spec={rs:.6f}  spread=" + "/".join(fmt(s) for s in spread))
        for q in CANDIDATE_QUAD_PTS:
            print(f"{'':18s}   {q:2d} pts: " + "  ".join(f"{v:.6f}" for v in vals[q]))

    conv_lines = []
    if not args.no_converged_check:
        with fixed_radau_weights():
            for name, a, b, g, n, sel, note in notes:
                lo, hi = (rt(a, b, g, n, q) for q in CONVERGED_QUAD_PTS)
                d_sel = [s - h for s, h in zip(sel, hi)]
                d_lo = [l - h for l, h in zip(lo, hi)]
                line = (f"#   {name}: selected-fixed96 " + ", ".join(f"{qn} {d:+.1e}" for qn, d in zip(QUANTITIES, d_sel))
                        + "; fixed64-fixed96 " + ", ".join(f"{qn} {d:+.1e}" for qn, d in zip(QUANTITIES, d_lo)))
                conv_lines.append(line)
                print(line[2:])
        # make sure the patch is gone
        assert iadpython.quadrature.radau.__module__ == "iadpython.quadrature"

    header = [
        f"# generator: tools/reference/iad_slabs.py; iadpython {iadpython.__version__} (Prahl, adding-doubling), "
        f"numpy {np.__version__}, scipy {scipy.__version__}, python {platform.python_version()}",
        "# geometry: air / slab / air, no glass slides (n_above = n_below = 1, b_above = b_below = 0); "
        "HG phase function with delta-M (M = quad_pts); b = (mu_s + mu_a) * d",
        "# ur1,ut1: total reflectance/transmittance, collimated NORMAL incidence; ur1 INCLUDES specular_r "
        "(and unscattered light reflected at the bottom), ut1 INCLUDES the unscattered beam",
        "# uru,utu: same for diffuse (Lambertian) irradiance from air; specular_r = ((n-1)/(n+1))^2",
        "# quadrature: each slab computed with 16, 24, 32 points; row = largest of these whose Radau rule is accurate "
        f"(iadpython's Radau weights break down; max error of its m-point Radau rule on x^k, k <= 2m-2: "
        f"{', '.join(f'm={m} {radau_err[m]:.0e}' for m in sorted(radau_err))}); "
        "n != 1 uses quad_pts/2 Radau points, n = 1 uses quad_pts",
        "# spread = max - min over 16, 24, 32 points (absolute):",
        *[nt[-1] for nt in notes],
    ]
    if conv_lines:
        header += ["# convergence diagnostic: iadpython with Radau weights recomputed stably (same nodes), "
                   "64 and 96 points (absolute differences):", *conv_lines]
    header.append("name,albedo,optical_thickness,g,n_slab,ur1,ut1,uru,utu,specular_r,quad_pts")

    with open(args.out, "w", encoding="utf-8", newline="\n") as f:
        f.write("\n".join(header) + "\n")
        for name, a, b, g, n, ur1, ut1, uru, utu, rs, q in rows:
            f.write(",".join([name, repr(a), repr(b), repr(g), repr(n),
                              repr(ur1), repr(ut1), repr(uru), repr(utu), repr(rs), str(q)]) + "\n")
    print(f"wrote {args.out} ({len(rows)} slabs)")
    print("iad_slabs_angular.csv not written: iadpython 0.5.3 has no angle-resolved output "
          "and no oblique incidence")
    return 0


if __name__ == "__main__":
    sys.exit(main())
