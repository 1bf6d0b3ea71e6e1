#!/usr/bin/env python3
"""Generate ``fixtures/reference/mie_absorbing_host.csv``: cross sections of a
sphere in an ABSORBING host, computed independently of lucent's recurrences.

Purpose
-------
lucent's Lorenz-Mie stage (src/optics/mie.rs) computes a_n, b_n with Riccati-Bessel
recurrences and a continued fraction.  This script computes the same quantities
directly from spherical Bessel functions of complex argument
(``scipy.special.spherical_jn`` / ``spherical_yn``, which wrap AMOS), with the
Bohren & Huffman (1983, eq. 4.53) formulas

    a_n = [m psi_n(mx) psi_n'(x) - psi_n(x) psi_n'(mx)] / [m psi_n(mx) xi_n'(x) - xi_n(x) psi_n'(mx)]
    b_n = [psi_n(mx) psi_n'(x) - m psi_n(x) psi_n'(mx)] / [psi_n(mx) xi_n'(x) - m xi_n(x) psi_n'(mx)]

psi_n(z) = z j_n(z), xi_n(z) = z (j_n(z) + i y_n(z)), x = 2 pi r n_h / lambda (complex),
m = n_p / n_h, and then the cross sections of Frisvad, Christensen & Jensen (2007)
as stated in docs/method.md#optics-mie:

    C_s = lambda^2 / (2 pi |n_h|^2) sum (2n+1)(|a_n|^2 + |b_n|^2) * F(alpha)
    C_t = lambda^2 / (2 pi)         sum (2n+1) Re((a_n + b_n) / n_h^2)
    F(alpha) = exp(-alpha) alpha^2 / (2 (1 + (alpha - 1) exp(alpha))),
    alpha = 4 pi r Im(n_h) / lambda, F = 1 for alpha < 1e-6,

qext = C_t / (pi r^2), qsca = C_s / (pi r^2), and g from the UNATTENUATED sums
(Bohren & Huffman eq. 4.62).  F is evaluated in 50-digit mpmath straight from the
closed form (lucent uses a series below alpha = 1 instead).

qabs is the power absorbed INSIDE the sphere over I0 pi r^2, I0 = 1/2 Re(n_h) c eps0
|E0|^2 the incident intensity at the centre, from the internal coefficients
(Bohren & Huffman eq. 4.52 with mu_1 = mu)

    c_n = i m / [psi_n(mx) xi_n'(x) - m xi_n(x) psi_n'(mx)],
    d_n = i m / [m psi_n(mx) xi_n'(x) - xi_n(x) psi_n'(mx)],
    qabs = (2 / Re x) Re[(i/y) sum (2n+1)(|d_n|^2 psi_n'(y) psi_n(y)* - |c_n|^2 psi_n(y) psi_n'(y)*)],

y = 2 pi r n_p / lambda (the inward Poynting flux through the surface).  It is >= 0
and 0 for a real n_p.  It is NOT qext - qsca in an absorbing host: the apparent
(far-field) extinction also counts the host absorption the sphere displaces
(a small clear sphere has qext < 0), and for alpha >~ 1 the far-field quantities
lose their meaning (qext grows like exp(alpha)).  Two checks of the qabs formula
run every time: for real hosts it must equal qext - qsca (energy conservation, to
1e-9 relative), and for every absorbing-particle row it must equal a direct volume
integral of (1/2) omega Im(eps_p) |E_1|^2 over the sphere (scipy.integrate.quad over
r of the orthogonal vector-spherical-harmonic terms, to 1e-8 relative).

Before writing anything the script checks its Bessel-function route against
miepython for REAL hosts (kappa_h = 0; miepython 3.3.0's coefficients with the
Bohren-Huffman sums of mie_miepython.py) on 24 spheres and stops if qext, qsca or
g differ by more than 1e-9 relative; the largest differences are printed.
``--mpmath-check`` additionally recomputes every committed row with mpmath Bessel
functions (besselj/bessely of order n + 1/2, 30 digits; about a minute).

Cases (deterministic, no random numbers): 60 spheres.  kappa_h in
{1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 5e-2} x radius in {0.05, 0.3, 1.1, 2.5, 6} um, each
with one non-absorbing and one absorbing particle; wavelength, host index and the
particle indices cycle through short lists (see make_cases).

Columns: wavelength_nm,radius_um,nh_re,nh_im,np_re,np_im,alpha,attenuation,
qext,qsca,qabs,g,terms (terms: series length used here).  Indices in the physics convention n + i kappa, kappa >= 0
absorbing (time factor exp(-i omega t), Bohren & Huffman).

How to run (from the repository root)::

    python3 tools/reference/mie_absorbing_host.py [--mpmath-check] [--out PATH]

Package versions used for the committed file: Python 3.11.7, scipy 1.17.1,
numpy 2.4.6, miepython 3.3.0 (numpy backend, only for the real-host check),
mpmath 1.3.0.  Install with

    pip install scipy==1.17.1 numpy==2.4.6 miepython==3.3.0 mpmath==1.3.0

The script refuses other scipy or miepython versions unless
``--allow-other-version`` is given.
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mpmath  # noqa: E402
import numpy as np  # noqa: E402
import scipy  # noqa: E402
from scipy.special import spherical_jn, spherical_yn  # noqa: E402

import mie_miepython as ref  # noqa: E402  (forces miepython's numpy backend)

EXPECTED = {"scipy": "1.17.1", "miepython": "3.3.0"}
COLUMNS = [
    "wavelength_nm", "radius_um", "nh_re", "nh_im", "np_re", "np_im",
    "alpha", "attenuation", "qext", "qsca", "qabs", "g", "terms",
]
KAPPA_H = (1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 5e-2)
RADII_UM = (0.05, 0.3, 1.1, 2.5, 6.0)
WAVELENGTHS_NM = (400.0, 550.0, 700.0, 480.0, 620.0)
HOST_RE = (1.5889, 1.33, 1.5)
CLEAR = (1.41, 1.2, 2.7, 1.0, 1.53)  # non-absorbing particles (1.0: a void)
ABSORBING = (
    complex(1.53, 2.3e-3),  # PVP-like (Koenig's kappa at 550 nm)
    complex(2.7, 0.05),  # TiO2-like with absorption
    complex(1.5, 0.5),
    complex(1.8, 1.0),  # carbon-black-like
    complex(1.41, 1e-6),
)


def default_out() -> Path:
    return Path(__file__).resolve().parents[2] / "fixtures" / "reference" / "mie_absorbing_host.csv"


def make_cases() -> list[tuple[float, float, complex, complex]]:
    """[(wavelength_nm, radius_um, n_host, n_particle)]."""
    cases = []
    k = 0
    for kh in KAPPA_H:
        for r in RADII_UM:
            lam = WAVELENGTHS_NM[k % len(WAVELENGTHS_NM)]
            nh = complex(HOST_RE[k % len(HOST_RE)], kh)
            cases.append((lam, r, nh, complex(CLEAR[k % len(CLEAR)], 0.0)))
            cases.append((lam, r, nh, ABSORBING[(k + 2) % len(ABSORBING)]))
            k += 1
    return cases


def n_terms(x_abs: float) -> int:
    """Wiscombe's truncation plus a margin (as mie_miepython.py)."""
    return ref.n_terms(x_abs)


def riccati(n: np.ndarray, z: complex):
    """psi_n(z), psi_n'(z), xi_n(z), xi_n'(z) from scipy's spherical Bessel functions."""
    j = spherical_jn(n, z)
    dj = spherical_jn(n, z, derivative=True)
    y = spherical_yn(n, z)
    dy = spherical_yn(n, z, derivative=True)
    psi = z * j
    dpsi = j + z * dj
    h = j + 1j * y
    dh = dj + 1j * dy
    return psi, dpsi, z * h, h + z * dh


def coefficients(m: complex, x: complex, nmax: int):
    """a_n, b_n for n = 1..nmax (Bohren & Huffman eq. 4.53, mu_1 = mu)."""
    n = np.arange(1, nmax + 1)
    psi_x, dpsi_x, xi_x, dxi_x = riccati(n, complex(x))
    psi_mx, dpsi_mx, _, _ = riccati(n, complex(m * x))
    a = (m * psi_mx * dpsi_x - psi_x * dpsi_mx) / (m * psi_mx * dxi_x - xi_x * dpsi_mx)
    b = (psi_mx * dpsi_x - m * psi_x * dpsi_mx) / (psi_mx * dxi_x - m * xi_x * dpsi_mx)
    return a, b


def attenuation(alpha: float) -> float:
    """F(alpha) of Frisvad et al. 2007 from the closed form in 50 digits; 1 below 1e-6."""
    if alpha < 1e-6:
        return 1.0
    with mpmath.workdps(50):
        a = mpmath.mpf(alpha)
        return float(mpmath.exp(-a) * a * a / (2 * (1 + (a - 1) * mpmath.exp(a))))


def sums(a: np.ndarray, b: np.ndarray):
    """(sum (2n+1)(|a|^2+|b|^2), sum (2n+1)(a+b), numerator of g) with math.fsum."""
    n = np.arange(1, len(a) + 1, dtype=np.float64)
    w = 2 * n + 1
    sca = math.fsum(w * (np.abs(a) ** 2 + np.abs(b) ** 2))
    ext = complex(math.fsum((w * (a + b)).real), math.fsum((w * (a + b)).imag))
    nn = n[:-1]
    gt = nn * (nn + 2) / (nn + 1) * (a[:-1] * np.conj(a[1:]) + b[:-1] * np.conj(b[1:])).real
    gt = np.concatenate([gt, w / (n * (n + 1)) * (a * np.conj(b)).real])
    return sca, ext, math.fsum(gt)


def internal(m: complex, x: complex, y: complex, nmax: int):
    """(c_n, d_n, psi_n(y), psi_n'(y)) for n = 1..nmax."""
    n = np.arange(1, nmax + 1)
    psi_x, dpsi_x, xi_x, dxi_x = riccati(n, complex(x))
    psi_y, dpsi_y, _, _ = riccati(n, complex(y))
    c = 1j * m / (psi_y * dxi_x - m * xi_x * dpsi_y)
    d = 1j * m / (m * psi_y * dxi_x - xi_x * dpsi_y)
    return c, d, psi_y, dpsi_y


def qabs_inside(lam_nm: float, r_um: float, nh: complex, npart: complex) -> float:
    """Power absorbed inside the sphere over I0 pi r^2 (surface flux form)."""
    k0r = 2 * math.pi * r_um * 1e-6 / (lam_nm * 1e-9)
    x, y, m = k0r * nh, k0r * npart, npart / nh
    nmax = n_terms(abs(x))
    c, d, psi, dpsi = internal(m, x, y, nmax)
    n = np.arange(1, nmax + 1)
    terms = (2 * n + 1) * (np.abs(d) ** 2 * dpsi * np.conj(psi) - np.abs(c) ** 2 * psi * np.conj(dpsi))
    total = complex(math.fsum(terms.real), math.fsum(terms.imag))
    return 2.0 / x.real * ((1j / y) * total).real + 0.0


def qabs_volume(lam_nm: float, r_um: float, nh: complex, npart: complex) -> float:
    """The same as a volume integral: Q = k0^2 Im(n_p^2) 2 pi sum_n int_0^a w_n(r) r^2 dr / (Re(k_h) pi a^2),
    w_n = (2n+1)(|c_n|^2 |j_n|^2 + |d_n|^2 (|psi_n'(rho)/rho|^2 + n(n+1) |j_n/rho|^2)), rho = k1 r
    (|E_1|^2 integrated over angles with the VSH orthogonality relations)."""
    from scipy.integrate import quad

    lam, a = lam_nm * 1e-9, r_um * 1e-6
    k0 = 2 * math.pi / lam
    x, y, m = k0 * a * nh, k0 * a * npart, npart / nh
    nmax = n_terms(abs(x))
    c, d, _, _ = internal(m, x, y, nmax)
    k1 = k0 * npart
    total = 0.0
    for i in range(1, nmax + 1):
        def w(rr, i=i):
            rho = k1 * rr
            j = spherical_jn(i, rho)
            v = (j + rho * spherical_jn(i, rho, derivative=True)) / rho
            return (2 * i + 1) * (
                abs(c[i - 1]) ** 2 * abs(j) ** 2 + abs(d[i - 1]) ** 2 * (abs(v) ** 2 + i * (i + 1) * abs(j / rho) ** 2)
            ) * rr * rr

        total += quad(w, 0.0, a, limit=400, epsabs=0.0, epsrel=1e-12)[0]
    return k0**2 * (npart**2).imag * 2 * math.pi * total / ((k0 * nh).real * math.pi * a * a)


def cross_section_row(lam_nm: float, r_um: float, nh: complex, npart: complex, coeffs=coefficients):
    lam = lam_nm * 1e-9
    r = r_um * 1e-6
    x = 2 * math.pi * r * nh / lam
    m = npart / nh
    nmax = n_terms(abs(x))
    a, b = coeffs(m, x, nmax)
    sca, _, gnum = sums(a, b)
    n = np.arange(1, nmax + 1, dtype=np.float64)
    ext_h = (2 * n + 1) * ((a + b) / (nh * nh))
    alpha = 4 * math.pi * r * nh.imag / lam
    f = attenuation(alpha)
    geometric = math.pi * r * r
    c_s = lam * lam / (2 * math.pi * abs(nh) ** 2) * sca * f
    c_t = lam * lam / (2 * math.pi) * math.fsum(ext_h.real)
    qext, qsca = c_t / geometric, c_s / geometric
    g = 2 * gnum / sca
    qabs = qabs_inside(lam_nm, r_um, nh, npart)
    return [lam_nm, r_um, nh.real, nh.imag, npart.real, npart.imag, alpha, f, qext, qsca, qabs, g, nmax]


def real_host_check() -> float:
    """The Bessel route against miepython for real hosts; returns the worst relative difference."""
    miepython = ref.miepython
    worst = (0.0, "")
    for x in (0.3, 1.0, 3.7, 12.0, 55.0, 150.0):
        for m in (complex(1.2, 0.0), complex(0.75, 0.0), complex(1.7, 0.03), complex(1.9, 0.9)):
            nmax = n_terms(x)
            a, b = coefficients(m, complex(x, 0.0), nmax)
            am, bm = miepython.coefficients(complex(m.real, -m.imag), x, n_pole=nmax)
            ours = sums(a, b)
            theirs = sums(np.asarray(am), np.asarray(bm))
            # the internal-absorption formula against energy conservation (real host)
            lam_nm, nh = 550.0, 1.5
            r_um = x * lam_nm * 1e-3 / (2 * math.pi * nh)
            q_in = qabs_inside(lam_nm, r_um, complex(nh, 0.0), m * nh)
            pairs = (
                ("qsca", ours[0], theirs[0]),
                ("qext", ours[1].real, theirs[1].real),
                ("g", ours[2] / ours[0], theirs[2] / theirs[0]),
            )
            if m.imag > 0:
                pairs += (("qabs (inside vs qext-qsca)", q_in, 2 / x**2 * (theirs[1].real - theirs[0])),)
            else:
                assert q_in == 0.0, f"qabs_inside of a clear sphere is {q_in}"
            for name, u, v in pairs:
                e = abs(u - v) / abs(v)
                if e > worst[0]:
                    worst = (e, f"{name} m={m} x={x}")
    print(f"real-host check against miepython {miepython.__version__}: worst relative difference {worst[0]:.2e} ({worst[1]})")
    if worst[0] > 1e-9:
        raise SystemExit(f"scipy Bessel route disagrees with miepython: {worst[0]:.3e} ({worst[1]})")
    return worst[0]


def coefficients_mpmath(m: complex, x: complex, nmax: int):
    """a_n, b_n with mpmath Bessel functions of order n + 1/2 (30 digits)."""
    with mpmath.workdps(30):
        mm, xx = mpmath.mpc(m), mpmath.mpc(x)

        def ric(z, n):
            s = mpmath.sqrt(mpmath.pi / (2 * z))
            j = lambda k: s * mpmath.besselj(k + 0.5, z)  # noqa: E731
            y = lambda k: s * mpmath.bessely(k + 0.5, z)  # noqa: E731
            jn, jn1 = j(n), j(n - 1)
            yn, yn1 = y(n), y(n - 1)
            psi = z * jn
            dpsi = z * jn1 - n * jn  # psi_n' = z j_{n-1} - n j_n
            hn, hn1 = jn + 1j * yn, jn1 + 1j * yn1
            return psi, dpsi, z * hn, z * hn1 - n * hn

        a, b = [], []
        for n in range(1, nmax + 1):
            px, dpx, xix, dxix = ric(xx, n)
            pm, dpm, _, _ = ric(mm * xx, n)
            a.append(complex((mm * pm * dpx - px * dpm) / (mm * pm * dxix - xix * dpm)))
            b.append(complex((pm * dpx - mm * px * dpm) / (pm * dxix - mm * xix * dpm)))
    return np.array(a), np.array(b)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=default_out())
    ap.add_argument("--mpmath-check", action="store_true", help="recompute every row with mpmath Bessel functions")
    ap.add_argument("--allow-other-version", action="store_true")
    args = ap.parse_args(argv)
    found = {"scipy": scipy.__version__, "miepython": ref.miepython.__version__}
    if found != EXPECTED and not args.allow_other_version:
        print(f"found {found}, the committed file was made with {EXPECTED}; pass --allow-other-version", file=sys.stderr)
        return 2

    real_worst = real_host_check()
    cases = make_cases()
    rows = [cross_section_row(*c) for c in cases]
    for r in rows:
        assert r[9] > 0, f"qsca <= 0 in {r}"
        assert r[10] >= 0 and (r[10] == 0) == (r[5] == 0), f"qabs sign in {r}"
        assert abs(r[11]) < 1, f"|g| >= 1 in {r}"
    n_neg = sum(1 for r in rows if r[8] - r[9] < 0)
    print(
        f"{len(rows)} cases; smallest F {min(r[7] for r in rows):.3g}; qext - qsca < 0 in {n_neg} cases "
        f"(smallest {min(r[8] - r[9] for r in rows):.3g}); qabs (inside) >= 0 in all"
    )
    vol_worst = 0.0
    for c, r in zip(cases, rows):
        if c[3].imag > 0:
            v = qabs_volume(*c)
            vol_worst = max(vol_worst, abs(v - r[10]) / v)
    print(f"qabs: surface flux against volume integral, worst relative difference {vol_worst:.1e}")
    if vol_worst > 1e-8:
        raise SystemExit("the internal-absorption formula disagrees with the volume integral")

    if args.mpmath_check:
        worst = {"qext": 0.0, "qsca": 0.0, "g": 0.0}
        for i, c in enumerate(make_cases()):
            mp_row = cross_section_row(*c, coeffs=coefficients_mpmath)
            for name, k in (("qext", 8), ("qsca", 9), ("g", 11)):
                e = abs(rows[i][k] - mp_row[k]) / abs(mp_row[k])
                worst[name] = max(worst[name], e)
        print("mpmath check (30 digits), largest relative deviation: " + ", ".join(f"{k} {v:.2e}" for k, v in worst.items()))

    header = [
        f"# generator: tools/reference/mie_absorbing_host.py; {len(rows)} spheres in absorbing hosts (kappa_h 1e-6 .. 5e-2, r 0.05 .. 6 um)",
        f"# scipy {scipy.__version__} spherical_jn/spherical_yn of complex argument, numpy {np.__version__}, python {platform.python_version()};"
        f" checked against miepython {ref.miepython.__version__} for real hosts (worst relative difference {real_worst:.1e})",
        "# a_n, b_n: Bohren-Huffman eq. 4.53 with psi_n = z j_n(z), xi_n = z h1_n(z); x = 2 pi r n_h / lambda, m = n_p / n_h;"
        " indices n + i kappa, kappa >= 0 absorbing",
        "# Frisvad et al. 2007: qsca = lambda^2/(2 pi |n_h|^2) sum (2n+1)(|a|^2+|b|^2) F(alpha) / (pi r^2),"
        " qext = lambda^2/(2 pi) sum (2n+1) Re((a+b)/n_h^2) / (pi r^2)",
        "# F(alpha) = exp(-alpha) alpha^2 / (2 (1 + (alpha-1) exp(alpha))), alpha = 4 pi r Im(n_h)/lambda, F = 1 for alpha < 1e-6;"
        " g from the unattenuated sums; terms = int(|x|+4.05|x|^(1/3)+2)+int(4|x|^(1/3))+8",
        "# qabs = power absorbed inside the sphere / (I0 pi r^2), I0 = incident intensity at the centre (internal coefficients"
        f" c_n, d_n; equals a volume integral of Im(eps)|E|^2 to {vol_worst:.0e}); >= 0, and != qext - qsca in an absorbing host",
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="\n") as fh:
        for line in header:
            fh.write(line + "\n")
        fh.write(",".join(COLUMNS) + "\n")
        for row in rows:
            fh.write(",".join(str(int(v)) if k == len(row) - 1 else repr(float(v)) for k, v in enumerate(row)) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
