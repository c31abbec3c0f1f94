# Builds, in a factory-startup Blender, a Geometry Nodes scatter and renders
# it: Instance on Points of an Ico Sphere (unrealized instances, one mesh)
# on an N x N grid, with random rotations and scales, over a floor, lit by a
# sun and a grey world. Used by test_instances.py and bench/instances.py.
#
#   blender -b --factory-startup [--addons coherent] --python scatter_scene.py -- \
#       ENGINE OUT GRID SUBDIVISIONS SAMPLES SIZE [EXPORT_ONLY]
#     ENGINE        COHERENT or CYCLES
#     OUT           output path prefix (an .exr is written)
#     GRID          N: N x N instances
#     SUBDIVISIONS  of the Ico Sphere (6: 20,480 triangles)
#     SAMPLES       samples per pixel
#     SIZE          image width and height in pixels
#     EXPORT_ONLY   1: only export the scene (COHERENT), print its counts and time
#
# Prints "SCATTER_SECONDS <seconds>" (render or export wall time), the
# process's peak and current resident memory ("SCATTER_MEMORY peak_kib=..
# current_kib=..") and, for COHERENT, "SCATTER_EXPORT prototypes=..
# instances=.. triangles=.. instanced_triangles=.. seconds=..".
import sys
import time

import bpy

engine, out, grid, subdivisions, samples, size = sys.argv[sys.argv.index("--") + 1:][:6]
export_only = sys.argv[sys.argv.index("--") + 1:][6:7] == ["1"]
grid, subdivisions, samples, size = int(grid), int(subdivisions), int(samples), int(size)

scene = bpy.context.scene
for ob in list(scene.objects):
    bpy.data.objects.remove(ob, do_unlink=True)


def grey_material(name, value):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (value, value, value, 1.0)
    out = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


bpy.ops.mesh.primitive_plane_add(size=12.0, location=(0.0, 0.0, 0.0))
bpy.context.active_object.data.materials.append(grey_material("floor", 0.5))

# The scatter: an empty mesh object whose modifier outputs the instances.
holder = bpy.data.objects.new("scatter", bpy.data.meshes.new("scatter"))
scene.collection.objects.link(holder)
tree = bpy.data.node_groups.new("scatter", "GeometryNodeTree")
tree.outputs.new("NodeSocketGeometry", "Geometry")
nodes, links = tree.nodes, tree.links
output = nodes.new("NodeGroupOutput")
points = nodes.new("GeometryNodeMeshGrid")
points.inputs["Size X"].default_value = 10.0
points.inputs["Size Y"].default_value = 10.0
points.inputs["Vertices X"].default_value = grid
points.inputs["Vertices Y"].default_value = grid
ico = nodes.new("GeometryNodeMeshIcoSphere")
ico.inputs["Radius"].default_value = 0.6 * 10.0 / max(grid, 2)
ico.inputs["Subdivisions"].default_value = subdivisions
set_material = nodes.new("GeometryNodeSetMaterial")
set_material.inputs["Material"].default_value = grey_material("rock", 0.8)
rotation = nodes.new("FunctionNodeRandomValue")
rotation.data_type = "FLOAT_VECTOR"
rotation.inputs["Max"].default_value = (6.2831853, 6.2831853, 6.2831853)
scale = nodes.new("FunctionNodeRandomValue")
scale.data_type = "FLOAT"
scale.inputs[2].default_value = 0.6  # Min (float)
scale.inputs[3].default_value = 1.2  # Max (float)
instance = nodes.new("GeometryNodeInstanceOnPoints")
links.new(ico.outputs["Mesh"], set_material.inputs["Geometry"])
links.new(points.outputs["Mesh"], instance.inputs["Points"])
links.new(set_material.outputs["Geometry"], instance.inputs["Instance"])
links.new(rotation.outputs[0], instance.inputs["Rotation"])
links.new(scale.outputs[1], instance.inputs["Scale"])
links.new(instance.outputs["Instances"], output.inputs["Geometry"])
holder.modifiers.new("scatter", "NODES").node_group = tree

sun_data = bpy.data.lights.new("sun", "SUN")
sun_data.energy = 3.0
sun = bpy.data.objects.new("sun", sun_data)
sun.rotation_euler = (0.5, 0.3, 0.0)
scene.collection.objects.link(sun)

cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
cam.location = (0.0, -9.0, 8.0)
cam.rotation_euler = (0.8, 0.0, 0.0)
scene.collection.objects.link(cam)
scene.camera = cam

world = bpy.data.worlds.new("grey")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1.0)
scene.world = world

render = scene.render
render.engine = engine
render.resolution_x = render.resolution_y = size
render.resolution_percentage = 100
render.image_settings.file_format = "OPEN_EXR"
render.image_settings.color_depth = "32"
render.filepath = out
if engine == "CYCLES":
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parents[2] / "blend_scenes"))
    from cycles_reference import configure_cycles_reference

    configure_cycles_reference(scene, samples)
    scene.cycles.max_bounces = 2
    scene.cycles.diffuse_bounces = 2
else:
    scene.coherent.samples = samples
    scene.coherent.max_bounces = 2
    scene.coherent.diffuse_bounces = 2

if export_only:
    from coherent import export, native_module

    depsgraph = bpy.context.evaluated_depsgraph_get()
    start = time.perf_counter()
    result = export.export_scene(native_module(), depsgraph, size, size)
    seconds = time.perf_counter() - start
    s = result.scene
    print(f"SCATTER_EXPORT prototypes={s.prototype_count} instances={s.instance_count} "
          f"triangles={s.triangle_count} instanced_triangles={s.instanced_triangle_count} seconds={seconds:.3f}")
    print(f"SCATTER_SECONDS {seconds:.3f}")
else:
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    print(f"SCATTER_SECONDS {time.perf_counter() - start:.3f}")
# Peak and current resident memory of this Blender process (Linux).
with open("/proc/self/status") as status:
    memory = {k: v.split()[0] for k, v in (line.split(":", 1) for line in status) if k in ("VmHWM", "VmRSS")}
print(f"SCATTER_MEMORY peak_kib={memory.get('VmHWM', 0)} current_kib={memory.get('VmRSS', 0)}")
sys.stdout.flush()
