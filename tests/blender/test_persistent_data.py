# Persistent data (scene.render.use_persistent_data) in final renders: a
# farm-style `blender -b -s 1 -e 3 -a` run keeps the engine between frames,
# and the kept meshes and BVHs must not change a pixel.
#
# Oracle: the same frames rendered with persistent data off, which exports
# and builds everything anew per frame (the path every other test covers).
# The seed is the same on every frame, so equal scenes give equal pixels;
# a refit BVH finds the same hits as a rebuilt one, and a kept prototype
# BVH the same as one built again. One exception, by design: once a mesh
# has changed geometry, persistent data gives it a BVH of its own (a
# prototype placed once, persistent.py) so that its next change rebuilds
# it alone; its hits then go through a transform and round differently,
# so those frames agree with the fresh ones within float rounding.

import re
from pathlib import Path

import numpy as np
import pytest

import blender_helpers as bh

SCRIPT = Path(__file__).with_name("persistent_scene.py")
SUMMARY = re.compile(r"^Coherent: persistent data: (\d+) meshes reused, (\d+) (?:re-)?extracted, BVH (refit|built) in "
                     r"[\d.]+ ms(?:, instanced BVHs: (\d+) reused, (\d+) built)?$", re.MULTILINE)


def render_frames(user_scripts, tmp_path, mode, persistent):
    out = tmp_path / f"{mode}_{persistent}_####"
    result = bh.run_blender(["--python", SCRIPT, "-o", out, "-s", "1", "-e", "3", "-a", "--", mode, str(persistent)],
                            user_scripts)
    assert result.returncode == 0, result.describe()
    frames = []
    for frame in (1, 2, 3):
        path = tmp_path / f"{mode}_{persistent}_{frame:04d}.exr"
        assert path.is_file(), result.describe()
        channels = bh.read_image_channels(path)
        frames.append(np.stack([channels[c] for c in "RGBA"], axis=-1))
    return frames, [m.groups() for m in SUMMARY.finditer(result.stdout)], result


@pytest.fixture(scope="module", params=["move", "deform"])
def renders(request, user_scripts, tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp(request.param)
    kept = render_frames(user_scripts, tmp_path, request.param, 1)
    fresh = render_frames(user_scripts, tmp_path, request.param, 0)
    return request.param, kept, fresh


def assert_same_image(kept, fresh, exact, what):
    assert np.isfinite(kept).all(), what
    if exact:
        assert np.array_equal(kept, fresh), f"{what}: max difference {np.abs(kept - fresh).max()}"
        return
    # Hits through a transform: the same surfaces at points a few ulps
    # apart, so the same paths, except where one grazes an edge.
    close = np.abs(kept - fresh) <= 1e-4 * np.maximum(1.0, np.abs(fresh))
    assert close.mean() > 0.99, f"{what}: {100 * (1 - close.mean()):.2f} % of values differ"
    assert np.abs(kept.mean() - fresh.mean()) <= 1e-3 * fresh.mean(), what


def test_frames_equal_without_persistent_data(renders):
    mode, (kept, _, _), (fresh, _, _) = renders
    for frame, (a, b) in enumerate(zip(kept, fresh), start=1):
        # The deforming floor has a BVH of its own from frame 2 on.
        assert_same_image(a, b, exact=mode == "move" or frame == 1, what=f"frame {frame}")
    # The animation did animate (else equal frames would prove little).
    assert np.abs(kept[0] - kept[2]).max() > 0.1


def test_summary_reports_reuse(renders):
    mode, (_, summaries, result), (_, off_summaries, _) = renders
    assert off_summaries == [], "persistent data off must keep nothing"
    assert len(summaries) == 3, result.describe()
    # Meshes: the cube, the floor and the spheres' one shared mesh.
    assert summaries[0] == ("0", "3", "built", None, None), result.describe()
    if mode == "move":
        # Only the cube moved: every mesh is reused, the world-space BVH
        # refit and the spheres' prototype BVH kept.
        assert summaries[1:] == [("3", "0", "refit", "1", "0")] * 2, result.describe()
    else:
        # The floor's shape key changed its geometry: it alone is extracted
        # again. On frame 2 it leaves the world-space BVH for one of its own
        # (so that BVH is rebuilt once); on frame 3 only the floor's BVH is
        # built, the cube's world-space BVH is refit and the spheres' kept.
        assert summaries[1] == ("2", "1", "built", "1", "1"), result.describe()
        assert summaries[2] == ("2", "1", "refit", "1", "1"), result.describe()


def test_edit_between_renders(user_scripts, tmp_path):
    # F12, an edit of the floor's vertices, F12 again: the edited mesh is
    # extracted again (the depsgraph reports its geometry update) and the
    # second image is the one a fresh render of the edited scene gives.
    images, summaries = {}, {}
    for persistent in (1, 0):
        out = tmp_path / f"edit_{persistent}"
        result = bh.run_blender(["--python", SCRIPT, "--", "edit", str(persistent), out], user_scripts)
        assert result.returncode == 0, result.describe()
        images[persistent] = [bh.read_image_channels(Path(f"{out}_{k}.exr"))["R"] for k in "ab"]
        summaries[persistent] = [m.groups() for m in SUMMARY.finditer(result.stdout)]
    assert summaries[1] == [("0", "3", "built", None, None), ("2", "1", "built", "1", "1")], summaries
    for k, (kept, fresh) in enumerate(zip(images[1], images[0])):
        assert_same_image(kept, fresh, exact=k == 0, what=f"render {k + 1}")
    assert np.abs(images[1][0] - images[1][1]).max() > 0.1, "the edit changed nothing visible"


def test_performance_panel_shows_persistent_data(coherent_addon):
    # The setting the engine reads must be where a user looks for it
    # (Cycles shows it under Performance too).
    import bpy
    from coherent import ui
    from test_tracing_settings import draw_panel
    shown = draw_panel(ui.RENDER_PT_coherent_performance, bpy.context.scene)
    assert shown.get("use_persistent_data") is True, shown
