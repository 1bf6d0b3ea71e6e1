"""One design across the module: a recipe is a path or a dict wherever a
function takes one; `wavelengths_nm` names a grid and `wavelength_nm` one
wavelength; `render()["spp"]` is a number; `compare()` on arrays takes the
images' variances and gives the command's model RMSE."""

import json
import tomllib

import numpy as np
import OpenEXR
import pytest

import lucent

from conftest import run_cli

RECIPE = "fixtures/samples/IOL1068-09.toml"
SCENE = "fixtures/render/plaque_dense.toml"
SMALL_SLICE = dict(theta_i=45.0, theta_o=0.0, pixels=21, pixel_mm=0.5, paths=3000, seed=5)


@pytest.fixture(scope="module")
def recipe_dict(repo):
    with open(repo / RECIPE, "rb") as f:
        return tomllib.load(f)


class PathLike:
    """An os.PathLike that is not a pathlib.Path."""

    def __init__(self, path):
        self.path = str(path)

    def __fspath__(self):
        return self.path


@pytest.mark.parametrize("form", ["str", "pathlike", "dict"])
def test_optics_and_bssrdf_take_the_recipe_as_a_path_or_a_dict(repo, recipe_dict, form):
    recipe = {"str": str(repo / RECIPE), "pathlike": PathLike(repo / RECIPE), "dict": recipe_dict}[form]
    reference = lucent.bssrdf(repo / RECIPE, wavelength_nm=600.0, **SMALL_SLICE)
    s = lucent.bssrdf(recipe, wavelength_nm=600.0, **SMALL_SLICE)
    np.testing.assert_array_equal(s["slice"], reference["slice"])
    assert s["optical_properties"] == reference["optical_properties"]
    o = lucent.optics(recipe, wavelengths_nm=[600.0], phase_entries=0)
    assert o.to_csv() == lucent.optics(repo / RECIPE, wavelengths_nm=600.0, phase_entries=0).to_csv()


def test_a_bad_recipe_argument_names_it(repo, recipe_dict):
    for f in (lambda r: lucent.optics(r), lambda r: lucent.bssrdf(r, paths=10),
              lambda r: lucent.fit(r, "m.csv:45/0", "weight_percent")):
        with pytest.raises(lucent.LucentError, match="recipe: expected a path .* or a dict"):
            f(42)
    bad = dict(recipe_dict, thicknes_mm=1.0)
    with pytest.raises(lucent.LucentError, match="thicknes_mm"):
        lucent.bssrdf(bad, paths=10)


def test_wavelength_names(repo):
    # A grid is wavelengths_nm, one wavelength wavelength_nm; both in nm and the same numbers.
    o = lucent.optics(repo / RECIPE, wavelengths_nm=[450.0, 600.0], phase_entries=0)
    np.testing.assert_array_equal(o.wavelengths_nm, [450.0, 600.0])
    np.testing.assert_array_equal(o.wavelength_nm, o.wavelengths_nm)
    assert o.units["wavelengths_nm"] == "nm"
    s = lucent.bssrdf(repo / RECIPE, wavelength_nm=450.0, **dict(SMALL_SLICE, paths=10))
    assert s["optical_properties"]["mu_s_per_m"] == pytest.approx(o.mu_s[0], rel=1e-12)
    qext, *_ = lucent.mie_sphere(radius_um=1.1, wavelength_nm=[450.0, 600.0], particle_index=1.41,
                                 host_index=1.5889)
    assert qext.shape == (2,)


def test_render_spp_is_a_number(repo):
    r = lucent.render(repo / SCENE, spp=4, seed=2, size="24x18")
    assert isinstance(r["spp"], int) and r["spp"] == 4
    assert r["spp_per_pixel"].shape == (18, 24) and r["spp_per_pixel"].dtype.kind == "u"
    assert (r["spp_per_pixel"] == 4).all()
    assert r["samples"] == r["spp_per_pixel"].sum()


def write_exr(path, channels):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}) as f:
        f.write(str(path))


def rgb_channels(img, prefix=""):
    return {f"{prefix}{c}": img[..., k] for k, c in enumerate("RGB")}


def noisy_pair(h=48, w=64, seed=4):
    """A photo and a render of one smooth picture, off by a model error, with
    known per-pixel variances and noise drawn from them."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w]
    truth = 0.4 + 0.2 * np.sin(0.15 * xx[..., None] + np.arange(3)) * np.cos(0.1 * yy[..., None])
    render_var = (0.0004 * truth).astype(np.float32)
    photo_var = np.full((h, w, 3), 0.0002, np.float32)
    photo = (truth + rng.normal(0, np.sqrt(photo_var))).astype(np.float32)
    render = (1.10 * truth + rng.normal(0, np.sqrt(render_var))).astype(np.float32)
    return photo, render, photo_var, render_var


def test_compare_arrays_with_variances_equal_the_command(lucent_cli, tmp_path):
    photo, render, photo_var, render_var = noisy_pair()
    write_exr(tmp_path / "photo.exr", rgb_channels(photo))
    write_exr(tmp_path / "render.exr", {**rgb_channels(render), **rgb_channels(render_var, "variance.")})
    write_exr(tmp_path / "photo_var.exr", rgb_channels(photo_var))
    run_cli(lucent_cli, "compare", "--photo", tmp_path / "photo.exr", "--render", tmp_path / "render.exr",
            "--photo-variance", tmp_path / "photo_var.exr", "--out", tmp_path / "out")
    cli = json.loads((tmp_path / "out/metrics.json").read_text())
    api = lucent.compare(photo, render, photo_variance=photo_var, render_variance=render_var)
    assert api["as_calibrated"] == cli["as_calibrated"]
    for key in ["total", "r", "g", "b", "blocks", "pixels", "block_px", "resamples", "definition"]:
        assert api["noise"][key] == cli["noise"][key], key
    # The model error is there: 10 % of the signal, above the noise floor.
    assert api["noise"]["total"]["model_rmse"] > api["noise"]["total"]["noise_floor"]
    # The same files through the module give the command's dict.
    files = lucent.compare(tmp_path / "photo.exr", tmp_path / "render.exr", photo_variance=tmp_path / "photo_var.exr")
    assert files["noise"] == cli["noise"]
    # Without the photo's variance: the render's alone, as the command says.
    no_photo = lucent.compare(photo, render, render_variance=render_var)
    assert no_photo["noise"]["photo_variance"].startswith("not given (0)")
    assert no_photo["noise"]["total"]["noise_floor"] < api["noise"]["total"]["noise_floor"]
    assert lucent.compare(photo, render)["noise"] is None


def test_compare_model_rmse_by_its_definition():
    # mean((R − P)² − var R − var P) over pixels and channels, square-rooted.
    photo, render, photo_var, render_var = noisy_pair(seed=9)
    mask = np.zeros(photo.shape[:2], bool)
    mask[8:40, 8:56] = True
    n = lucent.compare(photo, render, mask=mask, photo_variance=photo_var, render_variance=render_var)["noise"]
    p, r = photo.astype(np.float64)[mask], render.astype(np.float64)[mask]
    v = render_var.astype(np.float64)[mask] + photo_var.astype(np.float64)[mask]
    d = (r - p) ** 2 - v
    assert n["pixels"] == mask.sum()
    assert n["total"]["model_rmse"] == pytest.approx(np.sqrt(max(0.0, d.mean())), rel=1e-9)
    assert n["total"]["noise_floor"] == pytest.approx(np.sqrt(v.mean()), rel=1e-9)
    assert n["g"]["model_rmse"] == pytest.approx(np.sqrt(max(0.0, d[:, 1].mean())), rel=1e-9)
    lo, hi = n["total"]["ci95"]
    assert lo <= n["total"]["model_rmse"] <= hi


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(render_variance=np.zeros((48, 64))), r"render_variance: expected shape \(48, 64, 3\)"),
        (dict(render_variance=np.full((48, 64, 3), -1.0)), r"render_variance: pixel \(0, 0, 0\) holds -1"),
        (dict(render_variance=np.full((48, 64, 3), np.inf)), r"render_variance: pixel \(0, 0, 0\) holds inf"),
        (dict(render_variance=np.zeros((48, 64, 3)), photo_variance=np.full((48, 64, 3), np.nan)),
         r"photo_variance: pixel \(0, 0, 0\) holds NaN"),
        (dict(photo_variance=np.zeros((48, 64, 3))), "photo_variance needs render_variance"),
        (dict(render_variance=np.zeros((48, 64, 3)), photo_variance=np.full((48, 64, 3), 1e3)),
         "photo_variance: the variance is above"),
        (dict(render_variance="render.exr"), "render_variance: a file path needs the photo and render as file paths"),
    ],
)
def test_bad_variances_raise_value_errors_naming_them(kwargs, message):
    photo, render, _, _ = noisy_pair()
    with pytest.raises(ValueError, match=message):
        lucent.compare(photo, render, **kwargs)


def test_render_variance_with_files_is_refused(repo):
    ref = repo / "fixtures/reference/compare"
    with pytest.raises(lucent.LucentError, match="render_variance: with the render as a file path"):
        lucent.compare(ref / "base.exr", ref / "shifted.exr", render_variance=np.zeros((4, 4, 3)))


def test_the_render_feeds_compare(repo):
    # render()["variance"] is compare's render_variance as it stands.
    r = lucent.render(repo / SCENE, spp=4, seed=2, size="32x24")
    photo = r["mean"] * 1.02
    m = lucent.compare(photo, r["mean"], render_variance=r["variance"], data_range=float(photo.max()))
    assert m["noise"]["pixels"] == 32 * 24 and m["noise"]["render_variance"].startswith("render_variance")
