# Hand-over of Blender images to the native texture store (addon/coherent/
# images.py, native/shader/memory_images.h), against Cycles as the oracle.
#
# image_handover_scene.py renders a byte sRGB RGBA image, linearly filtered,
# held packed (a PNG), file-backed and generated-then-painted, with Cycles
# and twice with COHERENT. Each COHERENT render must agree with Cycles pixel
# for pixel up to float rounding (as the per-node image cases of
# test_shader_nodes.py), and the second render must reuse the in-memory
# images handed over by the first (its stats line says so) with the same
# pixels. An image repacked from other bytes of the same length must render
# its new texels (as Cycles does) and be handed over again. The same image
# with Straight alpha (packed, file-backed, float, Linear and Closest,
# Alpha unused and used) must agree with Cycles too:
# Cycles associates its texels before filtering (image_handover_scene.py).

import re

import numpy as np
import pytest

import blender_helpers as bh

SCRIPT = bh.REPO_ROOT / "tests" / "blender" / "image_handover_scene.py"
ABS_TOL, REL_TOL = 2e-5, 2e-5  # as test_shader_nodes.py
CASES = ("packed", "file", "generated", "repacked")
STRAIGHT_CASES = [f"straight_{source}_{interp}_{alpha}" for source in ("packed", "file", "float")
                  for interp in ("linear", "closest") for alpha in ("unused", "used")]


def _rgb(path):
    channels = bh.read_image_channels(path)
    return np.stack([channels["R"], channels["G"], channels["B"]], axis=-1).astype(np.float64)


@pytest.fixture(scope="module")
def handover(user_scripts, tmp_path_factory):
    out = tmp_path_factory.mktemp("handover")
    result = bh.run_blender(["--python", SCRIPT, "--", out], user_scripts, timeout=300)
    assert result.returncode == 0, result.describe()
    return out, result.stdout


@pytest.mark.parametrize("case", CASES)
def test_handed_over_image_matches_cycles(handover, case):
    out, _ = handover
    cycles = _rgb(out / f"{case}_cycles.exr")
    assert cycles.std() > 1e-3, f"{case}: Cycles' image is constant, the case tests nothing"
    for suffix in ("", "_again"):
        ours = _rgb(out / f"{case}_coherent{suffix}.exr")
        bad = np.abs(ours - cycles) > ABS_TOL + REL_TOL * np.abs(cycles)
        assert not bad.any(), f"{case}{suffix}: {bad.sum()} of {bad.size} values differ from Cycles'"
    assert np.array_equal(_rgb(out / f"{case}_coherent.exr"), _rgb(out / f"{case}_coherent_again.exr"))


@pytest.mark.parametrize("case", STRAIGHT_CASES)
def test_straight_alpha_image_matches_cycles(handover, case):
    out, _ = handover
    cycles = _rgb(out / f"{case}_cycles.exr")
    assert cycles.std() > 1e-3, f"{case}: Cycles' image is constant, the case tests nothing"
    ours = _rgb(out / f"{case}_coherent.exr")
    bad = np.abs(ours - cycles) > ABS_TOL + REL_TOL * np.abs(cycles)
    worst = np.max(np.abs(ours - cycles) / np.maximum(np.abs(cycles), 1e-3))
    assert not bad.any(), f"{case}: {bad.sum()} of {bad.size} values differ from Cycles' (worst {worst:.3g})"


def test_second_render_reuses_in_memory_images(handover):
    _, stdout = handover
    reused = {}
    for case, n, count in re.findall(r"HANDOVER_RENDER (\w+) (\d).*?Coherent: finished .*?1 images \((\d+) reused\)",
                                     stdout, flags=re.S):
        reused[(case, int(n))] = int(count)
    # In memory: handed over by the first render, reused by the second. Files: decoded natively by the
    # first render, reused by the second while the file is unchanged. Repacked from other bytes of the
    # same length: handed over again, then reused.
    assert reused == {("packed", 0): 0, ("packed", 1): 1, ("generated", 0): 0, ("generated", 1): 1,
                      ("file", 0): 0, ("file", 1): 1, ("repacked", 0): 0, ("repacked", 1): 1}, stdout[-3000:]


def test_repacked_image_is_not_the_one_held_before(handover):
    out, _ = handover
    before, after = _rgb(out / "repacked_before_coherent.exr"), _rgb(out / "repacked_coherent.exr")
    assert np.abs(before - after).max() > 0.05, "the two packed versions render alike: the case tests nothing"


def test_packed_files_are_hashed_in_place(handover):
    _, stdout = handover
    # A ctypes array over Blender's PackedFile.data (no copy), with the bytes of PackedFile.data.
    assert re.search(r"PACKED_VIEW c_char_Array_\d+ True", stdout), stdout[-3000:]
