#!/usr/bin/env python3
"""Export the colour data tables that ``lucent-colour`` embeds into ``colour/data/*.csv``.

Purpose
-------
The Rust crate ``lucent-colour`` (``colour/``) compiles these CSV files in with
``include_str!``.  Every table comes from the Python package colour-science
(``pip install colour-science``), which redistributes CIE, X-Rite and
N. Ohta data under its BSD-3-Clause licence; the original source of each table
is written into the header of its CSV file and into ``colour/data/README.md``.
Numbers are written with 12 significant digits (Python ``repr`` of the value
rounded to 12 digits): every digit of the source tables, without binary noise.

How to run (from the repository root)::

    pip install colour-science==0.4.7
    python3 tools/reference/export_colour_data.py            # writes colour/data/*.csv
    python3 tools/reference/export_colour_data.py --out /tmp/x

Versions used for the committed files: Python 3.11.7, colour-science 0.4.7,
numpy 2.4.6.  The script refuses another colour-science version unless
``--allow-other-version`` is given.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

try:
    import colour
except ImportError:  # pragma: no cover
    sys.exit("colour-science is not installed: pip install colour-science==0.4.7")

EXPECTED_VERSION = "0.4.7"
ROOT = pathlib.Path(__file__).resolve().parents[2]

OBSERVER_1931 = "CIE 1931 2 Degree Standard Observer"
# colour-science calls the CIE 2012 2-degree XYZ CMFs (CIE 170-2:2015, based
# on the Stockman & Sharpe 2000 cone fundamentals) "CIE 2015 2 Degree".
OBSERVER_2012 = "CIE 2015 2 Degree Standard Observer"
RGB_1931 = "Wright & Guild 1931 2 Degree RGB CMFs"
CHECKER = "ColorChecker24 - After November 2014"
CHECKER_SDS_NAME = "ColorChecker N Ohta"

COMMON = (
    "# exported by tools/reference/export_colour_data.py from colour-science {version} "
    "(BSD-3-Clause; data redistributed by colour-science)\n"
)


def fmt(x: float) -> str:
    # 12 significant digits drop binary noise such as 0.04799999999999999
    # (Ohta's table is 0.048) and keep every digit of the source tables.
    x = float(f"{float(x):.12g}")
    if x == 0.0:
        return "0"
    return repr(x)


def write(path: pathlib.Path, header: list[str], columns: list[str], rows) -> None:
    lines = [COMMON.format(version=colour.__version__)]
    lines += [f"# {h}\n" for h in header]
    lines.append(",".join(columns) + "\n")
    for row in rows:
        lines.append(",".join(r if isinstance(r, str) else fmt(r) for r in row) + "\n")
    path.write_text("".join(lines), encoding="utf-8")
    print(f"wrote {path} ({len(lines)} lines)")


def cmfs_rows(name: str):
    cmfs = colour.MSDS_CMFS[name]
    return [(w, *v) for w, v in zip(cmfs.wavelengths, cmfs.values)], cmfs.shape


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=pathlib.Path, default=ROOT / "colour" / "data")
    ap.add_argument("--allow-other-version", action="store_true")
    args = ap.parse_args()
    if colour.__version__ != EXPECTED_VERSION and not args.allow_other_version:
        sys.exit(f"colour-science {colour.__version__} found, {EXPECTED_VERSION} expected (--allow-other-version)")
    out: pathlib.Path = args.out
    out.mkdir(parents=True, exist_ok=True)

    rows, shape = cmfs_rows(OBSERVER_1931)
    write(
        out / "cie1931_2deg_xyz.csv",
        [
            f"CIE 1931 2-degree standard observer colour-matching functions x_bar, y_bar, z_bar ({shape.start:g}-{shape.end:g} nm, {shape.interval:g} nm)",
            "source: CIE 015:2018 / CIE 15:2004 tables (colour-science MSDS_CMFS['CIE 1931 2 Degree Standard Observer'])",
            "units: wavelength in nm (in air); CMFs dimensionless, y_bar(555 nm) = 1",
            "licence: CIE data tables, freely available; redistributed by colour-science (BSD-3-Clause)",
        ],
        ["wavelength_nm", "x_bar", "y_bar", "z_bar"],
        rows,
    )

    rows, shape = cmfs_rows(OBSERVER_2012)
    write(
        out / "cie2012_2deg_xyz.csv",
        [
            f"CIE 2012 2-degree XYZ colour-matching functions (CIE 170-2:2015; 'CIE 2015 2 Degree Standard Observer' in colour-science) ({shape.start:g}-{shape.end:g} nm, {shape.interval:g} nm)",
            "source: CVRL (Colour & Vision Research Laboratory, UCL), linear transformation of the Stockman & Sharpe (2000) 2-degree cone fundamentals, via colour-science MSDS_CMFS",
            "units: wavelength in nm; CMFs dimensionless",
            "licence: CIE/CVRL public data; redistributed by colour-science (BSD-3-Clause)",
        ],
        ["wavelength_nm", "x_bar", "y_bar", "z_bar"],
        rows,
    )

    rows, shape = cmfs_rows(RGB_1931)
    write(
        out / "cie1931_rgb_wright_guild.csv",
        [
            f"CIE 1931 RGB colour-matching functions r_bar, g_bar, b_bar (Wright & Guild data as adopted by the CIE in 1931; primaries 700, 546.1, 435.8 nm) ({shape.start:g}-{shape.end:g} nm, {shape.interval:g} nm)",
            "source: colour-science MSDS_CMFS['Wright & Guild 1931 2 Degree RGB CMFs'] (CVRL tabulation of the CIE 1931 r_bar g_bar b_bar); negative lobes are part of the data",
            "units: wavelength in nm; CMFs dimensionless, equal areas (equal-energy white E has R = G = B)",
            "licence: CIE/CVRL public data; redistributed by colour-science (BSD-3-Clause)",
        ],
        ["wavelength_nm", "r_bar", "g_bar", "b_bar"],
        rows,
    )

    ills = {k: colour.SDS_ILLUMINANTS[k] for k in ("D50", "D65", "A")}
    shapes = {k: v.shape for k, v in ills.items()}
    assert len(set(shapes.values())) == 1, shapes
    shape = shapes["D65"]
    wl = ills["D65"].wavelengths
    write(
        out / "illuminants_d50_d65_a.csv",
        [
            f"CIE illuminants D50, D65 and standard illuminant A, relative spectral power ({shape.start:g}-{shape.end:g} nm, {shape.interval:g} nm)",
            "source: CIE 15:2004 tables data (colour-science SDS_ILLUMINANTS); illuminant E (equal energy) is the constant 100 and is not tabulated",
            "units: wavelength in nm; relative spectral power, 100 at 560 nm",
            "licence: CIE data tables, freely available; redistributed by colour-science (BSD-3-Clause)",
        ],
        ["wavelength_nm", "D50", "D65", "A"],
        [(w, ills["D50"][w], ills["D65"][w], ills["A"][w]) for w in wl],
    )

    cc = colour.CCS_COLOURCHECKERS[CHECKER]
    xyY = np.array(list(cc.data.values()))
    lab = colour.XYZ_to_Lab(colour.xyY_to_XYZ(xyY), cc.illuminant)
    write(
        out / "colorchecker24_after_nov2014.csv",
        [
            "X-Rite ColorChecker Classic (24 patches), reference values for charts made after November 2014",
            "source: X-Rite (2016), 'New color specifications for ColorChecker SG and Classic Charts', via colour-science CCS_COLOURCHECKERS['ColorChecker24 - After November 2014']",
            f"illuminant: ICC D50, white point x = {cc.illuminant[0]!r}, y = {cc.illuminant[1]!r}, CIE 1931 2-degree observer",
            "units: x, y chromaticity; Y relative luminance with the perfect white at 1; L*, a*, b* CIELAB (D50) computed by colour-science from xyY (they equal X-Rite's published two-decimal L*a*b*)",
            "licence: published reference values of a commercial chart; redistributed by colour-science (BSD-3-Clause)",
            "order: row by row from the top-left patch (dark skin) to the bottom-right (black) with the chart's neutral row at the bottom",
        ],
        ["patch", "name", "x", "y", "Y", "L", "a", "b"],
        [
            (str(i + 1), name, *xyY[i], *[round(float(v), 10) for v in lab[i]])
            for i, name in enumerate(cc.data.keys())
        ],
    )

    sds = colour.SDS_COLOURCHECKERS[CHECKER_SDS_NAME]
    names = list(sds.keys())
    shape = sds[names[0]].shape
    wl = sds[names[0]].wavelengths
    write(
        out / "colorchecker_ohta_reflectance.csv",
        [
            f"Spectral reflectance of the 24 ColorChecker Classic patches, measured by N. Ohta ({shape.start:g}-{shape.end:g} nm, {shape.interval:g} nm)",
            "source: N. Ohta (1997), The basis of color reproduction engineering; identical to ISO 17321-1:2012 (colour-science SDS_COLOURCHECKERS['ColorChecker N Ohta'])",
            "note: a chart made before November 2014; the post-2014 reference L*a*b* (colorchecker24_after_nov2014.csv) differ from these spectra by dE2000 1.2 on average, 2.4 at most (D50, CIE 1931 2-degree)",
            "units: wavelength in nm; reflectance factor 0..1; columns patch_1 .. patch_24 in chart order",
            "licence: published measurement data; redistributed by colour-science (BSD-3-Clause)",
        ],
        ["wavelength_nm"] + [f"patch_{i + 1}" for i in range(len(names))],
        [(w, *[sds[n][w] for n in names]) for w in wl],
    )


if __name__ == "__main__":
    main()
