"""Mesh attributes Cycles derives from the geometry itself, computed only for
meshes whose materials read them: the Geometry node's Pointiness (numpy) and
Random Per Island (native: scene/mesh_islands.h, a sequential union-find).

They travel to the renderer as colour attributes under reserved names (a
leading dot: Blender keeps such names for its internal attributes), so the
shader program reads them with the ATTRIBUTE instruction like any other
(shader_compiler._geometry).
"""

import numpy as np

from .shader_compiler import POINTINESS_ATTRIBUTE as POINTINESS
from .shader_compiler import RANDOM_PER_ISLAND_ATTRIBUTE as RANDOM_PER_ISLAND

_FLT_EPSILON = np.float32(np.finfo(np.float32).eps)


def _welded(positions):
    """Cycles' attr_create_pointiness step 1: each vertex's representative
    among the vertices at (nearly) the same place (squared distance below
    FLT_EPSILON, coordinate sums within 3 FLT_EPSILON), the lowest index of
    exact duplicates. Vertices sorted by coordinate sum, exact duplicates by
    descending index (Cycles' comparator); each looks ahead in that order
    while the sums stay that close: one vectorised pass per step ahead."""
    n = positions.shape[0]
    sums = (positions[:, 0] + positions[:, 1]) + positions[:, 2]  # float32, in Cycles' order
    order = np.lexsort((-np.arange(n), positions[:, 2], positions[:, 1], positions[:, 0], sums))
    target = np.arange(n)
    open_ = np.ones(n, dtype=bool)  # sorted positions still looking ahead
    for step in range(1, n):
        idx = np.nonzero(open_[: n - step])[0]
        if idx.size == 0:
            break
        a, b = order[idx], order[idx + step]
        near = (sums[b] - sums[a]) <= 3 * _FLT_EPSILON
        d = positions[b] - positions[a]
        dup = near & (np.einsum("ij,ij->i", d, d) < _FLT_EPSILON)
        target[a[dup]] = b[dup]
        open_[idx[~near | dup]] = False
    # Follow the chains to their end (Cycles' "very first orig vertex").
    while True:
        nxt = target[target]
        if np.array_equal(nxt, target):
            return target
        target = nxt


def pointiness(positions, normals, edges):
    """Cycles 3.4 attr_create_pointiness: per vertex, the angle between the
    (welded) vertex normal and the mean direction of its unique edges, over
    pi, averaged with its edge neighbours (a two-ring blur).

    positions, normals: (N, 3) float32; edges: (E, 2) vertex indices."""
    n = positions.shape[0]
    orig = _welded(positions)
    normal_sum = np.zeros((n, 3), dtype=np.float32)
    np.add.at(normal_sum, orig, normals)
    length = np.sqrt(np.einsum("ij,ij->i", normal_sum, normal_sum))
    vert_normal = normal_sum / np.where(length > 0, length, 1)[:, None]
    # Unique edges between representatives (Cycles' EdgeMap), in first-seen order.
    v = np.sort(orig[edges], axis=1)
    _, first = np.unique(v[:, 0].astype(np.int64) * n + v[:, 1], return_index=True)
    v = orig[edges][np.sort(first)]
    v0, v1 = v[:, 0], v[:, 1]
    d = positions[v1] - positions[v0]
    d_len = np.sqrt(np.einsum("ij,ij->i", d, d))
    keep = d_len > 0  # a welded edge has no direction (Cycles: a NaN)
    v0, v1, d = v0[keep], v1[keep], d[keep] / d_len[keep][:, None]
    accum = np.zeros((n, 3), dtype=np.float32)
    np.add.at(accum, v0, d)
    np.add.at(accum, v1, -d)
    counter = np.bincount(v0, minlength=n) + np.bincount(v1, minlength=n)
    mean = accum / np.maximum(counter, 1)[:, None].astype(np.float32)
    cos = np.clip(np.einsum("ij,ij->i", vert_normal, mean), -1.0, 1.0)
    raw = np.where((counter > 0) & (orig == np.arange(n)), np.arccos(cos) * np.float32(1 / np.pi), 0.0)
    raw = raw.astype(np.float32)
    data = raw.copy()
    np.add.at(data, v0, raw[v1])
    np.add.at(data, v1, raw[v0])
    data /= (counter + 1).astype(np.float32)
    return data[orig]


def pointiness_rgba(mesh):
    """(N, 4) grey RGBA per vertex of `mesh`'s pointiness (a POINT-domain colour)."""
    n = len(mesh.vertices)
    positions = np.empty(n * 3, dtype=np.float32)
    normals = np.empty(n * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", positions)
    mesh.vertices.foreach_get("normal", normals)
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", edges)
    p = pointiness(positions.reshape(n, 3), normals.reshape(n, 3), edges.reshape(-1, 2)) if n else \
        np.zeros(0, dtype=np.float32)
    rgba = np.ones((n, 4), dtype=np.float32)
    rgba[:, :3] = p[:, None]
    return rgba


def random_per_island_corners(mesh, native, loops):
    """(M, 3, 4) per-corner grey RGBA of Random Per Island: one value per loop
    triangle (`loops`: their loop indices), constant over it, as Cycles' face
    attribute."""
    edges = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", edges)
    vertex_of_loop = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", vertex_of_loop)
    first = vertex_of_loop[loops[0::3]]
    values = native.random_per_island(len(mesh.vertices), edges, first)
    rgba = np.ones((first.shape[0], 3, 4), dtype=np.float32)
    rgba[..., :3] = values[:, None, None]
    return rgba
