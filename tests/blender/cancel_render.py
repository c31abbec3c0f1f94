# Run by test_robustness.py::test_cancel_then_render_again inside a
# subprocess Blender (after loading blend_scenes/cornell_box.blend):
#
#   blender -b cornell_box.blend --addons coherent --python cancel_render.py -- OUT_DIR
#
# 1. Starts an in-process final render that could never finish (2^24 samples
#    per pixel) and cancels it one second later from a timer thread through
#    the native module's Renderer.cancel() (documented as safe from any
#    thread). The engine constructs its renderer as `_coherent.Renderer(...)`,
#    so wrapping that module attribute gives us the instance.
#    (RenderEngine.test_break(), which Esc drives, cannot be overridden from
#    Python: RNA functions take precedence over Python attributes, and
#    background Blender has no Esc key.)
# 2. After it returned, renders again normally and writes OUT_DIR/after.png.
#
# Prints one line "CANCEL_RESULT {json}" for the test to check.

import json
import sys
import threading
import time

import bpy

import coherent  # enabled by --addons before this script runs

out_dir = sys.argv[sys.argv.index("--") + 1]
scene = bpy.context.scene
scene.render.engine = "COHERENT"
scene.render.resolution_percentage = 12
scene.coherent.samples = 1 << 24

native = coherent.native_module()
RealRenderer = native.Renderer
created = []
timers = []


def cancelling_renderer(*args, **kwargs):
    renderer = RealRenderer(*args, **kwargs)
    created.append(renderer)
    timer = threading.Timer(1.0, renderer.cancel)
    timers.append(timer)
    timer.start()
    return renderer


threads_before = threading.active_count()
native.Renderer = cancelling_renderer
start = time.monotonic()
try:
    first = bpy.ops.render.render()
finally:
    native.Renderer = RealRenderer
cancel_seconds = time.monotonic() - start - 1.0
for timer in timers:
    timer.join()
cancelled = [bool(r.cancelled) for r in created]
del created[:]

scene.coherent.samples = 4
scene.render.image_settings.file_format = "PNG"
scene.render.filepath = f"{out_dir}/after.png"
second = bpy.ops.render.render(write_still=True)

print("CANCEL_RESULT " + json.dumps({
    "first": sorted(first), "second": sorted(second),
    "seconds_after_cancel": cancel_seconds,
    "renderers_created": len(cancelled), "renderers_cancelled": sum(cancelled),
    "python_threads_before": threads_before, "python_threads_after": threading.active_count(),
}))
sys.stdout.flush()
