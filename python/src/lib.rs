//! Python bindings of difftransient: the native module `difftransient._difftransient`, which
//! the pure-Python package `difftransient` (python/difftransient/) wraps.
//!
//! - Scenes are loaded from a file or from description text (the JSON schema of
//!   scenes/README.md); parameter values are set on a copy of a loaded scene
//!   (`Scene::set_params`: the same scene as loading with `--set`, without reading files).
//! - Renders release the GIL and run on the library's own thread pool; their films are moved
//!   into numpy arrays without copying (the array's memory is the film's `Vec`). Ctrl-C stops
//!   a render and raises KeyboardInterrupt ([`cancellable`]).
//! - Errors become `SceneError` (bad scene description or parameter) or `RenderError`
//!   (anything a render refuses) with the library's messages.

use difftransient::kernel::SampleSequence;
use difftransient::named::Named;
use difftransient::render::TimeEdgeMode;
use difftransient::scene::shapes::LocalMesh;
use difftransient::scene::{Format, IntegratorKind, SceneState};
use difftransient::{BoundaryMode, RenderOptions, Scene, Transient};
use glam::DVec3;
use numpy::ndarray::{Array1, Array4};
use numpy::{IntoPyArray, PyArray1, PyArray3, PyArray4, PyReadonlyArray4};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use std::path::{Path, PathBuf};

pyo3::create_exception!(
    _difftransient,
    SceneError,
    PyValueError,
    "A scene description or parameter was refused."
);
pyo3::create_exception!(
    _difftransient,
    RenderError,
    PyValueError,
    "A render was refused or failed."
);

/// The layout of a pickled scene's state ([`PyScene::__reduce__`]); a pickle of another
/// layout is refused by name.
const STATE_VERSION: u32 = 1;

fn scene_err(e: impl std::fmt::Display) -> PyErr {
    SceneError::new_err(e.to_string())
}

/// A refused setting, named as Python sets it: `params["NAME"]` where the CLI's message says
/// `--set NAME` (the same error otherwise).
fn setting_err(e: difftransient::scene::SceneError) -> PyErr {
    match e {
        difftransient::scene::SceneError::Override { path, name, message } => {
            SceneError::new_err(format!("{}: params[{name:?}]: {message}", path.display()))
        }
        other => scene_err(other),
    }
}

fn render_err(e: difftransient::Error) -> PyErr {
    match e {
        difftransient::Error::Scene(s) => setting_err(s),
        // the parameters of a derivative render are its `params` argument, not `--diff`
        difftransient::Error::UnknownParameter { path, name, available } => RenderError::new_err(
            difftransient::Error::unknown_parameter(&path, "params", &name, &available),
        ),
        other => RenderError::new_err(other.to_string()),
    }
}

/// A loaded scene (which keeps the description it was resolved from, so parameter values are
/// set on it without reading any file again: `Scene::set_params`).
#[pyclass(name = "Scene", module = "difftransient._difftransient", frozen)]
struct PyScene {
    scene: Scene,
}

impl PyScene {
    fn build(
        text: &str,
        format: Format,
        source: &Path,
        overrides: &[(String, f64)],
        texts: &[(String, String)],
    ) -> PyResult<Self> {
        let scene = Scene::from_str_with_text(text, format, source, overrides, texts).map_err(setting_err)?;
        Ok(Self { scene })
    }
}

#[pymethods]
impl PyScene {
    /// Loads a scene file (.toml, .json, or a Mitsuba 3 .xml converted on load), with parameter
    /// values or numbers of the description `set` ([(name, value)]) and fields set to other
    /// values `text` ([(dotted path, TOML value)], as `dtr render --set nlos.scan=exhaustive`).
    #[staticmethod]
    #[pyo3(signature = (path, set = None, text = None))]
    fn load(path: PathBuf, set: Option<Vec<(String, f64)>>, text: Option<Vec<(String, String)>>) -> PyResult<Self> {
        // `Scene::load`, as `dtr render` loads it: its errors about an entry converted from a
        // Mitsuba XML scene name the XML element and line, as the CLI's do
        let scene =
            Scene::load_with_text(&path, &set.unwrap_or_default(), &text.unwrap_or_default()).map_err(setting_err)?;
        Ok(Self { scene })
    }

    /// A scene from JSON description text; relative mesh paths are resolved in `base_dir`.
    #[staticmethod]
    #[pyo3(signature = (json, base_dir, set = None, text = None))]
    fn from_json(
        json: String,
        base_dir: PathBuf,
        set: Option<Vec<(String, f64)>>,
        text: Option<Vec<(String, String)>>,
    ) -> PyResult<Self> {
        Self::build(
            &json,
            Format::Json,
            &base_dir.join("<dict>.json"),
            &set.unwrap_or_default(),
            &text.unwrap_or_default(),
        )
    }

    /// The same scene with parameter values replaced ({name: value}; the others keep theirs)
    /// and fields set to other values (`text`: [(dotted path, TOML value)]), set on a copy of
    /// the loaded scene without reading the scene file.
    #[pyo3(signature = (values, text = None))]
    fn with_params(&self, values: Vec<(String, f64)>, text: Option<Vec<(String, String)>>) -> PyResult<Self> {
        let mut scene = self.scene.clone();
        if let Some(text) = text.filter(|t| !t.is_empty()) {
            scene.set_text(&text).map_err(setting_err)?;
        }
        scene.set_params(&values).map_err(setting_err)?;
        Ok(Self { scene })
    }

    /// The same scene drawing `name`'s numbers: "sobol" (the default) or "independent"
    /// (`[integrator] sampler`, `dtr render --sampler`).
    fn with_sampler(&self, name: &str) -> PyResult<Self> {
        let sampler = SampleSequence::from_name(name).map_err(PyValueError::new_err)?;
        let mut scene = self.scene.clone();
        // in the description the scene keeps, so that later settings keep it too
        scene.set_integrator(None, Some(sampler)).map_err(scene_err)?;
        Ok(Self { scene })
    }

    /// The sampler's name ("independent" or "sobol").
    #[getter]
    fn sampler(&self) -> &'static str {
        self.scene.integrator.sampler.name()
    }

    /// The same scene rendered by `name`'s estimator: "path" (unidirectional, the default) or
    /// "bdpt" (`[integrator] kind`, `dtr render --integrator`).
    fn with_integrator(&self, name: &str) -> PyResult<Self> {
        let kind = IntegratorKind::from_name(name).map_err(PyValueError::new_err)?;
        let mut scene = self.scene.clone();
        scene.set_integrator(Some(kind), None).map_err(scene_err)?;
        Ok(Self { scene })
    }

    /// The estimator's name ("path" or "bdpt").
    #[getter]
    fn integrator(&self) -> &'static str {
        self.scene.integrator.kind.name()
    }

    /// Chooses the film's time window by a short pilot render, as `dtr render --auto-window`
    /// (src/auto_window.rs): (the scene with that window, the choice as JSON text). The pilot
    /// releases the GIL.
    #[pyo3(signature = (seed = None, threads = None))]
    fn auto_window(&self, py: Python<'_>, seed: Option<u64>, threads: Option<usize>) -> PyResult<(Self, String)> {
        let opts = RenderOptions {
            seed,
            threads,
            ..Default::default()
        };
        // the pilot and the chosen scene are the held scene with window fields set: no file
        // is read again (`Scene::set_params` takes the dotted fields `--set` takes)
        let with = |o: &[(String, f64)]| -> Result<Scene, difftransient::Error> {
            let mut scene = self.scene.clone();
            scene.set_params(o)?;
            Ok(scene)
        };
        let w = py
            .detach(|| difftransient::auto_window::choose_window_with(&self.scene.source, &[], &opts, with))
            .map_err(render_err)?;
        let scene = Self {
            scene: with(&w.overrides()).map_err(render_err)?,
        };
        Ok((scene, stats_json(&w)?))
    }

    /// {name: value} of the scene's `[[param]]` entries, in file order.
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in &self.scene.params {
            d.set_item(&p.name, p.value)?;
        }
        Ok(d)
    }

    /// The file the scene came from.
    #[getter]
    fn source(&self) -> PathBuf {
        self.scene.source.clone()
    }

    /// Film shape (height, width, bins, channels).
    #[getter]
    fn shape(&self) -> (usize, usize, usize, usize) {
        let f = &self.scene.film;
        (f.height as usize, f.width as usize, f.axis.bins, f.channels)
    }

    /// Optical path length (metres) at the centre of every time bin.
    fn bin_centres<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let a = &self.scene.film.axis;
        Array1::from_iter((0..a.bins).map(|l| a.bin_centre(l))).into_pyarray(py)
    }

    /// Pickling (`multiprocessing`, a job queue, a file): the scene's state
    /// (`difftransient::SceneState`: its description, the values set, its meshes), from which
    /// [`PyScene::from_state`] builds the same scene without reading any file.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyTuple>)> {
        let py = slf.py();
        let state = slf.get().scene.state();
        let meshes: Vec<(Bound<'py, PyBytes>, Bound<'py, PyBytes>)> = state
            .meshes
            .iter()
            .map(|m| {
                let p: Vec<u8> = m
                    .positions
                    .iter()
                    .flat_map(|v| v.to_array())
                    .flat_map(f64::to_le_bytes)
                    .collect();
                let t: Vec<u8> = m.tris.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
                (PyBytes::new(py, &p), PyBytes::new(py, &t))
            })
            .collect();
        let args = (
            STATE_VERSION,
            state.source,
            state.description,
            state.fields,
            state.params,
            meshes,
        );
        Ok((py.get_type::<Self>().getattr("_from_state")?, args.into_pyobject(py)?))
    }

    /// The scene of a pickled state ([`PyScene::__reduce__`]).
    #[staticmethod]
    fn _from_state(
        version: u32,
        source: PathBuf,
        description: String,
        fields: Vec<(String, f64)>,
        params: Vec<(String, f64)>,
        meshes: Vec<(Vec<u8>, Vec<u8>)>,
    ) -> PyResult<Self> {
        if version != STATE_VERSION {
            return Err(scene_err(format!(
                "{}: a pickled scene of format {version}; this difftransient reads format {STATE_VERSION}: load the scene file again",
                source.display()
            )));
        }
        let meshes = meshes
            .iter()
            .enumerate()
            .map(|(k, (p, t))| {
                if p.len() % 24 != 0 || t.len() % 12 != 0 {
                    return Err(scene_err(format!(
                        "{}: the pickled mesh of shape[{k}] holds {} bytes of positions and {} of triangles, not whole vertices and triangles",
                        source.display(),
                        p.len(),
                        t.len()
                    )));
                }
                let f = |b: &[u8]| f64::from_le_bytes(b.try_into().expect("8 bytes"));
                let u = |b: &[u8]| u32::from_le_bytes(b.try_into().expect("4 bytes"));
                Ok(LocalMesh {
                    positions: p.chunks_exact(24).map(|v| DVec3::new(f(&v[..8]), f(&v[8..16]), f(&v[16..]))).collect(),
                    tris: t.chunks_exact(12).map(|v| [u(&v[..4]), u(&v[4..8]), u(&v[8..])]).collect(),
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        let state = SceneState {
            source,
            description,
            fields,
            params,
            meshes,
        };
        Ok(Self {
            scene: Scene::from_state(state).map_err(scene_err)?,
        })
    }

    fn __repr__(&self) -> String {
        let (h, w, t, c) = self.shape();
        format!(
            "Scene({:?}, film {h}x{w}, {t} bins, {c} channel{}, params {:?})",
            self.scene.source.display().to_string(),
            if c == 1 { "" } else { "s" },
            self.scene.params.iter().map(|p| p.name.as_str()).collect::<Vec<_>>()
        )
    }
}

fn options(
    spp: Option<u32>,
    seed: Option<u64>,
    threads: Option<usize>,
    spp_boundary: Option<u32>,
    estimators: &str,
    time_edges: &str,
) -> PyResult<RenderOptions> {
    let time_edges = TimeEdgeMode::from_name(time_edges).ok_or_else(|| {
        RenderError::new_err(format!(
            "time_edges must be {} (got {time_edges:?})",
            TimeEdgeMode::listed()
        ))
    })?;
    let boundary = BoundaryMode::from_name(estimators).ok_or_else(|| {
        RenderError::new_err(format!(
            "estimators must be {} (got {estimators:?})",
            BoundaryMode::listed()
        ))
    })?;
    Ok(RenderOptions {
        spp,
        seed,
        threads,
        spp_boundary,
        boundary,
        time_edges,
        ..Default::default()
    })
}

/// Runs `job` (a render with `opts`) with the GIL released, on a thread of its own, while
/// this thread checks every 50 ms for a signal Python must act on (Ctrl-C's
/// KeyboardInterrupt): on one, it sets the render's cancel flag (`difftransient::cancel`),
/// waits for the render to stop (within a second or so) and raises the signal's exception.
/// Before, a long render could be stopped only by ending the process: in a notebook, the
/// kernel. Python runs signal handlers on its main thread only, so a render called from
/// another thread does not poll: it waits for its end without taking the GIL. Polling from
/// such a thread took the GIL every 50 ms, and a daemon thread rendering while the interpreter
/// shut down panicked ("The Python interpreter is not initialized").
fn cancellable<T: Send>(
    py: Python<'_>,
    mut opts: RenderOptions,
    job: impl FnOnce(&RenderOptions) -> Result<T, difftransient::Error> + Send,
) -> PyResult<T> {
    let cancel = difftransient::cancel::Cancel::new();
    opts.cancel = cancel.clone();
    let opts = &opts;
    let threading = py.import("threading")?;
    let polls = threading
        .call_method0("current_thread")?
        .is(&threading.call_method0("main_thread")?);
    let (result, interrupted) = py.detach(|| {
        std::thread::scope(|scope| {
            // the render's end wakes this thread at once (a render of a few milliseconds,
            // as an optimisation loop makes them, waits for no poll)
            let (done, finished) = std::sync::mpsc::channel();
            let worker = scope.spawn(move || {
                let result = job(opts);
                let _ = done.send(());
                result
            });
            let mut interrupted = None;
            match polls {
                false => {
                    let _ = finished.recv();
                }
                true => {
                    while let Err(std::sync::mpsc::RecvTimeoutError::Timeout) =
                        finished.recv_timeout(std::time::Duration::from_millis(50))
                    {
                        if interrupted.is_none()
                            && let Err(e) = Python::attach(|py| py.check_signals())
                        {
                            cancel.cancel();
                            interrupted = Some(e);
                        }
                    }
                }
            }
            let result = worker.join().unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (result, interrupted)
        })
    });
    match interrupted {
        Some(e) => Err(e),
        None => result.map_err(render_err),
    }
}

/// A film as a [H, W, T, C] float32 array, moved (not copied) into numpy.
fn film_array(py: Python<'_>, t: Transient) -> PyResult<Bound<'_, PyArray4<f32>>> {
    let [h, w, b, c] = t.shape();
    let a = Array4::from_shape_vec((h, w, b, c), t.data).map_err(|e| RenderError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

/// The time-summed image as [H, W, C], moved into numpy.
fn steady_array(py: Python<'_>, h: usize, w: usize, c: usize, data: Vec<f32>) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let a = numpy::ndarray::Array3::from_shape_vec((h, w, c), data).map_err(|e| RenderError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

fn stats_json(s: &impl serde::Serialize) -> PyResult<String> {
    serde_json::to_string(s).map_err(|e| RenderError::new_err(e.to_string()))
}

/// A render's stats as JSON text with the energy report's `warning` (the window holds no or
/// too little of the light; `null` when it looks right), as `dtr render` writes it in its
/// JSON; the Python package raises it as a `RuntimeWarning`.
fn stats_with_warning(s: &difftransient::RenderStats, warning: Option<String>) -> PyResult<String> {
    let mut v = serde_json::to_value(s).map_err(|e| RenderError::new_err(e.to_string()))?;
    v["energy"]["warning"] = serde_json::json!(warning);
    stats_json(&v)
}

type Film<'py> = Bound<'py, PyArray4<f32>>;

/// Renders the transient: (transient [H, W, T, C], steady [H, W, C], stats as JSON text).
#[pyfunction]
#[pyo3(signature = (scene, spp = None, seed = None, threads = None))]
fn render<'py>(
    py: Python<'py>,
    scene: &PyScene,
    spp: Option<u32>,
    seed: Option<u64>,
    threads: Option<usize>,
) -> PyResult<(Film<'py>, Bound<'py, PyArray3<f32>>, String)> {
    let opts = options(spp, seed, threads, None, "full", "auto")?;
    let (mut t, stats) = cancellable(py, opts, |o| difftransient::render(&scene.scene, o))?;
    let [h, w, _, c] = t.shape();
    let steady = std::mem::take(&mut t.steady);
    let stats = stats_with_warning(&stats, stats.energy.warning(&t.axis))?;
    Ok((film_array(py, t)?, steady_array(py, h, w, c, steady)?, stats))
}

/// Renders the transient and its derivative with respect to each of `params`:
/// (transient, [derivative per parameter], stats as JSON text).
#[pyfunction]
#[pyo3(signature = (scene, params, spp = None, seed = None, threads = None, spp_boundary = None, estimators = "full", time_edges = "auto"))]
#[allow(clippy::too_many_arguments)]
fn render_diff<'py>(
    py: Python<'py>,
    scene: &PyScene,
    params: Vec<String>,
    spp: Option<u32>,
    seed: Option<u64>,
    threads: Option<usize>,
    spp_boundary: Option<u32>,
    estimators: &str,
    time_edges: &str,
) -> PyResult<(Film<'py>, Vec<Film<'py>>, String)> {
    let opts = options(spp, seed, threads, spp_boundary, estimators, time_edges)?;
    let (t, d, stats) = cancellable(py, opts, |o| difftransient::render_diff(&scene.scene, &params, o))?;
    let stats = stats_with_warning(&stats, stats.energy.warning(&t.axis))?;
    let d = d.into_iter().map(|t| film_array(py, t)).collect::<PyResult<Vec<_>>>()?;
    Ok((film_array(py, t)?, d, stats))
}

/// What `gradient` adds to the scene's seed when it is given none. An adjoint ∂L/∂I computed
/// from a render (2(I − T) for an L2 loss) and contracted with dI/dθ of the same samples has
/// the expectation of 2 Cov(I, dI/dθ) added to the gradient: on scenes/diff_room.toml at its
/// true albedo, 16 spp, a mean of +1.3·10⁻⁵ ± 1.2·10⁻⁷ over 64 seeds where independent
/// samples give 0 within noise. `dtr optimize` draws the adjoint at seed + 1 for that reason;
/// a render at the scene's seed or at any small seed shares no samples with this one.
const ADJOINT_SEED_OFFSET: u64 = 1 << 31;

/// dL/dθ for each of `params`, given ∂L/∂I (`adjoint`, float32 [H, W, T, C] of the scene's
/// film): (gradient as float64 array, stats as JSON text). Same samples as `render_diff`
/// with the same seed; without one, the scene's seed + `ADJOINT_SEED_OFFSET`.
#[pyfunction]
#[pyo3(signature = (scene, params, adjoint, spp = None, seed = None, threads = None, spp_boundary = None, estimators = "full", time_edges = "auto"))]
#[allow(clippy::too_many_arguments)]
fn render_adjoint<'py>(
    py: Python<'py>,
    scene: &PyScene,
    params: Vec<String>,
    adjoint: PyReadonlyArray4<'py, f32>,
    spp: Option<u32>,
    seed: Option<u64>,
    threads: Option<usize>,
    spp_boundary: Option<u32>,
    estimators: &str,
    time_edges: &str,
) -> PyResult<(Bound<'py, PyArray1<f64>>, String)> {
    // no seed: samples of the gradient's own, independent of a render at the scene's seed
    // (`ADJOINT_SEED_OFFSET`)
    let seed = seed.unwrap_or_else(|| scene.scene.integrator.seed.wrapping_add(ADJOINT_SEED_OFFSET));
    let opts = options(spp, Some(seed), threads, spp_boundary, estimators, time_edges)?;
    let f = &scene.scene.film;
    let want = [f.height as usize, f.width as usize, f.axis.bins, f.channels];
    let view = adjoint.as_array();
    let got = view.shape();
    if got != want {
        return Err(RenderError::new_err(format!(
            "adjoint: shape {got:?} does not match the scene's film [H, W, T, C] = {want:?}"
        )));
    }
    let mut a = Transient::zeros(want[1], want[0], f.axis, f.channels);
    a.data = view.iter().copied().collect();
    if a.data.iter().any(|v| !v.is_finite()) {
        return Err(RenderError::new_err("adjoint: every value must be finite".to_string()));
    }
    let (g, stats) = cancellable(py, opts, |o| {
        difftransient::render_adjoint(&scene.scene, &params, &a, o)
    })?;
    Ok((g.into_pyarray(py), stats_json(&stats)?))
}

#[pymodule]
fn _difftransient(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(render_diff, m)?)?;
    m.add_function(wrap_pyfunction!(render_adjoint, m)?)?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add("RenderError", m.py().get_type::<RenderError>())?;
    Ok(())
}
