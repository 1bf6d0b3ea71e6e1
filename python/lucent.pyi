"""Type hints of `import lucent` (the PyO3 module in python/src/lib.rs).

Units: lengths of spheres in µm, wavelengths in nm, coefficients in 1/m,
phase functions in 1/sr, angles in rad, times in s. Absorbing refractive
indices are n + κi with κ ≥ 0 (miepython writes n − ki).

One naming throughout: a recipe is a path (str or os.PathLike) or a dict of
its keys wherever a function takes one; `wavelengths_nm` is a grid of
wavelengths, `wavelength_nm` a single one (or, in `mie_sphere`, one per
element of broadcast arrays). `**kwargs` only catches an older or confused
name (`wavelength=`) to raise a TypeError naming the current one.
python/tests/test_stubs.py checks that every function here has the
module's parameter names, kinds and defaults.
"""

from collections.abc import Callable, Mapping
from os import PathLike
from typing import Any

from typing_extensions import Never

import numpy as np
import numpy.typing as npt

__version__: str

_Path = str | PathLike[str]
_Float = float | npt.ArrayLike
_Complex = complex | float | npt.ArrayLike
_Efficiencies = tuple[Any, Any, Any, Any, Any]
_Recipe = _Path | Mapping[str, Any]

class LucentError(ValueError):
    """Bad input or a failed computation; the message is the lucent command's."""

def mie(m: _Complex, x: _Float) -> _Efficiencies:
    """(qext, qsca, qabs, qback, g) of spheres of relative index m, size parameter x (broadcast arrays)."""

def mie_sphere(
    radius_um: _Float, wavelength_nm: _Float, particle_index: _Complex, host_index: _Complex | None = None
) -> _Efficiencies:
    """(qext, qsca, qabs, qback, g) of spheres given physically; an absorbing host per Frisvad et al. 2007."""

class Optics:
    """Bulk optical properties of one recipe over wavelength."""

    @property
    def sample(self) -> str: ...
    @property
    def absorption(self) -> str: ...
    @property
    def wavelengths_nm(self) -> npt.NDArray[np.float64]:
        """Vacuum wavelengths [nm] of the grid."""
    @property
    def wavelength_nm(self) -> npt.NDArray[np.float64]:
        """The same as `wavelengths_nm` (the CSV column's name)."""
    @property
    def mu_s(self) -> npt.NDArray[np.float64]:
        """Scattering coefficient [1/m]."""
    @property
    def mu_a(self) -> npt.NDArray[np.float64]:
        """Absorption coefficient [1/m]."""
    @property
    def mu_t(self) -> npt.NDArray[np.float64]:
        """Extinction coefficient [1/m]."""
    @property
    def g(self) -> npt.NDArray[np.float64]: ...
    @property
    def n_bulk(self) -> npt.NDArray[np.float64]: ...
    @property
    def phase(self) -> npt.NDArray[np.float64]:
        """Phase function [1/sr], wavelength × angle."""
    @property
    def theta_rad(self) -> npt.NDArray[np.float64]: ...
    @property
    def units(self) -> dict[str, str]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def corrections(self) -> list[str]: ...
    def to_csv(self) -> str:
        """The table as `lucent optics` writes optical_properties.csv."""

def optics(
    recipe: _Recipe,
    wavelengths_nm: _Float | None = None,
    phase_entries: int = 4096,
    weight_percent: float | None = None,
    **kwargs: Never,
) -> Optics:
    """Bulk optical properties of a recipe (file path or dict); default grid 380–780 nm in 10 nm steps."""

def compare(
    photo: _Path | npt.ArrayLike,
    render: _Path | npt.ArrayLike,
    mask: _Path | npt.ArrayLike | None = None,
    mask_object: _Path | None = None,
    mask_board: _Path | None = None,
    photo_variance: _Path | npt.ArrayLike | None = None,
    render_variance: npt.ArrayLike | None = None,
    data_range: float = 1.0,
    luminance: str = "cie-rgb",
    band: _Path | dict[str, Any] | None = None,
    band_region: str = "object",
) -> dict[str, Any]:
    """Photo vs render metrics (RMSE, SSIM, model RMSE "noise" given the variances): metrics.json's dict (+ "notes")
    for paths, with "bands" (is the photo within the twin's predictive band? band = the render's uncertainty.json); {"as_calibrated", "noise", "notes", "width", "height"} for arrays, variances (H × W × 3) as arrays."""

def render(
    scene: _Path,
    spp: int | None = None,
    time_s: float | None = None,
    seed: int | None = None,
    size: str | None = None,
    threads: int | None = None,
    target_rel_error: float | None = None,
    sampling: str | None = None,
    dispersion: str | None = None,
    split_entry: bool = False,
    similarity_g: float | None = None,
    progress: Callable[[float, float, float, float], object] | None = None,
    uncertainty: bool = False,
    uncertainty_spp: int | None = None,
) -> dict[str, Any]:
    """Renders a scene file: {"mean", "variance"} (H × W × 3), "spp" (int), "spp_per_pixel", "object", "board" (H × W), "seed", …;
    with uncertainty=True also "band" (per region), "band_sd", "band_sd_std_error" (H × W × 3)."""

def bssrdf(
    recipe: _Recipe | None = None,
    *,
    wavelength_nm: float = 550.0,
    weight_percent: float | None = None,
    mu_s: float | None = None,
    mu_a: float | None = None,
    g: float | None = None,
    n: float | None = None,
    thickness_mm: float | None = None,
    theta_i: float = 45.0,
    phi_i: float = 0.0,
    theta_o: float = 0.0,
    phi_o: float = 180.0,
    phase: str | None = None,
    beam_fwhm_um: float = 200.0,
    beam_map: _Path | None = None,
    beam_map_pixel_mm: float | None = None,
    pixels: int = 259,
    pixel_mm: float = 0.1029,
    crop: int | None = None,
    rel_error: float | None = None,
    pixel_rel_error: float | None = None,
    paths: int | None = None,
    time_s: float | None = None,
    seed: int = 1,
    estimator: str = "auto",
    lobe_vertices: int = 16,
    roughness: str | None = None,
    no_fold: bool = False,
    similarity_g: float | None = None,
    progress: Callable[[float, float, float], object] | None = None,
    **kwargs: Never,
) -> dict[str, Any]:
    """Slab BSSRDF slice as `lucent bssrdf`: {"slice", "std_error"} (N × N, 1/(m² sr)), "sum", "sum_std_error", "profile", …"""

def fit(
    recipe: _Recipe,
    measured: _Path | list[_Path],
    free: str | list[str],
    *,
    objective: str = "sum",
    wavelength_nm: float = 550.0,
    weight_percent: float | None = None,
    measured_pixel_mm: float | None = None,
    beam_fwhm_um: float = 200.0,
    beam_map: _Path | None = None,
    beam_map_pixel_mm: float | None = None,
    measured_rel_sd: float = 0.05,
    threshold: float = 0.01,
    rel_error: float = 0.005,
    paths: int | None = None,
    pilot_time_s: float = 60.0,
    bounds: str | list[tuple[float, float]] | None = None,
    thickness_mm: float | None = None,
    seed: int = 1,
    out: _Path | None = None,
    progress: Callable[[str], object] | None = None,
    **kwargs: Never,
) -> dict[str, Any]:
    """Recipe parameters fitted to measured slices as `lucent fit`: fit.json's dict ("parameters", "identifiable", …)."""

def calibrate(
    images: _Path | list[_Path] | list[npt.NDArray[np.uint8]],
    board: str,
    square_mm: float,
    model: str = "pinhole-k3",
    detector: str = "auto",
) -> dict[str, Any]:
    """Chessboard calibration as `lucent calibrate`: camera.json's dict plus "camera_matrix" (3 × 3), "dist_coeffs" (OpenCV order)."""

def ccm(
    camera_rgb: npt.ArrayLike,
    reference_xyz: npt.ArrayLike | None = None,
    method: str = "Cheung 2004",
    white_index: int = 18,
) -> dict[str, Any]:
    """Colour-correction matrix camera RGB → XYZ (D50) and its per-patch ΔE; default reference: the ColorChecker."""

def delta_e_2000(lab1: npt.ArrayLike, lab2: npt.ArrayLike) -> Any:
    """CIEDE2000 of L*a*b* colours (last axis L*, a*, b*), broadcast."""
