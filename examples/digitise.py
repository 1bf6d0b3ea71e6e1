# %% [markdown]
# # Digitising a translucent plaque from Python
#
# recipe → optical properties → Mie check of one sphere against miepython →
# a small render of the twin. Run it as a script (`.venv-py/bin/python
# examples/digitise.py` after `make python`) or cell by cell (`# %%`) in an
# editor that understands them. The test suite runs it (python/tests/test_example.py).

# %%
import os
from pathlib import Path

import numpy as np

import lucent

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("MIEPYTHON_USE_JIT", "0")  # miepython without numba compilation

# %% [markdown]
# ## 1. Recipe → optical properties
# PDMS spheres (2.2 µm) in polycarbonate: μs, μa [1/m], g and the phase
# function (wavelength × angle) at three wavelengths.

# %%
o = lucent.optics(REPO / "fixtures/samples/IOL1068-09.toml", wavelengths_nm=[450, 550, 650], phase_entries=181)
for w, mu_s, mu_a, g in zip(o.wavelengths_nm, o.mu_s, o.mu_a, o.g):
    print(f"{w:5.0f} nm  μs {mu_s:9.1f} {o.units['mu_s']}  μa {mu_a:7.3f} {o.units['mu_a']}  g {g:.4f}")
print("phase table:", o.phase.shape, "over θ =", np.degrees(o.theta_rad[[0, -1]]), "deg")

# %% [markdown]
# ## 2. A slice of the phase function
# p(θ) at 550 nm around the forward peak, and the check that it integrates to
# one over the sphere (trapezoids in cos θ, as the renderer samples it).

# %%
p550 = o.phase[1]
mu = np.cos(o.theta_rad)
integral = 2 * np.pi * np.sum(0.5 * (p550[1:] + p550[:-1]) * (mu[:-1] - mu[1:]))
print("p(0°), p(10°), p(90°) =", p550[0], p550[10], p550[90], "1/sr; ∫p dΩ =", integral)
assert abs(integral - 1) < 1e-9

# %% [markdown]
# ## 3. One sphere against miepython
# The same PDMS sphere, relative index m = n_PDMS / n_PC at 550 nm, with
# lucent's solver and with miepython (which writes absorbing indices n − ki).

# %%
import miepython

m = 1.41 / 1.5889 + 1e-6j
x = 2 * np.pi * 1.1e-6 * 1.5889 / 550e-9
qext, qsca, qabs, qback, g = lucent.mie(m, x)
rext, rsca, rback, rg = miepython.efficiencies_mx(np.conj(m), x)
print(f"x = {x:.3f}: lucent qsca {qsca:.10f} g {g:.10f}; miepython qsca {rsca:.10f} g {rg:.10f}")
assert abs(qsca - rsca) < 1e-6 * rsca and abs(g - rg) < 1e-6

# %% [markdown]
# ## 4. A small render of the twin
# The dense plaque over the checkerboard at 48 × 36 pixels, 16 samples per
# pixel: the mean and the variance of each pixel's mean (H × W × 3).

# %%
seen = []
r = lucent.render(REPO / "fixtures/render/plaque_dense.toml", spp=16, seed=3, size="48x36",
                  progress=lambda done, target, s, err: seen.append(done))
mean, var = r["mean"], r["variance"]
on_object = r["object"] >= 0.5
rel = np.sqrt(var[on_object]).mean() / mean[on_object].mean()
print(f"{mean.shape}, {r['wall_s']:.2f} s, passes {seen}, mean RGB {mean.reshape(-1, 3).mean(0)}, "
      f"relative standard error on the object ≈ {100 * rel:.1f} %")
