#!/usr/bin/env python3
"""Generate ``fixtures/reference/mie_miepython.csv``: Lorenz-Mie reference values
for homogeneous spheres, computed with the independent Python package miepython.

Purpose
-------
The Rust crate (lucent) is checked against these rows.  Every row is one sphere:
relative refractive index ``m = m_re + i*m_im`` and size parameter ``x``, with the
efficiencies ``qext, qsca, qback``, the asymmetry parameter ``g`` and the
scattering intensities ``|S1|^2, |S2|^2`` at theta = 0, 30, 60, 90, 120, 150, 180 deg.

How to run (from the repository root)::

    python3 tools/reference/mie_miepython.py                  # writes the CSV
    python3 tools/reference/mie_miepython.py --mpmath-check   # + 40-digit mpmath audit
    python3 tools/reference/mie_miepython.py --out /tmp/x.csv --seed 7

Package versions used to produce the committed CSV
--------------------------------------------------
Python 3.11.7, miepython 3.3.0 (pure-numpy backend, ``MIEPYTHON_USE_JIT=0``, which
is miepython 3.3.0's default and is forced below), numpy 2.4.6, scipy 1.17.1
(imported by miepython), mpmath 1.3.0 (only for ``--mpmath-check``).  numba 0.68.1
was installed but the numba backend is not used here: its coefficients differ from
the numpy backend's by up to ~3e-11 relative in high orders, so it would make the
file depend on the backend.  The script refuses to run with another miepython
version unless ``--allow-other-version`` is given.

Cases
-----
Random numbers come from ``random.Random(seed)`` (Mersenne Twister; CPython
guarantees that ``random()`` gives the same sequence for the same seed on every
version), with exactly four ``random()`` draws per random case.  Default seed 1979.

* 28 fixed edge cases: x in {0.01, 0.1, 1, 10, 100, 500, 1000} crossed with
  m in {1.33, 1.5 + 0.01i, 0.75, 2.5 + 1i}.
* 300 random cases with m_re uniform in [1.05, 2.5] and 20 with m_re uniform in
  [0.7, 0.99]; x log-uniform in [0.01, 1000]; m_im = 0 when the fourth draw is
  < 0.5 (about half), otherwise log-uniform in [1e-6, 1] (third draw).

Sign conventions
----------------
* CSV (and lucent) use the physics convention ``m = n + i*kappa`` with kappa >= 0
  absorbing, i.e. time dependence exp(-i omega t) as in Bohren & Huffman (1983).
* miepython documents ``m = n - i*k`` for absorbing spheres (it silently conjugates
  a positive imaginary part).  This script always passes ``conj(m)`` explicitly.
  The a_n, b_n returned by ``miepython.coefficients`` are nevertheless in the
  Bohren-Huffman convention (e.g. a_1 ~ -2i/3 x^3 (m^2-1)/(m^2+2) for small x).
* Amplitudes are the UNNORMALISED Bohren-Huffman ones,
  ``S1 = sum (2n+1)/(n(n+1)) (a_n pi_n + b_n tau_n)``,
  ``S2 = sum (2n+1)/(n(n+1)) (a_n tau_n + b_n pi_n)``, so that
  ``Qext = 4/x^2 Re S1(0)`` and ``Qback = 4 |S1(180)|^2 / x^2``.
  In miepython 3.3.0 this is ``S1_S2(m, x, mu, norm='wiscombe')`` (normalisation
  factor 1).  ``norm='bohren'`` is NOT the Bohren-Huffman amplitude: it divides by
  1/2, giving 2*S.  miepython's ``S1_S2`` also returns the complex CONJUGATE of the
  Bohren-Huffman amplitude built from its own a_n, b_n (i.e. Wiscombe's MIEV0
  convention, Im S1(0) >= 0); only |S|^2 is written here, so this does not matter
  for the CSV, but the script asserts it so that nobody copies complex amplitudes
  from miepython with the wrong sign.
* ``qback`` is Bohren & Huffman's ``|sum_n (2n+1)(-1)^n (a_n - b_n)|^2 / x^2``
  (= 4|S1(180)|^2/x^2; the "radar" backscattering efficiency, 4 pi times the
  differential cross-section at 180 deg over the geometric cross-section).
  miepython's ``efficiencies_mx`` uses the same definition on its series path.
* ``mu = cos(theta)`` is ``numpy.cos(numpy.deg2rad(theta))`` in float64 (so at 90 deg
  mu = 6.1e-17, not 0; at 0 and 180 deg it is exactly +1 and -1).

How the numbers are obtained (and why not simply ``efficiencies_mx``)
---------------------------------------------------------------------
All columns are computed by this script from miepython's own Mie coefficients
``miepython.coefficients(conj(m), x, n_pole=N)`` and angular functions
``miepython.pi_tau`` with the Bohren & Huffman sums (math.fsum), truncated at

    N = int(x + 4.05 x^(1/3) + 2) + int(4 x^(1/3)) + 8

i.e. miepython's Wiscombe truncation plus a margin.  Two shortcomings of the stock
``efficiencies_mx`` make it unsuitable for a tight reference, and they are the
reason for doing the sums here (numbers measured on this case set):

1. for |m| x < 0.1 it returns small-particle approximations (Wiscombe's
   expansions) rather than the Mie series: relative errors up to 1.6e-6
   (m = 0.75, x = 0.1: qback 1.6e-6, g 1.4e-6; qext up to 5.8e-7);
2. Wiscombe's truncation leaves relative errors up to 1.7e-6 in qback (slowly
   converging alternating backscatter series; m = 1.33, x = 1000) and up to 6e-10
   in qext (a narrow resonance of order n = 213 just beyond the cut-off at x = 187).

The script still calls ``efficiencies_mx`` and ``S1_S2(norm='wiscombe')`` for every
case and asserts:
  * optical theorem Qext = 4/x^2 Re S1(0): (i) miepython's
    ``S1_S2(norm='wiscombe')`` against Qext from the same (Wiscombe-truncated)
    coefficients, relative 1e-9 asserted (observed <= 4e-16), (ii) the CSV's qext against the CSV's S1(0)
    (<= 1e-12 asserted), (iii) the CSV's qext against ``S1_S2`` (only the
    truncation differs; <= 1e-6 asserted, 6e-10 observed);
  * S1(0) == S2(0) and |S1(180)| == |S2(180)| (relative 1e-12);
  * ``S1_S2(norm='wiscombe')`` equals the complex conjugate of the B&H sum built
    from miepython's default-truncation coefficients (relative 1e-12);
  * qback == 4|S1(180)|^2/x^2 (relative 1e-12), 0 <= qsca <= qext (1 + 1e-12),
    |g| < 1, Re S1(0) > 0;
  * agreement with ``efficiencies_mx`` to 1e-5 relative (the summary printed at
    the end gives the largest differences per quantity and path).

``--mpmath-check`` re-evaluates every case with an independent implementation
in this file (mpmath, 40 significant digits: downward D_n(mx), Miller's downward
psi_n(x), upward chi_n(x), 20 + 4 x^(1/3) extra terms) and prints the largest
relative deviation of the CSV per column (about 70 s).  For the committed file
(seed 1979): qext, qsca <= 3.7e-12; g <= 4.5e-11; qback <= 7.0e-10; the |S|^2
columns <= 2.6e-9 (largest for x of several hundred, and for nearly vanishing
S2(90) at x = 0.01).  Tolerances of 1e-8 (relative) are therefore safe for all
columns.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import random
import sys
import time
from pathlib import Path

# Force miepython's pure-numpy backend (its 3.3.0 default) before importing it.
os.environ["MIEPYTHON_USE_JIT"] = "0"

import numpy as np  # noqa: E402

import miepython  # noqa: E402

EXPECTED_MIEPYTHON = "3.3.0"
DEFAULT_SEED = 1979
ANGLES_DEG = (0, 30, 60, 90, 120, 150, 180)
FIXED_X = (0.01, 0.1, 1.0, 10.0, 100.0, 500.0, 1000.0)
FIXED_M = (complex(1.33, 0.0), complex(1.5, 0.01), complex(0.75, 0.0), complex(2.5, 1.0))
N_MAIN = 300  # m_re in [1.05, 2.5]
N_LOW = 20  # m_re in [0.7, 0.99]
COLUMNS = ["m_re", "m_im", "x", "qext", "qsca", "qback", "g"] + [
    f"{p}_{a}" for a in ANGLES_DEG for p in ("s1sq", "s2sq")
]


def default_out() -> Path:
    """fixtures/reference/mie_miepython.csv relative to the repository root."""
    return Path(__file__).resolve().parents[2] / "fixtures" / "reference" / "mie_miepython.csv"


def make_cases(seed: int) -> list[tuple[str, complex, float]]:
    """Return [(kind, m, x)] with m in the physics convention (Im m >= 0)."""
    cases = [("fixed", m, x) for x in FIXED_X for m in FIXED_M]
    rng = random.Random(seed)
    for i in range(N_MAIN + N_LOW):
        u_x, u_re, u_k = rng.random(), rng.random(), rng.random()
        u_zero = rng.random()
        x = 10.0 ** (-2.0 + 5.0 * u_x)
        if i < N_MAIN:
            m_re = 1.05 + (2.5 - 1.05) * u_re
        else:
            m_re = 0.7 + (0.99 - 0.7) * u_re
        m_im = 0.0 if u_zero < 0.5 else 10.0 ** (-6.0 + 6.0 * u_k)
        cases.append(("random", complex(m_re, m_im), x))
    return cases


def n_terms(x: float) -> int:
    """miepython's Wiscombe truncation plus a safety margin (see module docstring)."""
    return int(x + 4.05 * x**0.33333 + 2.0) + int(4.0 * x ** (1.0 / 3.0)) + 8


def fsum_c(values) -> complex:
    """Correctly rounded sum of complex numbers (math.fsum on each part)."""
    values = np.asarray(values, dtype=np.complex128)
    return complex(math.fsum(values.real), math.fsum(values.imag))


def bh_sums(a: np.ndarray, b: np.ndarray, x: float, mus: np.ndarray):
    """Bohren-Huffman efficiencies and amplitudes from coefficients a_n, b_n."""
    n_max = len(a)
    n = np.arange(1, n_max + 1, dtype=np.float64)
    x2 = x * x
    qext = 2.0 / x2 * math.fsum((2 * n + 1) * (a.real + b.real))
    qsca = 2.0 / x2 * math.fsum((2 * n + 1) * (np.abs(a) ** 2 + np.abs(b) ** 2))
    alt = np.where(n.astype(np.int64) % 2 == 0, 1.0, -1.0)  # (-1)^n
    qback = abs(fsum_c((2 * n + 1) * alt * (a - b))) ** 2 / x2
    nn = n[:-1]
    g_terms = nn * (nn + 2) / (nn + 1) * (a[:-1] * np.conj(a[1:]) + b[:-1] * np.conj(b[1:])).real
    g_terms = np.concatenate([g_terms, (2 * n + 1) / (n * (n + 1)) * (a * np.conj(b)).real])
    g = 4.0 / x2 * math.fsum(g_terms) / qsca
    fac = (2 * n + 1) / (n * (n + 1))
    pi = np.zeros(n_max)
    tau = np.zeros(n_max)
    s1 = np.empty(len(mus), dtype=np.complex128)
    s2 = np.empty(len(mus), dtype=np.complex128)
    for k, mu in enumerate(mus):
        miepython.pi_tau(float(mu), pi, tau)
        s1[k] = fsum_c(fac * (a * pi + b * tau))
        s2[k] = fsum_c(fac * (a * tau + b * pi))
    return qext, qsca, qback, g, s1, s2


def rel(a, b) -> float:
    """|a - b| / |b| (0 when both vanish)."""
    a = complex(a)
    b = complex(b)
    if a == b:
        return 0.0
    return abs(a - b) / abs(b)


def compute_case(m: complex, x: float, mus: np.ndarray, stats: dict) -> list[float]:
    """One CSV row; asserts the convention checks described in the docstring."""
    m_mie = complex(m.real, -m.imag)  # miepython convention: m = n - i k
    a, b = miepython.coefficients(m_mie, x, n_pole=n_terms(x))
    qext, qsca, qback, g, s1, s2 = bh_sums(a, b, x, mus)
    tag = f"m={m!r}, x={x!r}"

    # --- miepython's own amplitudes (default truncation), norm='wiscombe' ---
    s1_mp, s2_mp = miepython.S1_S2(m_mie, x, mus, norm="wiscombe")
    a0, b0 = miepython.coefficients(m_mie, x)  # default (Wiscombe) truncation
    qext0, _, _, _, s1_0, s2_0 = bh_sums(a0, b0, x, mus)
    scale = max(np.max(np.abs(s1_0)), np.max(np.abs(s2_0)))
    conj_err = max(np.max(np.abs(s1_mp - np.conj(s1_0))), np.max(np.abs(s2_mp - np.conj(s2_0)))) / scale
    assert conj_err <= 1e-12, f"S1_S2(norm='wiscombe') != conj(B&H sum): {conj_err:.3g} at {tag}"
    # optical theorem, Qext = 4/x^2 Re S1(0):
    # (i) miepython's S1_S2(norm='wiscombe') against Qext from the same coefficients
    ot = abs(qext0 - 4.0 / (x * x) * s1_mp[0].real) / qext0
    assert ot <= 1e-9, f"optical theorem fails for S1_S2(norm='wiscombe') ({ot:.3g}) at {tag}"
    # (ii) the written qext against the written S1(0)
    ot_csv = abs(qext - 4.0 / (x * x) * s1[0].real) / qext
    assert ot_csv <= 1e-12, f"optical theorem fails for the CSV row ({ot_csv:.3g}) at {tag}"
    # (iii) the written qext against miepython's S1_S2 (differs only by truncation)
    ot_trunc = abs(qext - 4.0 / (x * x) * s1_mp[0].real) / qext
    assert ot_trunc <= 1e-6, f"qext vs 4/x^2 Re S1_S2(0) differ by {ot_trunc:.3g} at {tag}"
    assert s1_mp[0] == s2_mp[0] and rel(s1[0], s2[0]) <= 1e-12, f"S1(0) != S2(0) at {tag}"
    assert rel(abs(s1[-1]), abs(s2[-1])) <= 1e-12, f"|S1(180)| != |S2(180)| at {tag}"
    # sign convention of the amplitude: Re S(0) > 0 and, in B&H convention, the
    # conjugate of miepython's (MIEV0-convention) amplitude
    assert s1[0].real > 0.0, f"Re S1(0) <= 0 at {tag}"
    assert rel(qback, 4.0 * abs(s1[-1]) ** 2 / (x * x)) <= 1e-12, f"qback != 4|S1(180)|^2/x^2 at {tag}"
    assert 0.0 <= qsca <= qext * (1.0 + 1e-12), f"qsca/qext inconsistent at {tag}"
    assert abs(g) < 1.0, f"|g| >= 1 at {tag}"

    # --- cross-check against the stock efficiencies_mx ---
    q_mp = miepython.efficiencies_mx(m_mie, x)
    small_path = abs(m_mie) * x < 0.1
    key = "small-particle path" if small_path else "series path"
    tol = 1e-5
    for name, ours, theirs in zip(("qext", "qsca", "qback", "g"), (qext, qsca, qback, g), q_mp):
        r = rel(ours, float(theirs))
        slot = stats.setdefault(key, {}).setdefault(name, [0.0, ""])
        if r > slot[0]:
            slot[0], slot[1] = r, tag
        assert r <= tol, f"{name} differs from efficiencies_mx by {r:.3g} ({key}) at {tag}"
    stats["ot_max"] = max(stats.get("ot_max", 0.0), ot)
    stats["ot_csv_max"] = max(stats.get("ot_csv_max", 0.0), ot_csv)
    stats["ot_trunc_max"] = max(stats.get("ot_trunc_max", 0.0), ot_trunc)
    stats["conj_max"] = max(stats.get("conj_max", 0.0), conj_err)

    row = [m.real, m.imag, x, qext, qsca, qback, g]
    for k in range(len(mus)):
        row += [abs(s1[k]) ** 2, abs(s2[k]) ** 2]
    return row


# ----------------------------------------------------------------------------
# Optional independent audit in high precision (mpmath).  Own implementation of
# the textbook recurrences; not used for the CSV values.
# ----------------------------------------------------------------------------
def mie_mpmath(m: complex, x: float, angles_deg, dps: int = 40):
    """Mie series in mpmath; m in physics convention. Returns dict of mpf/mpc."""
    import mpmath as mpm

    mpm.mp.dps = dps
    mm = mpm.mpc(m.real, m.imag)
    xx = mpm.mpf(x)
    n_max = int(x + 4.05 * x ** (1 / 3) + 2) + 20 + int(4 * x ** (1 / 3))
    z = mm * xx
    n_start = int(max(n_max, abs(complex(z))) + 60 + 4 * abs(complex(z)) ** (1 / 3))
    d = [mpm.mpc(0)] * (n_start + 1)  # D_n(mx), downward recurrence
    dn = mpm.mpc(0)
    for n in range(n_start, 0, -1):
        dn = n / z - 1 / (dn + n / z)
        d[n - 1] = dn

    # psi_n(x) = x j_n(x): Miller's downward recurrence from far above n_max,
    # normalised with psi_0 = sin x or psi_1 = sin x / x - cos x (the larger one)
    n_top = n_max + 40 + int(10 * x ** (1 / 3))
    psi = [mpm.mpf(0)] * (n_top + 2)
    psi[n_top] = mpm.mpf(10) ** -30
    for n in range(n_top, 0, -1):
        psi[n - 1] = (2 * n + 1) / xx * psi[n] - psi[n + 1]
    psi0, psi1 = mpm.sin(xx), mpm.sin(xx) / xx - mpm.cos(xx)
    scale = psi1 / psi[1] if abs(psi1) > abs(psi0) else psi0 / psi[0]
    psi = [p * scale for p in psi[: n_max + 2]]
    chi = [mpm.mpf(0)] * (n_max + 2)  # chi_n(x) = -x y_n(x), upward
    chi[0] = mpm.cos(xx)
    chi[1] = mpm.cos(xx) / xx + mpm.sin(xx)
    for n in range(1, n_max + 1):
        chi[n + 1] = (2 * n + 1) / xx * chi[n] - chi[n - 1]
    a, b = [], []
    for n in range(1, n_max + 1):
        xi_n = psi[n] - 1j * chi[n]
        xi_nm1 = psi[n - 1] - 1j * chi[n - 1]
        t = d[n] / mm + n / xx
        a.append((t * psi[n] - psi[n - 1]) / (t * xi_n - xi_nm1))
        t = d[n] * mm + n / xx
        b.append((t * psi[n] - psi[n - 1]) / (t * xi_n - xi_nm1))
    x2 = xx * xx
    rng = range(1, n_max + 1)
    qext = 2 / x2 * mpm.fsum((2 * n + 1) * mpm.re(a[n - 1] + b[n - 1]) for n in rng)
    qsca = 2 / x2 * mpm.fsum((2 * n + 1) * (abs(a[n - 1]) ** 2 + abs(b[n - 1]) ** 2) for n in rng)
    qback = abs(mpm.fsum((2 * n + 1) * (-1) ** n * (a[n - 1] - b[n - 1]) for n in rng)) ** 2 / x2
    gsum = mpm.fsum(
        mpm.mpf(n * (n + 2)) / (n + 1) * mpm.re(a[n - 1] * mpm.conj(a[n]) + b[n - 1] * mpm.conj(b[n]))
        + mpm.mpf(2 * n + 1) / (n * (n + 1)) * mpm.re(a[n - 1] * mpm.conj(b[n - 1]))
        for n in range(1, n_max)
    )
    out = {"qext": qext, "qsca": qsca, "qback": qback, "g": 4 / x2 * gsum / qsca}
    for th in angles_deg:
        # same float64 mu as the CSV, promoted exactly to mpf
        mu = mpm.mpf(float(np.cos(np.deg2rad(th))))
        pi_nm1, pi_n = mpm.mpf(0), mpm.mpf(1)
        s1 = s2 = mpm.mpc(0)
        for n in rng:
            tau_n = n * mu * pi_n - (n + 1) * pi_nm1
            f = mpm.mpf(2 * n + 1) / (n * (n + 1))
            s1 += f * (a[n - 1] * pi_n + b[n - 1] * tau_n)
            s2 += f * (a[n - 1] * tau_n + b[n - 1] * pi_n)
            pi_nm1, pi_n = pi_n, ((2 * n + 1) * mu * pi_n - (n + 1) * pi_nm1) / n
        out[f"s1sq_{th}"] = abs(s1) ** 2
        out[f"s2sq_{th}"] = abs(s2) ** 2
    return out


def mpmath_audit(rows: list[list[float]], dps: int) -> None:
    worst = {c: (0.0, None) for c in COLUMNS[3:]}
    t0 = time.time()
    for i, row in enumerate(rows):
        m = complex(row[0], row[1])
        x = row[2]
        ref = mie_mpmath(m, x, ANGLES_DEG, dps)
        for j, c in enumerate(COLUMNS[3:], start=3):
            r = abs(row[j] - float(ref[c])) / abs(float(ref[c]))
            if r > worst[c][0]:
                worst[c] = (r, (m, x))
        if (i + 1) % 50 == 0:
            print(f"  mpmath audit: {i + 1}/{len(rows)} rows, {time.time() - t0:.0f} s", file=sys.stderr)
    print(f"mpmath audit ({dps} digits): largest relative deviation of the CSV per column")
    for c, (r, where) in worst.items():
        print(f"  {c:10s} {r:9.2e}   at m={where[0]!r}, x={where[1]!r}" if where else f"  {c:10s} 0")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=default_out(), help="output CSV (default: %(default)s)")
    ap.add_argument("--seed", type=int, default=DEFAULT_SEED, help="random seed (default: %(default)s)")
    ap.add_argument("--mpmath-check", action="store_true", help="audit every row against a 40-digit mpmath evaluation")
    ap.add_argument("--mpmath-dps", type=int, default=40)
    ap.add_argument("--allow-other-version", action="store_true", help="run with a miepython other than 3.3.0")
    args = ap.parse_args(argv)

    if miepython.__version__ != EXPECTED_MIEPYTHON and not args.allow_other_version:
        print(
            f"miepython {miepython.__version__} found, the committed file was made with {EXPECTED_MIEPYTHON}; "
            "pass --allow-other-version to continue anyway",
            file=sys.stderr,
        )
        return 2
    assert not miepython.USE_JIT, "expected miepython's numpy backend"

    mus = np.cos(np.deg2rad(np.array(ANGLES_DEG, dtype=np.float64)))
    cases = make_cases(args.seed)
    stats: dict = {}
    rows = []
    t0 = time.time()
    for kind, m, x in cases:
        rows.append(compute_case(m, x, mus, stats))
    elapsed = time.time() - t0

    header = [
        f"# generator: tools/reference/mie_miepython.py (seed {args.seed}); {len(rows)} cases "
        f"({len(FIXED_X) * len(FIXED_M)} fixed + {N_MAIN + N_LOW} random)",
        f"# miepython {miepython.__version__} (numpy backend, MIEPYTHON_USE_JIT=0), numpy {np.__version__}, "
        f"python {platform.python_version()}",
        "# convention: m = m_re + i*m_im, m_im >= 0 absorbing (miepython was called with conj(m)); "
        "x = 2*pi*r/lambda",
        "# qext,qsca,qback,g from miepython.coefficients with Bohren-Huffman sums, "
        "N = int(x+4.05x^(1/3)+2)+int(4x^(1/3))+8 terms; qback = |sum (2n+1)(-1)^n (a_n-b_n)|^2/x^2",
        "# s1sq_T,s2sq_T = |S1|^2,|S2|^2 at theta=T deg, unnormalised Bohren-Huffman amplitudes "
        "(Qext = 4/x^2 Re S1(0)); mu = cos(T*pi/180) in float64",
    ]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with open(args.out, "w", newline="\n") as fh:
        for line in header:
            fh.write(line + "\n")
        fh.write(",".join(COLUMNS) + "\n")
        for row in rows:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")

    n_abs = sum(1 for r in rows if r[1] > 0)
    n_low = sum(1 for r in rows if r[0] < 1)
    print(f"wrote {args.out} : {len(rows)} rows ({n_abs} absorbing, {n_low} with m_re < 1) in {elapsed:.1f} s")
    print("optical theorem, max |Qext - 4/x^2 Re S1(0)|/Qext:")
    print(f"  S1_S2(norm='wiscombe') vs Qext from the same (Wiscombe-truncated) a_n, b_n: {stats['ot_max']:.2e}")
    print(f"  CSV qext vs CSV S1(0):                                     {stats['ot_csv_max']:.2e}")
    print(f"  CSV qext vs S1_S2(norm='wiscombe') (truncation differs):   {stats['ot_trunc_max']:.2e}")
    print(f"S1_S2(norm='wiscombe') vs conj(B&H sum of miepython a_n,b_n): max rel {stats['conj_max']:.2e}")
    print("largest relative difference from miepython.efficiencies_mx:")
    for key, d in sorted(stats.items()):
        if not isinstance(d, dict):
            continue
        for name, (r, where) in d.items():
            print(f"  {key:20s} {name:6s} {r:9.2e}   at {where}")
    if args.mpmath_check:
        mpmath_audit(rows, args.mpmath_dps)
    return 0


if __name__ == "__main__":
    sys.exit(main())
