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
- the previous native Scene and its BVHs. The world-space BVH (meshes
  placed once) is refit when it holds the same unchanged meshes in the same
  order, only moved, instead of rebuilt. The instances' BVH keeps the
  BVH of every shared mesh whose triangles did not change; only changed
  meshes and the top level over the instances are built again
  (Scene.build_instance_bvh).
- which objects changed geometry before (deforming, animated modifiers):
  from their first change on, such an object's mesh gets a BVH of its own
  (a prototype placed once) so that its next change rebuilds it alone,
  not the world-space BVH of everything static. Its hits then go through
  a transform: the image agrees with a render without persistent data
  within float rounding, no longer bit for bit.

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
        self.scene = None       # native Scene of the previous render, with its BVHs
        self.flattened = None   # its world-space meshes (SceneExporter.flattened_keys)
        self.identity = None    # (scene, view layer, BVH-shaping settings) it was rendered for
        self.refits = 0         # consecutive refits since the last build
        self.report = None      # what the latest export reused (summary())

    def free(self):
        self.mesh_cache.clear()
        self.scene = self.flattened = self.identity = None
        self.refits = 0

    def export(self, native, depsgraph, width, height, identity, camera_override=None,
               cancelled=lambda: False, motion=None, frame_motion=None):
        """Exports `depsgraph` reusing the cached meshes and, where only
        transforms changed, the previous BVH refit. Returns an ExportResult."""
        if identity != self.identity:
            self.free()
            self.identity = identity
        cache = self.mesh_cache
        scene_reuse.invalidate_changed_meshes(cache, depsgraph)
        exporter = export.SceneExporter(native, depsgraph, width, height, camera_override, mesh_cache=cache,
                                        motion=motion, separate_objects=frozenset(cache.changed_objects),
                                        frame_motion=frame_motion)
        result = exporter.export(cancelled)
        cache.retain(exporter.used_keys)
        previous, self.scene = self.scene, result.scene
        flattened = tuple(exporter.flattened_keys)
        refit_seconds = None
        # A moving triangle lives in the MotionBvh, not in the refit tree:
        # motion blur rebuilds.
        if (previous is not None and previous.has_bvh and flattened == self.flattened and not motion
                and not exporter.extracted_keys.intersection(flattened)
                and previous.triangle_count == result.scene.triangle_count
                and self.refits < MAX_CONSECUTIVE_REFITS):
            refit_seconds = result.scene.refit_bvh_from(previous)
        self.refits = self.refits + 1 if refit_seconds is not None else 0
        self.flattened = flattened
        instanced = None
        if previous is not None and previous.has_instance_bvh and result.scene.instance_count:
            instanced = result.scene.build_instance_bvh(previous)
        extracted = len(exporter.extracted_keys)
        self.report = PersistentReport(len(exporter.used_keys) - extracted, extracted, refit_seconds, instanced,
                                       first=previous is None)
        # The previous scene goes now: until the Renderer builds (or the
        # refit gave) this one's BVH, nothing else needs it.
        return result


class PersistentReport:
    """What one persistent-data export reused, for the summary line and tests."""

    def __init__(self, reused, extracted, refit_seconds, instanced, first):
        self.reused = reused                  # meshes taken from the cache
        self.extracted = extracted            # meshes extracted (new or changed)
        self.refit_seconds = refit_seconds    # world-space BVH refit time, None if it is built
        self.instanced = instanced            # Scene.build_instance_bvh's counts, None if not kept
        self.first = first                    # nothing was kept before this render

    def summary(self, build_seconds):
        """e.g. "Coherent: persistent data: 12 meshes reused, 1 re-extracted, BVH refit in 3 ms,
        instanced BVHs: 4 reused, 1 built"."""
        if self.refit_seconds is not None:
            bvh = f"BVH refit in {1e3 * self.refit_seconds:.1f} ms"
        else:
            bvh = f"BVH built in {1e3 * build_seconds:.1f} ms"
        verb = "extracted" if self.first else "re-extracted"
        line = f"Coherent: persistent data: {self.reused} meshes reused, {self.extracted} {verb}, {bvh}"
        if self.instanced is not None:
            line += f", instanced BVHs: {self.instanced['reused']} reused, {self.instanced['built']} built"
        return line
