# Builds, in a factory-startup Blender, a small animation for the persistent
# data tests; the command line then renders its frames with -a.
#
#   blender -b --factory-startup --addons coherent --python persistent_scene.py \
#       -E COHERENT -o OUT_#### -s 1 -e 3 -a -- MODE PERSISTENT
#     MODE        move:   a cube keyframed along x beside a static floor and two ico spheres
#                         sharing one mesh (a prototype with two instances)
#                 deform: the same, plus the floor's shape key keyframed (its geometry
#                         changes every frame)
#                 edit:   the move scene at frame 1 rendered twice by this script (F12
#                         twice), the floor's mesh edited in between; give OUT after
#                         PERSISTENT instead of -o/-a: it writes OUT_a.exr and OUT_b.exr
#     PERSISTENT  1 = scene.render.use_persistent_data on, 0 = off
# Frames are 48x48 EXRs at 8 spp with the same seed on every frame.
import sys

import bpy

mode, persistent, *out = sys.argv[sys.argv.index("--") + 1:]
scene = bpy.context.scene
for ob in list(scene.objects):
    bpy.data.objects.remove(ob, do_unlink=True)


def linear(ob):
    for fc in ob.animation_data.action.fcurves:
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-1.0, 0.0, 0.4))
cube = bpy.context.active_object
cube.keyframe_insert("location", frame=1)
cube.location.x = 1.0
cube.keyframe_insert("location", frame=3)
linear(cube)

bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=3, radius=0.6, location=(0.0, 1.2, 0.6))
bpy.ops.object.shade_smooth()
bpy.ops.object.duplicate_move_linked(TRANSFORM_OT_translate={"value": (1.6, 0.4, 0.0)})

bpy.ops.mesh.primitive_plane_add(size=6.0)
floor = bpy.context.active_object
if mode == "deform":
    floor.shape_key_add(name="Basis")
    bulge = floor.shape_key_add(name="Bulge")
    for point in bulge.data[:2]:
        point.co.z += 1.5
    bulge.value = 0.0
    bulge.keyframe_insert("value", frame=1)
    bulge.value = 1.0
    bulge.keyframe_insert("value", frame=3)
    for fc in floor.data.shape_keys.animation_data.action.fcurves:
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"

bpy.ops.object.light_add(type="SUN", rotation=(0.6, 0.3, 0.0))
bpy.context.active_object.data.energy = 3.0
bpy.ops.object.camera_add(location=(0.0, -6.0, 3.0), rotation=(1.15, 0.0, 0.0))
scene.camera = bpy.context.active_object
scene.world.color = (0.2, 0.2, 0.25)

render = scene.render
render.engine = "COHERENT"
render.resolution_x = render.resolution_y = 48
render.resolution_percentage = 100
render.image_settings.file_format = "OPEN_EXR"
render.use_persistent_data = persistent == "1"
scene.frame_start, scene.frame_end = 1, 3
scene.coherent.samples = 8
scene.coherent.use_animated_seed = False

if mode == "edit":
    render.filepath = out[0] + "_a.exr"
    bpy.ops.render.render(write_still=True)
    for vertex in floor.data.vertices[:2]:
        vertex.co.z += 1.5
    floor.data.update()
    render.filepath = out[0] + "_b.exr"
    bpy.ops.render.render(write_still=True)
