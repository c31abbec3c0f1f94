# SPDX-License-Identifier: Apache-2.0
"""Interactive viewport rendering ("Rendered" shading in the 3D View).

Threads: every bpy access happens on Blender's main thread, in view_update()
(scene edits) and view_draw() (the view and the image). The render itself
runs on a native thread (Renderer.start()) that never touches Python; the
main thread polls Renderer.snapshot(), which hands over the film as of the
last *completed* sample pass, so a drawn frame is never torn. While a render
refines, a one-shot timer asks for the next redraw; once the last sample is
drawn no timer and no thread is left, and the CPU is idle.

Progressive restart: after any change the image is rendered in stages, a
coarse one first (at most FIRST_STAGE_PIXELS pixels, 1 sample: it shows
within tens of milliseconds), then twice the resolution per stage, then the
full viewport resolution with the Viewport sample count (the Auto sampler
is ICPT here: each pass spreads its error evenly over the image, the paper's
answer for intermediate results). A restarted render
never shows the previous image (which would be stale): draw() waits up to
FIRST_FRAME_WAIT for the new coarse pass instead.

Incremental updates (view_update): only what changed is re-exported.
- view (orbit, zoom, lens, clipping, viewport size): the native Scene only
  gets a new camera; the next Renderer reuses the BVH the scene keeps.
- material / world / light edits: replaced in place in the native Scene
  (Scene.set_material, clear_lights + add_light, world_color): the triangles
  and so the BVH stay.
- transforms and material slot changes (same instances of the same meshes):
  a new native Scene from the session's MeshCache (no mesh is re-extracted,
  so the triangles keep their order) and the previous BVH refit to it
  (Scene.refit_bvh_from: milliseconds instead of a ~0.2 s rebuild on
  Sponza; the hits are exact either way).
- added or removed objects: as above, but with a BVH rebuild (a fast one,
  without spatial splits).
- geometry edits: the edited meshes are re-extracted, then as above.
What changed is found by comparing scan_instances() (instances, matrices,
slot materials, light parameters) with the previous state, plus the
depsgraph's geometry and material updates for edits that keep all of those.
"""

from __future__ import annotations

import math
import sys
import time
import weakref

import bpy
import numpy as np

from . import export, materials

# Seconds between redraws while a viewport render is refining.
REDRAW_INTERVAL = 0.05
# Pixels of the first, coarse stage of a restarted render.
FIRST_STAGE_PIXELS = 16384
# Seconds draw() waits for a restarted render's first pass.
FIRST_FRAME_WAIT = 0.2

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


def progressive_stages(width, height, samples):
    """[(divisor, samples)] of a restart: coarse 1-sample stages, then the full resolution."""
    divisor = 1
    while math.ceil(width / divisor) * math.ceil(height / divisor) > FIRST_STAGE_PIXELS:
        divisor *= 2
    stages = []
    while divisor > 1:
        stages.append((divisor, 1))
        divisor //= 2
    stages.append((1, samples))
    return stages


def _tag_rendered_views():
    """Asks every 3D View in Rendered shading for a redraw (main thread)."""
    wm = bpy.context.window_manager
    if wm is None:
        return
    for window in wm.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and area.spaces.active.shading.type == "RENDERED":
                area.tag_redraw()


class ViewportSession:
    """Native scene, caches and running render of one viewport RenderEngine instance."""

    def __init__(self):
        self.scene = None            # native Scene; its camera is set per view
        self.exporter = None         # the SceneExporter that built `scene` (its material indices)
        self.mesh_cache = export.MeshCache()
        self.geometry = None         # scan_instances() geometry the scene was built from
        self.lights = None           # light arguments in the scene
        self.world = None            # world colour in the scene
        self.scene_version = 0       # bumped on every change of the native scene
        self.reset_pending = False   # undo: pointers may be reused, drop every cache
        self.fast_bvh = False        # build the scene's next BVH without spatial splits

        self.renderer = None
        self.view_key = None         # what the running restart was started with
        self.stages = []
        self.stage = 0
        self.texture = None
        self.texture_stamp = None    # (view_key, stage, samples) of the texture
        self.texture_current = False  # the texture shows the current scene and view
        self.error = None
        self._redraw_pending = False

        # Counters and timings, for tests and bench/viewport_latency.py.
        self.counters = dict(full_exports=0, geometry_rebuilds=0, material_updates=0, light_updates=0,
                             world_updates=0, restarts=0, bvh_builds=0, bvh_refits=0,
                             transform_updates=0)
        self.restart_time = None       # perf_counter() of the latest restart
        self.first_frame_seconds = None  # restart -> its first drawn frame
        self.final_seconds = None      # restart -> all samples drawn
        self.first_frame_at = None     # perf_counter() when the latest restart's first frame was drawn
        self.bvh_seconds = None        # build (or refit) time of the scene's latest BVH
        _sessions.add(self)
        _ensure_handlers()

    # -- lifetime -----------------------------------------------------------------

    def stop(self):
        """Cancels and joins the render thread (returns within a fraction of a pass)."""
        renderer = self.renderer
        self.renderer = None
        if renderer is not None:
            renderer.cancel()
            try:
                renderer.wait()
            except RuntimeError as e:  # a native error in the render: already reported in draw()
                print(f"Coherent: {e}", file=sys.stderr)
        self.view_key = None

    def free(self):
        self.stop()
        self.scene = None
        self.exporter = None
        self.mesh_cache.clear()
        self.texture = None
        self.texture_current = False

    # -- called from RenderEngine.view_update (main thread) ---------------------------

    def update(self, engine, context, depsgraph):
        from . import native_module

        try:
            native = native_module()
            if self.scene is None or self.reset_pending:
                self._export_all(native, depsgraph)
            else:
                self._apply_updates(native, depsgraph)
            self.error = None
        except Exception as e:  # noqa: BLE001 - shown in the viewport instead of a traceback
            self.stop()
            self.scene = None
            self.error = f"Coherent: {e}"
            print(self.error, file=sys.stderr)

    def _export_all(self, native, depsgraph, geometry=None, lights=None):
        """A new native scene from the depsgraph; meshes come from the cache when valid."""
        self.stop()
        self.scene = None
        if self.reset_pending:
            self.mesh_cache.clear()
            self.reset_pending = False
        if geometry is None:
            geometry, lights = export.scan_instances(depsgraph)
        exporter = export.SceneExporter(native, depsgraph, 1, 1, need_camera=False, mesh_cache=self.mesh_cache)
        result = exporter.export()
        self.mesh_cache.retain(exporter.used_keys)
        for warning in result.warnings:
            print(f"Coherent warning: {warning}", file=sys.stderr)
        self.scene, self.exporter = result.scene, exporter
        self.fast_bvh = False
        self.geometry, self.lights = geometry, lights
        self.world = materials.world_color(depsgraph.scene.world, [])
        self.scene_version += 1
        self.counters["full_exports"] += 1

    def _apply_updates(self, native, depsgraph):
        geometry_objects, geometry_data, edited_materials = set(), set(), {}
        all_materials = False
        for update in depsgraph.updates:
            id_ = update.id
            original = id_.original if id_.original is not None else id_
            if isinstance(id_, bpy.types.Object):
                if update.is_updated_geometry:
                    geometry_objects.add(original.as_pointer())
            elif isinstance(id_, (bpy.types.Mesh, bpy.types.Curve, bpy.types.MetaBall)):
                if update.is_updated_geometry:
                    geometry_data.update((id_.as_pointer(), original.as_pointer()))
            elif isinstance(id_, bpy.types.Material):
                edited_materials[original.as_pointer()] = id_
            elif isinstance(id_, bpy.types.NodeTree) and not id_.is_embedded_data:
                # A node group, maybe used by materials. (A material's own
                # tree is embedded and comes with an update of the material.)
                all_materials = True

        invalidated = self.mesh_cache.invalidate_objects(geometry_objects)
        invalidated |= self.mesh_cache.invalidate_data(geometry_data)
        geometry, lights = export.scan_instances(depsgraph)
        if invalidated or geometry != self.geometry:
            previous, previous_geometry = self.scene, self.geometry
            self._export_all(native, depsgraph, geometry, lights)
            if not invalidated and self._refit_from(previous, previous_geometry):
                # Transforms or slot materials only: the triangles are the
                # cached ones in the same order, moved; the BVH was refit.
                self.counters["transform_updates"] += 1
                return
            # Geometry edits come in bursts (dragging): build the next BVH
            # without spatial splits, ~2.5x faster to build on Sponza though
            # slower to trace (docs/results/viewport_latency.md).
            self.fast_bvh = True
            self.counters["geometry_rebuilds"] += 1
            return

        changed = False
        material_indices = self.exporter.materials.native_indices()  # original pointer -> native index
        if all_materials:
            by_pointer = {m.as_pointer(): m for m in bpy.data.materials}
            for pointer in material_indices:
                if pointer in by_pointer and pointer not in edited_materials:
                    edited_materials[pointer] = by_pointer[pointer].evaluated_get(depsgraph)
        edits = [(material_indices[p], m) for p, m in edited_materials.items() if p in material_indices]
        if edits:
            self.stop()
            warnings = []
            converter = materials.MaterialConverter(self.scene, warnings)
            for index, material in edits:
                closures, weights, emission = converter.convert(material)
                self.scene.set_material(index, material.name, closures=closures, weights=weights,
                                        emission=emission)
            for warning in warnings:
                print(f"Coherent warning: {warning}", file=sys.stderr)
            self.counters["material_updates"] += 1
            changed = True
        if lights != self.lights:
            self.stop()
            self.scene.clear_lights()
            for kind, args in lights:
                self.scene.add_light(kind, **args)
            self.lights = lights
            self.counters["light_updates"] += 1
            changed = True
        world = materials.world_color(depsgraph.scene.world, [])
        if world != self.world:
            self.stop()
            self.scene.world_color = world
            self.world = world
            self.counters["world_updates"] += 1
            changed = True
        if changed:
            self.scene_version += 1

    def _refit_from(self, previous, previous_geometry):
        """Gives the new scene `previous`'s BVH refit to the moved triangles; False if it can't.

        Refit needs the same triangles in the same order: the same instances
        of the same cached meshes (only matrices and slot materials may
        differ) and so the same triangle count (checked again natively, e.g.
        for triangles a degenerate scale dropped).
        """
        if previous is None or not previous.has_bvh or previous_geometry is None:
            return False
        if len(previous_geometry) != len(self.geometry):
            return False
        if any(old[:2] != new[:2] for old, new in zip(previous_geometry, self.geometry)):
            return False
        if previous.triangle_count != self.scene.triangle_count:
            return False
        self.bvh_seconds = self.scene.refit_bvh_from(previous)
        self.counters["bvh_refits"] += 1
        return True

    # -- called from RenderEngine.view_draw (main thread) ---------------------------

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
        camera = view_camera(context.region_data, scene, depsgraph, width, height)
        # Every setting the Renderer gets (integrator, traversal, sampler, ...)
        # restarts the view when changed; heatmaps are off in the viewport.
        kwargs = props.renderer_kwargs(scene)
        kwargs.pop("heatmaps", None)
        view_key = (self.scene_version, width, height, tuple(sorted(camera.items())), props.preview_samples,
                    props.seed, tuple(sorted(kwargs.items())))
        if view_key != self.view_key:
            self._restart(scene, camera, width, height, view_key)
        elif self.renderer is not None and not self.renderer.running and self.stage + 1 < len(self.stages):
            self._take_snapshot()  # the stage's last pass, before its renderer goes
            self.stage += 1
            self._start_stage(scene)

        self._take_snapshot(wait=0.0 if self.texture_current else FIRST_FRAME_WAIT)
        if self.texture is not None and self.texture_current:
            gpu.state.blend_set("ALPHA_PREMULT")
            engine.bind_display_space_shader(scene)
            draw_texture_2d(self.texture, (0, 0), region.width, region.height)
            engine.unbind_display_space_shader()
            gpu.state.blend_set("NONE")

        renderer = self.renderer
        progress = renderer.progress()
        divisor, _ = self.stages[self.stage]
        final_stage = self.stage + 1 == len(self.stages)
        if progress["error"]:
            engine.update_stats("", f"Coherent: {progress['error']}")
            return
        done = final_stage and not renderer.running and self.texture_stamp == (view_key, self.stage,
                                                                              progress["samples_done"])
        if done:
            if self.final_seconds is None and self.restart_time is not None:
                self.final_seconds = time.perf_counter() - self.restart_time
            engine.update_stats("", f"Sample {progress['samples_done']}/{progress['samples_total']} | "
                                    f"{progress['seconds']:.1f} s")
        else:
            if final_stage:
                engine.update_stats("", f"Sample {progress['samples_done']}/{progress['samples_total']} | "
                                        f"{progress['mrays_per_s']:.1f} Mrays/s")
            else:
                engine.update_stats("", f"Preview 1/{divisor} resolution")
            self._schedule_redraw()

    def _restart(self, scene, camera, width, height, view_key):
        self.stop()
        self.scene.set_camera(**camera)
        self.view_key = view_key
        self.width, self.height = width, height
        self.stages = progressive_stages(width, height, scene.coherent.preview_samples)
        self.stage = 0
        self.texture_current = False  # the old image must not be shown any more
        self.restart_time = time.perf_counter()
        self.first_frame_seconds = None
        self.first_frame_at = None
        self.final_seconds = None
        self.counters["restarts"] += 1
        self._start_stage(scene)

    def _start_stage(self, scene):
        from . import native_module
        native = native_module()
        if self.renderer is not None:
            self.stop_renderer_only()
        props = scene.coherent
        divisor, samples = self.stages[self.stage]
        kwargs = props.renderer_kwargs(scene)
        kwargs.update(width=max(1, math.ceil(self.width / divisor)), height=max(1, math.ceil(self.height / divisor)),
                      spp=samples, seed=props.seed, progressive_display=True,
                      heatmaps=False)  # the viewport draws Combined only: no counters to pay for
        if not self.scene.has_bvh:
            # Built here rather than by the Renderer to choose its quality;
            # every later Renderer over these triangles reuses it.
            self.bvh_seconds = self.scene.build_bvh(spatial_splits=not self.fast_bvh)
            self.counters["bvh_builds"] += 1
        self.renderer = native.Renderer(self.scene, **kwargs)
        self.renderer.start()

    def stop_renderer_only(self):
        """Drops the renderer of a finished stage (keeps view_key: same restart)."""
        renderer, self.renderer = self.renderer, None
        renderer.cancel()
        try:
            renderer.wait()
        except RuntimeError as e:
            print(f"Coherent: {e}", file=sys.stderr)

    def _take_snapshot(self, wait=0.0):
        """Uploads the latest completed pass as the texture; waits up to `wait` s for a first one."""
        import gpu

        renderer = self.renderer
        if renderer is None:
            return
        deadline = time.perf_counter() + wait
        while True:
            samples, pixels = renderer.snapshot()
            if pixels is not None or time.perf_counter() >= deadline or not renderer.running:
                break
            time.sleep(0.002)  # releases the GIL; the render thread never needs it anyway
        if pixels is None:
            return
        stamp = (self.view_key, self.stage, samples)
        if stamp == self.texture_stamp:
            return
        buffer = gpu.types.Buffer("FLOAT", pixels.size, pixels)
        self.texture = gpu.types.GPUTexture((renderer.film_width, renderer.film_height), format="RGBA16F",
                                            data=buffer)
        self.texture_stamp = stamp
        if not self.texture_current:
            self.texture_current = True
            if self.restart_time is not None:
                self.first_frame_at = time.perf_counter()
                self.first_frame_seconds = self.first_frame_at - self.restart_time

    def _schedule_redraw(self):
        if self._redraw_pending:
            return
        self._redraw_pending = True
        session_ref = weakref.ref(self)  # the timer must not keep a closed viewport's session alive

        def redraw():
            session = session_ref()
            if session is None:
                return None
            session._redraw_pending = False
            if session.renderer is not None:
                _tag_rendered_views()
            return None  # one-shot: draw() re-arms it while the render refines

        bpy.app.timers.register(redraw, first_interval=REDRAW_INTERVAL)


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
        session.reset_pending = True


def _ensure_handlers():
    for handlers, handler in ((bpy.app.handlers.load_pre, _stop_all_sessions),
                              (bpy.app.handlers.undo_post, _reset_after_undo),
                              (bpy.app.handlers.redo_post, _reset_after_undo)):
        if not any(getattr(h, "__name__", None) == handler.__name__ and getattr(h, "__module__", None) == __name__
                   for h in handlers):
            handlers.append(handler)
