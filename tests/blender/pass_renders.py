# Run by test_passes.py in a subprocess Blender:
#
#   blender -b SCENE.blend --python pass_renders.py -- OUT_DIR PERCENT SAMPLES MODE ENGINE [ENGINE ...]
#
# Ticks Cycles' passes in the view layer and renders the loaded scene with
# each ENGINE (CYCLES, COHERENT) to OUT_DIR/<engine>.exr, a multilayer EXR.
# MODE "light": the light passes, SAMPLES spp, 1-pixel box filter (as the
# agreement tests). MODE "data": Mist, Position, UV, Depth and the indices at
# SAMPLES spp with the filter shrunk to the pixel centre in Cycles; object
# and material pass indices are set first (1, 2, ... in name order), and
# meshes without UVs get two UV maps (add_uv_maps), and the scene's
# MetalSphere two linked copies (instances in our export).
# MODE "crypto": Cryptomatte object, material and asset (4 levels) and
# IndexOB; "matte": the same through the compositor's Cryptomatte node,
# which picks MetalSphere, to a plain EXR of its matte, and IndexOB through
# a File Output node to OUT_DIR/index0001.exr.

import math
import os
import sys

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "blend_scenes"))
from cycles_reference import configure_cycles_reference  # noqa: E402



def add_uv_maps():
    """Gives every mesh without one two UV maps no material reads: "Decoy",
    the constant (0.25, 0.75), and the active render map "Render", the
    direction of each vertex from the object's origin, (x, y) / |p| mapped
    to [0, 1]: continuous (no seam, where one pixel could span the whole
    range) and varying across every surface."""
    for mesh in bpy.data.meshes:
        if mesh.uv_layers:
            continue
        decoy, layer = mesh.uv_layers.new(name="Decoy"), mesh.uv_layers.new(name="Render")
        for loop in mesh.loops:
            x, y, z = mesh.vertices[loop.vertex_index].co
            r = max(1e-6, math.sqrt(x * x + y * y + z * z))
            decoy.data[loop.index].uv = (0.25, 0.75)
            layer.data[loop.index].uv = (0.5 + 0.5 * x / r, 0.5 + 0.5 * y / r)
        layer.active_render = True
        mesh.uv_layers.active = decoy


def add_linked_copies(name):
    """Two smaller, rotated copies of object `name` sharing its mesh, which
    our export renders as instances of one prototype."""
    source = bpy.data.objects[name]
    for i, location in enumerate(((2.6, 1.5, 0.6), (-2.6, 1.2, 0.7))):
        copy = source.copy()
        copy.location = location
        copy.rotation_euler = (0.3, 0.5 * i, 0.7)
        copy.scale = (0.6, 0.6, 0.6)
        bpy.context.scene.collection.objects.link(copy)


args = sys.argv[sys.argv.index("--") + 1:]
out_dir, percent, samples, mode, engines = args[0], int(args[1]), int(args[2]), args[3], args[4:]

LIGHT = ("diffuse_direct", "diffuse_indirect", "diffuse_color", "glossy_direct", "glossy_indirect",
         "glossy_color", "transmission_direct", "transmission_indirect", "transmission_color")

scene = bpy.context.scene
render = scene.render
render.resolution_percentage = percent
render.film_transparent = False
render.use_border = False
render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
render.image_settings.color_depth = "32"
render.image_settings.exr_codec = "ZIP"
view_layer = scene.view_layers[0]
if mode == "light":
    for name in LIGHT:
        setattr(view_layer, f"use_pass_{name}", True)
    view_layer.use_pass_emit = True
    view_layer.use_pass_environment = True
    view_layer.use_pass_ambient_occlusion = True
elif mode in ("crypto", "matte"):
    # Cryptomatte; "matte" also runs the compositor: Cryptomatte node
    # (picking MetalSphere) -> Composite, saved as a plain EXR.
    view_layer.use_pass_object_index = True
    view_layer.use_pass_cryptomatte_object = True
    view_layer.use_pass_cryptomatte_material = True
    view_layer.use_pass_cryptomatte_asset = True
    view_layer.pass_cryptomatte_depth = 4
    for i, ob in enumerate(sorted(bpy.data.objects, key=lambda o: o.name)):
        ob.pass_index = i + 1
    if mode == "matte":
        render.image_settings.file_format = "OPEN_EXR"
        render.use_compositing = True
        scene.use_nodes = True
        tree = scene.node_tree
        tree.nodes.clear()
        layers = tree.nodes.new("CompositorNodeRLayers")
        matte = tree.nodes.new("CompositorNodeCryptomatteV2")
        matte.source = "RENDER"
        matte.scene = scene
        matte.layer_name = f"{view_layer.name}.CryptoObject"
        matte.matte_id = "MetalSphere"
        out = tree.nodes.new("CompositorNodeComposite")
        tree.links.new(layers.outputs["Image"], matte.inputs["Image"])
        tree.links.new(matte.outputs["Matte"], out.inputs["Image"])
        index = tree.nodes.new("CompositorNodeOutputFile")  # IndexOB beside it: OUT_DIR/index0001.exr
        index.base_path = out_dir
        index.format.file_format = "OPEN_EXR"
        index.format.color_depth = "32"
        index.file_slots[0].path = "index"
        tree.links.new(layers.outputs["IndexOB"], index.inputs[0])
        print("METAL_SPHERE_INDEX", bpy.data.objects["MetalSphere"].pass_index)
else:
    for name in ("mist", "position", "uv", "z", "object_index", "material_index"):
        setattr(view_layer, f"use_pass_{name}", True)
    add_uv_maps()
    add_linked_copies("MetalSphere")
    for i, ob in enumerate(sorted(bpy.data.objects, key=lambda o: o.name)):
        ob.pass_index = i + 1
    for i, mat in enumerate(sorted(bpy.data.materials, key=lambda m: m.name)):
        mat.pass_index = 10 + i
    if scene.world is not None:
        scene.world.mist_settings.start = 2.0
        scene.world.mist_settings.depth = 9.0
        scene.world.mist_settings.falloff = "LINEAR"

c = configure_cycles_reference(scene, samples)
if mode == "data":
    c.filter_width = 0.01  # every sample at the pixel centre
scene.coherent.samples = samples
scene.coherent.use_animated_seed = False
scene.coherent.sampler = "SPT"

for engine in engines:
    render.engine = engine
    render.filepath = f"{out_dir}/{engine.lower()}.exr"
    bpy.ops.render.render(write_still=True)
    print(f"PASS_RENDER {engine} -> {render.filepath}")
    sys.stdout.flush()
