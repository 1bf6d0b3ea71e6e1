"""lucent.optics against the files of `lucent optics` for the same recipe."""

import csv
import tomllib

import numpy as np
import pytest

import lucent

from conftest import run_cli

RECIPE = "fixtures/samples/IOL1068-09.toml"


@pytest.fixture(scope="module")
def cli_out(lucent_cli, repo, tmp_path_factory):
    out = tmp_path_factory.mktemp("optics")
    run_cli(lucent_cli, "optics", repo / RECIPE, "--wavelengths", "450:650:100", "--out", out)
    return out


def test_optics_equals_the_command_files(repo, cli_out):
    o = lucent.optics(repo / RECIPE, wavelengths_nm=np.array([450.0, 550.0, 650.0]))
    text = (cli_out / "optical_properties.csv").read_text()
    assert o.to_csv() == text
    rows = list(csv.DictReader(text.splitlines()))
    np.testing.assert_array_equal(o.wavelength_nm, [float(r["wavelength_nm"]) for r in rows])
    for attr, col in [("mu_s", "mu_s_per_m"), ("mu_a", "mu_a_per_m"), ("mu_t", "mu_t_per_m"), ("g", "g"), ("n_bulk", "n_bulk")]:
        np.testing.assert_allclose(getattr(o, attr), [float(r[col]) for r in rows], rtol=1e-9, err_msg=attr)
    # The phase table the command writes (9 significant digits), wavelength × angle.
    [phase_file] = list(cli_out.rglob("phase_function.csv"))
    table = np.genfromtxt(phase_file, delimiter=",", names=True)
    assert o.phase.shape == (3, 4096)
    np.testing.assert_allclose(np.degrees(o.theta_rad), table["theta_deg"], atol=1e-7)
    for k, w in enumerate(o.wavelength_nm):
        np.testing.assert_allclose(o.phase[k], table[f"p_{w:g}nm_per_sr"], rtol=1e-8)
    assert o.units["mu_s"] == "1/m" and o.units["phase"] == "1/sr"
    assert o.sample == "IOL1068-09" and o.absorption == "volume-weighted-full-host"


def test_optics_from_a_dict_equals_the_file(repo):
    with open(repo / RECIPE, "rb") as f:
        recipe = tomllib.load(f)
    a = lucent.optics(recipe, wavelengths_nm=550.0, phase_entries=0)
    b = lucent.optics(repo / RECIPE, wavelengths_nm=[550.0], phase_entries=0)
    assert a.to_csv() == b.to_csv()
    assert a.phase.shape == (1, 0)


def test_a_wrong_recipe_key_names_it(repo):
    with open(repo / RECIPE, "rb") as f:
        recipe = tomllib.load(f)
    recipe["thicknes_mm"] = recipe.pop("thickness_mm")
    with pytest.raises(lucent.LucentError, match="thicknes_mm"):
        lucent.optics(recipe, wavelengths_nm=550.0)


def test_bad_recipe_files_raise_the_command_message(repo):
    bad = repo / "tests/bad/recipe"
    for path in sorted(bad.glob("*.toml")):
        with pytest.raises(lucent.LucentError) as e:
            lucent.optics(path, wavelengths_nm=550.0, phase_entries=0)
        assert path.name in str(e.value), (path, str(e.value))


def test_bad_wavelengths_raise(repo):
    with pytest.raises(lucent.LucentError, match="wavelengths_nm"):
        lucent.optics(repo / RECIPE, wavelengths_nm=[550.0, np.nan])
    with pytest.raises(lucent.LucentError, match="expected a path"):
        lucent.optics(42)
    with pytest.raises(lucent.LucentError, match="no such file|cannot read"):
        lucent.optics(repo / "no/such/recipe.toml")
