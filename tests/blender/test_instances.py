# Instancing through Blender: a Geometry Nodes scatter (Instance on Points of
# an Ico Sphere on a grid, left unrealized) reaches the native scene as one
# shared mesh plus a matrix per instance, and renders as Cycles renders it.

import re
from pathlib import Path

import numpy as np

import blender_helpers as bh

SCRIPT = Path(__file__).with_name("scatter_scene.py")
GRID, SUBDIVISIONS = 6, 3  # 36 instances of a 320-triangle ico sphere


def run_scatter(blender, engine, tmp_path, samples=0, size=48, export_only=False):
    out = tmp_path / engine.lower()
    args = [engine, out, GRID, SUBDIVISIONS, samples, size] + (["1"] if export_only else [])
    result = blender("--python", SCRIPT, "--", *map(str, args))
    assert result.returncode == 0, result.describe()
    return result, Path(str(out) + ".exr")


def test_scatter_exports_one_shared_mesh_not_a_copy_per_instance(blender, tmp_path):
    result, _ = run_scatter(blender, bh.ENGINE_ID, tmp_path, export_only=True)
    line = re.search(r"SCATTER_EXPORT (.*)", result.output)
    assert line, result.describe()
    counts = dict(kv.split("=") for kv in line.group(1).split())
    assert int(counts["prototypes"]) == 1, counts
    assert int(counts["instances"]) == GRID * GRID, counts
    ico_triangles = 20 * 4 ** (SUBDIVISIONS - 1)
    assert int(counts["instanced_triangles"]) == GRID * GRID * ico_triangles, counts
    assert int(counts["triangles"]) == 2, counts  # the floor, placed once, stays world-space


def test_scatter_renders_as_cycles_does(blender, tmp_path):
    images = {}
    for engine in (bh.ENGINE_ID, "CYCLES"):
        result, path = run_scatter(blender, engine, tmp_path, samples=64)
        assert path.is_file(), result.describe()
        channels = bh.read_image_channels(path)
        rgb = np.stack([channels[c] for c in "RGB"], axis=-1)
        assert np.isfinite(rgb).all()
        images[engine] = rgb.mean(axis=2)
        if engine == bh.ENGINE_ID:
            assert f"{GRID * GRID} instances of 1 shared meshes" in result.output, result.describe()
    ours, cycles = images[bh.ENGINE_ID], images["CYCLES"]
    print("scatter means", ours.mean(), cycles.mean())
    assert abs(ours.mean() / cycles.mean() - 1.0) < 0.03, (ours.mean(), cycles.mean())
    # 8 x 8 blocks of 36 pixels x 64 samples: the spheres' shading and
    # shadows in place, not just the mean.
    block = lambda img: img.reshape(8, 6, 8, 6).mean(axis=(1, 3))  # noqa: E731
    assert np.abs(block(ours) - block(cycles)).max() < 0.1 * cycles.mean() + 0.02, (block(ours), block(cycles))


LINKED_DUPLICATES = """
import bpy
from coherent import export, native_module
for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob, do_unlink=True)
bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2)
original = bpy.context.active_object
for k in range(3):  # linked duplicates: new objects sharing the sphere's mesh
    dup = bpy.data.objects.new(f"dup{k}", original.data)
    dup.location = (3.0 * (k + 1), 0.0, 0.0)
    bpy.context.scene.collection.objects.link(dup)
bpy.ops.mesh.primitive_plane_add(size=20.0)
depsgraph = bpy.context.evaluated_depsgraph_get()
s = export.export_scene(native_module(), depsgraph, 8, 8, need_camera=False).scene
print(f"LINKED prototypes={s.prototype_count} instances={s.instance_count} triangles={s.triangle_count} "
      f"instanced_triangles={s.instanced_triangle_count}")
"""


def test_linked_duplicates_share_one_prototype(blender, tmp_path):
    script = tmp_path / "linked.py"
    script.write_text(LINKED_DUPLICATES)
    result = blender("--python", script)
    assert result.returncode == 0, result.describe()
    line = re.search(r"LINKED (.*)", result.output)
    assert line, result.describe()
    counts = dict(kv.split("=") for kv in line.group(1).split())
    # Four objects share the sphere (80 triangles): one prototype, four
    # instances; the plane, used once, stays world-space triangles.
    assert counts == {"prototypes": "1", "instances": "4", "triangles": "2", "instanced_triangles": "320"}, counts
