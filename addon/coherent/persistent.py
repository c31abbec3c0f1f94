# SPDX-License-Identifier: Apache-2.0
"""Persistent data (Render > Performance > Persistent Data) for final renders.

With scene.render.use_persistent_data on, Blender keeps the RenderEngine
instance and its depsgraph between renders (F12 again, the next frame of an
animation, `blender -b -a` over a frame range), and reports in
depsgraph.updates what changed since the previous render. The engine then
keeps one PersistentScene, which holds between renders:
- the MeshCache: a mesh whose geometry the depsgraph did not update is not
  re-extracted (materials, lights, world and camera are exported anew: they
  cost little and carry no BVH);
- the previous native Scene and its BVH: when the new scene has the same
  instances of the same unchanged meshes, only moved, the BVH is refit to
  it (scene_reuse.refit_from, as the viewport does) instead of rebuilt.

Everything is dropped when the scene or view layer rendered changes, when
the render settings that shape the BVH change, with persistent data off,
and when Blender frees the engine.
"""

from __future__ import annotations

from . import export, scene_reuse

# Consecutive refits before the next rebuild. A refit keeps the topology of
# the BVH it came from, which traces slower as objects move away from where
# it was built (Scene.refit_bvh_from); a rebuild now and then bounds that
# over a long animation. 16 is a guess, not a measurement.
MAX_CONSECUTIVE_REFITS = 16


class PersistentScene:
    """Meshes and BVH kept from one final render to the next."""

    def __init__(self):
        self.mesh_cache = export.MeshCache()
        self.scene = None       # native Scene of the previous render, with its BVH
        self.geometry = None    # its scan_instances() geometry
        self.identity = None    # (scene, view layer, BVH-shaping settings) it was rendered for
        self.refits = 0         # consecutive refits since the last build
        self.report = None      # what the latest export reused (summary())

    def free(self):
        self.mesh_cache.clear()
        self.scene = self.geometry = self.identity = None
        self.refits = 0

    def export(self, native, depsgraph, width, height, identity, camera_override=None,
               cancelled=lambda: False, motion=None):
        """Exports `depsgraph` reusing the cached meshes and, where only
        transforms changed, the previous BVH refit. Returns an ExportResult."""
        if identity != self.identity:
            self.free()
            self.identity = identity
        cache = self.mesh_cache
        invalidated = scene_reuse.invalidate_changed_meshes(cache, depsgraph)
        extracted_before = cache.extracted
        exporter = export.SceneExporter(native, depsgraph, width, height, camera_override,
                                        mesh_cache=cache, motion=motion)
        result = exporter.export(cancelled)
        cache.retain(exporter.used_keys)
        extracted = cache.extracted - extracted_before
        geometry, _ = export.scan_instances(depsgraph)
        refit_seconds = None
        # A moving triangle lives in the MotionBvh, not in the refit tree:
        # motion blur rebuilds.
        if not extracted and not invalidated and not motion and self.refits < MAX_CONSECUTIVE_REFITS:
            refit_seconds = scene_reuse.refit_from(result.scene, self.scene, self.geometry, geometry)
        self.refits = self.refits + 1 if refit_seconds is not None else 0
        self.report = PersistentReport(len(exporter.used_keys) - extracted, extracted, refit_seconds,
                                       first=self.scene is None)
        # Until the Renderer builds (or refit gave) its BVH, the previous
        # scene is what a later render could refit from; release it now.
        self.scene, self.geometry = result.scene, geometry
        return result


class PersistentReport:
    """What one persistent-data export reused, for the summary line and tests."""

    def __init__(self, reused, extracted, refit_seconds, first):
        self.reused = reused                  # meshes taken from the cache
        self.extracted = extracted            # meshes extracted (new or changed)
        self.refit_seconds = refit_seconds    # BVH refit time, None if it is built
        self.first = first                    # nothing was kept before this render

    def summary(self, build_seconds):
        """e.g. "Coherent: persistent data: 12 meshes reused, 1 re-extracted, BVH refit in 3 ms"."""
        if self.refit_seconds is not None:
            bvh = f"BVH refit in {1e3 * self.refit_seconds:.1f} ms"
        else:
            bvh = f"BVH built in {1e3 * build_seconds:.1f} ms"
        verb = "extracted" if self.first else "re-extracted"
        return (f"Coherent: persistent data: {self.reused} meshes reused, {self.extracted} {verb}, {bvh}")
