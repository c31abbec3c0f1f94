# Run by test_vector_pass.py in a subprocess Blender (factory startup):
#
#   blender -b --factory-startup --addons coherent --python vector_renders.py -- OUT_DIR SAMPLES ENGINE [ENGINE ...]
#
# Builds a scene whose objects and camera move between frames 1 and 3
# (linear keyframes) and renders frame 2 with the Vector pass and IndexOB
# ticked (and Cycles' Denoising Data tick), motion blur off, with each ENGINE (CYCLES, COHERENT) to
# OUT_DIR/<engine>.exr (multilayer). What moves:
# - a cube (IndexOB 1), translated in x and z and turned about z;
# - two linked copies of a second cube (IndexOB 2), instances of one mesh in
#   our export, one moving, one still;
# - the camera, translated in x and turned a little about z.
# A still ground plane (IndexOB 3) shows camera motion alone. Cycles
# samples the pixel centre (filter width 0.01).
import math
import os
import sys

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "blend_scenes"))
from cycles_reference import configure_cycles_reference  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
out_dir, samples, engines = args[0], int(args[1]), args[2:]

scene = bpy.context.scene
for ob in list(scene.objects):
    bpy.data.objects.remove(ob, do_unlink=True)


def keyframe(ob, path, first, last):
    """`path` goes linearly from `first` (frame 1) to `last` (frame 3)."""
    setattr(ob, path, first)
    ob.keyframe_insert(path, frame=1)
    setattr(ob, path, last)
    ob.keyframe_insert(path, frame=3)
    for fc in ob.animation_data.action.fcurves:
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


bpy.ops.mesh.primitive_cube_add(size=1.6, location=(-1.2, 0.0, 0.0))
mover = bpy.context.active_object
mover.pass_index = 1
keyframe(mover, "location", (-1.6, 0.0, -0.2), (-0.8, 0.0, 0.3))
keyframe(mover, "rotation_euler", (0.0, 0.0, 0.0), (0.0, 0.0, math.radians(40.0)))

bpy.ops.mesh.primitive_cube_add(size=1.0, location=(1.6, 0.5, 0.0))
twin = bpy.context.active_object
twin.pass_index = 2
still_twin = twin.copy()  # shares the mesh: instances of one prototype in our export
still_twin.location = (1.6, 0.5, 1.4)
scene.collection.objects.link(still_twin)
keyframe(twin, "location", (1.3, 0.5, -0.5), (1.9, 0.5, 0.0))

bpy.ops.mesh.primitive_plane_add(size=30.0, location=(0.0, 0.0, -1.0))
bpy.context.active_object.pass_index = 3

cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
scene.collection.objects.link(cam)
scene.camera = cam
keyframe(cam, "location", (-0.3, -8.0, 2.5), (0.3, -8.0, 2.7))
keyframe(cam, "rotation_euler", (math.radians(75.0), 0.0, math.radians(-2.0)),
         (math.radians(75.0), 0.0, math.radians(2.0)))

world = bpy.data.worlds.new("grey")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.3, 0.3, 0.3, 1)
scene.world = world

scene.frame_set(2)
render = scene.render
render.resolution_x, render.resolution_y, render.resolution_percentage = 96, 72, 100
render.use_motion_blur = False
render.film_transparent = False
render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
render.image_settings.color_depth = "32"
view_layer = scene.view_layers[0]
view_layer.use_pass_vector = True
view_layer.use_pass_object_index = True
view_layer.use_pass_z = True  # against Denoising Depth, which is a ray length, not a view depth
view_layer.cycles.denoising_store_passes = True  # Cycles' tick only: scene.coherent's stays off
assert not scene.coherent.use_pass_denoising_data
configure_cycles_reference(scene, samples).filter_width = 0.01
scene.coherent.samples = samples

for engine in engines:
    render.engine = engine
    render.filepath = f"{out_dir}/{engine.lower()}.exr"
    bpy.ops.render.render(write_still=True)
    print(f"VECTOR_RENDER {engine} -> {render.filepath}")
    sys.stdout.flush()
