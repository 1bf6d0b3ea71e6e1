"""lucent.render against `lucent render`'s EXR; progress and Ctrl-C."""

import time

import numpy as np
import OpenEXR
import pytest

import lucent

from conftest import run_cli

SCENE = "fixtures/render/plaque_dense.toml"


def read_exr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {k: v.pixels for k, v in f.channels().items()}


def test_render_equals_the_command_exr(lucent_cli, repo, tmp_path):
    run_cli(lucent_cli, "render", repo / SCENE, "--spp", 8, "--seed", 11, "--size", "48x36", "--out", tmp_path, "--quiet")
    exr = read_exr(tmp_path / "render.exr")
    r = lucent.render(repo / SCENE, spp=8, seed=11, size="48x36")
    assert r["mean"].shape == (36, 48, 3) and r["variance"].shape == (36, 48, 3)
    for c, name in enumerate("RGB"):
        np.testing.assert_array_equal(r["mean"][..., c].astype(np.float32), exr[name])
        np.testing.assert_array_equal(r["variance"][..., c].astype(np.float32), exr[f"variance.{name}"])
    np.testing.assert_array_equal(r["spp_per_pixel"].astype(np.float32), exr["spp"])
    assert r["spp"] == 8
    np.testing.assert_array_equal(r["object"].astype(np.float32), exr["object"])
    assert r["seed"] == 11 and r["mean"].mean() > 0
    # The estimator options pass through as the command's.
    run_cli(lucent_cli, "render", repo / SCENE, "--spp", 4, "--size", "32x24", "--sampling", "object-weighted",
            "--split-entry", "--out", tmp_path / "b", "--quiet")
    r = lucent.render(repo / SCENE, spp=4, size="32x24", sampling="object-weighted", split_entry=True)
    np.testing.assert_array_equal(r["mean"][..., 1].astype(np.float32), read_exr(tmp_path / "b/render.exr")["G"])
    # The similar medium too.
    run_cli(lucent_cli, "render", repo / SCENE, "--spp", 4, "--size", "32x24", "--similarity-g", 0.2,
            "--out", tmp_path / "c", "--quiet")
    r = lucent.render(repo / SCENE, spp=4, size="32x24", similarity_g=0.2)
    np.testing.assert_array_equal(r["mean"][..., 0].astype(np.float32), read_exr(tmp_path / "c/render.exr")["R"])


def test_progress_is_reported_and_can_stop_the_render(repo):
    calls = []
    lucent.render(repo / SCENE, spp=8, size="32x24", progress=lambda *a: calls.append(a))
    assert calls and calls[-1][0] == 8 and calls[-1][1] == 8

    def stop(done, target, elapsed_s, rel_error):
        raise RuntimeError(f"stopped at {done}")

    with pytest.raises(RuntimeError, match="stopped at"):
        lucent.render(repo / SCENE, spp=4000, size="32x24", progress=stop)


def test_ctrl_c_interrupts_a_long_render(repo, ctrl_c):
    start = time.monotonic()
    ctrl_c(1.0)
    with pytest.raises(KeyboardInterrupt):
        # Minutes of work without the interrupt (the time budget only
        # bounds the test if the interrupt were ignored).
        lucent.render(repo / SCENE, spp=1_000_000, time_s=60.0)
    assert time.monotonic() - start < 15.0


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(spp=0), "--spp 0"),
        (dict(size="64by48"), "--size"),
        (dict(time_s=-1.0), "--time-s"),
        (dict(sampling="everywhere"), "sampling \"everywhere\": expected one of uniform, object-weighted"),
        (dict(target_rel_error=1.5), "--target-rel-error 1.5"),
        (dict(similarity_g=1.0), "--similarity-g 1"),
    ],
)
def test_bad_render_arguments_raise(repo, kwargs, message):
    with pytest.raises(lucent.LucentError, match=message):
        lucent.render(repo / SCENE, **kwargs)


def test_a_bad_scene_file_is_named(repo):
    for path in sorted((repo / "tests/bad/scene").glob("*.toml")):
        with pytest.raises(lucent.LucentError) as e:
            lucent.render(path, spp=1)
        assert path.stem in str(e.value), str(e.value)
