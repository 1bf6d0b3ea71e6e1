"""lucent.ccm and lucent.delta_e_2000 against colour-science."""

import colour
import numpy as np
import pytest

import lucent



def test_ccm_matches_colour_science_cheung2004():
    rng = np.random.default_rng(2004)
    xyz = rng.uniform(0.02, 0.9, (24, 3))
    cam = np.array([[0.9, 0.25, -0.1], [0.05, 0.85, 0.15], [0.02, 0.1, 0.75]])
    rgb = xyz @ np.linalg.inv(cam).T + rng.normal(0, 0.01, (24, 3))
    r = lucent.ccm(rgb, xyz, method="Cheung 2004")
    ref = colour.characterisation.matrix_colour_correction_Cheung2004(rgb, xyz, terms=3)
    assert r["matrix"].shape == (3, 3)
    np.testing.assert_allclose(r["matrix"], ref, rtol=1e-10, atol=1e-12)
    assert len(r["patches"]) == 24 and r["de2000_max"] >= r["de2000_mean"] > 0


def test_ccm_on_the_default_chart_has_the_24_named_patches():
    rng = np.random.default_rng(3)
    rgb = rng.uniform(0.05, 0.9, (24, 3))
    r = lucent.ccm(rgb, method="finlayson-2015")
    assert r["method"] == "Finlayson 2015" and r["matrix"].shape == (3, 6)
    assert r["patches"][18]["name"] and r["patches"][0]["patch"] == 1


def test_delta_e_2000_matches_colour_science():
    rng = np.random.default_rng(76)
    lab1 = np.column_stack([rng.uniform(0, 100, 500), rng.uniform(-80, 80, 500), rng.uniform(-80, 80, 500)])
    lab2 = lab1 + rng.normal(0, 5, (500, 3))
    ours = lucent.delta_e_2000(lab1, lab2)
    ref = colour.delta_E(lab1, lab2, method="CIE 2000")
    assert ours.shape == (500,)
    np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=1e-12)
    assert isinstance(lucent.delta_e_2000([50, 2.6772, -79.7751], [50, 0, -82.7485]), float)


def test_bad_colour_input_raises():
    with pytest.raises(lucent.LucentError, match=r"shape \(N, 3\)"):
        lucent.ccm(np.ones((24, 4)))
    with pytest.raises(lucent.LucentError, match="colour-correction method"):
        lucent.ccm(np.ones((24, 3)), method="magic")
    with pytest.raises(lucent.LucentError, match="patch 2"):
        lucent.ccm(np.array([[0.1, 0.2, 0.3], [np.nan, 0.1, 0.1], [0.3, 0.2, 0.1], [0.5, 0.5, 0.5]]), np.ones((4, 3)))
    with pytest.raises(lucent.LucentError, match="last axis"):
        lucent.delta_e_2000(np.ones((5, 2)), np.ones((5, 2)))
