"""lucent.mie / lucent.mie_sphere against miepython and the lucent command."""

import json

import miepython
import numpy as np
import pytest

import lucent

from conftest import run_cli


def random_spheres(n, seed):
    rng = np.random.default_rng(seed)
    m = rng.uniform(1.05, 2.5, n) + 1j * np.where(rng.random(n) < 0.5, 0.0, 10 ** rng.uniform(-4, 0, n))
    # x ≥ 0.5: below |m|x = 0.1 miepython's efficiencies_mx switches to
    # small-particle expansions accurate to ~1e-6 only.
    x = 10 ** rng.uniform(np.log10(0.5), np.log10(60.0), n)
    return m, x


def test_mie_matches_miepython_on_random_spheres():
    m, x = random_spheres(200, seed=28)
    qext, qsca, qabs, qback, g = lucent.mie(m, x)
    # miepython writes an absorbing index n − ki: conj of lucent's n + κi.
    rext, rsca, rback, rg = miepython.efficiencies_mx(np.conj(m), x)
    assert qext.shape == (200,)
    np.testing.assert_allclose(qext, rext, rtol=1e-6)
    np.testing.assert_allclose(qsca, rsca, rtol=1e-6)
    np.testing.assert_allclose(g, rg, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(qback, rback, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(qabs, rext - rsca, rtol=1e-6, atol=1e-8)
    assert np.all(qabs[m.imag == 0] == 0.0)


def test_mie_matches_the_committed_reference_table(repo):
    """The 348 spheres of fixtures/reference/mie_miepython.csv (miepython's
    coefficients with exact sums, see tools/reference/README.md)."""
    lines = [l for l in (repo / "fixtures/reference/mie_miepython.csv").read_text().splitlines() if not l.startswith("#")]
    t = np.genfromtxt(lines, delimiter=",", names=True)
    qext, qsca, _, qback, g = lucent.mie(t["m_re"] + 1j * t["m_im"], t["x"])
    np.testing.assert_allclose(qext, t["qext"], rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(qsca, t["qsca"], rtol=1e-9, atol=1e-300)
    np.testing.assert_allclose(g, t["g"], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(qback, t["qback"], rtol=1e-6, atol=1e-300)


def test_mie_broadcasts_and_returns_floats_for_scalars():
    q = lucent.mie(1.5, 3.0)
    assert all(isinstance(v, float) for v in q)
    grid = lucent.mie(np.array([[1.33], [1.5 + 0.01j]]), np.array([1.0, 2.0, 5.0]))
    assert grid[0].shape == (2, 3)
    assert grid[0][1, 2] == lucent.mie(1.5 + 0.01j, 5.0)[0]


def test_mie_equals_the_command(lucent_cli):
    out = run_cli(lucent_cli, "mie", "--size-parameter", "3.7", "--relative-index", "1.45+0.02i").stdout
    cli = json.loads(out)
    api = dict(zip(["qext", "qsca", "qabs", "qback", "g"], lucent.mie(1.45 + 0.02j, 3.7)))
    assert api == cli
    out = run_cli(
        lucent_cli, "mie", "--radius-um", "1.1", "--wavelength-nm", "550", "--particle-index", "1.41",
        "--host-index", "1.59+0.001i",
    ).stdout
    cli = json.loads(out)
    api = dict(zip(["qext", "qsca", "qabs", "qback", "g"], lucent.mie_sphere(1.1, 550.0, 1.41, 1.59 + 0.001j)))
    assert api == cli


def test_mie_sphere_in_a_clear_host_is_mie_of_the_relative_quantities():
    r_um, w_nm, n_p, n_h = np.array([0.2, 1.0, 3.0]), 633.0, 1.6 + 0.001j, 1.33
    phys = lucent.mie_sphere(r_um, w_nm, n_p, n_h)
    rel = lucent.mie(n_p / n_h, 2 * np.pi * r_um * 1e-6 * n_h / (w_nm * 1e-9))
    for a, b in zip(phys, rel):
        np.testing.assert_allclose(a, b, rtol=1e-12)


@pytest.mark.parametrize(
    "m, x, message",
    [
        (1.5, np.nan, "size parameter x = NaN"),
        ([1.5, 1.5], [1.0, -2.0], "element (1,): size parameter x = -2"),
        (1.5 - 0.1j, 1.0, "imaginary part must be ≥ 0"),
        (0.0, 1.0, "relative refractive index"),
    ],
)
def test_mie_rejects_bad_elements(m, x, message):
    with pytest.raises(lucent.LucentError, match=message.replace("(", r"\(").replace(")", r"\)")):
        lucent.mie(m, x)


def test_mie_rejects_shapes_that_do_not_broadcast():
    with pytest.raises(lucent.LucentError, match="do not broadcast"):
        lucent.mie(np.ones(3) * 1.5, np.ones(4))
