# SPDX-License-Identifier: Apache-2.0
"""Blender depsgraph to a native COHERENT scene.

Geometry goes through numpy arrays filled by `foreach_get` (no Python loop over
vertices or triangles). Triangle arrays are extracted once per mesh datablock
and reused for every instance of it (linked duplicates, collection instances,
Geometry Nodes instances); each instance only contributes its transform. A
mesh placed more than once is sent to the native scene once, as a prototype
that keeps its own BVH, and its placements as one (K, 4, 4) array of matrices
(Scene.add_instances): memory grows with unique triangles plus instances.

Conventions: Blender is Z-up and right-handed, a camera looks down its local
-Z axis with +Y up, lights point along their local -Z axis. Matrices are
row-major (numpy's view of a mathutils.Matrix), which is what the native
Transform expects.
"""

from __future__ import annotations

import math
import time
from itertools import chain

import numpy as np

from . import geometry_attributes, images, materials, motion
from .world import export_world

# Object types that evaluate to a surface we can triangulate.
_MESH_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
# Object types whose instances can move during the shutter (motion blur).
MOTION_TYPES = _MESH_TYPES
# Object types with nothing to render for us (not worth a warning).
_SILENT_TYPES = {"CAMERA", "EMPTY", "ARMATURE", "LATTICE", "SPEAKER", "LIGHT_PROBE", "GPENCIL"}


class ExportError(RuntimeError):
    """A problem that makes rendering impossible (e.g. no camera)."""


class MeshArrays:
    """Triangles of one mesh datablock in object space, ready for Scene.add_mesh."""

    __slots__ = ("positions", "indices", "normals", "material_index", "max_material_index", "shading",
                 "shading_request")

    def __init__(self, positions, indices, normals, material_index):
        self.positions = positions      # float32 (N, 3)
        self.indices = indices          # int32 (M, 3)
        self.normals = normals          # float32 (M, 3, 3) or None (flat shading)
        self.material_index = material_index  # int32 (M,) or None when all zero
        self.max_material_index = int(material_index.max()) if material_index is not None else 0
        self.shading = None          # add_mesh keyword arguments: uvs, tangents, generated (shading_arrays)
        self.shading_request = None  # the ShadingRequest they answer

    @property
    def triangle_count(self):
        return self.indices.shape[0]


class ShadingRequest(tuple):
    """What the materials' shader programs read from meshes: (uv_names, tangent_uv, objects, color_names)."""

    @classmethod
    def of(cls, converter):
        color_names = tuple(getattr(converter, "color_names", ()))
        if not converter.uv_names and not color_names and "objects" not in converter.uses and \
                "tangents" not in converter.uses:
            return None
        tangent_uv = converter.tangent_uv if "tangents" in converter.uses else None
        return cls((tuple(converter.uv_names), tangent_uv, "objects" in converter.uses, color_names))


def _uv_layer(mesh, name):
    if name:
        return mesh.uv_layers.get(name)
    return next((layer for layer in mesh.uv_layers if layer.active_render), None)


def _srgb_to_linear(c):
    return np.where(c < 0.04045, np.maximum(c, 0.0) / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _named_attribute(mesh, name):
    if name:
        return mesh.attributes.get(name)
    colors = mesh.color_attributes  # "": the colour attribute set for rendering
    index = getattr(colors, "render_color_index", -1)
    return colors[index] if 0 <= index < len(colors) else None


# Attribute data types: (foreach_get property, components).
_ATTRIBUTE_LAYOUT = {"FLOAT_COLOR": ("color", 4), "BYTE_COLOR": ("color_srgb", 4), "FLOAT": ("value", 1),
                     "INT": ("value", 1), "FLOAT_VECTOR": ("vector", 3), "FLOAT2": ("vector", 2)}


def _attribute_rgba(mesh, name):
    """(values (K, 4) linear RGBA, domain) of a named attribute or UV map; None if the mesh has neither."""
    if name == geometry_attributes.POINTINESS:
        return geometry_attributes.pointiness_rgba(mesh), "POINT"
    attribute = _named_attribute(mesh, name)
    if attribute is None:
        layer = mesh.uv_layers.get(name) if name else None
        if layer is None:
            return None
        attribute, layout, domain = layer, ("uv", 2), "CORNER"
    else:
        layout, domain = _ATTRIBUTE_LAYOUT.get(attribute.data_type), attribute.domain
        if layout is None:
            return None
    prop, k = layout
    flat = np.empty(len(attribute.data) * k, dtype=np.float32)
    attribute.data.foreach_get(prop, flat)
    flat = flat.reshape(-1, k)
    rgba = np.zeros((flat.shape[0], 4), dtype=np.float32)
    rgba[:, 3] = 1.0
    if k == 1:
        rgba[:, :3] = flat  # Cycles: a float attribute reads as grey
    else:
        rgba[:, :k] = flat
    if getattr(attribute, "data_type", "") == "BYTE_COLOR":  # Cycles decodes sRGB bytes per corner
        rgba[:, :3] = _srgb_to_linear(rgba[:, :3])
    return rgba, domain


def _corner_colors(mesh, name, loops, warnings):
    """(M, 3, 4) per-corner RGBA of attribute `name` for add_mesh's `colors`; None if absent."""
    if name == geometry_attributes.RANDOM_PER_ISLAND:
        from . import native_module
        return geometry_attributes.random_per_island_corners(mesh, native_module(), loops)
    found = _attribute_rgba(mesh, name)
    if found is None:
        return None
    rgba, domain = found
    m = loops.shape[0] // 3
    if domain == "CORNER":
        return rgba[loops].reshape(m, 3, 4)
    if domain == "POINT":
        vertex_of_loop = np.empty(len(mesh.loops), dtype=np.int32)
        mesh.loops.foreach_get("vertex_index", vertex_of_loop)
        return rgba[vertex_of_loop[loops]].reshape(m, 3, 4)
    if domain == "FACE":
        polygon = np.empty(m, dtype=np.int32)
        mesh.loop_triangles.foreach_get("polygon_index", polygon)
        return np.repeat(rgba[polygon][:, None, :], 3, axis=1)
    warnings.append(f"Mesh '{mesh.name}': attribute '{name}' on the {domain.lower()} domain is not supported")
    return None


def _foreach_get_indices(collection, prop, count):
    """`count` indices of `prop` as int32. Fetched as uint32, the type Blender
    stores them in: foreach_get then copies the raw array (about 10x faster
    than converting to int32 element by element)."""
    out = np.empty(count, dtype=np.uint32)
    collection.foreach_get(prop, out)
    return out.view(np.int32)  # indices stay far below 2^31


# Per-loop rows of 8 or 16 bytes gathered as single wide elements: np.take on
# a 1-D array is several times faster than fancy indexing of (L, k) rows, and
# copies the bytes unchanged.
_ROW_VIEW = {8: np.int64, 16: np.complex128}


def _corner_rows(per_loop, loops):
    """(M, 3, k) per-corner rows of a C-contiguous (L, k) float32 array."""
    k = per_loop.shape[1]
    wide = _ROW_VIEW.get(4 * k)
    if wide is None:
        rows = per_loop[loops]
    else:
        rows = np.take(per_loop.view(wide).reshape(-1), loops).view(np.float32)
    return rows.reshape(-1, 3, k)


def shading_arrays(mesh, request, warnings, loops=None):
    """add_mesh's uvs / tangents / generated arguments for `request` (foreach_get, no Python loops).

    loops: the loop triangles' loop indices (M * 3 int32) when already fetched."""
    uv_names, tangent_uv, objects, color_names = request
    tris = mesh.loop_triangles
    m = len(tris)
    if loops is None:
        loops = _foreach_get_indices(tris, "loops", m * 3)
    loop_count = len(mesh.loops)
    uvs = []
    for name in uv_names:
        layer = _uv_layer(mesh, name)
        if layer is None:
            uvs.append(None)
            continue
        flat = np.empty(loop_count * 2, dtype=np.float32)
        layer.data.foreach_get("uv", flat)
        uvs.append(_corner_rows(flat.reshape(-1, 2), loops))
    args = {"uvs": uvs}
    if color_names:
        args["colors"] = [_corner_colors(mesh, name, loops, warnings) for name in color_names]
    if tangent_uv is not None:
        layer = _uv_layer(mesh, tangent_uv)
        try:
            if layer is None:
                raise RuntimeError(f"no UV map '{tangent_uv or 'active render'}'")
            mesh.calc_tangents(uvmap=layer.name)
            tangent = np.empty(loop_count * 3, dtype=np.float32)
            sign = np.empty(loop_count, dtype=np.float32)
            mesh.loops.foreach_get("tangent", tangent)
            mesh.loops.foreach_get("bitangent_sign", sign)
            mesh.free_tangents()  # 16 bytes per loop that Blender would otherwise keep
            corners = np.empty((loop_count, 4), dtype=np.float32)
            corners[:, :3] = tangent.reshape(-1, 3)
            corners[:, 3] = sign
            args["tangents"] = _corner_rows(corners, loops)
        except RuntimeError as error:
            warnings.append(f"Mesh '{mesh.name}': no tangents for normal maps ({error})")
    if objects:
        size = np.array(getattr(mesh, "texspace_size", (1.0, 1.0, 1.0)), dtype=np.float64)
        location = np.array(getattr(mesh, "texspace_location", (0.0, 0.0, 0.0)), dtype=np.float64)
        scale = np.where(size != 0.0, 0.5 / np.where(size != 0.0, size, 1.0), 0.0)
        args["generated"] = (tuple(scale), tuple(0.5 - location * scale))
    return args


def mesh_arrays(mesh, shading=None, warnings=None):
    """Extracts triangles from a bpy Mesh with foreach_get; None if it has no faces.

    shading: a ShadingRequest; the arrays then also carry the UVs, tangents
    and texture space it asks for."""
    mesh.calc_loop_triangles()
    tris = mesh.loop_triangles
    m = len(tris)
    if m == 0:
        return None
    n = len(mesh.vertices)
    positions = np.empty(n * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    # A loop triangle's vertices are its loops' vertices; both index arrays
    # copy raw, unlike the computed loop_triangles.vertices.
    loops = _foreach_get_indices(tris, "loops", m * 3)
    indices = np.take(_foreach_get_indices(mesh.loops, "vertex_index", len(mesh.loops)), loops)

    # Per-triangle material indices only matter with several slots, and
    # fetching them costs as much as the vertex indices: skip when possible.
    material_index = None
    if len(mesh.materials) > 1:
        material_index = np.empty(m, dtype=np.int32)
        tris.foreach_get("material_index", material_index)
        if not material_index.any():
            material_index = None

    # Shading normals only where they differ from the geometric normal: a
    # mesh with every face flat and no custom normals is rendered faceted.
    normals = None
    polys = mesh.polygons
    smooth = np.empty(len(polys), dtype=bool)
    polys.foreach_get("use_smooth", smooth)
    if smooth.any() or mesh.has_custom_normals:
        mesh.calc_normals_split()  # fills the loop normals that split_normals reads (Blender 3.x)
        normals = np.empty(m * 9, dtype=np.float32)
        tris.foreach_get("split_normals", normals)
        normals = normals.reshape(m, 3, 3)

    arrays = MeshArrays(positions.reshape(n, 3), indices.reshape(m, 3), normals, material_index)
    if shading is not None:
        arrays.shading = shading_arrays(mesh, shading, warnings if warnings is not None else [], loops)
        arrays.shading_request = shading
    return arrays


def _original_pointer(ob):
    original = ob.original
    return (original if original is not None else ob).as_pointer()


def mesh_cache_key(ob):
    """Key of the triangles an evaluated object renders: shared by all instances of them."""
    data = ob.data
    if ob.type == "MESH" and data is not None:
        # The evaluated object's data already has modifiers applied and is
        # shared by every instance of it: cache on the datablock.
        return ("MESH", data.as_pointer())
    # Curves/text/metaballs evaluate per object: cache per object (instances
    # of the same object still share it).
    return (ob.type, _original_pointer(ob), data.as_pointer() if data is not None else 0)


class MeshCache:
    """MeshArrays per mesh_cache_key, optionally kept across exports.

    A final render uses a fresh cache per export, unless persistent data
    keeps one across renders (persistent.py). An interactive viewport keeps
    one for its whole session so that a transform, material or light edit
    never re-extracts a mesh. Both must then drop the entries whose
    geometry changed (invalidate_objects / invalidate_data, driven by the
    depsgraph's geometry updates) and those no longer used (retain).
    """

    def __init__(self):
        self.arrays = {}    # key -> MeshArrays, or None for an object without faces
        self.users = {}     # key -> set of original object pointers that rendered it
        self.sources = {}   # key -> original data pointer (0 if none)
        self.extracted = 0  # meshes extracted over the cache's lifetime
        # Original objects whose geometry an update invalidated at least once:
        # they tend to change again (deforming, animated modifiers), so a
        # persistent-data export gives them BVHs of their own (persistent.py).
        self.changed_objects = set()

    def __len__(self):
        return len(self.arrays)

    def lookup(self, key, ob):
        """Cached arrays for `key` (KeyError if absent); records `ob` as a user."""
        arrays = self.arrays[key]
        self.users[key].add(_original_pointer(ob))
        return arrays

    def store(self, key, ob, arrays):
        data = ob.data
        original_data = getattr(data, "original", None) if data is not None else None
        self.arrays[key] = arrays
        self.users[key] = {_original_pointer(ob)}
        self.sources[key] = (original_data or data).as_pointer() if data is not None else 0
        self.extracted += 1

    def invalidate_objects(self, object_pointers):
        """Drops what these (original) objects rendered; returns whether anything was dropped."""
        return self._invalidate([k for k, users in self.users.items() if users & object_pointers])

    def invalidate_data(self, data_pointers):
        """Drops what was extracted from these (original or evaluated) datablocks."""
        return self._invalidate([k for k in self.arrays
                                 if self.sources[k] in data_pointers or (k[0] == "MESH" and k[1] in data_pointers)])

    def _invalidate(self, keys):
        for k in keys:
            self.changed_objects |= self.users[k]
        return self._drop(keys)

    def retain(self, keys):
        """Drops every entry not in `keys` (deleted or hidden objects)."""
        self._drop([k for k in self.arrays if k not in keys])

    def clear(self):
        self._drop(list(self.arrays))
        self.changed_objects.clear()

    def _drop(self, keys):
        for k in keys:
            del self.arrays[k], self.users[k], self.sources[k]
        return bool(keys)


class ExportResult:
    def __init__(self, scene):
        self.scene = scene
        self.warnings = []
        self.seconds = 0.0
        self.meshes = 0      # unique meshes extracted
        self.instances = 0   # mesh instances added
        self.lights = 0
        self.texture_bytes = 0  # image texture cache in use after export


class InstanceGroup:
    """Placements of one object's triangles with one set of materials.

    Each placement costs one matrix copy in a list; the list becomes one
    float32 array when the group is added to the scene. With motion blur,
    `closes` holds every placement's transform at shutter close (the open one
    for those that stand still) once any placement moves. For the Vector
    pass, `frames` likewise holds every placement's (previous, next frame)
    matrices once any placement moves between frames.
    """

    __slots__ = ("arrays", "mesh_key", "owner", "name", "slots", "material_ids", "matrices", "closes", "frames")

    def __init__(self, arrays, mesh_key, owner, name, slots, material_ids):
        self.arrays = arrays
        self.mesh_key = mesh_key
        self.owner = owner  # the original object's pointer
        self.name = name
        self.slots = slots
        self.material_ids = material_ids
        self.matrices = []
        self.closes = None
        self.frames = None

    def add(self, matrix, close=None, frames=None):
        self.matrices.append(matrix.copy())
        if close is not None and self.closes is None:
            self.closes = self.matrices[:-1]  # the earlier placements stand still
        if self.closes is not None:
            self.closes.append(self.matrices[-1] if close is None else close)
        if frames is not None and self.frames is None:
            self.frames = [(m, m) for m in self.matrices[:-1]]
        if self.frames is not None:
            self.frames.append((self.matrices[-1],) * 2 if frames is None else frames)

    def frame_array(self, k=None):
        """The (previous, next frame) matrices as float32 (K, 2, 4, 4), or
        placement k's as (2, 4, 4); None when no placement moves."""
        if self.frames is None:
            return None
        if k is not None:
            return np.asarray(self.frames[k], dtype=np.float32)
        return np.asarray(self.frames, dtype=np.float32).reshape(len(self.frames), 2, 4, 4)

    @staticmethod
    def matrix_array(matrices):
        """Matrices as a (K, 4, 4) float32 array (rows of each matrix in order)."""
        count = len(matrices)
        flat = np.fromiter(chain.from_iterable(chain.from_iterable(matrices)), np.float32, count=16 * count)
        return flat.reshape(count, 4, 4)

    def prototype_slots(self):
        """Slots for the shared mesh, whose triangles keep their material indices.

        Blender clamps an index past the last slot to the last slot, and a
        single slot applies to every face: padding with the last slot does both.
        """
        if not self.slots:
            return []
        needed = self.arrays.max_material_index + 1
        return self.slots + [self.slots[-1]] * max(0, needed - len(self.slots))


class SceneExporter:
    """Converts one evaluated depsgraph into a native Scene."""

    def __init__(self, native, depsgraph, width, height, camera_override=None, need_camera=True, mesh_cache=None,
                 motion=None, separate_objects=frozenset(), frame_motion=None):
        self.native = native
        # Object motion blur: {motion.instance_key: (matrix_open, matrix_close)}
        # for the instances that move during the shutter (motion.py).
        self.motion = motion or {}
        # Vector pass: {motion.instance_key: (matrix_previous, matrix_next)}
        # for the instances that move between frames (motion.frame_matrices).
        self.frame_motion = frame_motion or {}
        self.depsgraph = depsgraph
        self.width = width
        self.height = height
        self.camera_override = camera_override
        self.need_camera = need_camera  # False for viewports, which bring their own view
        self.result = ExportResult(native.Scene())
        self.materials = materials.MaterialConverter(self.result.scene, self.result.warnings,
                                                     fold=getattr(native, "fold_shader_constants", None),
                                                     images=images.ImageExporter(
                                                         self.result.scene,
                                                         getattr(native, "image_file_format", None),
                                                         getattr(native, "content_hash", None)))
        self.shading = None  # ShadingRequest of the materials, set by export()
        self.mesh_cache = mesh_cache if mesh_cache is not None else MeshCache()
        self.used_keys = set()  # mesh_cache keys this export rendered
        self.extracted_keys = set()  # those it extracted (not found in the cache)
        # Objects whose triangles go into a BVH of their own (a prototype)
        # even when placed once, so that a change rebuilds only them.
        self.separate_objects = separate_objects
        self.flattened_keys = []  # mesh_cache key of each add_mesh, in order: the world-space triangles
        self._unsupported_types = set()
        # (original object, evaluated data) -> InstanceGroup, or None when it has no triangles
        self._groups = {}

    def export(self, cancelled=lambda: False):
        start = time.perf_counter()
        depsgraph = self.depsgraph
        bscene = depsgraph.scene  # evaluated scene
        if self.need_camera:
            self._export_camera(bscene)
        # Shader programs decide which mesh attributes are exported, so every
        # material is converted before the first mesh.
        if getattr(depsgraph.view_layer, "use_pass_uv", False):
            self.materials.uv_index("")  # the UV pass reads the active render UV map, even if no material does
        self.materials.prepare([i for i in depsgraph.ids if type(i).__name__ == "Material"])
        self.shading = ShadingRequest.of(self.materials)

        # Since Blender 3.0 curves, text, surfaces and metaballs reach render
        # engines as an extra MESH instance whose parent is the object itself.
        # The object entry is kept aside and exported through to_mesh() only
        # if no such instance showed up, so nothing is rendered twice.
        pending = {}   # original object pointer -> (evaluated object, matrix)
        covered = set()
        for count, inst in enumerate(depsgraph.object_instances):
            # Asking Blender costs about a microsecond: once per 256 instances
            # keeps cancelling prompt at a fraction of a scatter's export time.
            if count & 255 == 255 and cancelled():
                break
            if not getattr(inst, "show_self", True):
                continue
            ob = inst.object
            kind = ob.type
            if kind == "MESH":
                if inst.is_instance and inst.parent is not None:
                    covered.add(_original_pointer(inst.parent))
                self._export_mesh_instance(inst, ob, inst.matrix_world)
            elif kind in _MESH_TYPES:
                if not inst.is_instance:
                    pending[_original_pointer(ob)] = (ob, np.array(inst.matrix_world, dtype=np.float32))
            elif kind == "LIGHT":
                self._export_light(ob, np.array(inst.matrix_world, dtype=np.float64))
            elif kind not in _SILENT_TYPES and kind not in self._unsupported_types:
                self._unsupported_types.add(kind)
                self.result.warnings.append(f"objects of type {kind} are not supported and were skipped "
                                            f"(first: '{ob.name}')")
        for key, (ob, matrix) in pending.items():
            if key not in covered:
                self._export_mesh_instance(None, ob, matrix)
        self._add_instance_groups()

        export_world(bscene.world, self.result.scene, self.result.warnings)
        textures = self.result.scene.texture_stats()
        self.result.warnings.extend(textures["warnings"])
        self.result.texture_bytes = textures["memory_bytes"]
        summary = self.result.scene.dropped_summary
        if summary:
            self.result.warnings.append(summary)
        self.result.seconds = time.perf_counter() - start
        return self.result

    # -- geometry -------------------------------------------------------------

    def _mesh_for(self, ob):
        """Cached MeshArrays for this instance's geometry (None if empty)."""
        key = mesh_cache_key(ob)
        self.used_keys.add(key)
        try:
            arrays = self.mesh_cache.lookup(key, ob)
            if arrays is None or arrays.shading_request == self.shading:
                return arrays
        except KeyError:
            pass

        arrays = None
        data = ob.data
        if ob.type == "MESH" and data is not None and not data.is_editmode:
            arrays = mesh_arrays(data, self.shading, self.result.warnings)
        else:
            mesh = ob.to_mesh()
            try:
                if mesh is not None:
                    arrays = mesh_arrays(mesh, self.shading, self.result.warnings)
            finally:
                ob.to_mesh_clear()
        self.mesh_cache.store(key, ob, arrays)
        self.extracted_keys.add(key)
        if arrays is not None:
            self.result.meshes += 1
        return arrays

    def _material_binding(self, ob, arrays):
        """(slots, material_ids) for add_mesh: slot -> native material, resolved
        per object (objects sharing a mesh may link different materials)."""
        slots = [self.materials.index_of(slot.material) for slot in ob.material_slots]
        if not slots and ob.data is not None and hasattr(ob.data, "materials"):
            slots = [self.materials.index_of(m) for m in ob.data.materials]
        material_ids = None
        if len(slots) > 1 and arrays.material_index is not None:
            material_ids = arrays.material_index
            if arrays.max_material_index >= len(slots):
                # Blender clamps out-of-range material indices to the last slot.
                material_ids = np.minimum(material_ids, len(slots) - 1)
        elif slots:
            slots = slots[:1]
        return slots, material_ids

    def _group_for(self, inst, ob):
        """The InstanceGroup of this object's triangles and materials (None if it has none).

        Keyed by the original object and the evaluated data: the two decide
        the triangles and the material slots, while the evaluated object
        itself may be a temporary that Blender reuses for every instance.
        """
        data = ob.data
        key = (_original_pointer(ob), data.as_pointer() if data is not None else 0)
        try:
            return self._groups[key]
        except KeyError:
            pass
        arrays = self._mesh_for(ob)
        group = None
        if arrays is not None:
            name = ob.name
            if inst is not None and inst.is_instance and inst.parent is not None and inst.parent.name != ob.name:
                name = f"{inst.parent.name}/{ob.name}"
            slots, material_ids = self._material_binding(ob, arrays)
            group = InstanceGroup(arrays, mesh_cache_key(ob), key[0], name, slots, material_ids)
        self._groups[key] = group
        return group

    def _export_mesh_instance(self, inst, ob, matrix):
        """Queues one placement (`matrix`: object to world, a Matrix or a 4x4 array)."""
        group = self._group_for(inst, ob)
        if group is None:
            return
        key = motion.instance_key(inst, ob) if self.motion or self.frame_motion else None
        frames = self.frame_motion.get(key) if self.frame_motion else None
        moving = self.motion.get(key) if self.motion else None
        if moving is not None:
            group.add(*moving, frames=frames)
            return
        group.add(matrix, frames=frames)

    def _add_flattened(self, group, matrix, matrix_close=None, frame_matrices=None):
        arrays = group.arrays
        self.result.scene.add_mesh(group.name, arrays.positions, arrays.indices, np.asarray(matrix, dtype=np.float32),
                                   normals=arrays.normals, material_ids=group.material_ids,
                                   material_slots=group.slots, matrix_close=matrix_close,
                                   frame_matrices=frame_matrices, **(arrays.shading or {}))
        self.flattened_keys.append(group.mesh_key)
        self.result.instances += 1

    def _add_instance_groups(self):
        """Adds the queued placements: a mesh placed once as world-space
        triangles (as without instancing), else once as a prototype plus a
        matrix per placement (linked duplicates too: several groups, one mesh).
        A separate object's mesh is a prototype even when placed once."""
        scene = self.result.scene
        placements = {}  # mesh_cache_key -> placements over every group
        for group in self._groups.values():
            if group is not None:
                placements[group.mesh_key] = placements.get(group.mesh_key, 0) + len(group.matrices)
        prototypes = {}  # mesh_cache_key -> prototype index
        for group in self._groups.values():
            if group is None or not group.matrices:
                continue
            if placements[group.mesh_key] == 1 and group.owner not in self.separate_objects:
                for k, matrix in enumerate(group.matrices):
                    self._add_flattened(group, matrix, group.closes[k] if group.closes else None, group.frame_array(k))
                group.matrices = []
                continue
            arrays = group.arrays
            proto = prototypes.get(group.mesh_key)
            if proto is None:
                proto = scene.add_prototype(group.name, arrays.positions, arrays.indices, normals=arrays.normals,
                                            material_ids=arrays.material_index, **(arrays.shading or {}))
                prototypes[group.mesh_key] = proto
            if proto >= 0:
                closes = None if group.closes is None else group.matrix_array(group.closes)
                scene.add_instances(proto, group.matrix_array(group.matrices), material_slots=group.prototype_slots(),
                                    name=group.name, matrices_close=closes, frame_matrices=group.frame_array())
            self.result.instances += len(group.matrices)
            group.matrices = []

    # -- lights -----------------------------------------------------------------

    def _export_light(self, ob, matrix):
        light = light_arguments(ob, matrix, self.result.warnings)
        if light is None:
            return
        kind, args = light
        self.result.scene.add_light(kind, **args)
        self.result.lights += 1

    # -- camera -------------------------------------------------------------------

    def _export_camera(self, bscene):
        cam_ob = self.camera_override or bscene.camera
        if cam_ob is None:
            raise ExportError(f"scene '{bscene.name}' has no active camera: add a camera and make it active "
                              f"(Scene Properties > Camera)")
        cam_ob = cam_ob.evaluated_get(self.depsgraph)
        if cam_ob.type != "CAMERA":
            raise ExportError(f"the active camera '{cam_ob.name}' is a {cam_ob.type} object, not a camera")
        self.result.scene.set_camera(**camera_parameters(cam_ob, bscene.render, self.width, self.height,
                                                          self.result.warnings))


def light_arguments(ob, matrix, warnings):
    """(type, keyword arguments) of Scene.add_light for an evaluated light object, or None to skip it."""
    light = ob.data
    if light.energy <= 0.0 or max(light.color) <= 0.0:
        return None
    position = matrix[:3, 3]
    x_axis, y_axis, z_axis = matrix[:3, 0], matrix[:3, 1], matrix[:3, 2]
    direction = -z_axis  # lights shine along local -Z
    if np.linalg.norm(direction) < 1e-12:
        warnings.append(f"light '{ob.name}' has zero scale and was skipped")
        return None
    args = dict(color=tuple(light.color), power=float(light.energy), position=tuple(position),
                direction=tuple(direction))
    kind = light.type
    if kind in ("POINT", "SPOT"):
        args["radius"] = float(light.shadow_soft_size)
        if kind == "SPOT":
            args["spot_size"] = float(light.spot_size)
            args["spot_blend"] = float(light.spot_blend)
    elif kind == "SUN":
        args["sun_angle"] = float(light.angle)
    elif kind == "AREA":
        # Object scale stretches the emitter: sizes along the scaled axes.
        su, sv = float(np.linalg.norm(x_axis)), float(np.linalg.norm(y_axis))
        if su < 1e-12 or sv < 1e-12:
            warnings.append(f"area light '{ob.name}' has zero scale and was skipped")
            return None
        shape = light.shape
        size_u = float(light.size) * su
        size_v = (float(light.size) if shape in ("SQUARE", "DISK") else float(light.size_y)) * sv
        if shape == "SQUARE" and abs(size_u - size_v) > 1e-6 * max(size_u, size_v):
            shape = "RECTANGLE"
        elif shape == "DISK" and abs(size_u - size_v) > 1e-6 * max(size_u, size_v):
            shape = "ELLIPSE"
        args.update(shape=shape, size_u=size_u, size_v=size_v,
                    axis_u=tuple(x_axis / su), axis_v=tuple(y_axis / sv))
    else:
        warnings.append(f"light '{ob.name}' of type {kind} is not supported and was skipped")
        return None
    return kind, args


def camera_parameters(cam_ob, render, width, height, warnings=None):
    """Keyword arguments of Scene.set_camera for a Blender camera object.

    Follows Cycles (intern/cycles/blender/camera.cpp): the sensor is fitted to
    the horizontal or vertical image extent (AUTO: the larger one), shift is in
    units of the fitted extent, and the depth-of-field aperture radius is
    lens / (2 f-number) with the lens in metres.
    """
    cam = cam_ob.data
    m = np.array(cam_ob.matrix_world, dtype=np.float64)
    right, up, back = m[:3, 0], m[:3, 1], m[:3, 2]
    position = m[:3, 3]

    xratio = float(width) * render.pixel_aspect_x
    yratio = float(height) * render.pixel_aspect_y
    fit = cam.sensor_fit
    if fit == "AUTO":
        horizontal = xratio >= yratio
        sensor = cam.sensor_width
    elif fit == "HORIZONTAL":
        horizontal, sensor = True, cam.sensor_width
    else:
        horizontal, sensor = False, cam.sensor_height

    if cam.type == "ORTHO":
        fitted_half = 0.5 * cam.ortho_scale  # world units
    else:
        if cam.type == "PANO" and warnings is not None:
            warnings.append(f"panoramic camera '{cam_ob.name}' is not supported: rendered as perspective")
        fitted_half = 0.5 * sensor / cam.lens  # tan(fov / 2)
    if horizontal:
        half_width, half_height = fitted_half, fitted_half * yratio / xratio
    else:
        half_width, half_height = fitted_half * xratio / yratio, fitted_half

    # Blender's shift is a fraction of the fitted extent; the native camera
    # measures it in units of the larger extent.
    larger = max(half_width, half_height)
    shift_scale = fitted_half / larger

    aperture_radius, focus_distance = 0.0, 10.0
    if cam.dof.use_dof:
        fstop = max(cam.dof.aperture_fstop, 1e-5)
        if cam.type == "ORTHO":
            aperture_radius = 1.0 / (2.0 * fstop)
        else:
            aperture_radius = (cam.lens * 1e-3) / (2.0 * fstop)
        focus_distance = camera_focus_distance(cam_ob)
        if not (focus_distance > 0.0):
            focus_distance = 1e-3

    return dict(
        projection="ORTHO" if cam.type == "ORTHO" else "PERSP",
        position=tuple(position), forward=tuple(-back), up=tuple(up), right=tuple(right),
        half_width=half_width, half_height=half_height,
        shift_x=cam.shift_x * shift_scale, shift_y=cam.shift_y * shift_scale,
        clip_start=max(cam.clip_start, 0.0), clip_end=max(cam.clip_end, cam.clip_start + 1e-6),
        aperture_radius=aperture_radius, focus_distance=focus_distance,
    )


def camera_focus_distance(cam_ob):
    """Focus distance: along the view axis to the focus object's origin, else the typed distance."""
    dof = cam_ob.data.dof
    target = dof.focus_object
    if target is None:
        return float(dof.focus_distance)
    cm = np.array(cam_ob.matrix_world, dtype=np.float64)
    tm = np.array(target.matrix_world, dtype=np.float64)
    view = cm[:3, 2]
    norm = np.linalg.norm(view)
    if norm < 1e-12:
        return float(dof.focus_distance)
    return float(abs(np.dot(view / norm, cm[:3, 3] - tm[:3, 3])))


def scan_instances(depsgraph):
    """What the depsgraph renders, cheaply and without extracting geometry.

    Returns (geometry, lights). `geometry` has one entry per surface
    instance: its mesh_cache_key, object-to-world matrix and slot materials;
    two equal `geometry` values place the same cached triangles in the same
    places with the same materials (edits of the triangles themselves show up
    as depsgraph geometry updates instead). `lights` lists light_arguments().
    Instances are only valid while iterating, hence one pass that copies.
    """
    geometry, lights, warnings = [], [], []
    for inst in depsgraph.object_instances:
        if not getattr(inst, "show_self", True):
            continue
        ob = inst.object
        kind = ob.type
        if kind in _MESH_TYPES:
            slots = tuple(slot.material.original.as_pointer() if slot.material is not None else 0
                          for slot in ob.material_slots)
            geometry.append((mesh_cache_key(ob), inst.is_instance,
                             np.array(inst.matrix_world, dtype=np.float32).tobytes(), slots))
        elif kind == "LIGHT":
            light = light_arguments(ob, np.array(inst.matrix_world, dtype=np.float64), warnings)
            if light is not None:
                lights.append(light)
    return tuple(geometry), lights


def export_scene(native, depsgraph, width, height, camera_override=None, cancelled=lambda: False,
                 need_camera=True, mesh_cache=None, motion=None, frame_motion=None):
    """Exports the evaluated depsgraph; returns an ExportResult (scene, warnings, counts, seconds).

    width/height (pixels) only serve the camera's sensor fit; with
    need_camera=False the scene camera is ignored (viewports). `mesh_cache`
    (a MeshCache) lets an interactive session reuse extracted meshes.
    `motion` (motion.shutter_matrices) makes the instances it lists move
    during the shutter (object motion blur); `frame_motion`
    (motion.frame_matrices) gives those it lists their Vector pass motion.
    """
    exporter = SceneExporter(native, depsgraph, width, height, camera_override, need_camera, mesh_cache, motion,
                             frame_motion=frame_motion)
    return exporter.export(cancelled)
