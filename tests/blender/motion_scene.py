# Builds, in a factory-startup Blender, a scene for the motion blur tests and
# renders frame 2: an emissive cube (strength 1, world black) keyframed to
# slide along x from -1 (frame 1) to +1 (frame 3), linear, seen by a camera
# looking along +y. With the shutter centred on frame 2 and 1 frame long, the
# cube sweeps x in [-0.5, 0.5] during the exposure.
#
#   blender -b --factory-startup [--addons coherent] --python motion_scene.py -- ENGINE BLUR OUT
#     ENGINE  COHERENT or CYCLES
#     BLUR    1 = motion blur on, 0 = off
#     OUT     output path prefix (multilayer EXR)
import sys

import bpy

engine, blur, out = sys.argv[sys.argv.index("--") + 1:][:3]
scene = bpy.context.scene
for ob in list(scene.objects):
    bpy.data.objects.remove(ob, do_unlink=True)

bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-1.0, 0.0, 0.0))
cube = bpy.context.active_object
mat = bpy.data.materials.new("glow")
mat.use_nodes = True
nodes = mat.node_tree.nodes
nodes.clear()
emission = nodes.new("ShaderNodeEmission")
emission.inputs["Strength"].default_value = 1.0
output = nodes.new("ShaderNodeOutputMaterial")
mat.node_tree.links.new(emission.outputs["Emission"], output.inputs["Surface"])
cube.data.materials.append(mat)
cube.keyframe_insert("location", frame=1)
cube.location.x = 1.0
cube.keyframe_insert("location", frame=3)
for fc in cube.animation_data.action.fcurves:
    for kp in fc.keyframe_points:
        kp.interpolation = "LINEAR"

cam_data = bpy.data.cameras.new("cam")
cam_data.type = "ORTHO"
cam_data.ortho_scale = 4.0
cam = bpy.data.objects.new("cam", cam_data)
scene.collection.objects.link(cam)
cam.location = (0.0, -5.0, 0.0)
cam.rotation_euler = (1.5707963267948966, 0.0, 0.0)  # look along +y, z up
scene.camera = cam

world = bpy.data.worlds.new("black")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
scene.world = world

scene.render.engine = engine
scene.render.resolution_x = 64
scene.render.resolution_y = 16
scene.render.resolution_percentage = 100
scene.render.use_motion_blur = blur == "1"
scene.render.motion_blur_shutter = 1.0
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.filepath = out
if engine == "CYCLES":
    scene.cycles.samples = 256
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
else:
    scene.coherent.samples = 256
scene.frame_set(2)
bpy.ops.render.render(write_still=True)
