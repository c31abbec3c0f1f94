# Cycles' render passes in Blender (View Layer > Passes): our engine and
# Cycles render scenes blend_scenes/make_scenes.py builds with the same
# passes ticked, into multilayer EXRs (pass_renders.py), and the passes
# agree:
# - light passes (Diffuse/Glossy/Transmission Direct, Indirect, Color,
#   Emission, Environment, AO): per-channel image means within 3 % on
#   emissive_mesh.blend (diffuse, rough metal, an emissive mesh, a dim
#   world) at 1024 spp on 51 x 51 pixels; measured 0.0-1.1 % apart (also on
#   sun_dim_world.blend). On glass_scene.blend the passes free of caustics
#   are compared at 256 spp. Its Ind passes are dominated by a few caustic
#   fireflies at any affordable sample count (at 1024 spp: GlossInd 0.6 %,
#   DiffInd 1-3 %, TransInd 3 % apart), and its GlossDir by the small
#   reflections of the point light in the glass sphere: they cover a
#   fraction of a pixel, so each engine's value there is mostly noise (no
#   bias: docs/results/point_light_reflections.md, test_light_paths.py
#   compares them magnified), so those are not asserted there;
# - ours add up to our Combined per pixel: (Dir + Ind) x Col + Emit + Env;
# - data passes (Mist, Position, UV, Depth, IndexOB, IndexMA): per pixel, on
#   pixels inside one object (Cycles' IndexOB the same in the 3 x 3
#   neighbourhood). Cycles samples the pixel centre (filter width 0.01),
#   ours a random point of the pixel, so continuous passes may differ by the
#   largest step to a neighbouring pixel, no more. UV reads the active
#   render UV map, which no material uses (pass_renders.add_uv_maps), and
#   is (u, v, 1) on every object, which the test checks on its own; two
#   linked copies of a sphere check it (and the others) on instances.

import numpy as np
import pytest

import blender_helpers as bh

LIGHT_PASSES = ("DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol", "TransDir", "TransInd",
                "TransCol", "Emit", "Env", "AO")
MEAN_TOLERANCE = 0.03


def render(user_scripts, scene_file, out, mode, samples, percent=10):
    result = bh.run_blender([scene_file, "--python", bh.REPO_ROOT / "tests" / "blender" / "pass_renders.py",
                             "--", out, percent, samples, mode, "CYCLES", "COHERENT"], user_scripts, timeout=600)
    assert result.returncode == 0, result.describe()
    return {engine: bh.read_image_channels(out / f"{engine}.exr") for engine in ("cycles", "coherent")}


def rgb(channels, name):
    return bh.find_channels(channels, name, "RGB").astype(np.float64)


@pytest.fixture(scope="module")
def glass_light(user_scripts, tmp_path_factory):
    return render(user_scripts, bh.BLEND_SCENES / "glass_scene.blend", tmp_path_factory.mktemp("glass"), "light", 256)


@pytest.fixture(scope="module")
def emissive_light(user_scripts, tmp_path_factory):
    return render(user_scripts, bh.BLEND_SCENES / "emissive_mesh.blend", tmp_path_factory.mktemp("emissive"),
                  "light", 1024)


@pytest.fixture(scope="module")
def glass_data(user_scripts, tmp_path_factory):
    return render(user_scripts, bh.BLEND_SCENES / "glass_scene.blend", tmp_path_factory.mktemp("data"), "data", 1, 25)


def mean_mismatches(renders, names=LIGHT_PASSES):
    """Light passes whose per-channel mean differs from Cycles' by more than 3 %
    of the larger of that mean and 1 % of Combined's mean (an empty pass,
    such as TransDir without glass, is compared absolutely)."""
    floor = 0.01 * rgb(renders["cycles"], "Combined").mean()
    bad = {}
    for name in names:
        ours = rgb(renders["coherent"], name).mean(axis=(0, 1))
        theirs = rgb(renders["cycles"], name).mean(axis=(0, 1))
        if (np.abs(ours - theirs) > MEAN_TOLERANCE * np.maximum(np.abs(theirs), floor)).any():
            bad[name] = (ours.round(4).tolist(), theirs.round(4).tolist())
    return bad


def test_light_passes_match_cycles_glass_scene(glass_light):
    names = ("DiffDir", "DiffCol", "GlossCol", "TransDir", "TransCol", "Env", "AO")
    assert mean_mismatches(glass_light, names) == {}
    # Glass shows in its passes: Col of the sphere's refraction and reflection.
    assert rgb(glass_light["coherent"], "TransCol").mean() > 0.05


def test_light_passes_match_cycles_emissive_mesh(emissive_light):
    assert mean_mismatches(emissive_light) == {}
    # The scene has what Emit shows: an emitter the camera sees (the world it
    # does not: Env is tested in tests/native/test_passes.cpp).
    assert rgb(emissive_light["coherent"], "Emit").mean() > 1e-3


@pytest.mark.parametrize("scene", ["glass_light", "emissive_light"])
def test_light_passes_add_up_to_combined(scene, request):
    ch = request.getfixturevalue(scene)["coherent"]
    total = rgb(ch, "Emit") + rgb(ch, "Env")
    for lobe in ("Diff", "Gloss", "Trans"):
        total += (rgb(ch, lobe + "Dir") + rgb(ch, lobe + "Ind")) * rgb(ch, lobe + "Col")
    combined = rgb(ch, "Combined")
    assert np.abs(total - combined).max() <= 1e-4 * max(1.0, np.abs(combined).max())


def interior(index):
    """Pixels whose 3 x 3 neighbourhood shows one object."""
    h, w = index.shape
    inside = np.zeros_like(index, dtype=bool)
    c = index[1:-1, 1:-1]
    same = np.ones_like(c, dtype=bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            same &= index[1 + dy:h - 1 + dy, 1 + dx:w - 1 + dx] == c
    inside[1:-1, 1:-1] = same
    return inside


def neighbour_step(image):
    """Per pixel, the largest absolute difference to its 8 neighbours (interior pixels)."""
    h, w = image.shape[:2]
    step = np.zeros(image.shape[:2])
    c = image[1:-1, 1:-1]
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            d = np.abs(image[1 + dy:h - 1 + dy, 1 + dx:w - 1 + dx] - c)
            step[1:-1, 1:-1] = np.maximum(step[1:-1, 1:-1], d.max(axis=-1) if d.ndim == 3 else d)
    return step


def test_data_passes_match_cycles_per_pixel(glass_data):
    ours, theirs = glass_data["coherent"], glass_data["cycles"]
    index_ob = bh.find_channels(theirs, "IndexOB", "X")[..., 0]
    inside = interior(index_ob) & (index_ob > 0)
    assert inside.sum() > 500
    for name in ("IndexOB", "IndexMA"):
        a, b = bh.find_channels(ours, name, "X")[..., 0], bh.find_channels(theirs, name, "X")[..., 0]
        assert (a[inside] == b[inside]).all(), name
    for name, chans in (("Mist", "Z"), ("Depth", "Z"), ("Position", "XYZ"), ("UV", "UVA")):
        a = bh.find_channels(ours, name, chans).astype(np.float64)
        b = bh.find_channels(theirs, name, chans).astype(np.float64)
        allowed = neighbour_step(b) + 1e-4 * (1.0 + np.abs(b).max(axis=-1))
        err = np.abs(a - b).max(axis=-1)
        assert (err[inside] <= allowed[inside]).all(), (name, float((err - allowed)[inside].max()))


def test_uv_pass_reads_the_active_render_map(glass_data):
    """The UV pass shows the "Render" map with A = 1 on objects: on the floor
    its V varies, where the other map ("Decoy") is a constant."""
    ours = glass_data["coherent"]
    uva = bh.find_channels(ours, "UV", "UVA").astype(np.float64)
    index_ob = bh.find_channels(glass_data["cycles"], "IndexOB", "X")[..., 0]
    inside = interior(index_ob) & (index_ob > 0)
    assert (uva[..., 2][inside] == 1.0).all()
    floor = inside & (np.abs(bh.find_channels(ours, "Position", "Z")[..., 0]) < 1e-3)
    assert floor.sum() > 100
    assert np.ptp(uva[..., 1][floor]) > 0.2
