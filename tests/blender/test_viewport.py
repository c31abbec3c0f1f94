# The interactive viewport (addon/coherent/viewport.py).
#
# test_incremental_updates: headless; every kind of edit must be applied
# incrementally (no mesh re-extracted and the BVH refit, not rebuilt, for
# transforms; no BVH rebuilt for camera/material/light/world edits) and the incrementally updated scene must
# render exactly like a scene exported from scratch (the independent oracle).
#
# test_rendered_viewport_in_a_window: real Blender in an X window (Xvfb,
# Mesa's software OpenGL), driven by viewport_gui.py as a person would use
# it; assertions on the screenshots' pixels and on threads and memory.

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import blender_helpers as bh

HERE = Path(__file__).resolve().parent


def _counter_deltas(step):
    before, after = step["before"]["counters"], step["after"]["counters"]
    return {k: after[k] - before[k] for k in after if after[k] != before[k]}


@pytest.fixture(scope="module")
def updates_report(user_scripts, blend_scenes, tmp_path_factory):
    out = tmp_path_factory.mktemp("viewport_updates") / "updates.json"
    result = bh.run_blender([blend_scenes / "cornell_box.blend", "--python", HERE / "viewport_updates.py", "--",
                             out], user_scripts, timeout=300)
    assert result.returncode == 0 and out.is_file(), result.describe()
    return json.loads(out.read_text())


def test_view_camera_matches_render_camera(updates_report):
    # The viewport's camera from a 3D View's matrices equals the final
    # render's camera (lens, shift, sensor fit, orthographic scale, clipping).
    for name, diffs in updates_report["view_camera"].items():
        assert diffs.pop("projection_equal"), name
        for key, diff in diffs.items():
            assert diff < 1e-5, f"{name}: {key} differs by {diff} (relative)"


def test_incremental_updates(updates_report):
    steps = {k: v for k, v in updates_report.items() if k != "view_camera"}

    for name, step in steps.items():
        # The oracle: the same edit exported from scratch renders identically.
        assert step["max_diff"] < 1e-5, f"{name}: incremental scene differs from a fresh export by {step['max_diff']}"
        assert step["mean"] > 0.01, f"{name}: black image"

    # A camera-only change reuses the BVH.
    assert steps["camera"]["bvh_reused"] and _counter_deltas(steps["camera"]) == {}
    # A transform re-exports the scene from the cache (nothing re-extracted)
    # and refits the previous BVH instead of building one; the oracle above
    # shows the refit BVH finds exactly the hits of a freshly built one.
    t = steps["transform"]
    assert t["before"]["has_bvh"], "the transform step needs a BVH to refit"
    assert _counter_deltas(t) == {"full_exports": 1, "transform_updates": 1, "bvh_refits": 1}
    assert t["after"]["extracted"] == t["before"]["extracted"]
    assert t["after"]["has_bvh"] and t["bvh_reused"], "the transform edit did not keep a (refit) BVH"
    r = steps["rotate_scale"]
    assert _counter_deltas(r) == {"full_exports": 1, "transform_updates": 1, "bvh_refits": 1}
    assert r["bvh_reused"]
    # Material, light and world edits keep the scene's triangles and BVH.
    for name, counter in (("material", "material_updates"), ("light_energy", "light_updates"),
                          ("light_move", "light_updates"), ("world", "world_updates")):
        step = steps[name]
        assert _counter_deltas(step) == {counter: 1}, (name, _counter_deltas(step))
        assert step["bvh_reused"], f"{name}: the BVH was rebuilt"
        assert step["after"]["extracted"] == step["before"]["extracted"]
    # The edits were visible: the green material darkened the white box, the
    # doubled light brightened the image.
    assert steps["material"]["mean"] < steps["transform"]["mean"] - 0.005
    assert steps["light_energy"]["mean"] > steps["material"]["mean"] + 0.005
    # A mesh edit re-extracts exactly the edited mesh.
    m = steps["mesh_edit"]
    assert m["after"]["extracted"] == m["before"]["extracted"] + 1
    assert not m["bvh_reused"]
    assert _counter_deltas(m).get("bvh_refits", 0) == 0
    # Deleting an object removes its triangles and its cache entry.
    d = steps["delete"]
    assert d["after"]["triangles"] < d["before"]["triangles"]
    assert not d["bvh_reused"] and _counter_deltas(d).get("bvh_refits", 0) == 0, "a changed triangle set must rebuild"
    assert d["after"]["cached_meshes"] == d["before"]["cached_meshes"] - 1


def _blocks(image, n):
    """Mean of each cell of an n x n grid over the image (H, W, C)."""
    h, w = image.shape[:2]
    ys, xs = np.linspace(0, h, n + 1).astype(int), np.linspace(0, w, n + 1).astype(int)
    return np.array([[image[ys[i]:ys[i + 1], xs[j]:xs[j + 1]].mean(axis=(0, 1)) for j in range(n)]
                     for i in range(n)])


def _xvfb_blender(script, blend, out_dir, user_scripts, timeout):
    xvfb = shutil.which("xvfb-run")
    if xvfb is None:
        pytest.fail("xvfb-run is missing: install the Debian package xvfb (setup.sh does)")
    cmd = [xvfb, "-a", "-s", "-screen 0 1280x800x24", bh.blender_binary(), "--factory-startup",
           "--python-exit-code", "1", "--addons", bh.ADDON_MODULE, str(blend), "--python", str(script), "--",
           str(out_dir)]
    env = dict(os.environ)
    env["BLENDER_USER_SCRIPTS"] = str(user_scripts)
    env["BLENDER_USER_CONFIG"] = str(Path(user_scripts).parent / "config")
    env["TMPDIR"] = str(out_dir)  # Blender's quit.blend lands here, not in /tmp
    env.pop("PYTHONPATH", None)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env, cwd=str(out_dir))
    return bh.BlenderResult(cmd, proc)


def test_rendered_viewport_in_a_window(user_scripts, blend_scenes, tmp_path):
    result = _xvfb_blender(HERE / "viewport_gui.py", blend_scenes / "cornell_box.blend", tmp_path, user_scripts,
                           timeout=240)
    report = tmp_path / "result.json"
    assert report.is_file(), result.describe()
    r = json.loads(report.read_text())
    assert "error" not in r, r["error"] + "\n" + result.describe()
    assert r.get("ok"), result.describe()
    # Quitting while the viewport renders: a clean exit, no crash.
    assert result.returncode == 0, result.describe()
    assert "Segmentation fault" not in result.output and "Traceback" not in result.output, result.describe()

    shot1, shot2 = np.load(tmp_path / "shot1.npy"), np.load(tmp_path / "shot2.npy")
    assert shot1.shape == shot2.shape == (r["region"][1], r["region"][0], 3)

    # 1. The first screenshot shows what F12 renders from the same camera:
    # crop the camera frame, compare 16 x 16 cell means (noise averages out).
    x0, y0, x1, y1 = r["camera_rect"]
    crop = shot1[int(np.ceil(y0)) + 1:int(y1) - 1, int(np.ceil(x0)) + 1:int(x1) - 1]
    final = bh.read_image_channels(tmp_path / "final.png")
    final = np.stack([final[c] for c in "RGB"], axis=-1)[::-1]  # bottom row first, like the screenshot
    a, f = _blocks(crop, 16), _blocks(final, 16)
    assert f.mean() > 0.1, "the final render is dark: the scene did not render"
    diff = np.abs(a - f)
    correlation = np.corrcoef(a.ravel(), f.ravel())[0, 1]
    assert diff.mean() < 0.03 and diff.max() < 0.15 and correlation > 0.97, \
        f"viewport vs final render: mean {diff.mean():.4f}, max {diff.max():.4f}, correlation {correlation:.4f}"

    # 2. The second screenshot differs where the tall box moved, and much
    # less elsewhere in the frame (shadows and bounce light change a little).
    change = np.abs(shot2 - shot1).mean(axis=-1)
    b0, b1 = r["box_rect_before"], r["box_rect_after"]
    moved = np.zeros(change.shape, bool)
    moved[int(min(b0[1], b1[1])):int(max(b0[3], b1[3])), int(min(b0[0], b1[0])):int(max(b0[2], b1[2]))] = True
    frame = np.zeros(change.shape, bool)
    frame[int(np.ceil(y0)) + 1:int(y1) - 1, int(np.ceil(x0)) + 1:int(x1) - 1] = True
    inside, outside = change[moved].mean(), change[frame & ~moved].mean()
    assert inside > 0.05 and inside > 4.0 * outside, f"change where the box moved {inside:.4f}, elsewhere {outside:.4f}"
    # The move re-exported no mesh.
    assert r["extracted_2"] == r["extracted_1"]
    # It refit the BVH: no rebuild.
    c1, c2 = r["counters_1"], r["counters_2"]
    assert c2["transform_updates"] > c1["transform_updates"] and c2["bvh_refits"] > c1["bvh_refits"]
    assert c2["geometry_rebuilds"] == c1["geometry_rebuilds"] and c2["bvh_builds"] == c1["bvh_builds"]

    # 3. Closing the Rendered view stops the render thread and frees it:
    # the thread count returns to what it was without a viewport render
    # (allowing for the thread the F12 render left in Blender's job system),
    # and repeated open/close cycles neither add threads nor grow memory.
    baseline = max(r["threads_before"], r["threads_after_final_render"])
    assert all(t <= baseline for t in r["threads_after_close"]), (r["threads_before"], r["threads_after_close"])
    assert all(t > c for t, c in zip(r["threads_rendering_cycle"], r["threads_after_close"])), \
        "no render thread seen while rendering"
    rss = r["rss_after_close"]
    assert rss[-1] - rss[0] < 40.0, f"memory grows across viewport sessions: {rss} MB"
