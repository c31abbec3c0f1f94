# SPDX-License-Identifier: Apache-2.0
"""Interactive viewport rendering ("Rendered" shading in the 3D View).

One ViewportSession per viewport RenderEngine instance owns three parts:
- viewport_sync.SceneSync: depsgraph updates into the native scene,
  re-exporting only what changed (view_update);
- viewport_render.ProgressiveRender: the native render of the current scene
  and view, restarted coarse-to-fine after every change;
- viewport_draw.ViewportDisplay: the latest completed pass as a GPU texture,
  drawn in view_draw, and the redraws while the render refines.

Threads: every bpy access happens on Blender's main thread, in view_update()
(scene edits) and view_draw() (the view and the image). The render itself
runs on a native thread (Renderer.start()) that never touches Python; the
main thread polls Renderer.snapshot(). Once the last sample is drawn no
timer and no thread is left, and the CPU is idle.
"""

from __future__ import annotations

import sys
import weakref

import bpy
import numpy as np

from . import export
from .viewport_draw import FIRST_FRAME_WAIT, ViewportDisplay
from .viewport_render import ProgressiveRender
from .viewport_sync import SceneSync

# Live sessions, for the file-load/undo handlers and for tests.
_sessions = weakref.WeakSet()


def sessions():
    """The live viewport sessions (tests and benchmarks inspect them)."""
    return list(_sessions)


def view_camera(region_data, scene=None, depsgraph=None, width=1, height=1):
    """Scene.set_camera keyword arguments for a 3D View (its view and window matrices).

    In camera view the window matrix already holds the camera's lens, shift,
    zoom and clipping; depth of field then comes from the camera, as in a
    final render.
    """
    cam_to_world = np.array(region_data.view_matrix.inverted(), dtype=np.float64)
    P = np.array(region_data.window_matrix, dtype=np.float64)
    right, up, back, position = cam_to_world[:3, 0], cam_to_world[:3, 1], cam_to_world[:3, 2], cam_to_world[:3, 3]
    half_width, half_height = 1.0 / P[0, 0], 1.0 / P[1, 1]
    if region_data.is_perspective:
        # OpenGL perspective: the image centre sits at (P02/P00, P12/P11) at distance 1.
        center_x, center_y = P[0, 2] / P[0, 0], P[1, 2] / P[1, 1]
        near = P[2, 3] / (P[2, 2] - 1.0)
        far = P[2, 3] / (P[2, 2] + 1.0)
        projection = "PERSP"
        clip_start, clip_end = max(near, 0.0), far
    else:
        center_x, center_y = -P[0, 3] / P[0, 0], -P[1, 3] / P[1, 1]
        near = (P[2, 3] + 1.0) / P[2, 2]
        far = (P[2, 3] - 1.0) / P[2, 2]
        projection = "ORTHO"
        # Blender's orthographic views also show what lies behind the view
        # origin (negative near clip): start the rays that far back.
        back_norm = back / max(np.linalg.norm(back), 1e-30)
        if near < 0.0:
            position = position + back_norm * (-near)
            far -= near
            near = 0.0
        clip_start, clip_end = near, far
    larger = max(half_width, half_height)
    camera = dict(
        projection=projection, position=tuple(position), forward=tuple(-back), up=tuple(up), right=tuple(right),
        half_width=half_width, half_height=half_height,
        # Native shift is measured in full extents of the larger image side.
        shift_x=center_x / (2.0 * larger), shift_y=center_y / (2.0 * larger),
        clip_start=clip_start, clip_end=max(clip_end, clip_start + 1e-6),
    )
    if (scene is not None and depsgraph is not None and region_data.view_perspective == "CAMERA"
            and scene.camera is not None and scene.camera.type == "CAMERA" and scene.camera.data.dof.use_dof):
        cam_ob = scene.camera.evaluated_get(depsgraph)
        params = export.camera_parameters(cam_ob, scene.render, width, height)
        camera.update(aperture_radius=params["aperture_radius"], focus_distance=params["focus_distance"])
    return camera


class ViewportSession:
    """Scene sync, progressive render and display of one viewport RenderEngine instance."""

    def __init__(self):
        # Counters, for tests and bench/viewport_latency.py; the parts count into this one dict.
        self.counters = dict(full_exports=0, geometry_rebuilds=0, material_updates=0, light_updates=0,
                             world_updates=0, restarts=0, bvh_builds=0, bvh_refits=0,
                             transform_updates=0)
        self.render = ProgressiveRender(self.counters)
        self.sync = SceneSync(self.counters, stop_render=self.render.stop)
        self.display = ViewportDisplay()
        self.error = None
        _sessions.add(self)
        _ensure_handlers()

    # What tests and benchmarks read.
    scene = property(lambda self: self.sync.scene)  # the native Scene
    mesh_cache = property(lambda self: self.sync.mesh_cache)
    scene_version = property(lambda self: self.sync.scene_version)
    bvh_seconds = property(lambda self: self.sync.bvh_seconds)
    renderer = property(lambda self: self.render.renderer)  # the current stage's native Renderer
    stages = property(lambda self: self.render.stages)
    stage = property(lambda self: self.render.stage)
    restart_time = property(lambda self: self.render.restart_time)
    first_frame_at = property(lambda self: self.render.first_frame_at)
    first_frame_seconds = property(lambda self: self.render.first_frame_seconds)
    final_seconds = property(lambda self: self.render.final_seconds)

    def free(self):
        self.render.stop()
        self.sync.free()
        self.display.free()

    # -- called from RenderEngine.view_update (main thread) ---------------------------

    def update(self, engine, context, depsgraph):
        from . import native_module

        try:
            self.sync.update(native_module(), depsgraph)
            self.error = None
        except Exception as e:  # noqa: BLE001 - shown in the viewport instead of a traceback
            self.render.stop()
            self.sync.drop_scene()
            self.error = f"Coherent: {e}"
            print(self.error, file=sys.stderr)

    # -- called from RenderEngine.view_draw (main thread) ---------------------------

    def draw(self, engine, context, depsgraph):
        if self.error:
            engine.update_stats("", self.error)
            return
        if self.sync.scene is None:
            return
        scene = depsgraph.scene
        region = context.region
        pixel_size = max(1, int(engine.get_preview_pixel_size(scene)))
        width, height = max(1, region.width // pixel_size), max(1, region.height // pixel_size)
        camera = view_camera(context.region_data, scene, depsgraph, width, height)
        view_key = self._view_key(scene, camera, width, height)
        render, display = self.render, self.display
        if view_key != render.view_key:
            display.invalidate()
            render.restart(self.sync, scene, camera, width, height, view_key)
        elif render.stage_finished():
            self._show_latest_pass()  # the stage's last pass, before its renderer goes
            render.next_stage(self.sync, scene)
        self._show_latest_pass(wait=0.0 if display.texture_current else FIRST_FRAME_WAIT)
        display.draw(engine, scene, region)
        self._report_progress(engine)

    def _view_key(self, scene, camera, width, height):
        """Everything a restart depends on: a draw with another key restarts the render."""
        props = scene.coherent
        # Every setting the Renderer gets (integrator, traversal, sampler, ...)
        # restarts the view when changed; heatmaps and the denoising data
        # passes are off in the viewport.
        kwargs = props.renderer_kwargs(scene)
        kwargs.pop("heatmaps", None)
        kwargs.pop("denoising_data", None)
        return (self.sync.scene_version, width, height, tuple(sorted(camera.items())), props.preview_samples,
                props.seed, props.use_preview_denoising, tuple(sorted(kwargs.items())))

    def _show_latest_pass(self, wait=0.0):
        if self.display.upload(self.render, wait):
            self.render.note_first_frame()

    def _report_progress(self, engine):
        """The status line; schedules the next redraw until every sample is drawn."""
        render = self.render
        renderer = render.renderer
        progress = renderer.progress()
        if progress["error"]:
            engine.update_stats("", f"Coherent: {progress['error']}")
            return
        samples = f"Sample {progress['samples_done']}/{progress['samples_total']}"
        if (render.final_stage and not renderer.running
                and self.display.shows(render, progress["samples_done"])):
            render.note_all_samples_drawn()
            engine.update_stats("", f"{samples} | {progress['seconds']:.1f} s")
            return
        if render.final_stage:
            engine.update_stats("", f"{samples} | {progress['mrays_per_s']:.1f} Mrays/s")
        else:
            divisor, _ = render.stages[render.stage]
            engine.update_stats("", f"Preview 1/{divisor} resolution")
        self.display.schedule_redraw(render)


# -- file load and undo ------------------------------------------------------------

@bpy.app.handlers.persistent
def _stop_all_sessions(*_args):
    """Opening another file: stop every render thread before Blender frees the scene."""
    for session in list(_sessions):
        session.free()


@bpy.app.handlers.persistent
def _reset_after_undo(*_args):
    """Undo may reuse datablock addresses: the mesh caches must not trust them."""
    for session in list(_sessions):
        session.sync.reset_after_undo()


def _ensure_handlers():
    for handlers, handler in ((bpy.app.handlers.load_pre, _stop_all_sessions),
                              (bpy.app.handlers.undo_post, _reset_after_undo),
                              (bpy.app.handlers.redo_post, _reset_after_undo)):
        if not any(getattr(h, "__name__", None) == handler.__name__ and getattr(h, "__module__", None) == __name__
                   for h in handlers):
            handlers.append(handler)
