# Object motion blur in Blender: the shutter is evaluated at its two ends
# (motion.py), moving instances reach the engine with an open and a close
# transform, and the blurred image matches Cycles rendering the same scene.

from pathlib import Path

import numpy as np

import blender_helpers as bh

SCRIPT = Path(__file__).with_name("motion_scene.py")


def render(blender, engine, blur, tmp_path):
    out = tmp_path / f"{engine.lower()}_{blur}"
    result = blender("--python", SCRIPT, "--", engine, str(blur), out)
    assert result.returncode == 0, result.describe()
    path = Path(str(out) + ".exr")
    assert path.is_file(), result.describe()
    rgb = bh.find_channels(bh.read_image_channels(path), "Combined", "RGBA")[..., :3]
    assert np.isfinite(rgb).all()
    return rgb.mean(axis=2)


def test_motion_blur_smears_the_moving_cube_as_cycles_does(blender, tmp_path):
    sharp = render(blender, bh.ENGINE_ID, 0, tmp_path)
    blurred = render(blender, bh.ENGINE_ID, 1, tmp_path)
    cycles = render(blender, "CYCLES", 1, tmp_path)
    row = slice(6, 10)  # rows through the cube's middle
    sharp_profile, blurred_profile, cycles_profile = (img[row].mean(axis=0) for img in (sharp, blurred, cycles))
    # Without blur the cube's edges are sharp: few partly covered pixels;
    # with a one-frame shutter it sweeps one unit (16 pixels at 4 units
    # across 64): ramps of partial coverage on both sides.
    partial = lambda p: int(((p > 0.05) & (p < 0.95)).sum())  # noqa: E731
    assert partial(sharp_profile) <= 4, sharp_profile
    assert partial(blurred_profile) >= 20, blurred_profile
    # Energy is conserved: the blur spreads the cube, it does not dim it.
    assert abs(blurred_profile.sum() - sharp_profile.sum()) < 0.05 * sharp_profile.sum()
    # Cycles, the independent oracle, blurs the same way (256 spp each).
    assert np.abs(blurred_profile - cycles_profile).max() < 0.08, (blurred_profile, cycles_profile)
    assert np.abs(blurred_profile - cycles_profile).mean() < 0.02
