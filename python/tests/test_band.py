"""The twin's band from Python: render(uncertainty=True) as `lucent render
--uncertainty` computes it, and compare(band=…) on arrays as on files."""

import json

import numpy as np
import pytest

import lucent

from conftest import run_cli


def plaque(repo, folder, weight):
    """A 24 × 18 view of an IOL1068-09 plaque (`weight`: the recipe's
    weight_percent line) on a board under a constant sky."""
    folder.mkdir(parents=True, exist_ok=True)
    recipe = (
        (repo / "fixtures/samples/IOL1068-09.toml")
        .read_text()
        .replace("weight_percent = 0.65", f"weight_percent = {weight}")
        .replace("size_mm = [149.1, 104.5]", "size_mm = [40.0, 40.0]")
    )
    (folder / "u.toml").write_text(recipe)
    scene = folder / "s.toml"
    scene.write_text(
        '[camera]\nwidth = 24\nheight = 18\nposition_m = [0.0, -0.12, 0.10]\nlook_at_m = [0.0, 0.0, 0.0]\n'
        'up = [0.0, 0.0, 1.0]\nvertical_fov_deg = 25.0\n\n[object]\n\n[material]\nrecipe = "u.toml"\n'
        'wavelengths = "400:700:50"\ndispersion = false\n\n[board]\norigin_m = [-0.1, -0.1, 0.0]\n'
        'square_mm = 20.0\ncolumns = 10\nrows = 10\neven = [0.8, 0.8, 0.8]\nodd = [0.1, 0.1, 0.1]\n\n'
        '[environment]\nconstant = [1.0, 1.0, 1.0]\n\n[render]\nsimilarity_g = 0.0\n'
    )
    return scene


def test_render_band_and_compare_band(lucent_cli, repo, tmp_path):
    twin = plaque(repo, tmp_path / "twin", "{ value = 0.65, sd = 0.0325 }")
    r = lucent.render(twin, spp=256, seed=1, uncertainty=True)
    assert r["band_sd"].shape == (18, 24, 3) and r["band_sd_std_error"].shape == (18, 24, 3)
    assert r["band"]["input_methods"][0]["method"] == "path derivative"
    # The command's uncertainty.json holds the same band.
    run_cli(lucent_cli, "render", twin, "--spp", 256, "--seed", 1, "--uncertainty", "--out", tmp_path / "cli", "--quiet")
    with open(tmp_path / "cli/uncertainty.json") as f:
        assert json.load(f)["regions"] == r["band"]["regions"]
    # A photo at +5 σ lies outside the band, on arrays as on files, with the same numbers.
    far = plaque(repo, tmp_path / "far", 0.65 + 5 * 0.0325)
    photo = lucent.render(far, spp=256, seed=7)
    run_cli(lucent_cli, "render", far, "--spp", 256, "--seed", 7, "--out", tmp_path / "photo", "--quiet")
    on_arrays = lucent.compare(
        photo["mean"], r["mean"], mask=r["object"] >= 0.5, photo_variance=photo["variance"],
        render_variance=r["variance"], band=r["band"],
    )["bands"][0]
    exr = tmp_path / "photo/render.exr"
    on_files = lucent.compare(
        exr, tmp_path / "cli/render.exr", mask_object=tmp_path / "cli/render.exr", photo_variance=exr,
        band=tmp_path / "cli",
    )["bands"][0]
    assert not on_arrays["within"] and min(on_arrays["z"]) > 2.0, on_arrays
    for key in ["photo_mean", "render_mean", "predictive_sd", "z"]:
        np.testing.assert_allclose(on_arrays[key], on_files[key], rtol=1e-6, err_msg=key)
    assert on_arrays["pixels"] == on_files["pixels"]
    # A band needs its region's mask with arrays.
    with pytest.raises(lucent.LucentError, match="mask"):
        lucent.compare(photo["mean"], r["mean"], band=r["band"])
