# COHERENT and Cycles agree on the light selection scenes of
# blend_scenes/make_scenes.py (issue 10 item 3, issue 11's HDRI world):
#   sun_dim_world   a bright sun with a dim constant world
#   many_lights     40 point and area lights of 0.5 to 200 W
#   emissive_mesh   a large emissive panel (256 triangles) and a dim world
#   hdri_world      Blender's forest.exr through a Mapping node rotated 40 deg
# with COHERENT's default (power-based) light selection and, for the scenes
# where it changes the estimator most, the uniform one it replaced: both are
# unbiased, so both must match Cycles.
#
# Statistics as in test_cycles_agreement.py (its compare(): two seeds per
# engine, the seed difference estimates each engine's noise): per-channel
# means within 2 %, RMSE between the seed averages within K x its noise
# expectation, and every 16x16 block's mean within 5 of its own sigmas.
# Smaller and fewer samples than there (96 x 96 pixels, 64 spp, 3 bounces)
# to keep this entry short; the statistics account for the noise.

import numpy as np
import pytest

import blender_helpers as bh
from seeds import seeded
from test_cycles_agreement import BLOCK_SIGMAS, K, MEAN_TOLERANCE, compare, read_seed_renders

SAMPLES = 64
PERCENT = 19  # 512 -> 97 pixels
MAX_BOUNCES = 3
SEEDS = (seeded(3), seeded(4))

_RENDERS = {}


def render_pair(blender, scene_path, engine, out_dir, setup=()):
    key = (str(scene_path), engine, tuple(setup))
    if key in _RENDERS:
        return _RENDERS[key]
    # SPT: independent pixel errors, as the block statistic assumes.
    statements = ("scene.coherent.sampler = 'SPT'", *setup) if engine == bh.ENGINE_ID else ()
    before = ["--python-expr", bh.python_expr(*statements)] if statements else []
    result = blender(scene_path, *before,
                     "--python", bh.REPO_ROOT / "tests" / "blender" / "render_for_agreement.py",
                     "--", engine, SAMPLES, PERCENT, MAX_BOUNCES, out_dir, *SEEDS, timeout=600)
    # 96 x 96: the blocks the statistic uses, without the partial last row and column.
    images = [rgb[:96, :96] for rgb in read_seed_renders(result, out_dir, engine, SEEDS)]
    _RENDERS[key] = (images, result.stdout + result.stderr)
    return _RENDERS[key]


def describe(name, stats):
    text = (f"light agreement [{name}] {SAMPLES} spp, 96^2 px, {MAX_BOUNCES} bounces, seeds {SEEDS}:\n"
            f"  mean ratio ours/cycles = {', '.join(f'{v:.4f}' for v in stats['mean_ratio'])}\n"
            f"  noise ours {stats['noise_ours']:.5f}, cycles {stats['noise_cycles']:.5f}; "
            f"RMSE ratio {stats['rmse_ratio']:.3f} (bound {K})\n"
            f"  worst 16x16 block {stats['block_z'].max():.2f} sigma (bound {BLOCK_SIGMAS})")
    print(text)
    return text


UNIFORM = ("scene.coherent.uniform_light_selection = True",)
# (The HDRI scene has one emitter, the world: both selections are the same there.)
CASES = [("sun_dim_world.blend", ()), ("many_lights.blend", ()), ("emissive_mesh.blend", ()),
         ("hdri_world.blend", ()), ("many_lights.blend", UNIFORM)]


@pytest.mark.parametrize("scene_file,setup", CASES, ids=lambda v: "uniform" if v == UNIFORM else v or "power")
def test_light_scene_matches_cycles(blender, blend_scenes, tmp_path, scene_file, setup):
    scene_path = blend_scenes / scene_file
    cycles, _ = render_pair(blender, scene_path, "CYCLES", tmp_path / "cycles")
    ours, log = render_pair(blender, scene_path, bh.ENGINE_ID, tmp_path / "ours", setup)
    assert "not supported" not in log, f"the export warned about this scene:\n{log}"
    stats = compare(ours, cycles)
    text = describe(f"{scene_file}, {'uniform' if setup else 'power'} selection", stats)
    assert min(stats["mean_cycles"]) > 0.001
    for ratio in stats["mean_ratio"]:
        assert abs(ratio - 1.0) <= MEAN_TOLERANCE, f"mean differs from Cycles by more than 2 %\n{text}"
    assert stats["rmse_ratio"] <= K, f"difference to Cycles exceeds the noise level\n{text}"
    assert stats["block_z"].max() <= BLOCK_SIGMAS, f"a 16x16 block differs from Cycles beyond its noise\n{text}"


def test_power_selection_has_less_noise_where_lights_differ(blender, blend_scenes, tmp_path):
    """Many lights of varied power: picking by power lowers the per-pixel noise
    (measured in docs/results/light_selection.md); both renders share seeds."""
    scene_path = blend_scenes / "many_lights.blend"
    power, _ = render_pair(blender, scene_path, bh.ENGINE_ID, tmp_path / "power")
    uniform, _ = render_pair(blender, scene_path, bh.ENGINE_ID, tmp_path / "uniform", UNIFORM)
    noise = [float(np.sqrt(np.mean((a - b) ** 2))) for a, b in (power, uniform)]
    print(f"many_lights seed-difference RMS: power {noise[0]:.5f}, uniform {noise[1]:.5f}")
    assert noise[0] < 0.8 * noise[1], noise


def test_world_export_warns_for_unsupported_nodes_and_keeps_the_colour(coherent_addon):
    """Unsupported world nodes warn once, naming the world and the node, and fall
    back to the Background's own colour; a missing image likewise."""
    import bpy
    from coherent import world as world_export
    from coherent import _coherent as native
    world = bpy.data.worlds.new("WarnWorld")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes["Background"]
    bg.inputs["Color"].default_value = (0.2, 0.3, 0.4, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    noise = nodes.new("ShaderNodeTexNoise")
    links.new(noise.outputs["Color"], bg.inputs["Color"])
    warnings = []
    setup = world_export.parse_world(world, warnings)
    assert setup.image is None and setup.color == pytest.approx((0.4, 0.6, 0.8))
    assert len(warnings) == 1 and "WarnWorld" in warnings[0] and noise.name in warnings[0], warnings

    env = nodes.new("ShaderNodeTexEnvironment")
    links.new(env.outputs["Color"], bg.inputs["Color"])
    warnings = []
    setup = world_export.parse_world(world, warnings)
    assert setup.image is None and setup.color == pytest.approx((0.4, 0.6, 0.8))
    assert len(warnings) == 1 and env.name in warnings[0] and "no image" in warnings[0], warnings

    scene = native.Scene()
    with pytest.raises(ValueError, match="channels"):
        scene.set_world_map(np.zeros((4, 8, 2), dtype=np.float32))
    with pytest.raises(ValueError, match="orthonormal"):
        scene.set_world_map(np.ones((4, 8, 3), dtype=np.float32), np.eye(3) * 2.0)
    pixels = np.ones((4, 8, 4), dtype=np.float32)
    pixels[0, 0, 0] = np.nan
    assert scene.set_world_map(pixels) == 1
    assert scene.world_map_size == (8, 4)
    bpy.data.worlds.remove(world)
