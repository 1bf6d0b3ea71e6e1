"""lucent.fit against `lucent fit`'s fit.json; a known truth recovered; progress, Ctrl-C, bad input.

The measurement is a slice `lucent.bssrdf` simulates from the recipe with
0.425 wt-% (fixtures/fit/); the fit starts from the sample recipe's 0.65.
Small for test time: 21 × 21 pixels of 0.5 mm, a few thousand paths.
"""

import json
import time
import tomllib

import numpy as np
import pytest

import lucent

from conftest import run_cli

START = "fixtures/samples/IOL1068-09.toml"
TRUTH = "fixtures/fit/IOL1068-09_truth_0425.toml"


@pytest.fixture(scope="module")
def measured(repo, tmp_path_factory):
    """"FILE:45/0" of a 45°/0° slice simulated at the truth, as a CSV grid."""
    s = lucent.bssrdf(repo / TRUTH, theta_i=45.0, theta_o=0.0, pixels=21, pixel_mm=0.5, paths=20000, seed=77)
    path = tmp_path_factory.mktemp("fit") / "m45.csv"
    np.savetxt(path, s["slice"], delimiter=",")
    return f"{path}:45/0"


@pytest.fixture(scope="module")
def fitted(repo, measured):
    """lucent.fit of the sample recipe's file to the measurement, and its progress lines."""
    lines = []
    r = lucent.fit(repo / START, measured, "weight_percent", measured_pixel_mm=0.5, paths=5000,
                   progress=lines.append)
    return r, lines


def test_fit_equals_the_command_and_recovers_the_truth(lucent_cli, repo, measured, fitted, tmp_path):
    run_cli(lucent_cli, "fit", "--recipe", repo / START, "--measured", measured, "--measured-pixel-mm", 0.5,
            "--free", "weight_percent", "--paths", 5000, "--quiet", "--out", tmp_path)
    cli = json.loads((tmp_path / "fit.json").read_text())
    r, lines = fitted
    p, q = r["parameters"][0], cli["parameters"][0]
    for key in ["value", "std_error", "interval_95", "start", "bounds"]:
        assert p[key] == q[key], (key, p[key], q[key])
    for key in ["evaluations", "paths_total", "objective_start", "objective_end", "identifiable"]:
        assert r[key] == cli[key], (key, r[key], cli[key])
    # The truth lies in the reported 95 % interval; the start does not.
    lo, hi = p["interval_95"]
    assert lo <= 0.425 <= hi and hi < 0.65, p
    # One progress line per evaluation, as the command prints them.
    assert lines[0].startswith("pilot at") and len(lines) >= r["evaluations"] - 2, lines


def test_ctrl_c_interrupts_a_fit(repo, measured, ctrl_c):
    start = time.monotonic()
    ctrl_c(0.5)
    with pytest.raises(KeyboardInterrupt):
        # The pilot alone runs for a minute without the interrupt.
        lucent.fit(repo / START, measured, "weight_percent", measured_pixel_mm=0.5, rel_error=1e-5)
    assert time.monotonic() - start < 15.0


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(free="weight"), "unknown free parameter \"weight\""),
        (dict(free="weight_percent@3"), "particle type"),
        (dict(objective="best"), "objective \"best\": expected one of sum, msre"),
        (dict(measured="no/such.csv:45/0"), "--measured no/such.csv: no such file"),
        (dict(bounds=[(1.0, 2.0), (1.0, 2.0)]), "2 entries for 1 free parameter"),
        (dict(measured_pixel_mm=-1.0), "--measured-pixel-mm -1"),
    ],
)
def test_bad_fit_arguments_raise(repo, measured, kwargs, message):
    args = dict(measured=measured, free="weight_percent", measured_pixel_mm=0.5, paths=1000) | kwargs
    with pytest.raises(lucent.LucentError, match=message):
        lucent.fit(repo / START, **args)


def test_fit_takes_the_recipe_as_a_dict(repo, measured, fitted, tmp_path):
    # A dict of the recipe's keys fits as its file does; the fitted recipe is named after its `name`.
    with open(repo / START, "rb") as f:
        recipe = tomllib.load(f)
    a = lucent.fit(recipe, measured, "weight_percent", measured_pixel_mm=0.5, paths=5000, wavelength_nm=550.0,
                   out=tmp_path)
    b, _ = fitted
    for key in ["value", "std_error", "interval_95", "start"]:
        assert a["parameters"][0][key] == b["parameters"][0][key], key
    assert a["identifiable"] and b["identifiable"]
    fitted_recipe = tmp_path / "IOL1068-09_fitted.toml"
    assert (tmp_path / "fit.json").is_file() and fitted_recipe.is_file()
    assert lucent.optics(fitted_recipe, wavelengths_nm=550.0, phase_entries=0).sample == "IOL1068-09"
