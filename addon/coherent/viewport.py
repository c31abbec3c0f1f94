# SPDX-License-Identifier: Apache-2.0
"""Interactive viewport rendering ("Rendered" shading in the 3D View).

view_update() exports the depsgraph into a native Scene when something that
affects the image changed. view_draw() derives a camera from the 3D View's
view and projection matrices; when it (or the scene) changed, the running
render is cancelled and a new one started with Renderer.start(), which
renders on a native thread that never needs the GIL. Every draw uploads the
latest completed sample pass (Renderer.snapshot()) as a texture; while the
render runs, a timer on the main thread asks for the next redraw, so the
image refines without Python threads.

Limitation: the native Renderer builds its BVH in its constructor, so every
view change rebuilds it (fast for small scenes, noticeable beyond ~1M
triangles).
"""

from __future__ import annotations

import sys

import bpy
import numpy as np

from . import export

# Seconds between redraws while a viewport render is refining.
REDRAW_INTERVAL = 0.2


def view_camera(region_data):
    """Scene.set_camera keyword arguments for a 3D View (its view and window matrices)."""
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
    return dict(
        projection=projection, position=tuple(position), forward=tuple(-back), up=tuple(up), right=tuple(right),
        half_width=half_width, half_height=half_height,
        # Native shift is measured in full extents of the larger image side.
        shift_x=center_x / (2.0 * larger), shift_y=center_y / (2.0 * larger),
        clip_start=clip_start, clip_end=max(clip_end, clip_start + 1e-6),
    )


def _scene_changed(depsgraph):
    """Whether an update in this depsgraph can change the rendered image."""
    for update in depsgraph.updates:
        if update.is_updated_geometry or update.is_updated_transform or update.is_updated_shading:
            return True
        if isinstance(update.id, (bpy.types.Material, bpy.types.World, bpy.types.Light, bpy.types.NodeTree,
                                  bpy.types.Scene, bpy.types.Collection)):
            return True
    return False


class ViewportSession:
    """Native scene and running render of one viewport RenderEngine instance."""

    def __init__(self):
        self.scene = None        # native Scene (camera set per view)
        self.renderer = None
        self.key = None          # what the running render was started with
        self.texture = None
        self.texture_samples = -1
        self.error = None
        self._redraw_pending = False

    def stop(self):
        if self.renderer is not None:
            self.renderer.cancel()
            self.renderer.wait()
            self.renderer = None
        self.key = None

    def free(self):
        self.stop()
        self.scene = None
        self.texture = None

    # -- called from RenderEngine.view_update ------------------------------------

    def update(self, engine, context, depsgraph):
        if self.scene is not None and not _scene_changed(depsgraph):
            return
        from . import native_module

        self.stop()
        self.scene = None
        self.error = None
        try:
            exported = export.export_scene(native_module(), depsgraph, 1, 1, need_camera=False)
        except Exception as e:  # noqa: BLE001 - shown in the viewport instead of a traceback
            self.error = f"Coherent: {e}"
            print(self.error, file=sys.stderr)
            return
        for warning in exported.warnings:
            print(f"Coherent warning: {warning}", file=sys.stderr)
        self.scene = exported.scene

    # -- called from RenderEngine.view_draw ---------------------------------------

    def draw(self, engine, context, depsgraph):
        import gpu
        from gpu_extras.presets import draw_texture_2d

        if self.error:
            engine.update_stats("", self.error)
            return
        if self.scene is None:
            return
        scene = depsgraph.scene
        region = context.region
        pixel_size = max(1, int(engine.get_preview_pixel_size(scene)))
        width, height = max(1, region.width // pixel_size), max(1, region.height // pixel_size)
        props = scene.coherent
        camera = view_camera(context.region_data)
        key = (width, height, tuple(sorted(camera.items())), props.preview_samples, props.seed,
               props.max_bounces, props.diffuse_bounces, props.glossy_bounces, props.transmission_bounces,
               scene.render.film_transparent)
        if key != self.key:
            self._restart(scene, camera, width, height, key)

        renderer = self.renderer
        samples, pixels = renderer.snapshot()
        if pixels is not None and samples != self.texture_samples:
            buffer = gpu.types.Buffer("FLOAT", pixels.size, pixels)
            self.texture = gpu.types.GPUTexture((renderer.film_width, renderer.film_height), format="RGBA16F",
                                                data=buffer)
            self.texture_samples = samples
        if self.texture is not None:
            gpu.state.blend_set("ALPHA_PREMULT")
            engine.bind_display_space_shader(scene)
            draw_texture_2d(self.texture, (0, 0), region.width, region.height)
            engine.unbind_display_space_shader()
            gpu.state.blend_set("NONE")

        progress = renderer.progress()
        if progress["error"]:
            engine.update_stats("", f"Coherent: {progress['error']}")
        elif renderer.running:
            engine.update_stats("", f"Sample {samples}/{progress['samples_total']} | "
                                    f"{progress['mrays_per_s']:.1f} Mrays/s")
            self._schedule_redraw(engine)
        else:
            engine.update_stats("", f"Sample {samples}/{progress['samples_total']} | "
                                    f"{progress['seconds']:.1f} s")

    def _restart(self, scene, camera, width, height, key):
        from . import native_module
        from .engine import render_threads

        self.stop()
        props = scene.coherent
        self.scene.set_camera(**camera)
        self.renderer = native_module().Renderer(
            self.scene, width=width, height=height, spp=props.preview_samples, seed=props.seed,
            threads=render_threads(scene), max_bounces=props.max_bounces,
            diffuse_bounces=props.diffuse_bounces, glossy_bounces=props.glossy_bounces,
            transmission_bounces=props.transmission_bounces, transparent=scene.render.film_transparent,
            tile_size=props.tile_size)
        self.renderer.start()
        self.key = key
        self.texture_samples = -1  # keep showing the old texture until the first pass arrives

    def _schedule_redraw(self, engine):
        if self._redraw_pending:
            return
        self._redraw_pending = True

        def redraw():
            self._redraw_pending = False
            try:
                engine.tag_redraw()
            except ReferenceError:  # the engine (viewport) is gone
                pass
            return None  # one-shot

        bpy.app.timers.register(redraw, first_interval=REDRAW_INTERVAL)
