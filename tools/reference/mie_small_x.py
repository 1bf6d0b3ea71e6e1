#!/usr/bin/env python3
"""Generate ``fixtures/reference/mie_small_x.csv``: Lorenz-Mie efficiencies of very
small spheres (x = 1e-8 ... 3), for real and absorbing relative indices.

Purpose
-------
lucent switches from the upward recurrence of psi_n(x) to its power series below
|x| = 1 (src/optics/mie.rs, "Small spheres").  These rows check the small-x limit
and both sides of the switch against miepython.

How the numbers are obtained
----------------------------
As in ``mie_miepython.py``: ``miepython.coefficients(conj(m), x, n_pole=N)``
(miepython 3.3.0, numpy backend; its psi_n comes from Miller's downward
recurrence normalised with sin x, accurate at any x) summed with the
Bohren-Huffman formulas (``mie_miepython.bh_sums``), N = int(x + 4.05 x^(1/3) + 2)
+ int(4 x^(1/3)) + 8.  Not ``efficiencies_mx``: below |m| x = 0.1 that returns
Wiscombe's small-particle expansions, good to only ~1e-6.

Every row is then audited against the independent 50-digit mpmath evaluation of
``mie_miepython.mie_mpmath``; the script stops if qext or qsca differ by more than
1e-10 relative or g by more than 1e-13 absolute (the measured deviations are
printed and written into the header).

Cases: x in {1e-8, 3e-8, 1e-7, ..., 0.3} and around the switch
{0.5, 0.9, 0.99, 0.999, 0.9999, 1, 1.0001, 1.001, 1.01, 1.1, 1.5, 2, 3}, crossed with
m in {1.5, 0.9, 1.33, 2.5, 1.5+1e-6i, 1.5+0.01i, 0.9+0.1i, 2.5+1i, 1.8+0.5i}.
Convention: m = m_re + i m_im, m_im >= 0 absorbing (miepython gets conj(m)).

Run from the repository root::

    python3 tools/reference/mie_small_x.py [--out PATH]

Versions: Python 3.11.7, miepython 3.3.0, numpy 2.4.6, mpmath 1.3.0
(``pip install miepython==3.3.0 numpy==2.4.6 mpmath==1.3.0``); another miepython
version is refused unless ``--allow-other-version`` is given.
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

import mie_miepython as ref  # noqa: E402  (forces miepython's numpy backend)

miepython = ref.miepython
X_SMALL = [10.0**e for e in (-8, -7, -6, -5, -4, -3, -2, -1)] + [3.0 * 10.0**e for e in (-8, -7, -6, -5, -4, -3, -2, -1)]
X_SWITCH = [0.5, 0.9, 0.99, 0.999, 0.9999, 1.0, 1.0001, 1.001, 1.01, 1.1, 1.5, 2.0, 3.0]
M = [
    complex(1.5, 0.0),
    complex(0.9, 0.0),
    complex(1.33, 0.0),
    complex(2.5, 0.0),
    complex(1.5, 1e-6),
    complex(1.5, 0.01),
    complex(0.9, 0.1),
    complex(2.5, 1.0),
    complex(1.8, 0.5),
]
COLUMNS = ["m_re", "m_im", "x", "qext", "qsca", "qback", "g"]


def default_out() -> Path:
    return Path(__file__).resolve().parents[2] / "fixtures" / "reference" / "mie_small_x.csv"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=default_out())
    ap.add_argument("--allow-other-version", action="store_true")
    args = ap.parse_args(argv)
    if miepython.__version__ != ref.EXPECTED_MIEPYTHON and not args.allow_other_version:
        print(f"miepython {miepython.__version__} found, expected {ref.EXPECTED_MIEPYTHON}", file=sys.stderr)
        return 2

    xs = sorted(X_SMALL) + X_SWITCH
    mus = np.array([1.0])
    rows = []
    worst = {"qext": (0.0, ""), "qsca": (0.0, ""), "qback": (0.0, ""), "g": (0.0, "")}
    for m in M:
        for x in xs:
            a, b = miepython.coefficients(complex(m.real, -m.imag), x, n_pole=ref.n_terms(x))
            qext, qsca, qback, g, _, _ = ref.bh_sums(a, b, x, mus)
            mp = ref.mie_mpmath(m, x, (), dps=50)
            for name, ours in (("qext", qext), ("qsca", qsca), ("qback", qback)):
                e = abs(ours - float(mp[name])) / abs(float(mp[name]))
                if e > worst[name][0]:
                    worst[name] = (e, f"m={m} x={x}")
            e = abs(g - float(mp["g"]))
            if e > worst["g"][0]:
                worst["g"] = (e, f"m={m} x={x}")
            rows.append([m.real, m.imag, x, qext, qsca, qback, g])
    print(f"{len(rows)} cases; largest deviation from 50-digit mpmath:")
    for k, (e, where) in worst.items():
        print(f"  {k:6s} {e:.2e} {'absolute' if k == 'g' else 'relative'} ({where})")
    if worst["qext"][0] > 1e-10 or worst["qsca"][0] > 1e-10 or worst["g"][0] > 1e-13:
        print("miepython disagrees with mpmath beyond the tolerance; not writing", file=sys.stderr)
        return 1

    header = [
        f"# generator: tools/reference/mie_small_x.py; {len(rows)} cases, x = 1e-8 .. 3, real and absorbing m",
        f"# miepython {miepython.__version__} (numpy backend) coefficients with Bohren-Huffman sums, numpy {np.__version__},"
        f" python {platform.python_version()}; N = int(x+4.05x^(1/3)+2)+int(4x^(1/3))+8 terms",
        "# convention: m = m_re + i*m_im, m_im >= 0 absorbing (miepython was called with conj(m)); x = 2*pi*r*n_host/lambda",
        f"# audited against 50-digit mpmath: qext {worst['qext'][0]:.1e}, qsca {worst['qsca'][0]:.1e},"
        f" qback {worst['qback'][0]:.1e} relative; g {worst['g'][0]:.1e} absolute (largest deviations)",
    ]
    with open(args.out, "w", newline="\n") as fh:
        for line in header:
            fh.write(line + "\n")
        fh.write(",".join(COLUMNS) + "\n")
        for row in rows:
            fh.write(",".join(repr(float(v)) for v in row) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
