"""lucent.bssrdf against the files of `lucent bssrdf` for the same arguments."""

import json

import numpy as np
import OpenEXR
import pytest

import lucent

from conftest import run_cli

SLAB = dict(mu_s=2000.0, mu_a=20.0, g=0.8, n=1.5, thickness_mm=3.0, pixels=41, pixel_mm=0.1, beam_fwhm_um=300.0)


def cli_args(d):
    return [x for k, v in d.items() for x in (f"--{k.replace('_', '-')}", v)]


def test_slice_equals_the_command_files(lucent_cli, tmp_path):
    run = dict(SLAB, theta_i=30.0, theta_o=0.0, paths=20000, seed=3)
    run_cli(lucent_cli, "bssrdf", *cli_args(run), "--out", tmp_path, "--quiet")
    with OpenEXR.File(str(tmp_path / "bssrdf.exr"), separate_channels=True) as f:
        ch = {k: v.pixels for k, v in f.channels().items()}
    summary = json.loads((tmp_path / "summary.json").read_text())
    r = lucent.bssrdf(**run)
    assert r["slice"].shape == (41, 41)
    np.testing.assert_array_equal(r["slice"].astype(np.float32), ch["Y"])
    np.testing.assert_array_equal(r["std_error"].astype(np.float32), ch["std_error"])
    assert r["sum"] == summary["sum"] and r["sum_std_error"] == summary["sum_std_error"]
    assert r["paths"] == summary["paths"] and r["estimator"] == summary["estimator"]
    profile = np.genfromtxt(tmp_path / "profile.csv", delimiter=",", names=True)
    np.testing.assert_allclose(r["x_mm"], profile["x_mm"], atol=1e-6)
    np.testing.assert_allclose(r["profile"], profile["f_per_m2_sr"], rtol=1e-8)
    np.testing.assert_allclose(r["beam_profile"], profile["beam_relative"], rtol=1e-6)
    np.testing.assert_array_equal(r["profile"], r["slice"][20])


def test_the_sum_converges_within_its_error():
    # The slice sum of two independent seeds agrees within their errors.
    a = lucent.bssrdf(**SLAB, paths=20000, seed=1)
    b = lucent.bssrdf(**SLAB, paths=20000, seed=2)
    z = (a["sum"] - b["sum"]) / np.hypot(a["sum_std_error"], b["sum_std_error"])
    assert abs(z) < 4.5, z
    assert a["sum_std_error"] < 0.1 * a["sum"]


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(SLAB, paths=0), "--paths 0"),
        (dict(SLAB, paths=10, thickness_mm=-1.0), "--thickness-mm -1"),
        (dict(SLAB, paths=10, estimator="magic"), "estimator \"magic\": expected one of"),
        (dict(paths=10), "give --recipe"),
        (dict(SLAB, paths=10, beam_fwhm_um=9000.0), "wider than the slice"),
    ],
)
def test_bad_arguments_raise(kwargs, message):
    with pytest.raises(lucent.LucentError, match=message):
        lucent.bssrdf(**kwargs)


def test_ctrl_c_interrupts_a_long_simulation(ctrl_c):
    import time

    start = time.monotonic()
    ctrl_c(0.5)
    with pytest.raises(KeyboardInterrupt):
        lucent.bssrdf(**SLAB, rel_error=1e-6, time_s=60.0)
    assert time.monotonic() - start < 15.0


def test_other_threads_run_during_a_simulation():
    # The simulation releases the GIL: a Python thread keeps counting meanwhile.
    import threading
    import time

    ticks, done = [], threading.Event()

    def count():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.002)

    t = threading.Thread(target=count)
    t.start()
    try:
        start = time.monotonic()
        lucent.bssrdf(**SLAB, time_s=1.0)
        end = time.monotonic()
    finally:
        done.set()
        t.join()
    during = [x for x in ticks if start < x < end]
    # ~1 s at one tick per 2 ms: hundreds; none if the GIL were held.
    assert end - start >= 0.9 and len(during) > 100, (end - start, len(during))


def test_progress_is_reported():
    calls = []
    r = lucent.bssrdf(**SLAB, paths=20000, seed=1, progress=lambda *a: calls.append(a))
    assert calls and all(len(c) == 3 for c in calls)
    assert calls[-1][0] <= r["paths"] and calls[-1][2] > 0
