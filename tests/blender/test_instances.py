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


TEXTURED_DUPLICATES = """
import sys
import bpy
engine, out, samples = sys.argv[sys.argv.index("--") + 1:]
scene = bpy.context.scene
for ob in list(bpy.data.objects):
    bpy.data.objects.remove(ob, do_unlink=True)
mat = bpy.data.materials.new("checker_bumps")
mat.use_nodes = True
nodes, links = mat.node_tree.nodes, mat.node_tree.links
bsdf = nodes["Principled BSDF"]
coords = nodes.new("ShaderNodeTexCoord")
color = nodes.new("ShaderNodeTexChecker")
color.inputs["Scale"].default_value = 6.0
color.inputs["Color1"].default_value = (0.8, 0.2, 0.1, 1.0)
color.inputs["Color2"].default_value = (0.1, 0.3, 0.8, 1.0)
bumps = nodes.new("ShaderNodeTexChecker")
bumps.inputs["Scale"].default_value = 4.0
bumps.inputs["Color1"].default_value = (0.5, 0.5, 1.0, 1.0)
bumps.inputs["Color2"].default_value = (0.8, 0.5, 0.8, 1.0)
normal_map = nodes.new("ShaderNodeNormalMap")
links.new(coords.outputs["UV"], color.inputs["Vector"])
links.new(coords.outputs["UV"], bumps.inputs["Vector"])
links.new(bumps.outputs["Color"], normal_map.inputs["Color"])
links.new(color.outputs["Color"], bsdf.inputs["Base Color"])
links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.9, location=(-2.0, 0.0, 1.0))
bpy.ops.object.shade_smooth()
sphere = bpy.context.active_object
sphere.data.materials.append(mat)
# Linked duplicates (one mesh): rotated, scaled and mirrored.
for k, (location, rotation, scale) in enumerate([((0.0, 0.0, 1.0), (0.4, 0.0, 1.0), (1.0, 1.0, 1.0)),
                                                  ((2.0, 0.0, 1.0), (0.0, 0.7, 0.0), (-1.0, 0.8, 1.2))]):
    dup = bpy.data.objects.new(f"dup{k}", sphere.data)
    dup.location, dup.rotation_euler, dup.scale = location, rotation, scale
    scene.collection.objects.link(dup)
bpy.ops.mesh.primitive_plane_add(size=20.0)
bpy.ops.object.light_add(type="SUN", rotation=(0.5, 0.2, 0.3))
bpy.context.active_object.data.energy = 3.0
bpy.ops.object.camera_add(location=(0.0, -7.0, 2.5), rotation=(1.3, 0.0, 0.0))
scene.camera = bpy.context.active_object
scene.world.color = (0.2, 0.2, 0.2)
render = scene.render
render.engine = engine
render.resolution_x, render.resolution_y, render.resolution_percentage = 96, 48, 100
render.image_settings.file_format = "OPEN_EXR"
render.filepath = out
if engine == "CYCLES":
    scene.cycles.samples = int(samples)
    scene.cycles.use_denoising = False
    scene.cycles.device = "CPU"
else:
    scene.coherent.samples = int(samples)
    from coherent import export, native_module
    depsgraph = bpy.context.evaluated_depsgraph_get()
    s = export.export_scene(native_module(), depsgraph, 8, 8, need_camera=False).scene
    print(f"TEXTURED prototypes={s.prototype_count} instances={s.instance_count}")
bpy.ops.render.render(write_still=True)
"""


def test_textured_instances_shade_with_their_uvs_and_tangents(blender, tmp_path):
    # A UV-mapped sphere with a checker on its UVs and a normal map (tangent
    # space), placed three times (one mirrored) as linked duplicates: one
    # prototype that carries its UVs and tangents, shaded as Cycles does.
    script = tmp_path / "textured.py"
    script.write_text(TEXTURED_DUPLICATES)
    images = {}
    for engine in (bh.ENGINE_ID, "CYCLES"):
        out = tmp_path / f"{engine.lower()}.exr"
        result = blender("--python", script, "--", engine, out, "64")
        assert result.returncode == 0, result.describe()
        if engine == bh.ENGINE_ID:
            assert "TEXTURED prototypes=1 instances=3" in result.output, result.describe()
        channels = bh.read_image_channels(out)
        images[engine] = np.stack([channels[c] for c in "RGB"], axis=-1)
    ours, cycles = images[bh.ENGINE_ID], images["CYCLES"]
    assert np.isfinite(ours).all()
    means = ours.reshape(-1, 3).mean(axis=0), cycles.reshape(-1, 3).mean(axis=0)
    assert np.all(np.abs(means[0] / means[1] - 1.0) < 0.03), means
    # 12 x 6 blocks of 8 x 8 pixels: the checker's red and blue and the
    # normal map's shading where Cycles has them (a checker on the wrong
    # UVs, or unmapped tangents, moves whole blocks).
    block = lambda img: img.reshape(6, 8, 12, 8, 3).mean(axis=(1, 3))  # noqa: E731
    diff = np.abs(block(ours) - block(cycles))
    assert diff.max() < 0.08 * cycles.mean() + 0.02, diff.max()
