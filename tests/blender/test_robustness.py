# Renders that must survive bad input, fail loudly on impossible input, and
# stop promptly when cancelled.

import json
import re
from pathlib import Path

import numpy as np

import blender_helpers as bh

HERE = Path(__file__).resolve().parent
SMALL = bh.python_expr("scene.render.resolution_percentage = 12", "scene.coherent.samples = 4")


def test_broken_mesh_and_unsupported_nodes_still_render(blender, blend_scenes, tmp_path):
    result = blender(blend_scenes / "cornell_box.blend", "--python", HERE / "broken_scene.py",
                     "--python-expr", SMALL, "-E", bh.ENGINE_ID, "-o", tmp_path / "broken_####",
                     "-F", "PNG", "-f", "1")
    assert "broken_scene: added" in result.stdout, result.describe()
    out = tmp_path / "broken_0001.png"
    assert result.returncode == 0, result.describe()
    assert out.is_file(), result.describe()
    rgb = np.stack([bh.read_image_channels(out)[c] for c in "RGB"], axis=-1)
    assert np.isfinite(rgb).all()
    assert rgb.mean() > 0.02, "the Cornell box must still be visible"

    # Only the engine's lines: broken_scene.py's own message names the defects too.
    text = "\n".join(l for l in result.output.splitlines() if not l.startswith("broken_scene:"))
    # The user is told about each problem (wording is the add-on's; these are
    # the facts every message must name).
    assert "Toon" in text and "ToonMaterial" in text, f"no warning about the Toon BSDF\n{result.describe()}"
    assert "TexturedMaterial" in text and "Base Color" in text, \
        f"no warning about the texture-driven input\n{result.describe()}"
    broken_lines = [l.lower() for l in text.splitlines() if "BrokenObject" in l]
    assert any(("nan" in l or "non-finite" in l) and "degenerate" in l for l in broken_lines), \
        f"no report of the NaN vertex and degenerate triangles of BrokenObject\n{result.describe()}"
    # Exactly the 3 bad triangles are dropped: 34 (box) + 12 (textured cube)
    # + 4 (broken mesh) - 3 = 47 remain.
    assert re.search(r"Coherent: finished \d+x\d+, 4 spp, 47 triangles", result.stdout), result.describe()


def test_no_camera_fails_loudly(blender, blend_scenes, tmp_path):
    remove_camera = bh.python_expr("bpy.data.objects.remove(bpy.data.objects['Camera'])")
    result = blender(blend_scenes / "cornell_box.blend", "--python-expr", remove_camera, "-E", bh.ENGINE_ID,
                     "-o", tmp_path / "nocam_####", "-F", "PNG", "-f", "1")
    assert result.returncode != 0, result.describe()
    assert "camera" in result.output.lower(), result.describe()
    assert not (tmp_path / "nocam_0001.png").exists(), "a failed render must not leave an image behind"


def test_export_error_fails_loudly(blender, blend_scenes, tmp_path):
    # Blender accepts any object as scene camera; our exporter cannot render
    # from an Empty and must say so, not write a blank image.
    empty_camera = bh.python_expr(
        "e = bpy.data.objects.new('NotACamera', None)", "scene.collection.objects.link(e)",
        "e.location = (0, -6.8, 1)", "scene.camera = e")
    result = blender(blend_scenes / "cornell_box.blend", "--python-expr", empty_camera, "--python-expr", SMALL,
                     "-E", bh.ENGINE_ID, "-o", tmp_path / "empty_####", "-F", "PNG", "-f", "1")
    assert result.returncode != 0, result.describe()
    assert "NotACamera" in result.output and "not a camera" in result.output, result.describe()
    assert not (tmp_path / "empty_0001.png").exists(), "a failed render must not leave an image behind"


def test_cancel_then_render_again(blender, blend_scenes, tmp_path):
    # A subprocess, so that a cancel that never happens shows up as a timeout
    # of this test instead of a hung test session. The first render asks for
    # 2^24 samples per pixel: it can only return because it was cancelled
    # (at its first progress report, from another thread: cancel_render.py).
    result = blender(blend_scenes / "cornell_box.blend", "--python", HERE / "cancel_render.py", "--", tmp_path,
                     timeout=240)
    assert result.returncode == 0, result.describe()
    line = next((l for l in result.stdout.splitlines() if l.startswith("CANCEL_RESULT ")), None)
    assert line is not None, result.describe()
    info = json.loads(line.split(" ", 1)[1])
    print("cancel:", info)
    assert info["renderers_created"] == 1 and info["renderers_cancelled"] == 1, info
    # Prompt, by events: after cancel() returned on the other thread the
    # render reported no more progress and completed no further pass.
    assert info["passes_done_at_cancel"] is not None, info
    assert info["reports_after_cancel"] == 0, info
    assert info["passes_done"] == [info["passes_done_at_cancel"]], info
    # The engine noticed and said so (its summary line), rather than finishing.
    assert re.search(r"Coherent: cancelled \d+x\d+", result.stdout), result.describe()
    # After the cancel Blender still renders normally.
    assert info["second"] == ["FINISHED"], info
    after = tmp_path / "after.png"
    assert after.is_file()
    rgb = np.stack([bh.read_image_channels(after)[c] for c in "RGB"], axis=-1)
    assert np.isfinite(rgb).all() and rgb.mean() > 0.02
    assert info["python_threads_after"] == info["python_threads_before"], "a Python thread was left behind"
