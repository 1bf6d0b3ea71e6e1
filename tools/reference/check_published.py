#!/usr/bin/env python3
"""Cross-check ``fixtures/reference/mie_published.csv`` against miepython.

Every published value (Wiscombe 1979/1996 MIEV0 test cases, Bohren & Huffman 1983
Appendix A) is compared with

* ``miepython``: the Bohren-Huffman sums over miepython 3.3.0's Mie coefficients
  with the extended truncation used by ``mie_miepython.py`` (the same numbers that
  script would write), and
* ``eff_mx``: miepython's stock ``efficiencies_mx`` (Wiscombe truncation,
  small-particle expansions for |m| x < 0.1), for information only;
* with ``--mpmath``: also an independent 40-digit evaluation (slow for x = 10^4).

A value counts as a discrepancy when it differs from ``miepython`` by more than the
tolerance stated in the CSV header, ``|published - miepython| > 10**(1-digits) |published|``.

Conventions are those of the CSV: m = m_re + i m_im with m_im >= 0 absorbing
(miepython is called with conj(m)); qback = 4|S1(180)|^2/x^2.

Run from the repository root::

    python3 tools/reference/check_published.py [--mpmath] [--csv PATH]

Exit status 0 when every value is within tolerance, 1 otherwise.
Uses the same package versions as mie_miepython.py (miepython 3.3.0, numpy backend).
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import mie_miepython as ref  # noqa: E402  (sets MIEPYTHON_USE_JIT=0 before importing miepython)

miepython = ref.miepython
QUANTITIES = ("qext", "qsca", "qback", "g")


def read_rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    return list(csv.DictReader(lines))


def tolerance(value: float, digits: int) -> float:
    """Absolute tolerance for a published value carrying `digits` reliable digits."""
    return 10.0 ** (1 - digits) * abs(value)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--csv", type=Path, default=ref.default_out().with_name("mie_published.csv"))
    ap.add_argument("--mpmath", action="store_true", help="also compare with a 40-digit mpmath evaluation")
    args = ap.parse_args(argv)

    rows = read_rows(args.csv)
    mu1 = np.array([1.0])
    bad = []
    print(f"{len(rows)} rows from {args.csv}; miepython {miepython.__version__}")
    hdr = f"{'source':27s} {'m':>12s} {'x':>9s} {'qty':5s} {'published':>13s} {'miepython':>19s} {'rel.diff':>9s} {'eff_mx rel':>10s}"
    if args.mpmath:
        hdr += f" {'mpmath rel':>10s}"
    print(hdr)
    for row in rows:
        m = complex(float(row["m_re"]), float(row["m_im"]))
        x = float(row["x"])
        digits = int(row["digits"])
        m_mie = complex(m.real, -m.imag)
        a, b = miepython.coefficients(m_mie, x, n_pole=ref.n_terms(x))
        ours = dict(zip(QUANTITIES, ref.bh_sums(a, b, x, mu1)[:4]))
        stock = dict(zip(QUANTITIES, (float(v) for v in miepython.efficiencies_mx(m_mie, x))))
        mp = ref.mie_mpmath(m, x, ()) if args.mpmath else None
        mstr = f"{m.real:g}{m.imag:+g}i"
        for q in QUANTITIES:
            if not row[q]:
                continue
            pub = float(row[q])
            diff = abs(pub - ours[q])
            status = "" if diff <= tolerance(pub, digits) else "  <-- DISCREPANCY"
            line = (
                f"{row['source']:27s} {mstr:>12s} {x:9.4g} {q:5s} {row[q]:>13s} {ours[q]:19.12e} "
                f"{(pub - ours[q]) / abs(ours[q]):9.1e} {(stock[q] - ours[q]) / abs(ours[q]):10.1e}"
            )
            if mp is not None:
                line += f" {(ours[q] - float(mp[q])) / abs(float(mp[q])):10.1e}"
            print(line + status)
            if status:
                bad.append((row["source"], mstr, x, q, row[q], ours[q]))
    print()
    if bad:
        print(f"{len(bad)} published value(s) differ from miepython by more than 10^(1-digits) relative:")
        for src, mstr, x, q, pub, val in bad:
            print(f"  {src} m={mstr} x={x:g} {q}: published {pub}, miepython {val:.10g}")
        return 1
    print("all published values agree with miepython within their stated digits")
    return 0


if __name__ == "__main__":
    sys.exit(main())
