//! `import lucent`: the Python API of the lucent library (PyO3 + numpy).
//!
//! Every function calls the same library code as the `lucent` command: the
//! Lorenz–Mie solver (`lucent::optics::mie`), the bulk optical properties of a
//! recipe (`lucent::optics::bulk`), the photo/render comparison
//! (`lucent::compare`), the renderer (`lucent_render::tracer`, with the scene
//! prepared as `lucent render` prepares it), the slab simulator
//! (`lucent_render::slab`, planned as `lucent bssrdf` plans it), the fit of
//! recipe parameters to measured slices (`lucent::fit`, the problem built as
//! `lucent fit` builds it), the chessboard calibration
//! (`lucent_calib::camera`, photos read as `lucent calibrate` reads them)
//! and the colour-correction fits (`lucent_colour::ccm`, CIEDE2000 of
//! `lucent_colour::difference`).
//! Errors are raised as `lucent.LucentError` (a `ValueError`) with the
//! library's message; long calls release the GIL and stop on Ctrl-C.

use lucent::cli::bssrdf as bssrdf_cli;
use lucent::cli::camera as camera_cli;
use lucent::cli::fit::FitArgs;
use lucent::cli::groups::{BeamArgs, TwinRenderArgs};
use lucent::cli::render::RenderArgs;
use lucent::compare::{self, MaskSpec, Request};
use lucent::fit;
use lucent::imageio::RgbImage;
use lucent::optics::bulk::{self, OpticalSpectrum};
use lucent::optics::mie::{self, Efficiencies, MieError};
use lucent::optics::output;
use lucent::optics::recipe::{Overrides, Recipe};
use lucent_calib::camera::{self as calib_camera, Photo};
use lucent_calib::GrayImage;
use lucent_colour::WavelengthGrid;
use lucent_render::{slab, tracer};
use num_complex::Complex64;
use numpy::ndarray::{Array, Array2, IxDyn};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString, PyTuple};
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Duration;

create_exception!(
    lucent,
    LucentError,
    PyValueError,
    "Bad input or a failed computation in lucent; the message is the library's (the same as the lucent command's)."
);

/// A `LucentError` with `e`'s message (its causes joined by ": ").
fn error(e: impl std::fmt::Display) -> PyErr {
    LucentError::new_err(e.to_string())
}

/// A `LucentError` from an `anyhow` error with its whole chain of causes.
fn error_chain(e: anyhow::Error) -> PyErr {
    LucentError::new_err(format!("{e:#}"))
}

/// The numpy module.
fn np(py: Python<'_>) -> PyResult<Bound<'_, PyModule>> {
    py.import("numpy")
}

/// `obj` as a numpy array of `dtype` (a copy only where needed).
fn as_array<'py>(py: Python<'py>, obj: &Bound<'py, PyAny>, dtype: &str, what: &str) -> PyResult<Bound<'py, PyAny>> {
    let np = np(py)?;
    np.call_method1("asarray", (obj, np.getattr(dtype)?))
        .map_err(|e| error(format!("{what}: not convertible to an array of {dtype}: {e}")))
}

/// `obj` as a file path if it is a `str` or an `os.PathLike`.
fn as_path(obj: &Bound<'_, PyAny>) -> Option<PathBuf> {
    if obj.is_instance_of::<PyString>() || obj.hasattr("__fspath__").unwrap_or(false) {
        obj.extract::<PathBuf>().ok()
    } else {
        None
    }
}

/// Arrays over `shape` as numpy arrays (0-d: Python floats).
fn to_numpy<'py>(py: Python<'py>, shape: &[usize], data: Vec<f64>) -> PyResult<Bound<'py, PyAny>> {
    let a = Array::from_shape_vec(IxDyn(shape), data).map_err(error)?.into_pyarray(py);
    if shape.is_empty() {
        a.call_method0("item")
    } else {
        Ok(a.into_any())
    }
}

/// Where element `i` of a C-ordered array of `shape` sits, as "(i, j)".
fn index_of(mut i: usize, shape: &[usize]) -> String {
    let mut idx = vec![0; shape.len()];
    for (k, &n) in shape.iter().enumerate().rev() {
        idx[k] = i % n.max(1);
        i /= n.max(1);
    }
    let parts: Vec<String> = idx.iter().map(|v| v.to_string()).collect();
    format!("({}{})", parts.join(", "), if parts.len() == 1 { "," } else { "" })
}

/// Broadcasts the arrays (numpy rules) and returns them as flat vectors in C
/// order with the common shape.
fn broadcast<'py>(py: Python<'py>, arrays: &[Bound<'py, PyAny>]) -> PyResult<(Vec<usize>, Vec<Bound<'py, PyAny>>)> {
    let np = np(py)?;
    let b = np
        .call_method1("broadcast_arrays", PyTuple::new(py, arrays)?)
        .map_err(|e| error(format!("the arguments' shapes do not broadcast together: {e}")))?;
    let list: Vec<Bound<'py, PyAny>> = b.extract()?;
    let shape: Vec<usize> =
        list.first().map(|a| a.getattr("shape")).transpose()?.map(|s| s.extract()).transpose()?.unwrap_or_default();
    let flat = list
        .iter()
        .map(|a| np.call_method1("ascontiguousarray", (a,))?.call_method0("ravel"))
        .collect::<PyResult<Vec<_>>>()?;
    Ok((shape, flat))
}

fn flat_f64(a: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    let r: PyReadonlyArrayDyn<'_, f64> = a.extract()?;
    Ok(r.as_array().iter().copied().collect())
}

fn flat_c64(a: &Bound<'_, PyAny>) -> PyResult<Vec<Complex64>> {
    let r: PyReadonlyArrayDyn<'_, Complex64> = a.extract()?;
    Ok(r.as_array().iter().copied().collect())
}

/// The efficiencies as a tuple of arrays (qext, qsca, qabs, qback, g).
fn efficiencies_tuple<'py>(
    py: Python<'py>,
    shape: &[usize],
    q: Vec<Result<Efficiencies, String>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let mut cols: [Vec<f64>; 5] = Default::default();
    for (i, r) in q.into_iter().enumerate() {
        let e = r.map_err(|m| match shape.is_empty() {
            true => error(m),
            false => error(format!("element {}: {m}", index_of(i, shape))),
        })?;
        for (c, v) in cols.iter_mut().zip([e.qext, e.qsca, e.qabs, e.qback, e.g]) {
            c.push(v);
        }
    }
    let items = cols.into_iter().map(|c| to_numpy(py, shape, c)).collect::<PyResult<Vec<_>>>()?;
    PyTuple::new(py, items)
}

/// An index with a negative imaginary part: lucent writes absorbing indices
/// as n + κi (κ ≥ 0), as the lucent command does.
fn check_index(what: &str, m: Complex64) -> Result<(), String> {
    if m.im < 0.0 {
        return Err(format!(
            "{what} {m}: the imaginary part must be ≥ 0 (lucent writes an absorbing index as n+κi; miepython's n−ki means the same as n+ki here)"
        ));
    }
    Ok(())
}

/// Lorenz–Mie efficiencies of homogeneous spheres in a non-absorbing host
/// (Bohren & Huffman 1983; Wiscombe 1979), vectorised over numpy arrays
/// that broadcast together (as miepython's ``efficiencies_mx``).
///
/// m: relative refractive index n_sphere / n_host, real or complex; an
///    absorbing sphere has a POSITIVE imaginary part (m = n + κi; for
///    miepython's n − ki pass ``np.conj(m)`` to miepython, not to lucent).
/// x: size parameter 2π r n_host / λ (dimensionless, > 0).
///
/// Returns five arrays of the broadcast shape (floats for scalar inputs):
/// extinction, scattering, absorption and backscattering efficiencies
/// (cross sections over π r², dimensionless; qabs is the power absorbed
/// inside the sphere, exactly 0 for a real m) and the asymmetry parameter g.
/// qback = |Σ (2n+1)(−1)^n (a_n − b_n)|² / x² (Bohren & Huffman's
/// definition). The computation runs on all cores without the GIL.
///
/// Raises LucentError naming the element for a non-finite or non-positive x,
/// a zero or non-finite m, or a negative imaginary part of m.
#[pyfunction]
#[pyo3(name = "mie")]
fn py_mie<'py>(py: Python<'py>, m: &Bound<'py, PyAny>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyTuple>> {
    let m = as_array(py, m, "complex128", "m")?;
    let x = as_array(py, x, "float64", "x")?;
    let (shape, flat) = broadcast(py, &[m, x])?;
    let (m, x) = (flat_c64(&flat[0])?, flat_f64(&flat[1])?);
    let q: Vec<Result<Efficiencies, String>> = py.detach(|| {
        m.par_iter()
            .zip(x.par_iter())
            .map(|(&m, &x)| {
                check_index("m", m)?;
                if !(x.is_finite() && x > 0.0) {
                    return Err(format!("size parameter x = {x} must be a positive finite number"));
                }
                mie::efficiencies(m, x).map_err(|e: MieError| e.to_string())
            })
            .collect()
    });
    efficiencies_tuple(py, &shape, q)
}

/// Lorenz–Mie efficiencies (qext, qsca, qabs, qback, g) of spheres given
/// physically (what ``lucent mie --radius-um R --wavelength-nm L
/// --particle-index N --host-index N`` prints), vectorised over arrays that
/// broadcast together; floats for scalar inputs.
///
/// radius_um: sphere radius [µm]; wavelength_nm: vacuum wavelength [nm];
/// particle_index, host_index: complex refractive indices n + κi (κ ≥ 0).
///
/// In a real host these are the usual efficiencies (size parameter
/// x = 2π r n_host / λ). In an absorbing host (κ_host > 0) qext and qsca are
/// the apparent far-field efficiencies of Frisvad, Christensen & Jensen
/// (2007), qsca with the attenuation factor F(α), and qabs is the power
/// absorbed inside the sphere (so qext − qsca ≠ qabs). All relative to π r²,
/// dimensionless.
#[pyfunction]
#[pyo3(name = "mie_sphere", signature = (radius_um, wavelength_nm, particle_index, host_index = None))]
fn py_mie_sphere<'py>(
    py: Python<'py>,
    radius_um: &Bound<'py, PyAny>,
    wavelength_nm: &Bound<'py, PyAny>,
    particle_index: &Bound<'py, PyAny>,
    host_index: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyTuple>> {
    let one = 1.0f64.into_pyobject(py)?.into_any();
    let arrays = [
        as_array(py, radius_um, "float64", "radius_um")?,
        as_array(py, wavelength_nm, "float64", "wavelength_nm")?,
        as_array(py, particle_index, "complex128", "particle_index")?,
        as_array(py, host_index.unwrap_or(&one), "complex128", "host_index")?,
    ];
    let (shape, flat) = broadcast(py, &arrays)?;
    let (r, w, np_, nh) = (flat_f64(&flat[0])?, flat_f64(&flat[1])?, flat_c64(&flat[2])?, flat_c64(&flat[3])?);
    let q: Vec<Result<Efficiencies, String>> = py.detach(|| {
        (0..r.len())
            .into_par_iter()
            .map(|i| {
                check_index("particle_index", np_[i])?;
                check_index("host_index", nh[i])?;
                if !(r[i].is_finite() && r[i] > 0.0) {
                    return Err(format!("radius_um {}: must be a positive finite number", r[i]));
                }
                if !(w[i].is_finite() && w[i] > 0.0) {
                    return Err(format!("wavelength_nm {}: must be a positive finite number", w[i]));
                }
                mie::efficiencies_in_host(np_[i], nh[i], w[i] * 1e-9, r[i] * 1e-6).map_err(|e| e.to_string())
            })
            .collect()
    });
    efficiencies_tuple(py, &shape, q)
}

/// Spectral optical properties of one recipe (see ``lucent.optics``).
#[pyclass(frozen, module = "lucent")]
struct Optics {
    spectrum: OpticalSpectrum,
}

/// Units of the arrays of `Optics`.
const OPTICS_UNITS: [(&str, &str); 9] = [
    ("wavelengths_nm", "nm"),
    ("wavelength_nm", "nm"),
    ("mu_s", "1/m"),
    ("mu_a", "1/m"),
    ("mu_t", "1/m"),
    ("g", "1"),
    ("n_bulk", "1"),
    ("phase", "1/sr"),
    ("theta_rad", "rad"),
];

#[pymethods]
impl Optics {
    /// The sample's name (the recipe's ``name``).
    #[getter]
    fn sample(&self) -> &str {
        &self.spectrum.sample
    }
    /// The absorption model μ_a was computed with (the recipe's ``absorption``).
    #[getter]
    fn absorption(&self) -> &'static str {
        self.spectrum.absorption.name()
    }
    /// Vacuum wavelengths [nm] of the grid (``optics(wavelengths_nm=…)``).
    #[getter]
    fn wavelengths_nm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.wavelength_nm)
    }
    /// The same as ``wavelengths_nm`` under the name of the CSV column.
    #[getter]
    fn wavelength_nm<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.wavelength_nm)
    }
    /// Scattering coefficient μ_s [1/m] per wavelength.
    #[getter]
    fn mu_s<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.mu_s_per_m)
    }
    /// Absorption coefficient μ_a [1/m] per wavelength.
    #[getter]
    fn mu_a<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.mu_a_per_m)
    }
    /// Extinction coefficient μ_t = μ_s + μ_a [1/m] per wavelength.
    #[getter]
    fn mu_t<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.mu_t_per_m)
    }
    /// Asymmetry parameter g = <cos θ> of the bulk phase function per wavelength.
    #[getter]
    fn g<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.g)
    }
    /// Real refractive index of the bulk material per wavelength.
    #[getter]
    fn n_bulk<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_slice(py, &self.spectrum.n_bulk)
    }
    /// Phase function p(θ) [1/sr], wavelength × angle (angles in ``theta_rad``),
    /// normalised so that, linear in cos θ between nodes, ∫ p dΩ = 1.
    /// Shape (wavelengths, 0) when ``phase_entries=0``.
    #[getter]
    fn phase<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let rows = self.spectrum.phase.len();
        let cols = self.spectrum.phase.first().map_or(0, Vec::len);
        let flat: Vec<f64> = self.spectrum.phase.iter().flatten().copied().collect();
        Ok(Array2::from_shape_vec((rows, cols), flat).map_err(error)?.into_pyarray(py))
    }
    /// Scattering angles θ_i = iπ/(N−1) [rad] of the columns of ``phase``.
    #[getter]
    fn theta_rad<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let n = self.spectrum.phase.first().map_or(0, Vec::len);
        let t: Vec<f64> = (0..n).map(|i| std::f64::consts::PI * i as f64 / (n - 1) as f64).collect();
        PyArray1::from_vec(py, t)
    }
    /// The units of the arrays, e.g. ``units["mu_s"] == "1/m"``.
    #[getter]
    fn units<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (k, v) in OPTICS_UNITS {
            d.set_item(k, v)?;
        }
        Ok(d)
    }
    /// Warnings of the computation (extrapolated index data, …), one line per cause.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.spectrum.warnings.clone()
    }
    /// The recipe's corrections of the index data.
    #[getter]
    fn corrections(&self) -> Vec<String> {
        self.spectrum.corrections.clone()
    }
    /// The table as ``lucent optics`` writes it to optical_properties.csv.
    fn to_csv(&self) -> PyResult<String> {
        output::table_csv(&[&self.spectrum]).map_err(error)
    }
    fn __repr__(&self) -> String {
        let w = &self.spectrum.wavelength_nm;
        format!(
            "<lucent.Optics {:?}: {} wavelengths {}–{} nm, absorption {:?}>",
            self.spectrum.sample,
            w.len(),
            w.first().copied().unwrap_or(f64::NAN),
            w.last().copied().unwrap_or(f64::NAN),
            self.spectrum.absorption.name()
        )
    }
}

/// The name under which a recipe given as a dict appears in messages; its
/// relative index-file paths start from the working folder.
const RECIPE_DICT: &str = "<recipe dict>";

/// A `recipe` argument: a TOML file, or a dict with the file's keys and
/// values (as TOML text, relative paths anchored at `anchor`, a name in the
/// working folder).
enum RecipeArg {
    File(PathBuf),
    Dict { text: String, anchor: PathBuf },
}

impl RecipeArg {
    /// A path (str or os.PathLike) or a dict; anything else is a LucentError naming `recipe`.
    fn from_py(py: Python<'_>, recipe: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Some(path) = as_path(recipe) {
            return Ok(Self::File(path));
        }
        if let Ok(d) = recipe.cast::<PyDict>() {
            let json: String = py
                .import("json")?
                .call_method1("dumps", (d,))
                .map_err(|e| {
                    error(format!(
                        "recipe dict: not expressible as TOML (a value is not a str, number, bool, list or dict): {e}"
                    ))
                })?
                .extract()?;
            let value: serde_json::Value = serde_json::from_str(&json).map_err(error)?;
            let text =
                toml::to_string(&value).map_err(|e| error(format!("recipe dict: not expressible as TOML: {e}")))?;
            let cwd = std::env::current_dir()
                .map_err(|e| error(format!("recipe dict: the working folder is unknown: {e}")))?;
            return Ok(Self::Dict { text, anchor: cwd.join(RECIPE_DICT) });
        }
        Err(error(format!(
            "recipe: expected a path (str or os.PathLike) or a dict of the recipe's keys, got {}",
            type_name(recipe)
        )))
    }

    /// The validated recipe.
    fn load(&self, overrides: Overrides) -> PyResult<Recipe> {
        match self {
            Self::File(path) => Recipe::load(path, overrides).map_err(error),
            Self::Dict { text, anchor } => Recipe::parse(text, anchor, overrides).map_err(error),
        }
    }

    /// The path that stands for the recipe in the command's arguments.
    fn path(&self) -> PathBuf {
        match self {
            Self::File(path) => path.clone(),
            Self::Dict { anchor, .. } => anchor.clone(),
        }
    }
}

/// Raises TypeError for the keyword arguments in `kwargs` (those `func`
/// does not take), naming the argument's current name where `renamed`
/// lists it as (old name, new name).
fn reject_unknown_keywords(func: &str, kwargs: Option<&Bound<'_, PyDict>>, renamed: &[(&str, &str)]) -> PyResult<()> {
    let Some((key, _)) = kwargs.and_then(|k| k.iter().next()) else {
        return Ok(());
    };
    let key: String = key.extract()?;
    Err(PyTypeError::new_err(match renamed.iter().find(|(old, _)| *old == key) {
        Some((old, new)) => format!("{func}() got an unexpected keyword argument '{old}': it is called '{new}'"),
        None => format!("{func}() got an unexpected keyword argument '{key}'"),
    }))
}

/// Bulk optical properties of a turbid material from its recipe (Lorenz–Mie
/// theory over the particle types and their size distributions), as
/// ``lucent optics RECIPE`` computes them.
///
/// recipe: path of a recipe TOML file (str or os.PathLike), or a dict with
///     the same keys (relative index-file paths then start from the working
///     folder).
/// wavelengths_nm: the grid of vacuum wavelengths [nm], an array or a
///     scalar; default 380–780 nm in 10 nm steps. (``wavelength_nm`` or
///     ``wavelength`` raise a TypeError naming ``wavelengths_nm``.)
/// phase_entries: entries of the tabulated phase function, uniform in θ
///     over [0, π] (0: no table).
/// weight_percent: weight percentage for particle types whose recipe leaves
///     it unknown.
///
/// Returns an ``Optics`` object with numpy arrays ``mu_s``, ``mu_a``,
/// ``mu_t`` [1/m], ``g``, ``n_bulk``, ``phase`` [1/sr] (wavelength × angle,
/// angles in ``theta_rad``), ``wavelengths_nm`` and their ``units``.
/// Raises LucentError with the message of ``lucent optics`` for a bad
/// recipe (unknown key, missing index file, …) or wavelength.
#[pyfunction]
#[pyo3(name = "optics", signature = (recipe, wavelengths_nm = None, phase_entries = 4096, weight_percent = None, **kwargs))]
fn py_optics(
    py: Python<'_>,
    recipe: &Bound<'_, PyAny>,
    wavelengths_nm: Option<&Bound<'_, PyAny>>,
    phase_entries: usize,
    weight_percent: Option<f64>,
    kwargs: Option<&Bound<'_, PyDict>>,
) -> PyResult<Optics> {
    reject_unknown_keywords(
        "optics",
        kwargs,
        &[("wavelength_nm", "wavelengths_nm"), ("wavelength", "wavelengths_nm")],
    )?;
    if phase_entries == 1 {
        return Err(error("phase_entries must be 0 (no table) or at least 2"));
    }
    let recipe = RecipeArg::from_py(py, recipe)?.load(Overrides { weight_percent })?;
    let grid = match wavelengths_nm {
        None => WavelengthGrid::visible(),
        Some(w) => {
            let w = as_array(py, w, "float64", "wavelengths_nm")?.call_method0("ravel")?;
            WavelengthGrid::from_list(flat_f64(&w)?).map_err(|e| error(format!("wavelengths_nm: {e}")))?
        }
    };
    let options = bulk::Options { phase_entries, ..Default::default() };
    let spectrum = py.detach(|| bulk::compute(&recipe, &grid, &options)).map_err(error)?;
    Ok(Optics { spectrum })
}

/// The images of `compare` given as arrays: H × W × 3, finite.
fn rgb_image(py: Python<'_>, obj: &Bound<'_, PyAny>, role: &str) -> PyResult<RgbImage> {
    if let Some(path) = as_path(obj) {
        return compare::input::read_image(&path, "image").map(|l| l.image).map_err(error);
    }
    let a = as_array(py, obj, "float32", role)?;
    let r: PyReadonlyArrayDyn<'_, f32> = a.extract()?;
    let shape = r.shape().to_vec();
    let [h, w, 3] = shape[..] else {
        return Err(error(format!("{role}: expected an array of shape (height, width, 3), got {shape:?}")));
    };
    let data: Vec<f32> = r.as_array().iter().copied().collect();
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(error(format!("{role}: pixel {} holds {} (must be finite)", index_of(i, &shape), data[i])));
    }
    RgbImage::new(w, h, data).map_err(|e| error(format!("{role}: {e}")))
}

/// A serialisable value as a Python object (through JSON).
fn to_python<'py, T: serde::Serialize>(py: Python<'py>, value: &T) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(error)?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A per-pixel variance of `compare` given as an array: the images' shape
/// (height, width, 3), every value finite and ≥ 0; `role` names the argument.
fn variance_image(py: Python<'_>, obj: &Bound<'_, PyAny>, role: &str, images: &RgbImage) -> PyResult<Vec<f32>> {
    if as_path(obj).is_some() {
        return Err(error(format!(
            "{role}: a file path needs the photo and render as file paths too; with arrays give {role} as an array \
             of shape (height, width, 3)"
        )));
    }
    let a = as_array(py, obj, "float32", role)?;
    let r: PyReadonlyArrayDyn<'_, f32> = a.extract()?;
    let shape = r.shape().to_vec();
    if shape != [images.height, images.width, 3] {
        return Err(error(format!(
            "{role}: expected shape ({}, {}, 3) like the images, got {shape:?}",
            images.height, images.width
        )));
    }
    let data: Vec<f32> = r.as_array().iter().copied().collect();
    if let Some(i) = data.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
        return Err(error(format!(
            "{role}: pixel {} holds {} (a variance must be finite and ≥ 0)",
            index_of(i, &shape),
            data[i]
        )));
    }
    Ok(data)
}

/// Photo against render: RMSE (total and per channel), mean absolute error,
/// relative error, mean colours and SSIM (per channel, their mean, and of
/// the luminance Y; Wang et al. 2004, computed as scikit-image's
/// ``structural_similarity(gaussian_weights=True, sigma=1.5,
/// use_sample_covariance=False, data_range=data_range)``), and with the
/// render's variance the model RMSE (the error with the expected noise
/// removed, its 95 % interval and the noise floor), as ``lucent compare``
/// computes them.
///
/// photo, render: file paths (EXR, HDR, PNG, TIFF; str or os.PathLike) or
///     arrays of shape (height, width, 3), linear RGB in the same units.
/// mask: an image path, or with arrays a boolean array (height, width),
///     True = compared. mask_object, mask_board: scene JSON or render EXR
///     paths (with file paths only).
/// photo_variance: the per-pixel variance of the photo: an EXR path with
///     file paths, an array (height, width, 3) with arrays.
/// render_variance: with arrays, the variance of each render pixel's mean
///     (height, width, 3), e.g. ``render(…)["variance"]``; with a file path
///     the render EXR's variance layers are read instead.
/// data_range: SSIM's L (C1 = (0.01 L)², C2 = (0.03 L)²) in the images'
///     units; luminance: "cie-rgb" (0.1769, 0.8124, 0.0107) or "rec709".
/// band: the twin's band: ``render(…, uncertainty=True)["band"]`` or the
///     path of ``lucent render --uncertainty``'s uncertainty.json (or its
///     folder). With file paths it needs mask_object or mask_board; with
///     arrays a mask, whose pixels are taken as the band's ``band_region``
///     ("object" or "board"). The result's ``bands[0]`` says whether the
///     photo's mean over those pixels lies within the twin's predictive
///     band (``within``, ``z`` per band, ``statement``); with arrays the
///     render's and photo's noise come from render_variance and
///     photo_variance.
///
/// With both images as paths the result is the dict of metrics.json that
/// ``lucent compare --photo P --render R`` writes (``as_calibrated``, the
/// model RMSE ``noise`` when the render EXR carries its variance, …) plus
/// ``notes``. With arrays it is ``{"as_calibrated": metrics, "noise":
/// model RMSE or None, "notes": [...], "width": W, "height": H}``, ``noise``
/// the same numbers as the command's for the same images and variances
/// (given ``render_variance``; ``photo_variance`` needs it). The
/// variances must be finite, ≥ 0 and of the images' shape (LucentError, a
/// ValueError, naming the argument otherwise).
#[pyfunction]
#[pyo3(name = "compare", signature = (
    photo, render, mask = None, mask_object = None, mask_board = None, photo_variance = None,
    render_variance = None, data_range = 1.0, luminance = "cie-rgb", band = None,
    band_region = "object"
))]
#[allow(clippy::too_many_arguments)]
fn py_compare<'py>(
    py: Python<'py>,
    photo: &Bound<'py, PyAny>,
    render: &Bound<'py, PyAny>,
    mask: Option<&Bound<'py, PyAny>>,
    mask_object: Option<PathBuf>,
    mask_board: Option<PathBuf>,
    photo_variance: Option<&Bound<'py, PyAny>>,
    render_variance: Option<&Bound<'py, PyAny>>,
    data_range: f64,
    luminance: &str,
    band: Option<&Bound<'py, PyAny>>,
    band_region: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let luminance = compare::Luminance::from_name(luminance).map_err(error)?;
    let band = band
        .map(|b| match as_path(b) {
            Some(p) => compare::band::TwinBands::read(&p).map_err(error),
            None => {
                let text: String = py.import("json")?.call_method1("dumps", (b,))?.extract()?;
                compare::band::TwinBands::from_json(&text, "band").map_err(error)
            }
        })
        .transpose()?;
    if let (Some(photo_path), Some(render_path)) = (as_path(photo), as_path(render)) {
        let mask_image = mask
            .map(|m| {
                as_path(m).ok_or_else(|| error("mask: with file paths for the images, give the mask as a path too"))
            })
            .transpose()?;
        let mask = match (mask_image, mask_object, mask_board) {
            (Some(p), None, None) => MaskSpec::Image(p),
            (None, Some(p), None) => MaskSpec::Object(p),
            (None, None, Some(p)) => MaskSpec::Board(p),
            (None, None, None) => MaskSpec::None,
            _ => return Err(error("give at most one of mask, mask_object, mask_board")),
        };
        if render_variance.is_some() {
            return Err(error(
                "render_variance: with the render as a file path its variance is read from the EXR's \
                 variance.R/G/B layers; give the images as arrays to pass render_variance",
            ));
        }
        let photo_variance = photo_variance
            .map(|v| {
                as_path(v).ok_or_else(|| {
                    error(
                        "photo_variance: with file paths for the images, give the photo's variance as an EXR path too",
                    )
                })
            })
            .transpose()?;
        let req = Request {
            photo: photo_path,
            render: render_path,
            render_b: None,
            mask,
            scene: None,
            data_range,
            luminance,
            exposure: None,
            refine: None,
            photo_variance,
            photo_repeat: None,
            mask_also: None,
            twin_names: None,
            bands: band.into_iter().collect(),
        };
        let outcome = py.detach(|| compare::compare_files(&req)).map_err(error)?;
        let out = to_python(py, &outcome.report)?;
        out.set_item("notes", outcome.notes)?;
        return Ok(out);
    }
    if mask_object.is_some() || mask_board.is_some() {
        return Err(error("mask_object and mask_board need the photo and render as file paths"));
    }
    let photo = rgb_image(py, photo, "photo")?;
    let render = rgb_image(py, render, "render")?;
    compare::check_same_size(&photo, &render).map_err(error)?;
    let render_variance = render_variance.map(|v| variance_image(py, v, "render_variance", &photo)).transpose()?;
    let photo_variance = photo_variance.map(|v| variance_image(py, v, "photo_variance", &photo)).transpose()?;
    if let Some(v) = &photo_variance {
        if render_variance.is_none() {
            return Err(error(
                "photo_variance needs render_variance too: the model RMSE removes the noise of both images \
                 (give the render's variance, e.g. render(…)[\"variance\"])",
            ));
        }
        compare::check_photo_variance(v, &photo).map_err(|e| error(format!("photo_variance: {e}")))?;
    }
    let mask = match mask {
        None => None,
        Some(m) => {
            let a = np(py)?.call_method1("asarray", (m,))?.call_method1("astype", ("bool",))?;
            let r: PyReadonlyArrayDyn<'_, bool> = a.extract()?;
            if r.shape() != [photo.height, photo.width] {
                return Err(error(format!(
                    "mask: expected shape ({}, {}) like the images, got {:?}",
                    photo.height,
                    photo.width,
                    r.shape()
                )));
            }
            Some(compare::mask::Mask {
                width: photo.width,
                height: photo.height,
                include: r.as_array().iter().copied().collect(),
            })
        }
    };
    let settings = compare::Settings { ssim: compare::ssim::SsimParams::new(data_range).map_err(error)?, luminance };
    let mut notes = Vec::new();
    let (metrics, noise) = py.detach(|| -> PyResult<_> {
        let metrics = compare::metrics(&photo, &render, mask.as_ref(), &settings).map_err(error)?;
        let Some(rv) = &render_variance else {
            return Ok((metrics, None));
        };
        let mut report = compare::model_error(
            &photo,
            &render,
            (rv, photo_variance.as_deref()),
            mask.as_ref(),
            photo_variance.as_ref().map(|_| "photo_variance"),
            &mut notes,
        )
        .map_err(|e| error(format!("model RMSE: {e}")))?;
        report.render_variance = "render_variance (the variance of each pixel's mean)".into();
        report.photo_variance =
            if photo_variance.is_some() { "photo_variance" } else { compare::PHOTO_VARIANCE_NOT_GIVEN }.into();
        Ok((metrics, Some(report)))
    })?;
    let bands = match &band {
        None => Vec::new(),
        Some(b) => {
            let Some(m) = &mask else {
                return Err(error("band: give the mask of the band's region (band_region) with the arrays"));
            };
            let twin = b.region(band_region).map_err(error)?;
            let include = Some(m.include.as_slice());
            let (photo_mean, photo_var, n) =
                compare::band::region_mean(&photo.data, photo_variance.as_deref(), include);
            let (render_mean, render_var, _) =
                compare::band::region_mean(&render.data, render_variance.as_deref(), include);
            let mut c = compare::band::check(twin, photo_mean, photo_var, render_mean, render_var, n);
            c.render = "render".into();
            c.band = "band".into();
            vec![c]
        }
    };
    let out = PyDict::new(py);
    out.set_item("width", photo.width)?;
    out.set_item("height", photo.height)?;
    out.set_item("as_calibrated", to_python(py, &metrics)?)?;
    out.set_item("noise", noise.map(|n| to_python(py, &n)).transpose()?)?;
    out.set_item("bands", to_python(py, &bands)?)?;
    out.set_item("notes", notes)?;
    Ok(out.into_any())
}

/// What a long computation reports to the `progress` callable.
enum Report {
    /// Progress figures, passed as the callable's arguments; only the
    /// latest since the last call is passed.
    Figures(Vec<f64>),
    /// A line of text (a fit's evaluation), passed as its one argument; every line is passed.
    Line(String),
}

/// Runs `work` on a worker thread without the GIL while this thread checks
/// for Ctrl-C (KeyboardInterrupt) every 20 ms and feeds `progress` with what
/// `work` reports. Ctrl-C or an exception raised by the callback sets the
/// cancel flag `work` polls; the work then stops at its next check and the
/// exception is raised.
fn run_interruptible<T: Send>(
    py: Python<'_>,
    progress: Option<Py<PyAny>>,
    work: impl FnOnce(&AtomicBool, &(dyn Fn(Report) + Sync)) -> T + Send,
) -> PyResult<T> {
    let cancel = AtomicBool::new(false);
    let pending: Mutex<Vec<Report>> = Mutex::new(Vec::new());
    let report = |r: Report| {
        if let Ok(mut p) = pending.lock() {
            if matches!(r, Report::Figures(_)) {
                p.retain(|old| !matches!(old, Report::Figures(_)));
            }
            p.push(r);
        }
    };
    let (result, stop) = py.detach(|| {
        std::thread::scope(|s| {
            let worker = s.spawn(|| work(&cancel, &report));
            let mut stop: Option<PyErr> = None;
            let poll = |stop: &mut Option<PyErr>| {
                Python::attach(|py| {
                    if let Err(e) = py.check_signals() {
                        stop.get_or_insert(e);
                    }
                    let reports = pending.lock().map(|mut p| std::mem::take(&mut *p)).unwrap_or_default();
                    for r in reports {
                        let (Some(cb), None) = (&progress, stop.as_ref()) else { break };
                        let args = match r {
                            Report::Figures(v) => PyTuple::new(py, v),
                            Report::Line(l) => PyTuple::new(py, [l]),
                        };
                        if let Err(e) = args.and_then(|a| cb.call1(py, a)) {
                            *stop = Some(e);
                        }
                    }
                });
                if stop.is_some() {
                    cancel.store(true, Ordering::Relaxed);
                }
            };
            while !worker.is_finished() {
                std::thread::sleep(Duration::from_millis(20));
                poll(&mut stop);
            }
            if stop.is_none() {
                poll(&mut stop);
            }
            (worker.join(), stop)
        })
    });
    if let Some(e) = stop {
        return Err(e);
    }
    result.map_err(|_| error("the computation failed (a worker thread panicked)"))
}

/// Renders the digital twin of a scene file as ``lucent render SCENE`` does
/// (same scene loading, same overrides, same random streams: for a given
/// seed and spp, ``mean`` equals the R, G, B of the command's render.exr).
///
/// scene: path of the scene TOML (str or os.PathLike). spp: samples per pixel; time_s: wall-time
/// budget [s] (stops after the pass that exceeds it); seed: seed of the
/// random streams; size: "WIDTHxHEIGHT" instead of the camera's (intrinsics
/// scaled); threads: worker threads (default all cores); target_rel_error:
/// stop when the median relative standard error over the object's pixels
/// reaches this fraction; sampling: "uniform" or "object-weighted" (default:
/// object-weighted with an error target, else uniform);
/// dispersion: "per-band" or "shared-directions"; split_entry: follow both
/// reflection and refraction where a path enters the object; similarity_g:
/// walk the object's similar medium with phase asymmetry this, raised (the
/// same in every band) where it would be under 3 mean free paths deep
/// (0 ≤ g < 1; μs(1 − g), μa and n kept; biased by a few %, see the
/// method's similarity section). Each overrides the scene's [render] value,
/// as the command's options of the same names.
/// uncertainty: carry the recipe's uncertain inputs (``weight_percent = {
/// value = 0.65, sd = 0.03 }`` in the scene's [material] recipe) to the
/// render, as ``lucent render --uncertainty``: the result gets ``band``
/// (uncertainty.json's dict: per region, the mean's standard deviation
/// from the inputs, its Monte Carlo error, each input's share) and
/// ``band_sd``, ``band_sd_std_error`` (H × W × 3, per pixel);
/// uncertainty_spp: samples of each render at ±1 σ (even; default half the
/// render's on the object), for inputs the render's own paths do not carry.
/// Pass ``band`` to ``compare(…, band=…)``.
/// progress: optional callable, called with the floats ``(spp_done,
/// spp_target, elapsed_s, object_rel_error)`` after passes (object_rel_error: the
/// median relative standard error over the object's pixels, NaN without
/// object pixels); an exception it raises stops the render and propagates.
///
/// Returns a dict: ``mean`` (H × W × 3, linear CIE RGB radiance),
/// ``variance`` (H × W × 3, the variance of each pixel's mean), ``spp``
/// (an int: the samples per pixel, render.json's ``spp``, i.e. the largest
/// per-pixel count; every pixel's with uniform sampling), ``spp_per_pixel``
/// (H × W int array: each pixel's samples, more on the object with
/// object-weighted sampling; the EXR's ``spp`` layer), ``object`` and
/// ``board`` (H × W, the fraction of the pixel's camera rays that hit the
/// object / the board first), ``seed``, ``wall_s``, ``samples`` (in all),
/// ``warnings``. Releases the GIL while rendering;
/// Ctrl-C (KeyboardInterrupt) stops it after the current pass and raises.
#[pyfunction]
#[pyo3(name = "render", signature = (
    scene, spp = None, time_s = None, seed = None, size = None, threads = None, target_rel_error = None,
    sampling = None, dispersion = None, split_entry = false, similarity_g = None, progress = None,
    uncertainty = false, uncertainty_spp = None
))]
#[allow(clippy::too_many_arguments)]
fn py_render<'py>(
    py: Python<'py>,
    scene: PathBuf,
    spp: Option<u32>,
    time_s: Option<f64>,
    seed: Option<u64>,
    size: Option<String>,
    threads: Option<usize>,
    target_rel_error: Option<f64>,
    sampling: Option<&str>,
    dispersion: Option<&str>,
    split_entry: bool,
    similarity_g: Option<f64>,
    progress: Option<Py<PyAny>>,
    uncertainty: bool,
    uncertainty_spp: Option<u32>,
) -> PyResult<Bound<'py, PyDict>> {
    let args = RenderArgs {
        scene,
        out: PathBuf::new(),
        render: TwinRenderArgs {
            spp,
            seed,
            size: size.map(|t| t.parse().map_err(|e| error(format!("--size {e}")))).transpose()?,
            threads,
        },
        time_s,
        exposure: 0.0,
        target_rel_error,
        sampling: sampling.map(|t| choice("sampling", t)).transpose()?,
        dispersion: dispersion.map(|t| choice("dispersion", t)).transpose()?,
        split_entry,
        similarity_g,
        quiet: true,
        shard: None,
        uncertainty,
        uncertainty_spp,
        uncertainty_renders: false,
    };
    // The job `lucent render` checks (the ranges of its flags), then the scene.
    let job = lucent::job::RenderJob::from(&args);
    job.validate().map_err(error)?;
    let ctx = lucent::job::Context { quiet: true };
    let (loaded, mut settings) = job.prepare().map_err(|e| error_chain(e.into()))?;
    let uncertain = job.uncertain_inputs(&ctx, &loaded, &mut settings).map_err(|e| error_chain(e.into()))?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.unwrap_or(0)).build().map_err(error)?;
    let (image, stats) = run_interruptible(py, progress, |cancel, report| {
        pool.install(|| {
            tracer::render_cancellable(
                &loaded.scene,
                &settings,
                &mut |p| {
                    report(Report::Figures(vec![
                        f64::from(p.spp_done),
                        f64::from(p.spp_target),
                        p.elapsed_s,
                        p.errors.object.median,
                    ]))
                },
                Some(cancel),
            )
        })
    })?
    .map_err(error)?;
    let (w, h) = (image.width, image.height);
    let rgb = |v: &[[f64; 3]]| -> PyResult<Bound<'py, PyAny>> {
        Ok(Array::from_shape_vec(IxDyn(&[h, w, 3]), v.iter().flatten().copied().collect())
            .map_err(error)?
            .into_pyarray(py)
            .into_any())
    };
    let plane = |f: &dyn Fn(usize) -> f64| -> PyResult<Bound<'py, PyAny>> {
        Ok(Array::from_shape_vec(IxDyn(&[h, w]), (0..w * h).map(f).collect())
            .map_err(error)?
            .into_pyarray(py)
            .into_any())
    };
    let out = PyDict::new(py);
    out.set_item("mean", rgb(&image.mean)?)?;
    out.set_item("variance", rgb(&image.variance_of_mean)?)?;
    out.set_item("spp", image.samples.iter().copied().max().unwrap_or(0))?;
    out.set_item(
        "spp_per_pixel",
        Array2::from_shape_vec((h, w), image.samples.clone()).map_err(error)?.into_pyarray(py),
    )?;
    out.set_item("object", plane(&|i| image.object_fraction(i))?)?;
    out.set_item("board", plane(&|i| f64::from(image.board_samples[i]) / f64::from(image.samples[i].max(1)))?)?;
    out.set_item("seed", settings.seed)?;
    out.set_item("wall_s", stats.wall_s)?;
    out.set_item("samples", stats.samples)?;
    out.set_item("warnings", loaded.warnings.clone())?;
    if let Some(u) = &uncertain {
        let (band, _) = run_interruptible(py, None, |cancel, _| {
            job.band_of(&ctx, &loaded, &settings, &pool, &image, &u.recipe, &u.path_derivatives, cancel)
        })?
        .map_err(|e| error_chain(anyhow::anyhow!(e)))?;
        out.set_item("band_sd", rgb(&band.pixel_sd)?)?;
        out.set_item("band_sd_std_error", rgb(&band.pixel_sd_std_error)?)?;
        out.set_item("band", to_python(py, &band)?)?;
    }
    Ok(out)
}

/// Arrays over an n × n slice.
fn square<'py>(py: Python<'py>, n: usize, v: &[f64]) -> PyResult<Bound<'py, PyAny>> {
    Ok(Array2::from_shape_vec((n, n), v.to_vec()).map_err(error)?.into_pyarray(py).into_any())
}

/// A library type's name, or an error listing its names.
fn named<T: std::str::FromStr + strum::VariantNames>(what: &str, text: &str) -> PyResult<T> {
    text.parse().map_err(|_| error(format!("{what} {text:?}: expected one of {}", T::VARIANTS.join(", "))))
}

fn choice<T: clap::ValueEnum>(what: &str, text: &str) -> PyResult<T> {
    T::from_str(text, true).map_err(|_| {
        let names: Vec<String> = T::value_variants()
            .iter()
            .filter_map(|v| v.to_possible_value())
            .map(|p| p.get_name().to_string())
            .collect();
        error(format!("{what} {text:?}: expected one of {}", names.join(", ")))
    })
}

/// Slab BSSRDF slice of one configuration by light tracing with explicit
/// connection to the camera, as ``lucent bssrdf`` simulates it (same
/// options under the same names, same defaults, same random streams: for a
/// given seed and ``paths``, ``slice`` equals the Y of its bssrdf.exr).
///
/// The medium: ``recipe`` (a path, str or os.PathLike, or a dict of the
/// recipe's keys as ``optics`` takes it; bulk properties by Lorenz–Mie at
/// ``wavelength_nm`` [nm], ``weight_percent`` for a recipe that leaves it
/// unknown, the recipe's thickness and [surface]) or all of ``mu_s``,
/// ``mu_a`` [1/m], ``g`` and ``n`` (Henyey–Greenstein; ``thickness_mm``
/// default 6.35). ``phase``: "mie" or "hg".
/// Geometry: incidence ``theta_i``, ``phi_i`` and view ``theta_o``,
/// ``phi_o`` [degrees]; a Gaussian beam of ``beam_fwhm_um`` [µm] or a
/// measured ``beam_map`` (EXR, float TIFF or CSV grid of irradiance; its
/// pixel size ``beam_map_pixel_mm`` [mm], else from its sidecar JSON); a
/// camera of ``pixels`` × ``pixels`` of
/// ``pixel_mm`` [mm] on the surface (``crop``: only the central N × N).
/// ``roughness``: "smooth", "tr:ALPHA", "beckmann:ALPHA" or "measured:FIT.json".
/// Stop rules (the first reached ends the run): ``paths``, ``time_s``,
/// ``rel_error`` of the slice sum, ``pixel_rel_error`` (median per pixel);
/// none given: 1 % on the sum, at most 600 s. ``estimator``: "auto",
/// "ring", "lobe" or "connection"; ``lobe_vertices``: camera-side vertices
/// of the lobe connection's chains (0 … 32; 0: the fixed-direction
/// connection); ``seed``; ``no_fold``; ``similarity_g``:
/// simulate the similar medium with g at most this (0 ≤ g < 1; far off near
/// the beam, for totals only).
/// ``progress``: optional callable, called with the floats ``(paths,
/// elapsed_s, rel_error)`` as the run goes; an exception it raises stops it.
///
/// Returns a dict: ``slice`` and ``std_error`` (N × N, f_ssr in 1/(m² sr)
/// and its standard error per pixel, rows along y, columns along x),
/// ``x_mm`` (pixel centres), ``profile`` and ``profile_std_error`` (the
/// middle row), ``beam_profile`` (relative irradiance along it), ``sum``
/// and ``sum_std_error`` (1/(m² sr)), ``paths``, ``events``, ``wall_s``,
/// ``estimator``, ``specular_reflectance``, ``diffuse_reflectance``,
/// ``transmittance``, ``optical_properties`` (mu_s_per_m, mu_a_per_m, g, n),
/// ``phase``, ``roughness``. Releases the GIL; Ctrl-C stops it.
/// ``wavelength=`` (the older name) raises a TypeError naming ``wavelength_nm``.
#[pyfunction]
#[pyo3(name = "bssrdf", signature = (
    recipe = None, *, wavelength_nm = 550.0, weight_percent = None, mu_s = None, mu_a = None, g = None, n = None,
    thickness_mm = None, theta_i = 45.0, phi_i = 0.0, theta_o = 0.0, phi_o = 180.0, phase = None,
    beam_fwhm_um = 200.0, beam_map = None, beam_map_pixel_mm = None, pixels = 259, pixel_mm = 0.1029, crop = None,
    rel_error = None, pixel_rel_error = None, paths = None, time_s = None, seed = 1, estimator = "auto",
    lobe_vertices = 16, roughness = None, no_fold = false, similarity_g = None, progress = None, **kwargs
))]
#[allow(clippy::too_many_arguments)]
fn py_bssrdf<'py>(
    py: Python<'py>,
    recipe: Option<&Bound<'py, PyAny>>,
    wavelength_nm: f64,
    weight_percent: Option<f64>,
    mu_s: Option<f64>,
    mu_a: Option<f64>,
    g: Option<f64>,
    n: Option<f64>,
    thickness_mm: Option<f64>,
    theta_i: f64,
    phi_i: f64,
    theta_o: f64,
    phi_o: f64,
    phase: Option<&str>,
    beam_fwhm_um: f64,
    beam_map: Option<PathBuf>,
    beam_map_pixel_mm: Option<f64>,
    pixels: usize,
    pixel_mm: f64,
    crop: Option<usize>,
    rel_error: Option<f64>,
    pixel_rel_error: Option<f64>,
    paths: Option<u64>,
    time_s: Option<f64>,
    seed: u64,
    estimator: &str,
    lobe_vertices: u8,
    roughness: Option<String>,
    no_fold: bool,
    similarity_g: Option<f64>,
    progress: Option<Py<PyAny>>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    reject_unknown_keywords("bssrdf", kwargs, &[("wavelength", "wavelength_nm"), ("wavelengths_nm", "wavelength_nm")])?;
    if recipe.is_some() && (mu_s.is_some() || mu_a.is_some()) {
        return Err(error("give either recipe or mu_s, mu_a, g, n, not both"));
    }
    let recipe = recipe.map(|r| RecipeArg::from_py(py, r)).transpose()?;
    let args = bssrdf_cli::RunArgs {
        recipe: recipe.as_ref().map(RecipeArg::path),
        weight_percent,
        wavelength: wavelength_nm,
        mu_s,
        mu_a,
        g,
        n,
        thickness_mm,
        theta_i,
        phi_i,
        theta_o,
        phi_o,
        configs: None,
        phase: phase.map(|p| named("phase", p)).transpose()?,
        beam: BeamArgs { beam_fwhm_um, beam_map, beam_map_pixel_mm },
        pixels,
        pixel_mm,
        crop,
        rel_error,
        pixel_rel_error,
        paths,
        time_s,
        seed,
        estimator: named("estimator", estimator)?,
        lobe_vertices,
        roughness: roughness
            .map(|r| r.parse::<lucent::bssrdf::RoughnessSpec>().map_err(|e| error(format!("roughness {e}"))))
            .transpose()?,
        no_fold,
        similarity_g,
        out: PathBuf::new(),
        quiet: true,
        shard: None,
        uncertainty: false,
    };
    if let Some(job) = lucent::cli::jobs::bssrdf_run(&args) {
        job.validate().map_err(error)?;
    }
    let job = lucent::job::BssrdfJob::from(&args);
    let recipe = recipe.map(|r| r.load(Overrides { weight_percent })).transpose()?;
    let ctx = lucent::job::Context::default();
    let plan = job.plan_with(recipe.as_ref(), Some(&ctx)).map_err(|e| error_chain(e.into()))?;
    let run = plan.runs.first().ok_or_else(|| error("no configuration to simulate"))?;
    let slice = run_interruptible(py, progress, |cancel, report| {
        slab::simulate_cancellable(
            &run.setup,
            &run.options,
            |p| report(Report::Figures(vec![p.paths as f64, p.elapsed_s, p.rel_error])),
            cancel,
        )
    })?
    .map_err(error)?;
    let n = slice.pixels;
    let row = n / 2;
    let x_mm: Vec<f64> = (0..n).map(|c| (c as f64 + 0.5 - 0.5 * n as f64) * pixel_mm).collect();
    let out = PyDict::new(py);
    out.set_item("slice", square(py, n, &slice.values)?)?;
    out.set_item("std_error", square(py, n, &slice.std_error)?)?;
    out.set_item("x_mm", PyArray1::from_vec(py, x_mm))?;
    out.set_item("profile", PyArray1::from_slice(py, &slice.values[row * n..(row + 1) * n]))?;
    out.set_item("profile_std_error", PyArray1::from_slice(py, &slice.std_error[row * n..(row + 1) * n]))?;
    out.set_item("beam_profile", PyArray1::from_vec(py, plan.beam_profile(run, pixel_mm)))?;
    out.set_item("sum", slice.sum)?;
    out.set_item("sum_std_error", slice.sum_std_error)?;
    out.set_item("paths", slice.paths)?;
    out.set_item("events", slice.events)?;
    out.set_item("wall_s", slice.wall_s)?;
    out.set_item("estimator", slice.estimator.name())?;
    out.set_item("specular_reflectance", slice.specular_reflectance)?;
    out.set_item("diffuse_reflectance", slice.diffuse_reflectance)?;
    out.set_item("transmittance", slice.transmittance)?;
    let o = plan.optical_properties();
    let props = PyDict::new(py);
    props.set_item("mu_s_per_m", o.mu_s_per_m)?;
    props.set_item("mu_a_per_m", o.mu_a_per_m)?;
    props.set_item("g", o.g)?;
    props.set_item("n", o.n)?;
    out.set_item("optical_properties", props)?;
    out.set_item("phase", plan.phase_name())?;
    out.set_item("roughness", plan.roughness.clone())?;
    Ok(out)
}

/// One path-like or a list of them, as the command line's strings; `what`
/// names the argument in errors.
fn path_list(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<String>> {
    let one = |o: &Bound<'_, PyAny>| -> PyResult<String> {
        let p = as_path(o).ok_or_else(|| {
            error(format!("{what}: expected a path (str or os.PathLike) or a list of them, got {}", type_name(o)))
        })?;
        Ok(p.to_string_lossy().into_owned())
    };
    if as_path(obj).is_some() {
        return Ok(vec![one(obj)?]);
    }
    obj.try_iter()
        .map_err(|_| error(format!("{what}: expected a path or a list of paths, got {}", type_name(obj))))?
        .map(|o| one(&o?))
        .collect()
}

/// The Python type name of `obj` (for messages).
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())
}

/// Recipe parameters fitted to measured BSSRDF slices, as ``lucent fit``
/// fits them (same options under the same names, same defaults, same
/// common random numbers: for a given seed the result equals its fit.json).
///
/// recipe: the recipe holding the start values: a path of its TOML file
///     (str or os.PathLike) or a dict of its keys, as ``optics`` takes it.
/// measured: measured slices, a path or a list, each "FILE", "FILE:THETA_I/
///     THETA_O" or "FILE:THETA_I/PHI_I/THETA_O/PHI_O" [degrees] (without
///     angles: from the file's sidecar FILE.json or summary.json); EXR,
///     float TIFF or CSV grids of f_ssr [1/(m² sr)].
/// free: the free parameters, a str "weight_percent,diameter_um" or a list
///     (``NAME@K`` for particle type K): weight_percent [wt-%],
///     diameter_um [µm], real_part_n.
/// objective: "sum" (relative error of the slice sums) or "msre" (mean
///     squared relative error over the pixels above ``threshold`` of the
///     measured maximum). wavelength_nm [nm]; measured_pixel_mm [mm]; the beam:
///     ``beam_fwhm_um`` [µm] or ``beam_map`` (+ ``beam_map_pixel_mm``);
///     measured_rel_sd: relative uncertainty of each measured slice;
///     rel_error: target relative error of each simulated sum (sets the path
///     count by a pilot run capped at ``pilot_time_s`` [s]), or ``paths``
///     per configuration and evaluation; bounds: "LO:HI,…" or a list of
///     (lo, hi) per free parameter; thickness_mm [mm]; seed.
/// out: optional folder for fit.json, objective.png and the fitted recipe
///     (as the command writes them; ``NAME_fitted.toml`` after the recipe
///     file, or after the recipe's ``name`` for a dict).
/// progress: optional callable, called with one line of text per
///     evaluation; an exception it raises stops the fit.
///
/// Returns the dict of fit.json: ``parameters`` (per free parameter:
/// ``name``, ``start``, ``value``, ``std_error``, ``interval_95``, …),
/// ``identifiable`` and ``reason``, ``objective_start``, ``objective_end``,
/// ``evaluations``, ``paths_total``, ``wall_s``, ``configurations``,
/// ``history``. Unlike the command (which exits non-zero), a fit the data
/// cannot pin down is returned with ``identifiable`` False and values None.
/// Releases the GIL; Ctrl-C stops it at the end of the simulation round
/// under way and raises KeyboardInterrupt. ``wavelength=`` (the older
/// name) raises a TypeError naming ``wavelength_nm``.
#[pyfunction]
#[pyo3(name = "fit", signature = (
    recipe, measured, free, *, objective = "sum", wavelength_nm = 550.0, weight_percent = None,
    measured_pixel_mm = None, beam_fwhm_um = 200.0, beam_map = None, beam_map_pixel_mm = None,
    measured_rel_sd = 0.05, threshold = 0.01, rel_error = 0.005, paths = None, pilot_time_s = 60.0,
    bounds = None, thickness_mm = None, seed = 1, out = None, progress = None, **kwargs
))]
#[allow(clippy::too_many_arguments)]
fn py_fit<'py>(
    py: Python<'py>,
    recipe: &Bound<'py, PyAny>,
    measured: &Bound<'py, PyAny>,
    free: &Bound<'py, PyAny>,
    objective: &str,
    wavelength_nm: f64,
    weight_percent: Option<f64>,
    measured_pixel_mm: Option<f64>,
    beam_fwhm_um: f64,
    beam_map: Option<PathBuf>,
    beam_map_pixel_mm: Option<f64>,
    measured_rel_sd: f64,
    threshold: f64,
    rel_error: f64,
    paths: Option<u64>,
    pilot_time_s: f64,
    bounds: Option<&Bound<'py, PyAny>>,
    thickness_mm: Option<f64>,
    seed: u64,
    out: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
    kwargs: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    reject_unknown_keywords("fit", kwargs, &[("wavelength", "wavelength_nm"), ("wavelengths_nm", "wavelength_nm")])?;
    let recipe = RecipeArg::from_py(py, recipe)?;
    let free: Vec<String> = match free.extract::<String>() {
        Ok(text) => text.split(',').map(str::to_string).collect(),
        Err(_) => free
            .extract::<Vec<String>>()
            .map_err(|_| error(format!("free: expected a str or a list of str, got {}", type_name(free))))?,
    };
    let free: Vec<lucent::fit::FreeSpec> =
        free.iter().map(|t| t.parse().map_err(|e| error(format!("free: {e}")))).collect::<PyResult<_>>()?;
    let bounds = match bounds {
        None => None,
        Some(b) => Some(match b.extract::<String>() {
            Ok(text) => text.parse::<lucent::fit::SearchBounds>().map_err(|e| error(format!("bounds: {e}")))?,
            Err(_) => lucent::fit::SearchBounds(
                b.extract::<Vec<(f64, f64)>>()
                    .map_err(|_| {
                        error(format!("bounds: expected \"LO:HI,…\" or a list of (lo, hi), got {}", type_name(b)))
                    })?
                    .into_iter()
                    .map(|(lo, hi)| lucent::fit::SearchRange { lo, hi })
                    .collect(),
            ),
        }),
    };
    let measured: Vec<lucent::job::MeasuredSlice> = path_list(measured, "measured")?
        .iter()
        .map(|t| t.parse().map_err(|e| error(format!("measured: {e}"))))
        .collect::<PyResult<_>>()?;
    let args = FitArgs {
        recipe: recipe.path(),
        weight_percent,
        measured,
        measured_pixel_mm,
        free,
        objective: named::<lucent::fit::Objective>("objective", objective)?,
        wavelength: wavelength_nm,
        beam: BeamArgs { beam_fwhm_um, beam_map, beam_map_pixel_mm },
        measured_rel_sd,
        threshold,
        rel_error,
        paths,
        pilot_time_s,
        bounds,
        thickness_mm,
        seed,
        out: out.clone().unwrap_or_default(),
        quiet: true,
    };
    let job = lucent::job::FitJob::from(&args);
    job.validate().map_err(error)?;
    let problem = job.problem_with(recipe.load(Overrides { weight_percent })?).map_err(|e| error_chain(e.into()))?;
    let result = run_interruptible(py, progress, |cancel, report| {
        fit::fit_cancellable(&problem, |line| report(Report::Line(line.clone())), cancel)
    })?
    .map_err(error)?;
    if let Some(dir) = &out {
        std::fs::create_dir_all(dir)
            .map_err(|e| error(format!("out {}: cannot create the folder: {e}", dir.display())))?;
        match &recipe {
            RecipeArg::File(_) => lucent::job::write_fit_outputs(dir, &problem, &result),
            RecipeArg::Dict { text, .. } => {
                let stem: String = problem
                    .recipe
                    .name
                    .chars()
                    .map(|c| if c.is_alphanumeric() || "-_.".contains(c) { c } else { '_' })
                    .collect();
                lucent::job::write_fit_outputs_with_recipe_text(dir, &problem, &result, text, &stem)
            }
        }
        .map_err(|e| error_chain(e.into()))?;
    }
    to_python(py, &result)
}

/// The photos of `calibrate`: paths as the command reads them, or 2-D
/// uint8 grey arrays named "image 0", "image 1", ….
fn calibration_photos(py: Python<'_>, images: &Bound<'_, PyAny>) -> PyResult<Vec<Photo>> {
    if let Ok(list) = images.cast::<PyList>()
        && list.iter().all(|o| o.hasattr("__array_interface__").unwrap_or(false))
        && !list.is_empty()
    {
        return list
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let what = format!("images[{i}]");
                let a = as_array(py, &o, "uint8", &what)?;
                let r: PyReadonlyArray2<'_, u8> = a.extract().map_err(|_| {
                    error(format!(
                        "{what}: expected a 2-D uint8 grey image (height, width), got shape {:?}",
                        shape_of(&a)
                    ))
                })?;
                let (h, w) = (r.shape()[0], r.shape()[1]);
                let image = GrayImage::new(w, h, r.as_array().iter().copied().collect()).map_err(error)?;
                Ok(Photo { name: format!("image {i}"), image })
            })
            .collect();
    }
    camera_cli::read_photos(&path_list(images, "images")?).map_err(error_chain)
}

/// The shape of a numpy array (for messages).
fn shape_of(a: &Bound<'_, PyAny>) -> Vec<usize> {
    a.getattr("shape").and_then(|s| s.extract()).unwrap_or_default()
}

/// Camera calibration from photos of a chessboard, as ``lucent calibrate``
/// computes it (Zhang 2000 through OpenCV's ``calibrateCamera``, or
/// Kannala–Brandt through its fisheye module), so that the result can be
/// set beside ``cv2.calibrateCamera`` on the same corners.
///
/// images: a folder, a file or a pattern ('DIR/*.jpg', 'DIR/left0[1-5].jpg'),
///     or a list of them (JPEG/PNG/TIFF, EXR/HDR and RAW files), or a list
///     of 2-D uint8 grey arrays (height, width).
/// board: inner corners "COLSxROWS", e.g. "9x6" for a board of 10 × 7 squares.
/// square_mm: side of one square [mm] (sets the units of the poses only).
/// model: "pinhole-k3" (k1 k2 p1 p2 k3), "rational" (k1..k6 p1 p2) or
///     "fisheye" (Kannala–Brandt k1..k4).
/// detector: "auto" (sector-based, else classic + cornerSubPix),
///     "sector-based" or "classic".
///
/// Returns the dict of the command's camera.json (``camera`` with
/// ``intrinsics`` fx, fy, cx, cy [px] and ``distortion``; ``rms_px``, the
/// overall RMS reprojection error [px]; ``views`` with each view's pose
/// ``rvec`` [rad], ``tvec_m`` [m], corners and residuals [px];
/// ``not_found``), plus ``camera_matrix`` (3 × 3) and ``dist_coeffs`` (in
/// OpenCV's order for the model) as numpy arrays, as cv2 returns them.
/// Releases the GIL while it works; Ctrl-C raises KeyboardInterrupt when
/// the calibration under way ends (seconds).
#[pyfunction]
#[pyo3(name = "calibrate", signature = (images, board, square_mm, model = "pinhole-k3", detector = "auto"))]
fn py_calibrate<'py>(
    py: Python<'py>,
    images: &Bound<'py, PyAny>,
    board: &str,
    square_mm: f64,
    model: &str,
    detector: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let model: lucent_calib::camera::DistortionModel = named("model", model)?;
    let detector: lucent_calib::cv::Detector = named("detector", detector)?;
    let board = lucent::cli::common::board_spec(board, square_mm).map_err(error_chain)?;
    let photos = calibration_photos(py, images)?;
    let cal = run_interruptible(py, None, |_, _| calib_camera::calibrate_photos(&photos, &board, model, detector))?
        .map_err(error)?;
    let out = to_python(py, &cal)?;
    let k = &cal.camera.intrinsics;
    let matrix =
        Array2::from_shape_vec((3, 3), vec![k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0]).map_err(error)?;
    out.set_item("camera_matrix", matrix.into_pyarray(py))?;
    out.set_item("dist_coeffs", PyArray1::from_vec(py, cal.camera.distortion.to_opencv(cal.camera.model)))?;
    Ok(out)
}

/// N × 3 rows of an array-like.
fn rows3(py: Python<'_>, obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    let a = as_array(py, obj, "float64", what)?;
    let r: PyReadonlyArrayDyn<'_, f64> = a.extract()?;
    let shape = r.shape().to_vec();
    let [_, 3] = shape[..] else {
        return Err(error(format!("{what}: expected an array of shape (N, 3), got {shape:?}")));
    };
    let v: Vec<f64> = r.as_array().iter().copied().collect();
    Ok(v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
}

/// Fits a colour-correction matrix camera RGB → CIE XYZ (D50, Y_white = 1)
/// by least squares over the patches, as ``lucent colour calibrate`` does.
///
/// camera_rgb: (N, 3) linear camera RGB of the patches.
/// reference_xyz: (N, 3) XYZ the patches should map to; default (None): the
///     24 ColorChecker Classic patches, post-2014 X-Rite references (ICC D50),
///     in chart order.
/// method: "Cheung 2004" (3 × 3 least squares; colour-science's
///     ``matrix_colour_correction_Cheung2004``), "Finlayson 2015"
///     (root-polynomial, degree 2, 3 × 6) or "Finlayson 1997" (3 × 3,
///     white-point preserving: patch ``white_index`` (0-based) maps exactly).
///
/// Returns ``{"method", "matrix" (3 × T array, XYZ = M · t(RGB)), "terms",
/// "de2000_mean", "de2000_max", "de76_mean", "de76_max", "patches"}``, the
/// ΔE in CIE L*a*b* relative to the ICC D50 white.
#[pyfunction]
#[pyo3(name = "ccm", signature = (camera_rgb, reference_xyz = None, method = "Cheung 2004", white_index = 18))]
fn py_ccm<'py>(
    py: Python<'py>,
    camera_rgb: &Bound<'py, PyAny>,
    reference_xyz: Option<&Bound<'py, PyAny>>,
    method: &str,
    white_index: usize,
) -> PyResult<Bound<'py, PyDict>> {
    use lucent_colour::ccm::{self, CcmMethod};
    let method: CcmMethod = method.parse().map_err(error)?;
    let rgb = rows3(py, camera_rgb, "camera_rgb")?;
    let (fit, report) = match reference_xyz {
        None => ccm::fit_colorchecker(method, &rgb).map_err(error)?,
        Some(x) => {
            let xyz = rows3(py, x, "reference_xyz")?;
            let fit = ccm::fit(method, &rgb, &xyz, white_index).map_err(error)?;
            let report = fit.report(&rgb, &xyz, lucent_colour::data::ICC_D50_XYZ, &[]).map_err(error)?;
            (fit, report)
        }
    };
    let out = PyDict::new(py);
    out.set_item("method", method.name())?;
    let m = fit.matrix();
    let flat: Vec<f64> = m.iter().flatten().copied().collect();
    out.set_item("matrix", Array2::from_shape_vec((3, method.terms()), flat).map_err(error)?.into_pyarray(py))?;
    out.set_item("terms", method.term_names().to_vec())?;
    let r = to_python(py, &report)?;
    for k in ["de2000_mean", "de2000_max", "de76_mean", "de76_max", "white_xyz", "patches"] {
        out.set_item(k, r.get_item(k)?)?;
    }
    Ok(out)
}

/// CIEDE2000 colour difference (Sharma, Wu & Dalal 2005; k_L = k_C = k_H = 1)
/// of CIE L*a*b* colours, vectorised: ``lab1`` and ``lab2`` are arrays whose
/// last axis holds L*, a*, b* and whose other axes broadcast together.
/// Returns the differences (a float for single colours).
#[pyfunction]
#[pyo3(name = "delta_e_2000")]
fn py_delta_e_2000<'py>(
    py: Python<'py>,
    lab1: &Bound<'py, PyAny>,
    lab2: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let (a, b) = (as_array(py, lab1, "float64", "lab1")?, as_array(py, lab2, "float64", "lab2")?);
    for (x, name) in [(&a, "lab1"), (&b, "lab2")] {
        let shape: Vec<usize> = x.getattr("shape")?.extract()?;
        if shape.last() != Some(&3) {
            return Err(error(format!("{name}: the last axis must hold L*, a*, b* (length 3), got shape {shape:?}")));
        }
    }
    let (shape, flat) = broadcast(py, &[a, b])?;
    let (a, b) = (flat_f64(&flat[0])?, flat_f64(&flat[1])?);
    let out: Vec<f64> = a
        .chunks_exact(3)
        .zip(b.chunks_exact(3))
        .map(|(p, q)| lucent_colour::difference::delta_e_2000([p[0], p[1], p[2]], [q[0], q[1], q[2]]))
        .collect();
    to_numpy(py, &shape[..shape.len() - 1], out)
}

/// lucent: digital twins of translucent objects, from Python.
///
/// Lorenz–Mie efficiencies (``mie``, ``mie_sphere``), bulk optical
/// properties of recipes (``optics``), renders of scene files (``render``),
/// slab BSSRDF slices (``bssrdf``) and fits to measured ones (``fit``),
/// photo/render metrics (``compare``), camera calibration (``calibrate``),
/// colour correction (``ccm``, ``delta_e_2000``). The same library code as the ``lucent`` command;
/// errors raise ``LucentError`` (a ValueError) with its messages.
#[pymodule(name = "lucent")]
fn lucent_module(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("LucentError", m.py().get_type::<LucentError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Optics>()?;
    m.add_function(wrap_pyfunction!(py_mie, m)?)?;
    m.add_function(wrap_pyfunction!(py_mie_sphere, m)?)?;
    m.add_function(wrap_pyfunction!(py_optics, m)?)?;
    m.add_function(wrap_pyfunction!(py_compare, m)?)?;
    m.add_function(wrap_pyfunction!(py_render, m)?)?;
    m.add_function(wrap_pyfunction!(py_bssrdf, m)?)?;
    m.add_function(wrap_pyfunction!(py_fit, m)?)?;
    m.add_function(wrap_pyfunction!(py_calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(py_ccm, m)?)?;
    m.add_function(wrap_pyfunction!(py_delta_e_2000, m)?)?;
    Ok(())
}
