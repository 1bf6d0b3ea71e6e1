#!/usr/bin/env python3
"""Time miepython against lucent on the spheres of fixtures/reference/mie_miepython.csv.

What is timed: efficiencies only (qext, qsca, qback, g), one call of
``miepython.efficiencies_mx(m_array, x_array)`` over all cases of the CSV (m passed
as conj(m), miepython's sign convention), reported as seconds per sphere:

(a) miepython's numba backend (``MIEPYTHON_USE_JIT=1``); one warm-up call over all
    cases first, so JIT compilation is not timed; timed in ``--rounds`` rounds that
    alternate with lucent's benchmark (this machine's speed drifts by tens of
    percent within minutes; each side keeps its best over all rounds);
(b) miepython's pure-numpy backend (``MIEPYTHON_USE_JIT=0``, the default of
    miepython 3.3.0; module ``miepython.mie_nojit``).

miepython chooses its backend when it is imported, so each backend runs in its own
Python subprocess (this script re-invoked with ``--worker``).  Each timing is
repeated ``--repeats`` times; the best (minimum) and the median are reported and
the ratios use the best.

Then (unless ``--no-lucent``) it runs, from the repository root,

    cargo run --release --quiet -- bench mie --cases fixtures/reference/mie_miepython.csv --repeats N

(the same number of repeats, the best of them reported) which must print one
JSON object on stdout with at least ``seconds_per_sphere``,
and prints miepython_numba / lucent and miepython_nojit / lucent (how many times
faster lucent is).  If that command fails or prints no such JSON, the miepython
numbers are still printed, a message explains what went wrong, and the exit
status is 1.

Usage (from the repository root)::

    python3 tools/bench_miepython.py [--repeats N] [--rounds R] [--no-lucent] [--cases PATH]

Versions used when this was written: Python 3.11.7, miepython 3.3.0, numba 0.68.1,
numpy 2.4.6.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_CASES = Path("fixtures/reference/mie_miepython.csv")


def read_cases(path: Path):
    """(m_re, m_im, x) of every data row; lines starting with '#' are comments."""
    rows = []
    with open(path) as fh:
        lines = [ln.strip() for ln in fh if ln.strip() and not ln.startswith("#")]
    cols = lines[0].split(",")
    i_re, i_im, i_x = cols.index("m_re"), cols.index("m_im"), cols.index("x")
    for ln in lines[1:]:
        f = ln.split(",")
        rows.append((float(f[i_re]), float(f[i_im]), float(f[i_x])))
    return rows


def worker(backend: str, cases_path: Path, repeats: int) -> int:
    """Runs inside the subprocess: MIEPYTHON_USE_JIT is already set by the parent."""
    import numpy as np

    import miepython

    want_jit = backend == "numba"
    if bool(miepython.USE_JIT) != want_jit:
        print(json.dumps({"error": f"miepython.USE_JIT={miepython.USE_JIT}, expected {want_jit}"}))
        return 1
    cases = read_cases(cases_path)
    m = np.array([complex(re, -im) for re, im, _ in cases])  # miepython: m = n - i k
    x = np.array([xx for _, _, xx in cases])

    t0 = time.perf_counter()
    miepython.efficiencies_mx(m, x)  # warm-up (numba: compiles everything not compiled at import)
    warmup = time.perf_counter() - t0

    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        miepython.efficiencies_mx(m, x)
        times.append(time.perf_counter() - t0)
    n = len(cases)
    print(
        json.dumps(
            {
                "backend": backend,
                "miepython": miepython.__version__,
                "spheres": n,
                "repeats": repeats,
                "warmup_seconds": warmup,
                "seconds_per_sphere": min(times) / n,
                "seconds_per_sphere_median": statistics.median(times) / n,
            }
        )
    )
    return 0


def last_json_object(text: str):
    """The JSON object printed on stdout (whole text, else the last line that parses)."""
    text = text.strip()
    try:
        obj = json.loads(text)
        if isinstance(obj, dict):
            return obj
    except json.JSONDecodeError:
        pass
    for line in reversed(text.splitlines()):
        line = line.strip()
        if line.startswith("{"):
            try:
                obj = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(obj, dict):
                return obj
    return None


def run_backend(backend: str, cases_path: Path, repeats: int) -> dict:
    env = dict(os.environ, MIEPYTHON_USE_JIT="1" if backend == "numba" else "0")
    cmd = [sys.executable, str(Path(__file__).resolve()), "--worker", backend, "--cases", str(cases_path)]
    cmd += ["--repeats", str(repeats)]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, cwd=REPO_ROOT)
    res = last_json_object(proc.stdout)
    if proc.returncode != 0 or res is None or "error" in res:
        detail = (res or {}).get("error") or proc.stderr.strip()[-2000:] or "no output"
        return {"backend": backend, "error": detail}
    return res


def run_lucent(cases_path: Path, repeats: int, quiet: bool = False):
    cmd = ["cargo", "run", "--release", "--quiet", "--", "bench", "mie", "--cases", str(cases_path), "--repeats", str(repeats)]
    if not quiet:
        print(f"running: {' '.join(cmd)}", flush=True)
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO_ROOT)
    except FileNotFoundError:
        return None, "cargo was not found on PATH"
    if proc.returncode != 0:
        tail = "\n".join(proc.stderr.strip().splitlines()[-15:])
        return None, f"`{' '.join(cmd)}` exited with status {proc.returncode}:\n{tail}"
    res = last_json_object(proc.stdout)
    if res is None or not isinstance(res.get("seconds_per_sphere"), (int, float)) or res["seconds_per_sphere"] <= 0:
        return None, f"lucent printed no JSON object with a positive 'seconds_per_sphere'; stdout was:\n{proc.stdout[-2000:]}"
    return res, None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=Path, default=DEFAULT_CASES, help="case CSV, relative to the repo root (default: %(default)s)")
    ap.add_argument("--repeats", type=int, default=20, help="timed repetitions per backend and for lucent (default: %(default)s)")
    ap.add_argument("--rounds", type=int, default=3, help="alternating numba/lucent rounds (default: %(default)s)")
    ap.add_argument("--no-lucent", action="store_true", help="only time miepython")
    ap.add_argument("--worker", choices=("numba", "nojit"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.repeats < 1 or args.rounds < 1:
        ap.error("--repeats and --rounds must be >= 1")

    cases_path = args.cases if args.cases.is_absolute() else REPO_ROOT / args.cases
    if args.worker:
        return worker(args.worker, cases_path, args.repeats)
    if not cases_path.exists():
        print(f"case file {cases_path} not found; run tools/reference/mie_miepython.py first", file=sys.stderr)
        return 2

    n = len(read_cases(cases_path))
    print(f"{n} spheres from {cases_path.relative_to(REPO_ROOT) if cases_path.is_relative_to(REPO_ROOT) else cases_path}")
    print(
        f"python {platform.python_version()} on {platform.machine()}, {os.cpu_count()} CPUs; "
        f"{args.rounds} rounds of numba then lucent, {args.repeats} repeats each, best reported"
    )
    # The machine's speed drifts by tens of percent within minutes, so
    # miepython (numba) and lucent are timed alternately, round after round,
    # and each side keeps its best: both get the same quiet moments.
    numba = None
    lucent = None
    for r in range(args.rounds):
        res = run_backend("numba", cases_path, args.repeats)
        if "error" in res:
            numba = res
            break
        if numba is None or res["seconds_per_sphere"] < numba["seconds_per_sphere"]:
            numba = res
        if args.no_lucent:
            continue
        res, err = run_lucent(args.cases, args.repeats, quiet=r > 0)
        if res is None:
            print(f"lucent benchmark unavailable: {err}")
            print("(use --no-lucent to time miepython alone)")
            return 1
        if lucent is None:
            lucent = res
        else:
            for key in ("seconds_per_sphere", "seconds_per_sphere_all_cores"):
                if res.get(key, float("inf")) < lucent.get(key, float("inf")):
                    lucent[key] = res[key]
        print(
            f"  round {r + 1}: numba {numba['seconds_per_sphere'] if 'error' not in numba else float('nan'):.3e}, "
            f"lucent {res['seconds_per_sphere']:.3e} one core, {res.get('seconds_per_sphere_all_cores', float('nan')):.3e} all cores",
            flush=True,
        )
    results = {"numba": numba, "nojit": run_backend("nojit", cases_path, max(1, args.repeats // 4))}
    for backend in ("numba", "nojit"):
        res = results[backend]
        if "error" in res:
            print(f"  miepython {backend:5s}: FAILED: {res['error']}")
        else:
            print(
                f"  miepython {res['miepython']} {backend:5s}: {res['seconds_per_sphere']:.3e} s/sphere "
                f"(median {res['seconds_per_sphere_median']:.3e}; warm-up {res['warmup_seconds']:.2f} s)"
            )
    if args.no_lucent:
        return 0 if all("error" not in r for r in results.values()) else 1

    t_l = float(lucent["seconds_per_sphere"])
    print(f"  lucent           : {t_l:.3e} s/sphere (one core)")
    t_all = lucent.get("seconds_per_sphere_all_cores")
    if isinstance(t_all, (int, float)) and t_all > 0 and "error" not in results["numba"]:
        print(
            f"  lucent all cores : {t_all:.3e} s/sphere ({lucent.get('threads')} threads); "
            f"throughput ratio miepython_numba / lucent = {results['numba']['seconds_per_sphere'] / t_all:.2f}"
        )
    for backend, label in (("numba", "miepython_numba / lucent"), ("nojit", "miepython_nojit / lucent")):
        res = results[backend]
        if "error" in res:
            print(f"  {label}: n/a ({backend} run failed)")
        else:
            print(f"  {label}: {res['seconds_per_sphere'] / t_l:.1f}")
    return 0 if all("error" not in r for r in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
