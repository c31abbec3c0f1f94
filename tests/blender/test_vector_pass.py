# The Vector pass against Cycles (View Layer > Passes > Data > Vector):
# vector_renders.py builds a scene whose objects (world-space triangles and
# an instance) and camera move between frames 1 and 3, and renders frame 2
# with both engines. On pixels inside one object (Cycles' IndexOB the same
# in the 3 x 3 neighbourhood, IndexOB equal in both) the four channels
# (previous-frame and next-frame screen motion, in pixels) agree. Cycles
# samples the pixel centre, ours points spread over the pixel: where the
# vector field is linear across a pixel, ours differs from the centre's by
# at most half the largest step of Cycles' vector to a neighbouring pixel
# (centres one pixel apart, our points at most half a pixel from ours);
# 0.02 pixels more cover the field's curvature (perspective, rotation) and
# float rounding. Measured: at most 0.05 pixels inside that bound, mean
# error 0.054 pixels on the turning cube (vectors of about 10 pixels) and
# less on the others; the mean error per object must stay under 0.1 pixels. A sign, axis, frame or
# projection mix-up fails by whole pixels.
# The same renders tick Cycles' View Layer "Denoising Data" (not our
# scene-wide setting): both engines then write Denoising Albedo, Normal and
# Depth, and the Depth one is compared per pixel like the vectors.

import numpy as np
import pytest

import blender_helpers as bh
from test_passes import interior, neighbour_step


@pytest.fixture(scope="module")
def renders(user_scripts, tmp_path_factory):
    out = tmp_path_factory.mktemp("vector")
    result = bh.run_blender(["--python", bh.REPO_ROOT / "tests" / "blender" / "vector_renders.py", "--", out, 4,
                             "CYCLES", "COHERENT"], user_scripts, timeout=300)
    assert result.returncode == 0, result.describe()
    return {engine: bh.read_image_channels(out / f"{engine}.exr") for engine in ("cycles", "coherent")}


def test_vector_pass_matches_cycles_per_pixel(renders):
    ours, theirs = renders["coherent"], renders["cycles"]
    index = bh.find_channels(theirs, "IndexOB", "X")[..., 0]
    same = bh.find_channels(ours, "IndexOB", "X")[..., 0] == index
    a = bh.find_channels(ours, "Vector", "XYZW").astype(np.float64)
    b = bh.find_channels(theirs, "Vector", "XYZW").astype(np.float64)
    err = np.abs(a - b).max(axis=-1)
    allowed = 0.5 * neighbour_step(b) + 0.02
    for ob in (1, 2, 3):
        inside = interior(index) & same & (index == ob)
        assert inside.sum() > 300, ob
        # Every object moves on screen (at least the camera moves): a real test.
        assert np.abs(b[inside]).max() > 1.0, ob
        assert (err[inside] <= allowed[inside]).all(), (ob, float((err - allowed)[inside].max()))
        assert err[inside].mean() < 0.1, (ob, float(err[inside].mean()))
    world = interior(index) & (index == 0)
    assert (a[world] == 0.0).all()


def test_view_layer_denoising_data_tick_writes_the_feature_passes(renders):
    for engine in ("cycles", "coherent"):
        albedo = bh.find_channels(renders[engine], "Denoising Albedo", "RGB")
        normal = bh.find_channels(renders[engine], "Denoising Normal", "XYZ")
        assert albedo.max() > 0.1 and np.abs(normal).max() > 0.5, engine


def test_denoising_depth_matches_cycles_per_pixel(renders):
    # Denoising Depth is the camera ray's length to these diffuse objects
    # (each feature segment's length times the feature throughput, 1 here),
    # not the Depth pass's view-axis distance. Cycles samples pixel centres,
    # ours spread over the pixel: half a neighbour step is allowed.
    ours, theirs = renders["coherent"], renders["cycles"]
    index = bh.find_channels(theirs, "IndexOB", "X")[..., 0]
    same = bh.find_channels(ours, "IndexOB", "X")[..., 0] == index
    a = bh.find_channels(ours, "Denoising Depth", "Z")[..., 0].astype(np.float64)
    b = bh.find_channels(theirs, "Denoising Depth", "Z")[..., 0].astype(np.float64)
    z = bh.find_channels(theirs, "Depth", "Z")[..., 0].astype(np.float64)
    inside = interior(index) & same & (index > 0)
    assert inside.sum() > 900
    assert (b[inside] > z[inside] * (1 + 1e-4)).mean() > 0.5  # off-axis rays are longer than their view depth
    err = np.abs(a - b)
    allowed = 0.5 * neighbour_step(b) + 1e-3 * b
    assert (err[inside] <= allowed[inside]).all(), float((err - allowed)[inside].max())
    assert (a[interior(index) & (index == 0)] == 0.0).all()  # the world writes no depth
