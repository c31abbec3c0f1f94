# SPDX-License-Identifier: Apache-2.0
"""What the viewport and persistent-data final renders share to reuse a previous scene.

Both keep a MeshCache and the previous native Scene with its BVH, and on the
next export need the same two answers:
- which cached meshes changed (classify_updates: the depsgraph's geometry
  updates; Blender 3.4 fills depsgraph.updates for a persistent-data final
  render too, as Cycles' sync_recalc relies on);
- whether the new scene holds the same triangles in the same order, only
  moved, so that the previous BVH can be refit instead of rebuilt
  (refit_from).
"""

from __future__ import annotations

import bpy


def classify_updates(depsgraph):
    """(objects with new geometry, mesh data with new geometry, {material pointer:
    edited material}, whether a node group changed) from the depsgraph's
    updates; pointers are of the original datablocks (the evaluated ones'
    too for mesh data)."""
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
    return geometry_objects, geometry_data, edited_materials, all_materials


def invalidate_changed_meshes(mesh_cache, depsgraph):
    """Drops the cached meshes whose geometry the depsgraph updated; returns whether any was."""
    geometry_objects, geometry_data, _, _ = classify_updates(depsgraph)
    invalidated = mesh_cache.invalidate_objects(geometry_objects)
    return mesh_cache.invalidate_data(geometry_data) | invalidated


def same_triangles(previous_geometry, geometry):
    """Whether two scan_instances() geometries place the same cached meshes in
    the same order (matrices and slot materials may differ)."""
    if previous_geometry is None or len(previous_geometry) != len(geometry):
        return False
    return all(old[:2] == new[:2] for old, new in zip(previous_geometry, geometry))


def refit_from(scene, previous, previous_geometry, geometry):
    """Gives `scene` `previous`'s BVH refit to its moved triangles: the refit
    seconds, or None if it can't.

    Refit needs the same triangles in the same order: the same instances of
    the same cached meshes (no mesh re-extracted since `previous` was built;
    the caller knows) and so the same triangle count (checked again here,
    e.g. for triangles a degenerate scale dropped).
    """
    if previous is None or not previous.has_bvh or not same_triangles(previous_geometry, geometry):
        return None
    if previous.triangle_count != scene.triangle_count:
        return None
    return scene.refit_bvh_from(previous)
