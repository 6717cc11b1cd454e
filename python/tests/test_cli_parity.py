"""The Python package against the CLI (`dtr`, DTR_BIN): a Mitsuba XML scene's errors carry the
CLI's message (file, element, line), the automatic time window is the CLI's, and the CLI's
`--exr` opens in OpenEXR's own reader (the Python `OpenEXR` package, an implementation
independent of ours) with every bin, the steady image and the time axis where the README
says."""

import json
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

import difftransient as dt

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"

XML_HEAD = """<scene version="3.0.0">
    <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="2"/></sampler>
        <film type="transient_hdr_film"><integer name="width" value="8"/><integer name="height" value="8"/>
            <integer name="temporal_bins" value="20"/><float name="bin_width_opl" value="0.5"/></film>
    </sensor>
    <emitter type="point"><point name="position" value="0, 0, 2"/><rgb name="intensity" value="1"/></emitter>
"""


def dtr():
    path = os.environ.get("DTR_BIN", str(ROOT / "target" / "release" / "dtr"))
    if not Path(path).exists():
        pytest.skip("no dtr binary (set DTR_BIN)")
    return path


def run(*args, cwd=None):
    return subprocess.run([dtr(), *map(str, args)], capture_output=True, text=True, cwd=cwd)


@pytest.mark.parametrize(
    "body, element, marker",
    [
        # refused while converting
        ('\n\n<shape type="disk"/>', '<shape type="disk">', "disk"),
        # refused after conversion, when the description is checked: the XML element is named
        ('\n<shape type="rectangle"><bsdf type="diffuse">\n<float name="reflectance" value="1.5"/></bsdf></shape>',
         '<bsdf type="diffuse">', "diffuse"),
        # an XML syntax error (its line and column)
        ('\n<shape type="rectangle">', "XML syntax error", None),
    ],
)
def test_xml_errors_carry_the_clis_message(tmp_path, body, element, marker):
    path = tmp_path / "bad.xml"
    text = XML_HEAD + body + "\n</scene>\n"
    path.write_text(text)
    with pytest.raises(dt.SceneError) as err:
        dt.Scene.load(path)
    message = str(err.value)
    assert message.startswith(str(path)) and element in message, message
    if marker is not None:
        line = text[: text.index(marker)].count("\n") + 1
        assert f"(line {line})" in message, message
    cli = run("render", path, "-o", tmp_path / "out")
    assert cli.returncode != 0
    assert message in cli.stderr, f"python: {message}\ncli: {cli.stderr}"


def test_auto_window_is_the_clis(tmp_path):
    scene = dt.Scene.load(SCENES / "cornell_box.toml")
    chosen = scene.auto_window(seed=3)
    w = chosen.window
    assert w["bins"] == scene.shape[2] == chosen.shape[2]
    assert w["pilot_start_opl"] <= w["start_opl"] < w["low_quantile_opl"]
    assert w["high_quantile_opl"] < w["start_opl"] + w["bins"] * w["bin_width_opl"] <= w["pilot_end_opl"]
    centres = chosen.bin_centres
    np.testing.assert_allclose(centres[0], w["start_opl"] + 0.5 * w["bin_width_opl"], rtol=1e-12)
    np.testing.assert_allclose(np.diff(centres), w["bin_width_opl"], rtol=1e-9)
    # the CLI's choice, with the same seed: the same window
    out = tmp_path / "cb"
    cli = run("render", SCENES / "cornell_box.toml", "--auto-window", "--seed", 3, "--spp", 1, "-o", out)
    assert cli.returncode == 0, cli.stderr
    meta = json.loads(Path(str(out) + ".json").read_text())
    for k in ("start_opl", "bin_width_opl", "bins", "low_quantile_opl", "high_quantile_opl"):
        assert meta["auto_window"][k] == w[k], k
    # render(auto_window=True) renders the chosen scene and reports the choice
    r = dt.render(scene, spp=2, seed=3, auto_window=True)
    same = dt.render(chosen, spp=2, seed=3)
    assert np.array_equal(r.transient, same.transient)
    assert r.stats["auto_window"]["start_opl"] == w["start_opl"]
    np.testing.assert_array_equal(r.bin_centres, centres)
    # the window holds the light: it is no longer mostly empty, as the scene's own is
    assert r.transient.sum() > 0 and (r.transient.sum(axis=(0, 1, 3)) > 0).mean() > 0.9
    assert dt.render(scene, spp=2, seed=3).stats.get("auto_window") is None


def test_exr_opens_in_openexr_with_every_bin_the_steady_image_and_the_time_axis(tmp_path):
    OpenEXR = pytest.importorskip("OpenEXR", reason="the OpenEXR package (tools/test installs it)")
    out = tmp_path / "s"
    cli = run("render", SCENES / "shadow_hidden_occluder.toml", "--spp", 2, "--exr", "--preview", "--steady",
              "full", "-o", out)
    assert cli.returncode == 0, cli.stderr
    film = np.load(str(out) + ".npy")
    steady = np.load(str(out) + ".steady.npy")
    meta = json.loads(Path(str(out) + ".json").read_text())
    h, w, bins, c = film.shape
    names = ["Y"] if c == 1 else ["R", "G", "B"]
    with OpenEXR.File(str(out) + ".exr", separate_channels=True) as f:
        assert len(f.parts) == 1
        channels = f.channels()
        # doubles read back as one-element arrays
        header = {k: (v.item() if isinstance(v, np.ndarray) and v.size == 1 else v) for k, v in f.header().items()}
        expected = set(names) | {f"t{t:04d}.{n}" for t in range(bins) for n in names}
        assert set(channels) == expected
        for ci, n in enumerate(names):
            assert channels[n].pixels.dtype == np.float32
            assert np.array_equal(channels[n].pixels, steady[:, :, ci]), n
            for t in range(bins):
                assert np.array_equal(channels[f"t{t:04d}.{n}"].pixels, film[:, :, t, ci]), (t, n)
    # --steady full: the default layer holds light outside the window too
    assert steady.sum() > film.sum() > 0
    axis = meta["time_axis"]
    assert header["start_opl"] == axis["start_opl"]
    assert header["bin_width_opl"] == axis["bin_width_opl"]
    assert header["time_bins"] == bins
    assert header["opl_units"] == "metres"
    np.testing.assert_allclose(header["end_opl"], axis["start_opl"] + bins * axis["bin_width_opl"], rtol=1e-12)
    np.testing.assert_allclose(header["bin_width_ns"], axis["bin_width_opl"] / 299792458.0 * 1e9, rtol=1e-12)
    # grouped as viewers group them: the default layer is an RGB (or Y) image, each bin a layer
    with OpenEXR.File(str(out) + ".exr") as f:
        grouped = f.channels()
        if c == 3:
            assert np.array_equal(grouped["RGB"].pixels, steady)
            assert np.array_equal(grouped["t0001.RGB"].pixels, film[:, :, 1, :])


def test_the_largest_exr_dtr_writes_opens_in_openexr_and_one_bin_more_is_refused(tmp_path):
    """OpenEXR opens at most 32767 channels: 10921 RGB bins (32766 channels with the steady
    image's) open, and 10922 are refused before the render, where dtr wrote a file OpenEXR
    would not open (exit 0; an independent audit)."""
    OpenEXR = pytest.importorskip("OpenEXR", reason="the OpenEXR package (tools/test installs it)")
    common = ["--spp", 1, "--exr", "--set", "camera.resolution=[1, 1]", "--set", "film.bin_width_opl=0.001"]
    out = tmp_path / "wide"
    cli = run("render", SCENES / "cornell_box.toml", *common, "--set", "film.bins=10921", "-o", out)
    assert cli.returncode == 0, cli.stderr
    with OpenEXR.File(str(out) + ".exr", separate_channels=True) as f:
        assert len(f.channels()) == 32766
    over = tmp_path / "over"
    cli = run("render", SCENES / "cornell_box.toml", *common, "--set", "film.bins=10922", "-o", over)
    assert cli.returncode == 2 and "more than the 32767 OpenEXR opens" in cli.stderr, cli.stderr
    assert not list(tmp_path.glob("over*"))
