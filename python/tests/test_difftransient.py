"""Tests of the Python package: the bindings hand over the renderer's own results (the same
bytes as `dtr render`), without copying, derivatives agree with central finite differences,
the adjoint gradient is the contraction of the derivative films, errors carry the
renderer's messages, and renders release the GIL."""

import os
import subprocess
import sys
import threading
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

import difftransient as dt

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"


def scene(name, **params):
    return dt.Scene.load(SCENES / name, params or None)


def test_render_is_the_cli_render(tmp_path):
    """Same scene, spp and seed: the array is the .npy that `dtr render` writes, byte for byte."""
    dtr = os.environ.get("DTR_BIN", str(ROOT / "target" / "release" / "dtr"))
    if not Path(dtr).exists():
        pytest.skip("no dtr binary (set DTR_BIN)")
    out = tmp_path / "cb"
    subprocess.run([dtr, "render", str(SCENES / "diff_room.toml"), "--spp", "4", "--seed", "3", "-o", str(out)],
                   check=True, capture_output=True)
    cli = np.load(str(out) + ".npy")
    r = dt.render(scene("diff_room.toml"), spp=4, seed=3)
    assert r.transient.shape == cli.shape == scene("diff_room.toml").shape
    assert r.transient.dtype == np.float32
    assert np.array_equal(r.transient, cli)
    assert r.transient.sum() > 0
    assert r.bin_centres.shape == (cli.shape[2],)
    assert r.stats["spp"] == 4


def test_nlos_geometry_derivative_is_the_clis(tmp_path):
    """A capture's derivative with respect to a hidden shape's position (interior and boundary
    term at the sensor and laser points): the bytes of `dtr render --diff`."""
    dtr = os.environ.get("DTR_BIN", str(ROOT / "target" / "release" / "dtr"))
    if not Path(dtr).exists():
        pytest.skip("no dtr binary (set DTR_BIN)")
    out = tmp_path / "plate"
    subprocess.run([dtr, "render", str(SCENES / "nlos_moving_plate.toml"), "--spp", "16", "--seed", "5",
                    "--diff", "plate_x", "-o", str(out)], check=True, capture_output=True)
    cli = np.load(str(out) + ".d_plate_x.npy")
    d = dt.render_diff(scene("nlos_moving_plate.toml"), ["plate_x"], spp=16, seed=5).derivatives["plate_x"]
    assert d.shape == cli.shape == (8, 8, 140, 1)
    assert np.array_equal(d, cli)
    # the plate is black: the whole derivative is the boundary term, and it is not zero
    assert np.abs(d).sum() > 0


def _owned_by_renderer(a):
    # numpy does not own the memory: its base is the renderer's buffer (not another array)
    return (not a.flags["OWNDATA"]) and a.base is not None and not isinstance(a.base, np.ndarray)


def test_results_are_handed_over_without_copying():
    s = scene("diff_room.toml")
    r = dt.render(s, spp=1)
    assert _owned_by_renderer(r.transient) and _owned_by_renderer(r.steady)
    assert r.transient.flags["C_CONTIGUOUS"] and r.transient.flags["WRITEABLE"]
    d = dt.render_diff(s, ["albedo"], spp=1)
    assert _owned_by_renderer(d.transient) and _owned_by_renderer(d.derivatives["albedo"])
    # the steady image is the time sum of the transient (window mode)
    np.testing.assert_allclose(r.steady, r.transient.sum(axis=2), rtol=1e-4, atol=1e-6)


def _blocks(t):
    """4x4 blocks of the time-summed image and groups of 10 bins of the image total."""
    h, w, b, c = t.shape
    img = t.sum(axis=(2, 3), dtype=np.float64)
    blocks = img.reshape(4, h // 4, 4, w // 4).sum(axis=(1, 3)).ravel()
    bins = t.sum(axis=(0, 1, 3), dtype=np.float64)
    return np.concatenate([blocks, bins[: b - b % 10].reshape(-1, 10).sum(axis=1)])


@pytest.mark.parametrize("param,value,h", [("albedo", 0.6, 0.01), ("eta", 1.0, 0.002)])
def test_derivative_matches_central_differences(param, value, h):
    """dI/dθ from render_diff against (I(θ+h) − I(θ−h)) / 2h with common random numbers, over
    seeds: the mean difference per aggregate vanishes within its standard error (plus the
    differences' truncation error, estimated from steps h and 2h)."""
    s = scene("diff_room.toml")
    d, f1, f2 = [], [], []
    for seed in range(12):
        ad = dt.render_diff(s, [param], spp=4, seed=seed).derivatives[param]
        at = lambda v: _blocks(dt.render(s.with_params({param: v}), spp=4, seed=seed).transient)
        fd1 = (at(value + h) - at(value - h)) / (2 * h)
        fd2 = (at(value + 2 * h) - at(value - 2 * h)) / (4 * h)
        d.append(_blocks(ad) - fd1)
        f1.append(fd1)
        f2.append(fd2)
    d, f1, f2 = map(np.array, (d, f1, f2))
    mean, se = d.mean(axis=0), d.std(axis=0, ddof=1) / np.sqrt(len(d))
    trunc = np.abs((f2 - f1).mean(axis=0)) / 3
    used = (se > 0) | (mean != 0)
    z = mean[used] / (se[used] + trunc[used] + 1e-9 * np.abs(f1).max())
    assert np.abs(z).max() < 6, (param, z)
    assert (z**2).sum() < used.sum() + 6 * np.sqrt(2 * used.sum()) + 10, (param, z)
    signal = np.abs(f1.mean(axis=0)) / (f1.std(axis=0, ddof=1) / np.sqrt(len(f1)) + 1e-30)
    assert signal.max() > 10, "the derivative must be distinguishable from zero"


def test_gradient_is_the_contraction_of_the_derivatives():
    """gradient(scene, params, A) = Σ A·dI/dθ_k from render_diff on the same samples."""
    s = scene("diff_room.toml")
    params = ["albedo", "intensity", "eta"]
    rng = np.random.default_rng(5)
    a = rng.standard_normal(s.shape).astype(np.float32)
    d = dt.render_diff(s, params, spp=2, seed=9)
    g, stats = dt.gradient(s, params, a, spp=2, seed=9)
    assert g.dtype == np.float64 and g.shape == (3,)
    for k, p in enumerate(params):
        want = float((a.astype(np.float64) * d.derivatives[p]).sum())
        assert abs(g[k] - want) <= 1e-4 * (np.abs(a) * np.abs(d.derivatives[p])).sum() + 1e-9, (p, g[k], want)
    assert stats["paths"] > 0


def test_a_gradient_without_a_seed_does_not_reuse_the_renders_samples():
    """The README's recipe: an L2 adjoint 2(I − T) from `render` at the scene's seed, then
    `gradient` without a seed. At the true albedo the mean gradient over seeds is 0; with
    the render's own samples it is 2 Cov(I, dI/dθ) > 0 (z = +31 over these 8 renders when
    `gradient` defaulted to the scene's seed, as `render` does)."""
    base = scene("diff_room.toml")
    target = dt.render(base, spp=1024, seed=777).transient.astype(np.float64)
    g_default = []
    for k in range(8):
        s = base.with_params({"integrator.seed": k})
        image = dt.render(s, spp=4).transient.astype(np.float64)
        adj = (2 * (image - target) / image.size).astype(np.float32)
        g, stats = dt.gradient(s, ["albedo"], adj, spp=4)
        assert stats["seed"] == k + 2**31
        g_default.append(g[0])
        if k == 0:
            same, _ = dt.gradient(s, ["albedo"], adj, spp=4, seed=k + 2**31)
            assert same[0] == g[0]
            shared, _ = dt.gradient(s, ["albedo"], adj, spp=4, seed=k)
            assert shared[0] != g[0]
    g = np.array(g_default)
    z = g.mean() / (g.std(ddof=1) / np.sqrt(len(g)))
    assert abs(z) < 4, (g, z)


def test_parameters_are_set_on_a_copy():
    s = scene("diff_room.toml")
    assert s.params["albedo"] == pytest.approx(0.6)
    t = s.with_params({"albedo": 0.3})
    assert t.params["albedo"] == pytest.approx(0.3) and s.params["albedo"] == pytest.approx(0.6)
    lo = dt.render(t, spp=2, seed=1).transient.sum()
    hi = dt.render(s, spp=2, seed=1).transient.sum()
    assert 0 < lo < hi


def test_fields_set_at_load_equal_the_same_fields_in_the_file(tmp_path):
    """`Scene.load` and `with_params` set fields of the description to strings, bools, lists and
    dicts as well as numbers (as `dtr render --set` does): the scene renders the bytes of a
    file that says the same."""
    text = (SCENES / "nlos_occluder.toml").read_text()
    edits = [('scan = "confocal"', 'scan = "exhaustive"'), ("grid = [16, 16]", "grid = [4, 3]"),
             ('channels = "mono"', 'channels = "rgb"'),
             ('pulse = { type = "gaussian", sigma_opl = 0.01 }', 'pulse = { type = "box", width_opl = 0.04 }')]
    for a, b in edits:
        assert text.count(a) == 1, a
        text = text.replace(a, b)
    edited = tmp_path / "edited.toml"
    edited.write_text(text)
    settings = {"nlos.scan": "exhaustive", "nlos.grid": [4, 3], "film.channels": "rgb",
                "emitter.laser.pulse": {"type": "box", "width_opl": 0.04}, "hidden_x": 0.5}
    s = dt.Scene.load(SCENES / "nlos_occluder.toml", settings)
    a = dt.render(s, spp=4, seed=2).transient
    b = dt.render(dt.Scene.load(edited), spp=4, seed=2).transient
    assert a.shape == (12, 12, 128, 3)
    assert a.sum() > 0 and np.array_equal(a, b)
    c = dt.Scene.load(SCENES / "nlos_occluder.toml").with_params(settings)
    assert np.array_equal(dt.render(c, spp=4, seed=2).transient, a)
    with pytest.raises(dt.SceneError, match="'confocal' or 'exhaustive'"):
        dt.Scene.load(SCENES / "nlos_occluder.toml", {"nlos.scan": "sideways"})
    with pytest.raises(dt.SceneError, match="takes numbers"):
        dt.Scene.load(SCENES / "nlos_occluder.toml", {"hidden_x": "left"})


def test_with_params_renders_the_bytes_of_a_reload():
    """`with_params` sets values on a copy of the loaded scene (no file read again): the same
    scene, so the same bytes, as loading with those values; settings accumulate."""
    s = scene("diff_room.toml")
    t = s.with_params({"room_z": 0.1}).with_params({"albedo": 0.45, "eta": 1.2})
    u = scene("diff_room.toml", room_z=0.1, albedo=0.45, eta=1.2)
    assert t.params == u.params
    a = dt.render_diff(t, ["room_z"], spp=2, seed=6, estimators="interior")
    b = dt.render_diff(u, ["room_z"], spp=2, seed=6, estimators="interior")
    assert a.transient.sum() > 0
    assert np.array_equal(a.transient, b.transient)
    assert np.array_equal(a.derivatives["room_z"], b.derivatives["room_z"])
    assert not np.array_equal(a.transient, dt.render(s, spp=2, seed=6).transient)


@pytest.mark.parametrize("method, prop, scene_name, name, default, key, unknown, spp", [
    # sampler = "independent" against the default Sobol points
    ("with_sampler", "sampler", "diff_room.toml", "independent", "sobol", "sampler", "halton", 4),
    # kind = "bdpt" on a confocal NLOS capture against the path tracer
    ("with_integrator", "integrator", "nlos_occluder.toml", "bdpt", "path", "kind", "mlt", 16),
])
def test_with_sampler_and_integrator_are_the_scene_files_settings(method, prop, scene_name, name, default, key,
                                                                   unknown, spp):
    """`with_sampler(name)` / `with_integrator(name)` render the bytes of the scene whose
    [integrator] says so, differ from the default's render, and refuse an unknown name."""
    import json
    import tomllib

    s = scene(scene_name)
    assert getattr(s, prop) == default
    t = getattr(s, method)(name)
    assert getattr(t, prop) == name
    desc = tomllib.loads((SCENES / scene_name).read_text())
    desc.setdefault("integrator", {})[key] = name
    u = dt.Scene.from_dict(json.loads(json.dumps(desc)), base_dir=SCENES)
    a = dt.render(t, spp=spp, seed=2).transient
    assert a.sum() > 0
    assert np.array_equal(a, dt.render(u, spp=spp, seed=2).transient)
    assert not np.array_equal(a, dt.render(s, spp=spp, seed=2).transient)
    with pytest.raises(ValueError, match=unknown):
        getattr(s, method)(unknown)


def test_scene_from_a_dict():
    import json
    import tomllib

    desc = tomllib.loads((SCENES / "diff_room.toml").read_text())
    s = dt.Scene.from_dict(json.loads(json.dumps(desc)), base_dir=SCENES)
    a = dt.render(s, spp=2, seed=4).transient
    b = dt.render(scene("diff_room.toml"), spp=2, seed=4).transient
    assert np.array_equal(a, b)


def test_errors_carry_the_renderers_messages(tmp_path):
    with pytest.raises(dt.SceneError, match="nope.toml"):
        dt.Scene.load(tmp_path / "nope.toml")
    # read as the CLI reads it: a FIFO is refused, not waited on
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    with pytest.raises(dt.SceneError, match="not a regular file"):
        dt.Scene.load(fifo)
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENES / "diff_room.toml").read_text().replace("value = 0.6", "value = -3.0"))
    with pytest.raises(dt.SceneError, match="bad.toml"):
        dt.Scene.load(bad)
    s = scene("diff_room.toml")
    with pytest.raises(dt.SceneError, match="no parameter named \"nope\""):
        s.with_params({"nope": 1.0})
    with pytest.raises(dt.RenderError, match="shape"):
        dt.gradient(s, ["albedo"], np.zeros((2, 2, 2, 1), np.float32))
    with pytest.raises(dt.RenderError, match='estimators must be "full", "interior", "boundary", "primary" or "secondary"'):
        dt.render_diff(s, ["albedo"], estimators="some")
    with pytest.raises(dt.RenderError):
        dt.render_diff(s, ["no_such_param"])


def test_arguments_are_checked_by_name():
    """Numbers of numpy's types are numbers; a bad count, scene, name list or adjoint is refused
    naming the argument. Before 2026-11-30: np.float32(0.2) as a parameter value was a
    TypeError ("cannot set a value of type float32"), spp=-1 an OverflowError naming nothing,
    render_diff(s, "albedo") looked for parameters "a", "l", ..., a repeated name gave one
    derivative, a list as the adjoint "'ndarray' object cannot be cast as 'ndarray'", and a
    path as the scene an AttributeError."""
    s = scene("diff_room.toml")
    for v in (np.float32(0.25), np.float64(0.25), np.array(0.25)):
        assert s.with_params({"albedo": v}).params["albedo"] == pytest.approx(0.25)
    assert s.with_params({"albedo": np.int64(1)}).params["albedo"] == 1.0
    for kw, message in (({"spp": -1}, "spp must be >= 0"), ({"spp": 2**40}, "spp must be at most"),
                        ({"seed": -1}, "seed must be >= 0"), ({"threads": -2}, "threads must be >= 0")):
        with pytest.raises(ValueError, match=message):
            dt.render(s, **kw)
    with pytest.raises(TypeError, match="spp must be a whole number"):
        dt.render(s, spp=1.5)
    with pytest.raises(TypeError, match="load it first"):
        dt.render(str(SCENES / "diff_room.toml"), spp=1)
    with pytest.raises(TypeError, match="list of parameter names"):
        dt.render_diff(s, "albedo", spp=1)
    with pytest.raises(ValueError, match="more than once"):
        dt.render_diff(s, ["albedo", "albedo"], spp=1)
    with pytest.raises(ValueError, match="more than once"):
        dt.gradient(s, ["albedo", "albedo"], np.zeros(s.shape, np.float32), spp=1)
    for bad in ([[1.0]], None, np.zeros(s.shape, np.complex64)):
        with pytest.raises(TypeError, match="adjoint must be a real numpy array"):
            dt.gradient(s, ["albedo"], bad, spp=1)
    huge = np.zeros(s.shape)
    huge[0, 0, 0, 0] = 1e300
    with pytest.raises(dt.RenderError, match="float32's range"):
        dt.gradient(s, ["albedo"], huge, spp=1)
    # until the forty-third session: numpy values inside a list were a TypeError ("cannot set
    # a value of type float32"), and auto_window's seed=-1 an OverflowError naming nothing
    cb = scene("cornell_box.toml")
    for v in ([np.int64(32), np.int64(32)], np.array([32, 32]), (np.int32(32), 32)):
        assert cb.with_params({"camera.resolution": v}).shape[:2] == (32, 32)
    with pytest.raises(ValueError, match="seed must be >= 0"):
        cb.auto_window(seed=-1)
    with pytest.raises(ValueError, match="threads must be >= 0"):
        cb.auto_window(threads=-1)


def test_a_scenes_window_follows_it_until_its_time_axis_is_set():
    """`window` (the choice of `auto_window`) was lost by every `with_*` until the forty-third
    session; it is kept where the scene keeps that window, and dropped where the film's time
    axis is set."""
    s = scene("diff_room.toml").auto_window(seed=1)
    assert s.window is not None
    for kept in (s.with_params({"albedo": 0.4}), s.with_sampler("independent"), s.with_integrator("bdpt"),
                 s.with_params({"camera.fov": 30})):
        assert kept.window == s.window
        assert kept.shape == s.shape and np.array_equal(kept.bin_centres, s.bin_centres)
    for name, value in (("film.start_opl", 1.0), ("film.bin_width_opl", 0.05), ("film.bins", 8)):
        assert s.with_params({name: value}).window is None, name


def test_renders_release_the_gil():
    """While a render runs in another thread, this thread keeps running Python: no gap between
    its loop iterations comes near the render's duration."""
    s = scene("cornell_box.toml")
    done = {}

    def work():
        t0 = time.perf_counter()
        dt.render(s, spp=48, threads=1)
        done["seconds"] = time.perf_counter() - t0

    th = threading.Thread(target=work)
    last, gap = time.perf_counter(), 0.0
    th.start()
    while th.is_alive():
        now = time.perf_counter()
        gap, last = max(gap, now - last), now
    th.join()
    assert done["seconds"] > 0.1, "the render is too short to tell"
    assert gap < done["seconds"] / 3, (gap, done["seconds"])


def test_torch_adapter_backward_is_the_adjoint():
    torch = pytest.importorskip("torch")
    from difftransient.torch import render

    s = scene("diff_room.toml")
    names = ["albedo", "intensity"]
    target = torch.from_numpy(dt.render(s.with_params({"albedo": 0.5, "intensity": 4.0}), spp=8, seed=2).transient)
    theta = torch.tensor([0.6, 5.0], dtype=torch.float64, requires_grad=True)
    image = render(s, names, theta, spp=4, seed=7)
    assert image.shape == s.shape and image.dtype == torch.float32
    loss = ((image - target) ** 2).sum()
    loss.backward()
    # the same adjoint by hand: ∂loss/∂I = 2 (I − target), on the backward pass's seed
    adj = (2 * (image.detach() - target)).numpy()
    g, _ = dt.gradient(s.with_params({"albedo": 0.6, "intensity": 5.0}), names, adj, spp=4, seed=8)
    np.testing.assert_allclose(theta.grad.numpy(), g, rtol=1e-6)
    assert theta.grad.dtype == torch.float64
    # both too bright: the loss falls as albedo and intensity fall
    assert (theta.grad.numpy() > 0).all()


def test_smooth_dielectric_index_needs_estimators_interior():
    """A smooth dielectric's index has no boundary term (supplemental assumption A.4): refused
    by default, computed with estimators="interior" by render_diff and by gradient (the
    adjoint the optimizers use), the latter the contraction of the former's derivative film."""
    s = scene("slab_ior.toml")
    with pytest.raises(dt.RenderError, match="--estimators interior"):
        dt.render_diff(s, ["slab_ior"], spp=2)
    with pytest.raises(dt.RenderError, match="--estimators interior"):
        dt.gradient(s, ["slab_ior"], np.ones(s.shape, np.float32), spp=2)
    d = dt.render_diff(s, ["slab_ior"], spp=4, seed=5, estimators="interior")
    dI = d.derivatives["slab_ior"]
    assert np.isfinite(dI).all() and np.abs(dI).sum() > 0
    adj = np.random.default_rng(1).standard_normal(s.shape).astype(np.float32)
    g, _ = dt.gradient(s, ["slab_ior"], adj, spp=4, seed=5, estimators="interior")
    want = float((adj.astype(np.float64) * dI).sum())
    assert abs(g[0] - want) <= 1e-4 * (np.abs(adj) * np.abs(dI)).sum(), (g[0], want)


def test_torch_adapter_passes_estimators_to_the_backward_pass():
    torch = pytest.importorskip("torch")
    from difftransient.torch import render

    s = scene("slab_ior.toml")
    theta = torch.tensor([1.5], dtype=torch.float64, requires_grad=True)
    with pytest.raises(dt.RenderError, match="--estimators interior"):
        render(s, ["slab_ior"], theta, spp=2, seed=3).sum().backward()
    theta.grad = None
    image = render(s, ["slab_ior"], theta, spp=2, seed=3, estimators="interior")
    image.sum().backward()
    g, _ = dt.gradient(s, ["slab_ior"], np.ones(s.shape, np.float32), spp=2, seed=4, estimators="interior")
    np.testing.assert_allclose(theta.grad.numpy(), g, rtol=1e-6)


def test_time_edges_option_reaches_the_renderer():
    """`time_edges` switches the path tracer's draws on the bin edges (the default where they
    apply) in render_diff and gradient."""
    s = scene("narrow_pulse_box.toml")
    on = dt.render_diff(s, ["tall_box_x"], spp=1, seed=2, estimators="interior")
    off = dt.render_diff(s, ["tall_box_x"], spp=1, seed=2, estimators="interior", time_edges="off")
    assert on.stats["time_edges"] is True and off.stats["time_edges"] is False
    # same paths: the primal is the same bytes, the derivative differs (its time term is drawn)
    assert np.array_equal(on.transient, off.transient)
    assert not np.array_equal(on.derivatives["tall_box_x"], off.derivatives["tall_box_x"])
    g, stats = dt.gradient(s, ["tall_box_x"], np.ones(s.shape, np.float32), spp=1, seed=2,
                           estimators="interior", time_edges="off")
    assert stats["time_edges"] is False
    with pytest.raises(dt.RenderError, match="time_edges"):
        dt.render_diff(s, ["tall_box_x"], spp=1, time_edges="sometimes")


def test_an_empty_time_window_is_warned_about():
    """A window that holds none of the light returns zeros with a RuntimeWarning and the
    warning in stats["energy"], as `dtr render` warns on stderr and writes it in its JSON.
    Before, Python returned the zeros silently (helper 20)."""
    s = scene("diff_room.toml").with_params({"film.start_opl": 100.0})
    with pytest.warns(RuntimeWarning, match="holds no energy"):
        r = dt.render(s, spp=1, threads=1)
    assert not r.transient.any()
    assert "holds no energy" in r.stats["energy"]["warning"]
    with pytest.warns(RuntimeWarning, match="holds no energy"):
        d = dt.render_diff(s, ["albedo"], spp=1, threads=1)
    assert "holds no energy" in d.stats["energy"]["warning"]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = dt.render(scene("diff_room.toml"), spp=1, threads=1)
    assert r.stats["energy"]["warning"] is None


def test_calls_without_a_seed_draw_fresh_samples():
    """The torch adapter's seed: a given one is kept (common random numbers), none draws a new
    one at each call, so that an optimiser's iterations do not all see one frozen set of
    samples (before, every call without a seed rendered at the scene's seed; helper 20)."""
    from difftransient import _draw_seed

    assert _draw_seed(5) == 5 and _draw_seed(0) == 0
    drawn = {_draw_seed(None) for _ in range(64)}
    assert len(drawn) == 64 and all(0 <= s < 2**62 for s in drawn)


def test_a_scene_copies():
    """copy.copy and copy.deepcopy of a Scene (as optimisation loops and dataclasses make them)
    give a scene that renders the same bytes; they raised TypeError (helper 20)."""
    import copy

    s = scene("diff_room.toml")
    for c in (copy.copy(s), copy.deepcopy(s), copy.deepcopy({"scene": s})["scene"]):
        assert isinstance(c, dt.Scene) and c.shape == s.shape
        assert np.array_equal(dt.render(c, spp=1, seed=3, threads=1).transient,
                              dt.render(s, spp=1, seed=3, threads=1).transient)


def test_the_estimator_and_sampler_chosen_stay_through_later_settings():
    """with_integrator and with_sampler survive with_params (how the torch adapter sets
    values at every call) and auto_window, and the render is the chosen estimator's. Before, every later
    setting resolved the scene again from its file's [integrator] table: a BDPT scene with
    independent numbers came back from with_params as the path tracer with Sobol points."""
    s = scene("pose_plate.toml").with_integrator("bdpt").with_sampler("independent")
    later = {
        "with_params": s.with_params({"plate_x": 0.05}),
        "with_params of a field": s.with_params({"film.bins": 30}),
        "auto_window": s.auto_window(threads=1),
    }
    for how, t in later.items():
        assert (t.integrator, t.sampler) == ("bdpt", "independent"), how
    moved = later["with_params"]
    ref = scene("pose_plate.toml").with_params({"plate_x": 0.05})
    bdpt = dt.render(ref.with_integrator("bdpt").with_sampler("independent"), spp=2, seed=5, threads=1)
    path = dt.render(ref, spp=2, seed=5, threads=1)
    got = dt.render(moved, spp=2, seed=5, threads=1)
    assert np.array_equal(got.transient, bdpt.transient)
    assert not np.array_equal(got.transient, path.transient)


def test_refused_settings_are_named_as_python_sets_them():
    """A refused parameter or field names it as the Python call gave it (params["NAME"],
    params), not as the CLI flag (--set NAME, --diff) the same error names in dtr."""
    s = scene("pose_plate.toml")
    with pytest.raises(dt.SceneError, match=r'params\["nope"\]: no parameter named "nope"') as e:
        s.with_params({"nope": 1.0})
    assert "--set" not in str(e.value)
    with pytest.raises(dt.SceneError, match=r'params\["plate_x"\]: expected a finite number'):
        dt.Scene.load(SCENES / "pose_plate.toml", {"plate_x": float("nan")})
    with pytest.raises(dt.RenderError, match=r': params: no parameter named "nope"') as e:
        dt.render_diff(s, ["nope"], spp=1, threads=1)
    assert "--diff" not in str(e.value)


def test_a_scene_pickles_whole():
    """A Scene pickles (multiprocessing sends scenes so) with its values set, estimator,
    sampler, meshes and chosen window, and the unpickled scene renders the same bytes without
    reading any file: the OBJ may be gone. It raised TypeError. A damaged pickle is refused by
    SceneError, not a crash."""
    import pickle
    import shutil

    d = Path(tempfile.mkdtemp())
    try:
        src = ROOT / "scenes"
        shutil.copy(src / "obj_mesh.toml", d / "obj_mesh.toml")
        shutil.copytree(src / "meshes", d / "meshes")
        s = dt.Scene.load(d / "obj_mesh.toml", {"camera.fov": 35.0}).with_sampler("independent")
        s = s.auto_window(threads=1)
        blob = pickle.dumps(s)
        shutil.rmtree(d / "meshes")
        back = pickle.loads(blob)
        assert (back.sampler, back.integrator, back.window, back.shape) == (s.sampler, s.integrator, s.window, s.shape)
        assert np.array_equal(dt.render(back, spp=2, seed=1, threads=1).transient,
                              dt.render(s, spp=2, seed=1, threads=1).transient)
        # and it still takes settings
        assert back.with_params({"camera.fov": 30.0}).sampler == "independent"
    finally:
        shutil.rmtree(d, ignore_errors=True)
    p = scene("pose_plate.toml").with_params({"plate_x": 0.03})
    q = pickle.loads(pickle.dumps(p))
    assert q.params == p.params
    # a damaged state: bytes that are not whole vertices
    fn, args = p._native.__reduce__()
    bad = args[:5] + ([(b"\0" * 23, b"")],)
    with pytest.raises(dt.SceneError, match="not whole vertices"):
        fn(*bad)
    with pytest.raises(dt.SceneError, match="format 99"):
        fn(99, *args[1:])


def test_ctrl_c_stops_a_long_render():
    """Ctrl-C (SIGINT) during a render of weeks of samples raises KeyboardInterrupt within
    seconds, for render, render_diff and gradient, and the next render runs as usual. Before,
    the render went on after SIGINT (still running 20 s later): only ending the process, in a
    notebook the kernel, stopped it (helper 20)."""
    import signal

    s = scene("diff_room.toml")
    adjoint = np.zeros(s.shape, np.float32)
    # about a minute each if nothing stopped them (so a failure does not hang the suite)
    spp = 2**18
    calls = {
        "render": lambda: dt.render(s, spp=spp, threads=1),
        "render_diff": lambda: dt.render_diff(s, ["room_z"], spp=spp, spp_boundary=4096, threads=1),
        "gradient": lambda: dt.gradient(s, ["room_z"], adjoint, spp=spp, spp_boundary=4096, threads=1),
    }
    # Python's own Ctrl-C handler, which it does not install where SIGINT was ignored when it
    # started (a background job of a non-interactive shell: CI rehearsal 68 hung here)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        for name, call in calls.items():
            timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
            start = time.monotonic()
            timer.start()
            with pytest.raises(KeyboardInterrupt):
                call()
            timer.join()
            assert time.monotonic() - start < 10, name
    finally:
        signal.signal(signal.SIGINT, previous)
    assert dt.render(s, spp=1, threads=1).transient.any()


def test_a_64_bit_seed_set_as_a_field_is_exact():
    """integrator.seed beyond 2⁵³ through with_params renders as the same seed given to render
    (the same bytes); before, it went through a float and was refused (helper 20)."""
    s = scene("diff_room.toml")
    seed = 2**53 + 1
    a = dt.render(s.with_params({"integrator.seed": seed}), spp=1, threads=1)
    b = dt.render(s, spp=1, seed=seed, threads=1)
    assert a.stats["seed"] == seed
    assert np.array_equal(a.transient, b.transient)


def test_a_render_in_a_daemon_thread_leaves_a_clean_exit():
    """A render called from a thread other than the main one does not poll for signals
    (Python handles them on the main thread only). Before, it took the GIL every 50 ms to
    poll, and a daemon thread rendering while the interpreter shut down printed a pyo3 panic
    ("The Python interpreter is not initialized"), 12 times in 12 (found by an independent
    sweep)."""
    code = (
        "import threading, time, difftransient as dt\n"
        f"s = dt.Scene.load({str(SCENES / 'diff_room.toml')!r})\n"
        "threading.Thread(target=lambda: dt.render(s, spp=2**14, threads=1), daemon=True).start()\n"
        "time.sleep(0.5)\n"
    )
    for _ in range(3):
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        assert "panic" not in r.stderr and "not initialized" not in r.stderr, r.stderr


def test_the_module_docstrings_example_runs(monkeypatch):
    """The example at the top of `difftransient`'s docstring runs as written (from the
    repository's root). It named a parameter the scene it loaded does not have, and a loss
    adjoint it never made (found by an independent sweep)."""
    lines = dt.__doc__.split("\n")
    start = lines.index("    import difftransient as dt")
    block = []
    for line in lines[start:]:
        if not line.startswith("    "):
            break
        block.append(line[4:])
    monkeypatch.chdir(SCENES.parent)
    scope = {}
    exec("\n".join(block), scope)
    assert scope["g"].shape == (1,) and np.isfinite(scope["g"]).all()


def test_strings_set_through_params_read_back_as_themselves():
    """Strings set through `params` are written as TOML that reads back as the same string.
    A character beyond the BMP (a mesh file `p😀.obj`) was written as a JSON surrogate pair,
    which TOML refuses, and the loader took the whole text, quotes included, as the value
    (found by an independent sweep)."""
    import tomllib
    for s in ["p😀.obj", 'a"b', "back\\slash", "tab\tnew\nline", "é", ""]:
        assert tomllib.loads("v = " + dt._toml_value(s))["v"] == s, s
        assert tomllib.loads("v = " + dt._toml_value({s: [s]}))["v"] == {s: [s]}, s


def test_a_boundary_only_render_does_not_warn_of_its_empty_transient():
    """`estimators="boundary"` leaves the transient 0 on purpose; `dtr render` says nothing
    of it, and neither does Python now (it warned "no light reached the camera"; found by an
    independent sweep)."""
    import warnings
    s = dt.Scene.load(str(SCENES / "shadow_hidden_occluder.toml"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = dt.render_diff(s, ["occluder_x"], spp=2, seed=1, threads=1, estimators="boundary")
    assert not d.transient.any() and d.derivatives["occluder_x"].any()
    assert d.stats["energy"]["warning"]


def test_each_boundary_term_renders_alone():
    """`estimators="primary"` and `"secondary"` render one boundary term each (to find which
    carries a derivative's noise): with the same seed they add up to `"boundary"`; a sliding
    cube's silhouette is the primary term's, a hidden occluder's shadow the secondary's; the
    transient stays 0 without a warning, and another name is refused, listing the five."""
    import warnings
    scenes = [("silhouette_slide.toml", "cube_x", True), ("shadow_hidden_occluder.toml", "occluder_x", False)]
    for name, param, seen in scenes:
        s = dt.Scene.load(str(SCENES / name), {"camera.resolution": [16, 16]})
        run = lambda e: dt.render_diff(s, [param], spp=2, seed=3, threads=1, estimators=e)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            p, q, b = run("primary"), run("secondary"), run("boundary")
        dp, dq, db = (r.derivatives[param] for r in (p, q, b))
        assert not p.transient.any() and not q.transient.any(), name
        # the camera sees the cube, never the occluder
        assert dp.any() if seen else not dp.any() and dq.any(), name
        np.testing.assert_array_equal(dp + dq, db)
    with pytest.raises(dt.RenderError, match='"primary" or "secondary"'):
        run("edges")


def test_renders_compare_by_identity():
    """`==` between two renders is identity (their arrays compare with np.array_equal). The
    dataclass's generated `__eq__` compared the arrays with ==, and raised ValueError
    ("truth value of an array is ambiguous"; found by an independent sweep)."""
    s = dt.Scene.load(str(SCENES / "diff_room.toml"))
    a, b = (dt.render(s, spp=1, seed=1, threads=1) for _ in range(2))
    assert a == a and a != b and np.array_equal(a.transient, b.transient)
