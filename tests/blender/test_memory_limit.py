# A render that does not fit in memory fails with a clear error and leaves
# Blender working: the native renderer's check before building raises
# MemoryError naming the sizes, the engine reports it as an ERROR, and the
# next render in the same session succeeds and reports its memory.

import json
import re
from pathlib import Path

import numpy as np

import blender_helpers as bh

HERE = Path(__file__).resolve().parent


def test_a_render_over_the_memory_limit_fails_cleanly_and_blender_renders_again(blender, blend_scenes, tmp_path):
    result = blender(blend_scenes / "cornell_box.blend", "--python", HERE / "memory_limit_render.py", "--", tmp_path)
    assert result.returncode == 0, result.describe()
    line = next((l for l in result.stdout.splitlines() if l.startswith("MEMORY_RESULT ")), None)
    assert line is not None, result.describe()
    info = json.loads(line.split(" ", 1)[1])

    # The error names what did not fit and the limit, as an ERROR report, not a traceback.
    error = next((l for l in result.output.splitlines() if "not enough memory" in l), None)
    assert error is not None, result.describe()
    assert "Coherent:" in error and "COHERENT_MEMORY_LIMIT=16K" in error and "16.0 KiB" in error, error
    assert re.search(r"\d+ triangles", error), error
    assert "Traceback" not in result.output, result.describe()

    # Blender kept working: the next render finished and wrote its image.
    assert info["second"] == ["FINISHED"], info
    rgb = np.stack([bh.read_image_channels(tmp_path / "after.png")[c] for c in "RGB"], axis=-1)
    assert np.isfinite(rgb).all() and rgb.mean() > 0.02
    memory = re.search(r"Coherent: memory: peak ([\d.]+) (MiB|GiB), ([\d,]+) triangles at (\d+) bytes each",
                       result.stdout)
    assert memory, result.describe()
    assert 50 <= int(memory.group(4)) <= 5000  # the Cornell box: few triangles, fixed costs per triangle
