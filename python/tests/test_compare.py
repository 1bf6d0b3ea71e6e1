"""lucent.compare against scikit-image and the files of `lucent compare`."""

import json

import numpy as np
import pytest
from skimage.metrics import structural_similarity

import lucent

from conftest import run_cli

REF = "fixtures/reference/compare"
LUMA = np.array([0.1769, 0.8124, 0.0107])  # Y row of CIE RGB -> XYZ


def skimage_ssim(a, b, data_range=1.0):
    return structural_similarity(
        a.astype(np.float64), b.astype(np.float64), gaussian_weights=True, sigma=1.5,
        use_sample_covariance=False, data_range=data_range,
    )


def images(seed, h=40, w=56):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    base = 0.4 + 0.25 * np.sin(0.2 * xx[..., None] + np.arange(3)) * np.cos(0.15 * yy[..., None])
    photo = (base + rng.normal(0, 0.03, (h, w, 3))).astype(np.float32)
    render = (0.9 * base + 0.03 + rng.normal(0, 0.03, (h, w, 3))).astype(np.float32)
    return photo, render


def test_ssim_and_rmse_of_arrays_match_scikit_image_and_numpy():
    photo, render = images(6)
    m = lucent.compare(photo, render, data_range=1.0)["as_calibrated"]
    for c, name in enumerate("RGB"):
        assert abs(m["ssim"][name] - skimage_ssim(photo[..., c], render[..., c])) < 1e-12
    y = skimage_ssim(photo.astype(np.float64) @ LUMA, render.astype(np.float64) @ LUMA)
    assert abs(m["ssim"]["Y"] - y) < 1e-12
    d = render.astype(np.float64) - photo.astype(np.float64)
    assert abs(m["rmse"] - np.sqrt(np.mean(d**2))) < 1e-12
    assert m["pixels"] == 40 * 56


def test_a_mask_restricts_the_errors():
    photo, render = images(7)
    mask = np.zeros(photo.shape[:2], dtype=bool)
    mask[5:30, 10:40] = True
    m = lucent.compare(photo, render, mask=mask)["as_calibrated"]
    d = (render.astype(np.float64) - photo.astype(np.float64))[mask]
    assert m["pixels"] == mask.sum()
    assert abs(m["rmse"] - np.sqrt(np.mean(d**2))) < 1e-12


def test_paths_give_the_command_metrics_json(lucent_cli, repo, tmp_path):
    photo, render = repo / REF / "base.exr", repo / REF / "shifted.exr"
    run_cli(lucent_cli, "compare", "--photo", photo, "--render", render, "--out", tmp_path)
    cli = json.loads((tmp_path / "metrics.json").read_text())
    api = lucent.compare(photo, render)
    for key in ["as_calibrated", "width", "height", "channels", "mask", "definitions", "noise", "display"]:
        assert api[key] == cli[key], key
    # Arrays read from the same files give the same numbers.
    reference = json.loads((repo / REF / "reference.json").read_text())
    case = next(c for c in reference["cases"] if c["name"] == "shifted" and c["mask"] is None)
    assert abs(api["as_calibrated"]["ssim"]["Y"] - case["ssim"]["Y"]) < 1e-12
    assert abs(api["as_calibrated"]["rmse"] - case["rmse"]) < 1e-12
    mixed = lucent.compare(str(photo), render)
    assert mixed["as_calibrated"] == api["as_calibrated"]


@pytest.mark.parametrize(
    "photo, render, message",
    [
        (np.zeros((10, 12, 3)), np.zeros((10, 12)), r"render: expected an array of shape \(height, width, 3\)"),
        (np.zeros((10, 12, 3)), np.zeros((12, 10, 3)), "size|pixels"),
        (np.full((10, 12, 3), np.nan), np.zeros((10, 12, 3)), r"photo: pixel \(0, 0, 0\) holds NaN"),
    ],
)
def test_bad_arrays_raise(photo, render, message):
    with pytest.raises(lucent.LucentError, match=message):
        lucent.compare(photo, render)


def test_bad_options_raise(repo):
    photo, render = images(8)
    with pytest.raises(lucent.LucentError, match="luminance|rec709"):
        lucent.compare(photo, render, luminance="xyz")
    with pytest.raises(lucent.LucentError, match="mask: expected shape"):
        lucent.compare(photo, render, mask=np.ones((3, 3), dtype=bool))
    with pytest.raises(lucent.LucentError, match="missing.exr"):
        lucent.compare(repo / REF / "base.exr", repo / REF / "missing.exr")
