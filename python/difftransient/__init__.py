"""difftransient: differentiable transient rendering (Yi et al., "Differentiable Transient
Rendering", ACM TOG 40(6) 286, 2021) on Embree, from Python.

A transient gives every pixel a histogram over optical path length (OPL, metres; time is
OPL / c). Arrays are numpy, shaped [H, W, T, C] (height, width, time bins, channels), float32,
handed over from the renderer without copying.

    import difftransient as dt
    scene = dt.Scene.load("scenes/narrow_pulse_box.toml")
    r = dt.render(scene, spp=16)
    r = dt.render(scene, spp=16, auto_window=True)   # window over the light's arrival and decay
    r.transient.shape            # (H, W, T, C)
    d = dt.render_diff(scene, ["tall_box_x"], spp=16)
    d.derivatives["tall_box_x"]  # dI/dθ, same shape
    dloss_dimage = 2 * d.transient                   # ∂L/∂I of L = Σ I²
    g, stats = dt.gradient(scene, ["tall_box_x"], dloss_dimage, spp=16)   # dL/dθ, one each

Renders release the GIL. Errors raise `SceneError` (the description or a parameter) or
`RenderError` (what a render refuses), with the renderer's messages. `difftransient.torch`
has a `torch.autograd.Function` whose backward is the adjoint gradient.
"""

from __future__ import annotations

import json
import os
import secrets
import warnings
from dataclasses import dataclass, field
from typing import Any, Dict, Iterable, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ._difftransient import RenderError, SceneError
from ._difftransient import Scene as _NativeScene
from ._difftransient import render as _render
from ._difftransient import render_adjoint as _render_adjoint
from ._difftransient import render_diff as _render_diff

__all__ = [
    "Scene",
    "SceneError",
    "RenderError",
    "Render",
    "DiffRender",
    "render",
    "render_diff",
    "gradient",
]


class Scene:
    """A loaded scene (immutable). Set parameter values with `with_params`, which gives a copy
    with the new values (the scene `dtr render --set NAME=VALUE` renders) without reading any
    file again. A scene pickles whole (its description, values, estimator, sampler and
    meshes), so `multiprocessing` can send it to workers, which read no file."""

    def __init__(self, native: _NativeScene):
        self._native = native
        #: the window chosen by `auto_window` (a dict), or None
        self.window: Optional[dict] = None

    def __copy__(self) -> "Scene":
        # the native scene is immutable: copies share it (they raised TypeError)
        return self._like(self._native)

    def __deepcopy__(self, memo: dict) -> "Scene":
        import copy

        s = Scene(self._native)
        s.window = copy.deepcopy(self.window, memo)
        return s

    @staticmethod
    def load(path: "os.PathLike[str] | str", params: Optional[Mapping[str, Any]] = None) -> "Scene":
        """Loads a scene file (.toml, .json, or a Mitsuba 3 .xml converted on load), with `params`
        ({name: value}) set: a `[[param]]` by its name, or any field of the description by its
        dotted path (`dtr render --set`), to a number, a string, a bool, a list or a dict
        ({"film.bins": 100, "nlos.scan": "exhaustive", "nlos.grid": [8, 8]})."""
        numbers, texts = _settings(params)
        return Scene(_NativeScene.load(os.fspath(path), numbers, texts))

    @staticmethod
    def from_dict(
        description: Mapping, base_dir: "os.PathLike[str] | str" = ".", params: Optional[Mapping[str, Any]] = None
    ) -> "Scene":
        """A scene from a description dict (the schema of scenes/README.md, as JSON); relative
        mesh paths are resolved in `base_dir`; `params` as for `load`."""
        numbers, texts = _settings(params)
        return Scene(_NativeScene.from_json(json.dumps(description), os.fspath(base_dir), numbers, texts))

    def with_params(self, params: Mapping[str, Any]) -> "Scene":
        """The same scene with the values of `params` ({name: value}, as for `load`) replaced.
        It keeps `window` unless `params` sets the film's time axis."""
        numbers, texts = _settings(params)
        return self._like(self._native.with_params(numbers, texts),
                          keep_window=not any(name in _WINDOW_FIELDS for name, _ in numbers + texts))

    def _like(self, native: _NativeScene, keep_window: bool = True) -> "Scene":
        """A scene of `native` that keeps this one's `window` where it still describes it (it
        was lost by every `with_*` until the forty-third session)."""
        s = Scene(native)
        s.window = self.window if keep_window else None
        return s

    def with_sampler(self, name: str) -> "Scene":
        """The same scene drawing `name`'s numbers: "sobol" (the default: Owen-scrambled Sobol
        points, stratified over each pixel's samples, several times less error at about the
        same cost) or "independent" (independent numbers per path and dimension; `dtr render
        --sampler`)."""
        return self._like(self._native.with_sampler(name))

    @property
    def sampler(self) -> str:
        """The sampler's name ("independent" or "sobol")."""
        return self._native.sampler

    def with_integrator(self, name: str) -> "Scene":
        """The same scene rendered by `name`'s estimator: "path" (unidirectional path tracing,
        the default) or "bdpt" (bidirectional, with MIS over every strategy; it renders NLOS
        captures too; `dtr render --integrator`)."""
        return self._like(self._native.with_integrator(name))

    @property
    def integrator(self) -> str:
        """The estimator's name ("path" or "bdpt")."""
        return self._native.integrator

    def auto_window(self, *, seed: Optional[int] = None, threads: Optional[int] = None) -> "Scene":
        """The same scene with its time window (film start and bin width; the number of bins
        kept) chosen by a short pilot render over where the light arrives and decays, as
        `dtr render --auto-window`. The returned scene's `window` is the choice (a dict: the
        window, the pilot's resolution, spp, span and seconds)."""
        native, info = self._native.auto_window(_count("seed", seed), _count("threads", threads))
        scene = Scene(native)
        scene.window = json.loads(info)
        return scene

    @property
    def params(self) -> Dict[str, float]:
        """{name: value} of the scene's parameters, in file order."""
        return dict(self._native.params)

    @property
    def shape(self):
        """(H, W, T, C) of the film."""
        return self._native.shape

    @property
    def bin_centres(self) -> np.ndarray:
        """OPL (metres) at the centre of each time bin; divide by c for seconds."""
        return self._native.bin_centres()

    @property
    def source(self) -> str:
        return str(self._native.source)

    def __repr__(self) -> str:
        return repr(self._native)


@dataclass(eq=False)  # == on arrays is elementwise: a generated __eq__ raised ValueError
class Render:
    """A forward render: `transient` [H, W, T, C], `steady` [H, W, C] (the time-summed image),
    `bin_centres` (OPL, metres) and the run statistics."""

    transient: np.ndarray
    steady: np.ndarray
    bin_centres: np.ndarray
    stats: dict = field(repr=False)


@dataclass(eq=False)
class DiffRender:
    """A derivative render: the transient, and dI/dθ per parameter name (each [H, W, T, C])."""

    transient: np.ndarray
    derivatives: Dict[str, np.ndarray]
    bin_centres: np.ndarray
    stats: dict = field(repr=False)


def render(scene: Scene, *, spp: Optional[int] = None, seed: Optional[int] = None,
           threads: Optional[int] = None, auto_window: bool = False) -> Render:
    """Renders the scene's transient (spp and seed default to the scene's). With
    `auto_window`, the time window is chosen first (`Scene.auto_window`, with this seed) and
    the choice is `stats["auto_window"]`, as in the JSON of `dtr render --auto-window`."""
    scene = _scene(scene)
    spp, seed, threads = _count("spp", spp), _count("seed", seed), _count("threads", threads)
    window = None
    if auto_window:
        scene = scene.auto_window(seed=seed, threads=threads)
        window = scene.window
    t, steady, stats = _render(scene._native, spp, seed, threads)
    stats = _warn_of_window(json.loads(stats))
    if window is not None:
        stats["auto_window"] = window
    return Render(t, steady, scene.bin_centres, stats)


def render_diff(scene: Scene, params: Sequence[str], *, spp: Optional[int] = None, seed: Optional[int] = None,
                threads: Optional[int] = None, spp_boundary: Optional[int] = None,
                estimators: str = "full", time_edges: str = "auto") -> DiffRender:
    """Renders the transient and dI/dθ for each name in `params`: the interior (Algorithm 1)
    plus, when a parameter moves geometry, the boundary terms (Algorithm 2). `estimators`:
    "full", "interior" or "boundary", or one boundary term alone, "primary" (silhouettes seen
    from the camera) or "secondary" (edges seen from path vertices), to find which carries a
    derivative's noise; all but "full" and "interior" leave the transient 0. `time_edges`:
    "auto" (the path tracer draws the time term f·dS_e/dd·ḋ on the bin edges where that
    applies; what makes delta pulses differentiable) or "off" (`dtr render --time-edges`)."""
    scene, params = _scene(scene), _names(params)
    spp, seed, threads = _count("spp", spp), _count("seed", seed), _count("threads", threads)
    spp_boundary = _count("spp_boundary", spp_boundary)
    t, d, stats = _render_diff(scene._native, params, spp, seed, threads, spp_boundary, estimators, time_edges)
    # the boundary terms alone leave the transient 0 on purpose: nothing to warn of (as the CLI)
    stats = _warn_of_window(json.loads(stats), primal=estimators in ("full", "interior"))
    return DiffRender(t, dict(zip(params, d)), scene.bin_centres, stats)


def _draw_seed(seed: Optional[int]) -> int:
    """`seed` where one is given; else a fresh one (62 random bits), so that calls without a
    seed draw new samples each time: an optimiser fed gradients of one frozen set of samples
    settles where that noise puts it, not at the answer (`dtr optimize` renders iteration i
    at seeds S + 2i and S + 2i + 1 for that reason)."""
    return seed if seed is not None else secrets.randbits(62)


def _warn_of_window(stats: dict, primal: bool = True) -> dict:
    """Raises the energy report's warning (the time window holds no light, or too little of
    it) as a RuntimeWarning, as `dtr render` warns on stderr: an empty answer is never silent.
    Not where no primal was rendered (`primal` False). Returns `stats`, whose
    `stats["energy"]["warning"]` holds it too (None when it looks right)."""
    warning = stats.get("energy", {}).get("warning")
    if warning and primal:
        warnings.warn(warning, RuntimeWarning, stacklevel=3)
    return stats


def gradient(scene: Scene, params: Sequence[str], adjoint: np.ndarray, *, spp: Optional[int] = None,
             seed: Optional[int] = None, threads: Optional[int] = None, spp_boundary: Optional[int] = None,
             estimators: str = "full", time_edges: str = "auto"):
    """dL/dθ = Σ ⟨∂L/∂I, dI/dθ⟩ for each name in `params`, given `adjoint` = ∂L/∂I shaped like
    the film [H, W, T, C], without holding one derivative volume per parameter (any number of
    parameters). With the same seed it uses the same samples as `render_diff`. Without a
    seed it draws samples of its own (the scene's seed + 2³¹), independent of a `render` at
    the scene's seed or any small seed: an adjoint computed from a render (2(I − T) for an L2
    loss) contracted with dI/dθ of the same samples gives a biased gradient (Cov(I, dI/dθ)
    is added). Returns (gradient as a float64 array, stats; stats["seed"] is the seed used)."""
    scene = _scene(scene)
    spp, seed, threads = _count("spp", spp), _count("seed", seed), _count("threads", threads)
    spp_boundary = _count("spp_boundary", spp_boundary)
    if not isinstance(adjoint, np.ndarray) or adjoint.dtype.kind not in "fiu":
        raise TypeError(f"adjoint must be a real numpy array shaped like the film {scene.shape}, got "
                        f"{type(adjoint).__name__}" + (f" of {adjoint.dtype}" if isinstance(adjoint, np.ndarray) else ""))
    if adjoint.shape != tuple(scene.shape):
        raise RenderError(f"adjoint: shape {adjoint.shape} does not match the scene's film [H, W, T, C] = {tuple(scene.shape)}")
    if not np.isfinite(adjoint).all():
        raise RenderError("adjoint: every value must be finite")
    if adjoint.dtype != np.float32 and np.abs(adjoint).max(initial=0.0) > np.finfo(np.float32).max:
        raise RenderError("adjoint: values beyond float32's range (3.4e38) cannot be rendered with")
    a = np.ascontiguousarray(adjoint, dtype=np.float32)
    g, stats = _render_adjoint(scene._native, _names(params), a, spp, seed, threads, spp_boundary, estimators,
                               time_edges)
    return g, json.loads(stats)


def _toml_value(v: Any) -> str:
    """`v` written as a TOML value (what `dtr render --set PATH=VALUE` reads after the `=`)."""
    if isinstance(v, (np.ndarray, np.generic)):
        v = v.tolist()  # numpy values, also inside lists and dicts, as Python's (a list for an array)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        # TOML's \u escapes take no surrogates: characters beyond the BMP go as themselves
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, (int, float)):
        return repr(float(v)) if isinstance(v, float) else str(v)
    if isinstance(v, Mapping):
        return "{ " + ", ".join(f"{_toml_value(str(k))} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot set a value of type {type(v).__name__}: use a number, str, bool, list or dict")


def _settings(params: Optional[Mapping[str, Any]]) -> Tuple[List[tuple], List[tuple]]:
    """`params` split as the loader takes them: numbers, and other values of fields as TOML."""
    if params is None:
        return [], []
    if not isinstance(params, Mapping):
        raise TypeError("params must be a mapping {name: value}")
    numbers, texts = [], []
    for k, v in params.items():
        if isinstance(v, np.ndarray) and v.ndim == 0:
            v = v.item()  # a 0-d array is its one value
        if isinstance(v, np.generic):
            v = v.item()  # numpy scalars (np.float32(0.2), np.int64(1), np.bool_) as Python's
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) > 2**53:
            # beyond what a float holds exactly (a 64-bit seed): as the TOML integer it is
            texts.append((str(k), str(v)))
        elif isinstance(v, (int, float)) and not isinstance(v, bool):
            numbers.append((str(k), float(v)))
        else:
            texts.append((str(k), _toml_value(v)))
    return numbers, texts


# the fields that `Scene.auto_window` chooses: a scene with them set no longer has that window
_WINDOW_FIELDS = {"film.start_opl", "film.bin_width_opl", "film.bins"}

# the largest value of each count the renderer takes (u64 seed, usize threads; u32 otherwise)
_COUNT_LIMITS = {"seed": 2**64 - 1, "threads": 2**63 - 1}


def _count(name: str, v: Optional[int]) -> Optional[int]:
    """`v`, an optional count (spp, seed, threads, spp_boundary), checked by name: a whole
    number from 0 to 2⁶⁴ − 1 (the renderer refuses the zeros it cannot use)."""
    if v is None:
        return None
    if isinstance(v, np.integer):
        v = int(v)
    if isinstance(v, bool) or not isinstance(v, int):
        raise TypeError(f"{name} must be a whole number, got {v!r} ({type(v).__name__})")
    if v < 0:
        raise ValueError(f"{name} must be >= 0, got {v}")
    limit = _COUNT_LIMITS.get(name, 2**32 - 1)
    if v > limit:
        raise ValueError(f"{name} must be at most {limit}, got {v}")
    return v


def _scene(scene: Any) -> "Scene":
    """`scene`, which must be a loaded Scene (a path is not one: `Scene.load(path)`)."""
    if not isinstance(scene, Scene):
        hint = " (load it first: dt.Scene.load(path))" if isinstance(scene, (str, os.PathLike)) else ""
        raise TypeError(f"scene must be a difftransient.Scene, got {type(scene).__name__}{hint}")
    return scene


def _names(params: Any) -> List[str]:
    """`params` as a list of parameter names, each once."""
    if isinstance(params, (str, bytes)):
        raise TypeError(f"params must be a list of parameter names, got the string {params!r} (use [{params!r}])")
    names = [str(p) for p in params]
    seen = set()
    for n in names:
        if n in seen:
            raise ValueError(f"params names {n!r} more than once")
        seen.add(n)
    return names
