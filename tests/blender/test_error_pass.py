# The reference-free error estimate in Blender: the "Error" pass
# (scene.coherent.use_pass_error) and the Target Error / Time Limit stopping
# rules, through headless command-line renders as a user runs them.

import re

import numpy as np
import pytest

import blender_helpers as bh

SMALL = bh.python_expr("scene.render.resolution_percentage = 12",  # 512 -> 61 px
                       "scene.coherent.samples = 8")

# "Coherent: error 12.3 % after 8 samples in 0.05 s" (also an INFO report).
SUMMARY = re.compile(r"Coherent: error ([\d.]+) % after (\d+) samples in ([\d.]+) s")


def summary(result):
    m = SUMMARY.search(result.stdout)
    assert m, f"no error summary in stdout\n{result.describe()}"
    return float(m.group(1)) / 100.0, int(m.group(2))


def test_error_pass_in_multilayer_exr(blender, blend_scenes, tmp_path):
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "OPEN_EXR_MULTILAYER",
                     "-o", tmp_path / "err_####", "--python-expr", SMALL,
                     "--python-expr", bh.python_expr("scene.coherent.use_pass_error = True"), "-f", "1")
    out = tmp_path / "err_0001.exr"
    assert result.returncode == 0, result.describe()
    assert out.is_file(), result.describe()
    ch = bh.read_image_channels(out)
    error = bh.find_channels(ch, "Error", "X")[..., 0]
    rgb = bh.find_channels(ch, "Combined", "RGBA")[..., :3]
    assert error.shape == rgb.shape[:2] == (61, 61)
    assert np.isfinite(error).all()
    assert (error >= 0).all()
    # 8 samples of a path-traced Cornell box are noisy: most lit pixels carry
    # a positive estimate, and the pass is consistent with the printed
    # relative estimate: RMS(pass) / mean(radiance).
    assert (error > 0).mean() > 0.5
    estimate, samples = summary(result)
    assert samples == 8
    # (The summary prints one decimal of a percentage.)
    relative = np.sqrt(np.mean(error.astype(np.float64) ** 2)) / rgb.astype(np.float64).mean()
    assert relative == pytest.approx(estimate, abs=0.0006)


def test_error_pass_off_by_default(blender, blend_scenes, tmp_path):
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "OPEN_EXR_MULTILAYER",
                     "-o", tmp_path / "plain_####", "--python-expr", SMALL, "-f", "1")
    assert result.returncode == 0, result.describe()
    ch = bh.read_image_channels(tmp_path / "plain_0001.exr")
    assert not any(n.split(".")[-2:] == ["Error", "X"] for n in ch), sorted(ch)


def test_target_error_stops_early(blender, blend_scenes, tmp_path):
    settings = bh.python_expr("scene.render.resolution_percentage = 6",  # 512 -> 30 px
                              "scene.coherent.samples = 100000",
                              "scene.coherent.target_error = 0.2")
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "PNG",
                     "-o", tmp_path / "target_####", "--python-expr", settings, "-f", "1")
    assert result.returncode == 0, result.describe()
    assert (tmp_path / "target_0001.png").is_file()
    estimate, samples = summary(result)
    assert 2 <= samples < 100000 and samples % 2 == 0
    assert 0.0 < estimate <= 0.2 + 0.0005  # printed to 0.1 %
    assert re.search(rf"Coherent: finished \d+x\d+, {samples} spp", result.stdout), result.describe()
