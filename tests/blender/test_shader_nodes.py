# Shader node graphs (native/shader, addon/coherent/shader_compiler.py)
# against Cycles as the oracle.
#
# Per node: node_scenes.py renders, with both engines at 1 spp, a plane whose
# Emission colour is driven by the node under test, read at coordinates that
# are constant over each pixel (normal maps: a diffuse plane lit by a
# point-like sun, direct light only, which is as deterministic). An emitter seen by the camera shows exactly its
# emission, so the images must agree pixel for pixel up to float rounding:
# our nodes use Cycles' formulas, and image lookups (OIIO) filter the same
# texels with the same weights. The few outputs that cannot be made constant
# over a pixel (Geometry's Parametric and Tangent) are compared within the
# most two points of one pixel can differ (node_scenes.SMOOTH_TOLERANCE).
#
# Whole scenes: a sun-lit cube and ground plane with an image texture on UVs
# through a Mapping node and a roughness from a node group; a smooth sphere
# with a tangent-space normal map of bumps on a ground plane. Path traced by
# both: per-channel means within 2 %, every 16x16 block within 8 %.
#
# Malformed input: a missing image file and node groups nested too deep
# render (magenta for the image, as Cycles) with warnings naming the material
# and the node.

import numpy as np
import pytest

import blender_helpers as bh
import node_scenes

NODE_SCRIPT = bh.REPO_ROOT / "tests" / "blender" / "node_scenes.py"
# Float rounding of the same formulas evaluated in a different order (and
# Cycles' fast sRGB power approximation for byte images).
ABS_TOL, REL_TOL = 2e-5, 2e-5


CASES = list(node_scenes.cases())  # the per-node scenes, by name


def _rgb(path):
    channels = bh.read_image_channels(path)
    return np.stack([channels["R"], channels["G"], channels["B"]], axis=-1).astype(np.float64)


@pytest.fixture(scope="module")
def node_renders(user_scripts, tmp_path_factory):
    out = tmp_path_factory.mktemp("nodes")
    result = bh.run_blender(["--python", NODE_SCRIPT, "--", out], user_scripts, timeout=300)
    assert result.returncode == 0, result.describe()
    return out, result


@pytest.mark.parametrize("case", CASES)
def test_node_matches_cycles(node_renders, case):
    out, result = node_renders
    cycles, ours = _rgb(out / f"{case}_cycles.exr"), _rgb(out / f"{case}_coherent.exr")
    # The case must exercise something: a constant image would pass trivially.
    assert cycles.std() > 1e-3, f"{case}: Cycles' image is constant, the case tests nothing"
    # Emission is non-negative here (a negative Cycles emission shows as is; ours is clamped).
    cycles = np.maximum(cycles, 0.0)
    # A value that varies inside a pixel differs by where each engine's one sample fell.
    abs_tol = node_scenes.SMOOTH_TOLERANCE.get(case, ABS_TOL)
    bad = np.abs(ours - cycles) > abs_tol + REL_TOL * np.abs(cycles)
    worst = np.unravel_index(np.argmax(np.abs(ours - cycles)), cycles.shape)
    assert not bad.any(), (f"{case}: {bad.sum()} of {bad.size} values differ; worst at {worst}: "
                           f"ours {ours[worst]:.7g}, Cycles {cycles[worst]:.7g}")


@pytest.mark.parametrize("scene", ["scene_textured", "scene_normal_mapped"])
def test_whole_scene_matches_cycles(blender, tmp_path, scene):
    result = blender("--python", NODE_SCRIPT, "--", tmp_path, scene, timeout=300)
    assert result.returncode == 0, result.describe()
    cycles, ours = _rgb(tmp_path / f"{scene}_cycles.exr"), _rgb(tmp_path / f"{scene}_coherent.exr")
    ratio = ours.mean(axis=(0, 1)) / cycles.mean(axis=(0, 1))
    assert np.all(np.abs(ratio - 1.0) <= 0.02), f"per-channel mean ratio ours/Cycles {ratio}"
    h, w, _ = cycles.shape
    blocks = lambda im: im.reshape(h // 16, 16, w // 16, 16, 3).mean(axis=(1, 3))  # noqa: E731
    block_ratio = blocks(ours) / np.maximum(blocks(cycles), 1e-6)
    assert np.all(np.abs(block_ratio - 1.0) <= 0.08), f"16x16 block ratios ours/Cycles:\n{block_ratio.round(3)}"


def test_malformed_inputs_warn_and_render(blender, tmp_path):
    result = blender("--python", NODE_SCRIPT, "--", tmp_path, "malformed", timeout=300)
    assert result.returncode == 0, result.describe()
    log = result.stdout + result.stderr
    assert "Material 'under_test', node 'missing_tex', image 'missing'" in log and "magenta" in log, log[-3000:]
    assert "Material 'under_test': node group" in log and "nested deeper than" in log, log[-3000:]
    image = _rgb(tmp_path / "malformed_coherent.exr")
    # Cycles' missing-texture magenta, at emission strength 1 (1 + the dropped group's default 0).
    assert np.allclose(image, np.array([1.0, 0.0, 1.0]), atol=1e-6), image.mean(axis=(0, 1))


def test_malformed_data_warns_and_stays_finite(blender, tmp_path):
    """A zero-byte image file, NaN/infinite pixels (emission, base colour and normal map) and a
    cycle of links: warnings name the material and the node; every pass stays finite.
    (A node group containing itself cannot be built: Blender refuses to assign it.)"""
    result = blender("--python", NODE_SCRIPT, "--", tmp_path, "malformed_data", timeout=300)
    assert result.returncode == 0, result.describe()
    log = result.stdout + result.stderr
    expected = ["Material 'zero_size_image', node 'zero_size_image_tex', image 'zero_size': image cannot be read",
                "Material 'nan_emission', node 'nan_emission_tex', image 'nan_pixels': image has 104 NaN or infinite",
                "Material 'cyclic_links': link from node 'loop_"]
    for text in expected:
        assert text in log, f"missing warning {text!r}:\n{log[-3000:]}"
    channels = bh.read_image_channels(tmp_path / "malformed_data_coherent.exr")
    passes = {name.split(".")[-2] for name in channels}
    assert {"Combined", "Normal", "DiffCol", "Emit"} <= passes, sorted(passes)
    for name, plane in channels.items():
        assert np.isfinite(plane).all(), f"{name}: {(~np.isfinite(plane)).sum()} non-finite values"
    rgb = np.stack([channels[f"ViewLayer.Combined.{c}"] for c in "RGB"], axis=-1)
    # Each of the four quads is seen: something in every quarter of the image.
    w = rgb.shape[1]
    for k in range(4):
        assert rgb[:, k * w // 4:(k + 1) * w // 4].max() > 0.05, f"quad {k} renders black"
