#!/usr/bin/env python3
"""Reference data for lucent::surface (tests/surface.rs, agrees_with_numpy_surfalize_and_x3pio).

Writes into fixtures/reference/surface/:
  plain_D.x3p          float64, no invalid point (x3pio)
  masked_F.x3p         float32, NaN at invalid points (x3pio)
  masked_L.x3p         int32 with a validity file (x3pio)
  masked_I.x3p         int16 with a validity file (x3pio)
  reference.json       per file: size, valid points, Σ heights and sample heights as x3pio reads them;
                       the least-squares plane (numpy lstsq); Gaussian-weighted plane-fit slopes at
                       selected pixels (numpy lstsq, window 15, σ 1 px, weight fraction ≥ 0.9);
                       for plain_D: S_q, S_dq of the levelled surface by surfalize (reading the file
                       with its own X3P reader). lucent_fixture: the project's shipped X3P as x3pio
                       reads it (checksums verified) and as surfalize reads it.

Run from the repository root:
  pip install x3pio==2.0.0 surfalize==0.19.2 numpy==2.4.6 scipy==1.17.1
  python3 tools/reference/surface_reference.py [lucent-written .x3p files to verify with x3pio ...]
"""
import json
import sys
from pathlib import Path

import numpy as np
import scipy
import scipy.ndimage
import surfalize
import x3pio

OUT = Path("fixtures/reference/surface")
FIXTURE = Path("fixtures/surface/tr_0p0084.x3p")
VERSIONS = {"x3pio": "2.0.0", "surfalize": "0.19.2", "numpy": "2.4.6", "scipy": "1.17.1"}
WINDOW, SIGMA, MIN_FRACTION = 15, 1.0, 0.9


def check_versions():
    got = {"x3pio": x3pio.__version__, "surfalize": surfalize.__version__, "numpy": np.__version__, "scipy": scipy.__version__}
    if got != VERSIONS and "--allow-other-version" not in sys.argv:
        sys.exit(f"versions {got} differ from {VERSIONS}; pass --allow-other-version to run anyway")


def surface(nx=96, ny=72, px=0.871e-6, py=1.1e-6):
    """A smooth random surface (Gaussian-filtered noise, σ 3 px) plus a tilt and a ripple, metres."""
    rng = np.random.default_rng(2026)
    noise = scipy.ndimage.gaussian_filter(rng.standard_normal((ny, nx)), 3.0, mode="wrap")
    noise *= 5e-8 / noise.std()
    y, x = np.mgrid[:ny, :nx]
    z = noise + 0.004 * x * px - 0.002 * y * py + 2e-8 * np.sin(2 * np.pi * x / 23.0) + 3e-7
    invalid = rng.random((ny, nx)) < 0.02
    invalid[30:34, 40:45] = True
    invalid[0, 0] = True
    return z, invalid, px, py


def plane(z):
    ny, nx = z.shape
    y, x = np.mgrid[:ny, :nx]
    ok = np.isfinite(z)
    a = np.column_stack([np.ones(ok.sum()), x[ok], y[ok]])
    c, *_ = np.linalg.lstsq(a, z[ok], rcond=None)
    return c  # per pixel


def plane_fit(z, i, j, px, py):
    """Gaussian-weighted least-squares plane at pixel (i, j): slopes or None."""
    ny, nx = z.shape
    r = WINDOW // 2
    w1 = np.exp(-np.arange(-r, r + 1) ** 2 / (2 * SIGMA**2))
    full = w1.sum() ** 2
    rows, weights, values = [], [], []
    for v in range(-r, r + 1):
        for u in range(-r, r + 1):
            ii, jj = i + u, j + v
            if 0 <= ii < nx and 0 <= jj < ny and np.isfinite(z[jj, ii]):
                rows.append([1.0, u, v])
                weights.append(w1[u + r] * w1[v + r])
                values.append(z[jj, ii])
    fraction = sum(weights) / full
    if not np.isfinite(z[j, i]) or fraction < MIN_FRACTION:
        return None, fraction
    sw = np.sqrt(np.array(weights))
    c, *_ = np.linalg.lstsq(np.array(rows) * sw[:, None], np.array(values) * sw, rcond=None)
    return (c[1] / px, c[2] / py), fraction


def pixels(z, rng):
    ny, nx = z.shape
    picks = {(int(rng.integers(0, nx)), int(rng.integers(0, ny))) for _ in range(40)}
    picks |= {(0, 10), (1, 10), (2, 10), (10, 0), (10, 1), (nx - 1, 20), (nx - 2, ny - 2), (44, 29), (46, 32), (39, 31)}
    bad = np.argwhere(~np.isfinite(z))
    for jj, ii in bad[:: max(1, len(bad) // 10)]:
        for di, dj in ((1, 0), (0, 1), (2, 1)):
            if 0 <= ii + di < nx and 0 <= jj + dj < ny:
                picks.add((int(ii + di), int(jj + dj)))
    return sorted(picks)


def describe(path, px, py, with_surfalize):
    f = x3pio.read(str(path), verify=True)
    z = np.asarray(f.layers[0].z, dtype=np.float64)
    ny, nx = z.shape
    assert abs(f.header.x.increment - px) < 1e-20 and abs(f.header.y.increment - py) < 1e-20
    rng = np.random.default_rng(7)
    samples = []
    for _ in range(25):
        i, j = int(rng.integers(0, nx)), int(rng.integers(0, ny))
        samples.append({"i": i, "j": j, "z_m": float(z[j, i]) if np.isfinite(z[j, i]) else None})
    for jj, ii in np.argwhere(~np.isfinite(z))[:5]:
        samples.append({"i": int(ii), "j": int(jj), "z_m": None})
    c = plane(z)
    yy, xx = np.mgrid[:ny, :nx]
    levelled = z - (c[0] + c[1] * xx + c[2] * yy)
    fits = []
    for i, j in pixels(z, rng):
        s, frac = plane_fit(levelled, i, j, px, py)
        fits.append({"i": i, "j": j, "weight_fraction": frac, "slope_x": s and float(s[0]), "slope_y": s and float(s[1])})
    case = {
        "file": path.name,
        "nx": nx,
        "ny": ny,
        "valid_points": int(np.isfinite(z).sum()),
        "sum_valid_m": float(np.nansum(z)),
        "samples": samples,
        "plane": {"slope_x": float(c[1] / px), "slope_y": float(c[2] / py)},
        "plane_fits": fits,
    }
    if with_surfalize:
        s = surfalize.Surface.load(str(path))
        assert np.allclose(s.data * 1e-6, z, rtol=0, atol=1e-18), "surfalize and x3pio read different heights"
        lev = s.level()
        case["surfalize"] = {"Sq_m": float(lev.Sq()) * 1e-6, "Sdq": float(lev.Sdq()), "units": "surfalize µm → m"}
    return case


def main():
    check_versions()
    OUT.mkdir(parents=True, exist_ok=True)
    z, invalid, px, py = surface()
    x3pio.write(str(OUT / "plain_D.x3p"), z, x_scale=px, y_scale=py, metadata=None)
    zm = np.where(invalid, np.nan, z)
    x3pio.write(str(OUT / "masked_F.x3p"), zm, x_scale=px, y_scale=py, z_type=x3pio.DataType.FLOAT32)
    x3pio.write(str(OUT / "masked_L.x3p"), zm, x_scale=px, y_scale=py, z_type=x3pio.DataType.INT32)
    x3pio.write(str(OUT / "masked_I.x3p"), zm, x_scale=px, y_scale=py, z_type=x3pio.DataType.INT16)
    files = [describe(OUT / n, px, py, n == "plain_D.x3p") for n in ("plain_D.x3p", "masked_F.x3p", "masked_L.x3p", "masked_I.x3p")]
    fx = x3pio.read(str(FIXTURE), verify=True)
    fz = np.asarray(fx.layers[0].z, dtype=np.float64)
    sf = surfalize.Surface.load(str(FIXTURE))
    assert int(np.isfinite(sf.data).sum()) == int(np.isfinite(fz).sum()), "surfalize and x3pio disagree on the fixture"
    fixture = {
        "file": str(FIXTURE),
        "reader": "x3pio.read(verify=True): zip CRCs and all MD5 checksums verified; surfalize reads the same valid points",
        "valid_points": int(np.isfinite(fz).sum()),
        "sum_valid_m": float(np.nansum(fz)),
        "pitch_x_m": float(fx.header.x.increment),
    }
    for extra in sys.argv[1:]:
        if extra.startswith("--"):
            continue
        e = x3pio.read(extra, verify=True)
        print(f"{extra}: x3pio reads it (checksums verified), {np.isfinite(e.layers[0].z).sum()} valid points, type {e.header.z.data_type}")
    ref = {
        "generator": "tools/reference/surface_reference.py",
        "versions": VERSIONS,
        "plane_fit": {"window_px": WINDOW, "sigma_px": SIGMA, "min_weight_fraction": MIN_FRACTION},
        "files": files,
        "lucent_fixture": fixture,
    }
    (OUT / "reference.json").write_text(json.dumps(ref, indent=1) + "\n")
    print(f"wrote {OUT}/reference.json: {len(files)} files; plain_D Sq {files[0]['surfalize']['Sq_m']:.4e} m, Sdq {files[0]['surfalize']['Sdq']:.5f}")


if __name__ == "__main__":
    main()
