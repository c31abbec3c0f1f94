# Run inside Blender by test_memory_limit.py: a render over its memory limit
# (COHERENT_MEMORY_LIMIT), then the same render without it, in one session.
# Prints MEMORY_RESULT {"first": ..., "second": [...]}.
import json
import os
import sys

import bpy

out_dir = sys.argv[sys.argv.index("--") + 1]
scene = bpy.context.scene
scene.render.engine = "COHERENT"
scene.render.resolution_percentage = 12
scene.coherent.samples = 2

os.environ["COHERENT_MEMORY_LIMIT"] = "16K"
try:
    first = list(bpy.ops.render.render(write_still=False))
except RuntimeError as e:
    first = f"RuntimeError: {e}"
del os.environ["COHERENT_MEMORY_LIMIT"]

scene.render.filepath = os.path.join(out_dir, "after.png")
scene.render.image_settings.file_format = "PNG"
second = list(bpy.ops.render.render(write_still=True))
print("MEMORY_RESULT " + json.dumps({"first": first, "second": second}))
