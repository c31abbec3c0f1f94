# SPDX-License-Identifier: Apache-2.0
"""Scene sync for the Rendered viewport: depsgraph updates into the native scene.

Only what changed is re-exported (view_update, main thread):
- view (orbit, zoom, lens, clipping, viewport size): not handled here; the
  next restart only gives the native Scene a new camera and its Renderer
  reuses the BVH the scene keeps.
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

Every change of the native scene bumps scene_version (the viewport restarts
its render on a new version) and first stops the running render, whose
thread reads the scene.
"""

from __future__ import annotations

import sys

import bpy

from . import export, materials, object_settings, scene_reuse


class SceneSync:
    """The native scene of one viewport, kept in step with the depsgraph."""

    def __init__(self, counters, stop_render):
        self.scene = None            # native Scene; its camera is set per view
        self.exporter = None         # the SceneExporter that built `scene` (its material indices)
        self.mesh_cache = export.MeshCache()
        self.geometry = None         # scan_instances() geometry the scene was built from
        self.lights = None           # light arguments in the scene
        self.world = None            # world colour in the scene
        self.scene_version = 0       # bumped on every change of the native scene
        self.reset_pending = False   # undo: pointers may be reused, drop every cache
        self.fast_bvh = False        # build the scene's next BVH without spatial splits
        self.bvh_seconds = None      # build (or refit) time of the scene's latest BVH
        self.counters = counters     # shared with the session (tests and benchmarks read them)
        self._stop_render = stop_render

    def update(self, native, depsgraph):
        """Brings the native scene up to date with `depsgraph` (main thread)."""
        if self.scene is None or self.reset_pending:
            self._export_all(native, depsgraph)
        else:
            self._apply_updates(native, depsgraph)

    def drop_scene(self):
        """Forgets the native scene (after a failed update): the next update exports anew."""
        self.scene = None

    def free(self):
        self.scene = None
        self.exporter = None
        self.mesh_cache.clear()

    def reset_after_undo(self):
        """Undo may reuse datablock addresses: the next update trusts no cached pointer."""
        self.reset_pending = True

    def ensure_bvh(self):
        """Builds the scene's BVH unless it has one. Built here rather than by the
        Renderer to choose its quality; every later Renderer over these
        triangles reuses it."""
        if not self.scene.has_bvh:
            self.bvh_seconds = self.scene.build_bvh(spatial_splits=not self.fast_bvh)
            self.counters["bvh_builds"] += 1

    # -- whole scene --------------------------------------------------------------

    def _export_all(self, native, depsgraph, geometry=None, lights=None):
        """A new native scene from the depsgraph; meshes come from the cache when valid."""
        self._stop_render()
        self.scene = None
        if self.reset_pending:
            self.mesh_cache.clear()
            self.reset_pending = False
        if geometry is None:
            geometry, lights = export.scan_instances(depsgraph)
        exporter = export.SceneExporter(native, depsgraph, 1, 1, need_camera=False, mesh_cache=self.mesh_cache)
        result = exporter.export()
        object_settings.set_shadow_terminator(result.scene)
        self.mesh_cache.retain(exporter.used_keys)
        for warning in result.warnings:
            print(f"Coherent warning: {warning}", file=sys.stderr)
        self.scene, self.exporter = result.scene, exporter
        self.fast_bvh = False
        self.geometry, self.lights = geometry, lights
        self.world = materials.world_color(depsgraph.scene.world, [])
        self.scene_version += 1
        self.counters["full_exports"] += 1

    def _refit_from(self, previous, previous_geometry):
        """Gives the new scene `previous`'s BVH refit to the moved triangles; False if it can't."""
        seconds = scene_reuse.refit_from(self.scene, previous, previous_geometry, self.geometry)
        if seconds is None:
            return False
        self.bvh_seconds = seconds
        self.counters["bvh_refits"] += 1
        return True

    # -- incremental --------------------------------------------------------------

    def _apply_updates(self, native, depsgraph):
        geometry_objects, geometry_data, edited_materials, all_materials = scene_reuse.classify_updates(depsgraph)
        invalidated = self.mesh_cache.invalidate_objects(geometry_objects)
        invalidated |= self.mesh_cache.invalidate_data(geometry_data)
        geometry, lights = export.scan_instances(depsgraph)
        if invalidated or geometry != self.geometry:
            self._rebuild(native, depsgraph, geometry, lights, invalidated)
            return
        changed = self._update_materials(depsgraph, edited_materials, all_materials)
        changed |= self._update_lights(lights)
        changed |= self._update_world(depsgraph)
        if changed:
            self.scene_version += 1

    def _rebuild(self, native, depsgraph, geometry, lights, invalidated):
        """A new scene for changed instances or geometry; refits the old BVH where it can."""
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

    def _update_materials(self, depsgraph, edited_materials, all_materials):
        """Converts edited materials again, in place; True if any was."""
        material_indices = self.exporter.materials.native_indices()  # original pointer -> native index
        if all_materials:
            by_pointer = {m.as_pointer(): m for m in bpy.data.materials}
            for pointer in material_indices:
                if pointer in by_pointer and pointer not in edited_materials:
                    edited_materials[pointer] = by_pointer[pointer].evaluated_get(depsgraph)
        edits = [(material_indices[p], m) for p, m in edited_materials.items() if p in material_indices]
        if not edits:
            return False
        self._stop_render()
        warnings = []
        converter = self.exporter.materials.fresh(warnings)
        for index, material in edits:
            closures, weights, emission, program = converter.convert(material)
            try:
                self.scene.set_material(index, material.name, closures=closures, weights=weights,
                                        emission=emission, program=program)
            except ValueError as error:  # a program reading a UV map the meshes were exported without
                warnings.append(f"Material '{material.name}': {error}; re-render to see its textures")
                self.scene.set_material(index, material.name, closures=closures, weights=weights, emission=emission)
        for warning in warnings:
            print(f"Coherent warning: {warning}", file=sys.stderr)
        self.counters["material_updates"] += 1
        return True

    def _update_lights(self, lights):
        if lights == self.lights:
            return False
        self._stop_render()
        self.scene.clear_lights()
        for kind, args in lights:
            self.scene.add_light(kind, **args)
        self.lights = lights
        self.counters["light_updates"] += 1
        return True

    def _update_world(self, depsgraph):
        world = materials.world_color(depsgraph.scene.world, [])
        if world == self.world:
            return False
        self._stop_render()
        self.scene.world_color = world
        self.world = world
        self.counters["world_updates"] += 1
        return True
