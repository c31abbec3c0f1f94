# Run by test_robustness.py::test_cancel_then_render_again inside a
# subprocess Blender (after loading blend_scenes/cornell_box.blend):
#
#   blender -b cornell_box.blend --addons coherent --python cancel_render.py -- OUT_DIR
#
# 1. Starts an in-process final render that could never finish (2^24 samples
#    per pixel) and cancels it from another thread through the native
#    module's Renderer.cancel() (documented as safe from any thread), as
#    events rather than after a delay: the first progress report the engine
#    receives hands over to a canceller thread and waits until cancel() has
#    returned there. From then on the render must report no more progress
#    and complete no further pass. The engine constructs its renderer as
#    `_coherent.Renderer(...)`, so wrapping that module attribute gives us the
#    instance (behind a proxy that also wraps its progress callback).
#    (RenderEngine.test_break(), which Esc drives, cannot be overridden from
#    Python: RNA functions take precedence over Python attributes, and
#    background Blender has no Esc key.)
# 2. After it returned, renders again normally and writes OUT_DIR/after.png.
#
# Prints one line "CANCEL_RESULT {json}" for the test to check.

import json
import sys
import threading

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
events = {"reports": 0, "reports_after_cancel": 0, "done_at_cancel": None}


class CancellingRenderer:
    """The real renderer, whose render() cancels from another thread at the first progress report."""

    def __init__(self, real):
        self._real = real
        self._asked = threading.Event()
        self._cancelled = threading.Event()
        self.canceller = threading.Thread(target=self._cancel_when_asked, name="test-canceller")
        self.canceller.start()

    def _cancel_when_asked(self):
        self._asked.wait()
        self._real.cancel()
        self._cancelled.set()

    def __getattr__(self, name):
        return getattr(self._real, name)

    def render(self, progress):
        def wrapped(p):
            keep_going = progress(p)
            events["reports"] += 1
            if events["done_at_cancel"] is not None:
                events["reports_after_cancel"] += 1
            else:
                events["done_at_cancel"] = p["samples_done"]
                self._asked.set()
                self._cancelled.wait()
            return keep_going
        try:
            return self._real.render(wrapped)
        finally:
            self._asked.set()  # a render that never reported still lets the canceller end
            self.canceller.join()


def cancelling_renderer(*args, **kwargs):
    renderer = CancellingRenderer(RealRenderer(*args, **kwargs))
    created.append(renderer)
    return renderer


threads_before = threading.active_count()
native.Renderer = cancelling_renderer
try:
    first = bpy.ops.render.render()
finally:
    native.Renderer = RealRenderer
cancelled = [bool(r.cancelled) for r in created]
passes_done = [r.stats()["spp"] for r in created]
del created[:]

scene.coherent.samples = 4
scene.render.image_settings.file_format = "PNG"
scene.render.filepath = f"{out_dir}/after.png"
second = bpy.ops.render.render(write_still=True)

print("CANCEL_RESULT " + json.dumps({
    "first": sorted(first), "second": sorted(second),
    "renderers_created": len(cancelled), "renderers_cancelled": sum(cancelled),
    "reports": events["reports"], "reports_after_cancel": events["reports_after_cancel"],
    "passes_done_at_cancel": events["done_at_cancel"], "passes_done": passes_done,
    "python_threads_before": threads_before, "python_threads_after": threading.active_count(),
}))
sys.stdout.flush()
