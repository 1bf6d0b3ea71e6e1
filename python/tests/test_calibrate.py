"""lucent.calibrate against OpenCV-Python's calibrateCamera on the same photos.

The reference, fixtures/reference/opencv_left_calibration.json, was made by
tools/reference/opencv_calibration.py (opencv-python-headless, OpenCV 5.0)
with the same detection policy: sector-based detector, else the classic one
with cornerSubPix. opencv-python is not among the test tools, so the
committed file stands in for running cv2 here.
"""

import json

import numpy as np
import pytest
from skimage import io

import lucent

BOARD = "fixtures/camera/chessboard"


@pytest.fixture(scope="module")
def reference(repo):
    return json.loads((repo / "fixtures/reference/opencv_left_calibration.json").read_text())


@pytest.fixture(scope="module")
def from_files(repo, reference):
    return lucent.calibrate(repo / BOARD / "left*.jpg", board="9x6", square_mm=reference["square"])


def test_calibrate_matches_opencv_python(from_files, reference):
    ref, r = reference["auto"], from_files
    k = r["camera_matrix"]
    assert k.shape == (3, 3) and k[2, 2] == 1.0
    # The focal lengths and principal point within 0.5 % (the two OpenCV
    # versions' corner refinement differs by a few hundredths of a pixel).
    for mine, key in [(k[0, 0], "fx"), (k[1, 1], "fy"), (k[0, 2], "cx"), (k[1, 2], "cy")]:
        assert abs(mine / ref[key] - 1) < 5e-3, (key, mine, ref[key])
    assert abs(r["rms_px"] - ref["rms_px"]) < 0.05, (r["rms_px"], ref["rms_px"])
    d = r["dist_coeffs"]
    assert d.shape == (5,)
    # k1, k2 of this strongly distorted lens: within 0.02 (k3 trades off against k2).
    np.testing.assert_allclose(d[:2], ref["distortion_k1_k2_p1_p2_k3"][:2], atol=0.02)
    assert [v["image"] for v in r["views"]] == [v["image"] for v in ref["views"]]
    assert [v["detector"] for v in r["views"]] == [v["detector"] for v in ref["views"]]
    assert r["not_found"] == [] and len(r["views"][0]["corners_px"]) == 54
    assert r["board"]["square_m"] == pytest.approx(reference["square"] * 1e-3)


def test_arrays_give_the_calibration_of_the_files(repo, reference, from_files):
    files = sorted((repo / BOARD).glob("left*.jpg"))
    grey = [io.imread(f) for f in files]
    assert grey[0].dtype == np.uint8 and grey[0].ndim == 2
    from_arrays = lucent.calibrate(grey, board="9x6", square_mm=reference["square"])
    assert [v["image"] for v in from_arrays["views"]] == [f"image {i}" for i in range(len(files))]
    # Two JPEG decoders may differ by a grey level here and there.
    np.testing.assert_allclose(from_arrays["camera_matrix"], from_files["camera_matrix"], rtol=2e-3)


@pytest.mark.parametrize(
    "images, kwargs, message",
    [
        (BOARD + "/left0[1-3].jpg", dict(board="10x6"), "no photo shows a chessboard of 10x6"),
        (BOARD, dict(board="9by6"), "--board/--square-mm"),
        (BOARD, dict(board="9x6", model="pinhole"), "model \"pinhole\": expected one of pinhole-k3, rational, fisheye"),
        ("no/such/folder", dict(board="9x6"), "no/such/folder: no such file or folder"),
    ],
)
def test_bad_calibration_input_raises(repo, images, kwargs, message):
    images = images if images.startswith("no/") else repo / images
    with pytest.raises(lucent.LucentError, match=message):
        lucent.calibrate(images, square_mm=25.0, **kwargs)


def test_a_wrong_array_is_named():
    with pytest.raises(lucent.LucentError, match=r"images\[1\]: expected a 2-D uint8"):
        lucent.calibrate([np.zeros((48, 64), np.uint8), np.zeros((48, 64, 3), np.uint8)], board="9x6", square_mm=25.0)
