"""The examples run to their end (so they never rot): examples/digitise.py
and docs/python_example.py (with its tiny settings, LUCENT_EXAMPLE_FAST=1)."""

import json
import os
import runpy
import subprocess
import sys

from PIL import Image


def test_the_digitise_example_runs(repo, capsys):
    runpy.run_path(str(repo / "examples/digitise.py"), run_name="__main__")
    out = capsys.readouterr().out
    assert "phase table: (3, 181)" in out and "relative standard error on the object" in out


def test_the_python_example_runs_and_writes_its_pictures(repo, tmp_path):
    env = dict(os.environ, LUCENT_EXAMPLE_FAST="1")
    p = subprocess.run([sys.executable, str(repo / "docs/python_example.py"), "--out", str(tmp_path / "out")],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    assert "model RMSE" in p.stdout and "4 spp" in p.stdout, p.stdout
    sizes = {name: Image.open(tmp_path / "out" / f"{name}.png").size for name in
             ["slice", "photo", "render", "difference"]}
    assert sizes == {"slice": (21, 21), "photo": (64, 48), "render": (64, 48), "difference": (64, 48)}
    # overview.png: the four side by side at 8 × 48 rows (the slice at 18 × 21 = 378), 8-px gaps.
    overview = Image.open(tmp_path / "out/overview.png")
    assert overview.size == (18 * 21 + 3 * 8 * 64 + 4 * 8, 8 * 48), overview.size
    metrics = json.loads((tmp_path / "out/metrics.json").read_text())
    assert metrics["plaque"]["noise"]["pixels"] < metrics["whole_image"]["noise"]["pixels"] == 64 * 48
