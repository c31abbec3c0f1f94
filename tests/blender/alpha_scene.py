# Builds, in a factory-startup Blender, a scene of see-through and cut-out
# surfaces and renders it (test_alpha.py compares COHERENT with Cycles):
#   - an alpha-clipped quad: Principled BSDF whose Base Color and Alpha come
#     from one Image Texture (a numpy-written pattern: opaque discs, a
#     half-transparent band, fully transparent elsewhere), in front of a
#     coloured wall, lit by a sun so its cut-out shadow falls on the wall;
#   - a Translucent BSDF leaf lit from behind by a point light;
#   - a tinted Transparent BSDF pane mixed 70/30 with a diffuse (Mix Shader);
#   - a Holdout sphere, which cuts the pixel alpha.
#
#   blender -b --factory-startup --addons coherent --python alpha_scene.py -- ENGINE OUT SAMPLES SIZE SEED
#
# Writes OUT.exr (RGBA, 32-bit float, linear), then OUT_nodes.exr: a
# deterministic scene (one sample per pixel gives the exact value, 32 x 32):
# an orthographic camera over an emitting plane, seen through a coloured
# Transparent BSDF on the left half, and on the right half a Mix Shader (0.5)
# of Holdout and Emission (colour halved, alpha 0.5).
import math
import sys
from pathlib import Path

import bpy
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "blend_scenes"))
from cycles_reference import configure_comparison  # noqa: E402

engine, out, samples, size, seed = sys.argv[sys.argv.index("--") + 1:][:5]
samples, size, seed = int(samples), int(size), int(seed)
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
BOUNCES = dict(max_bounces=3, diffuse_bounces=3, glossy_bounces=3, transmission_bounces=3,
               transparent_max_bounces=8)


def material(name, build):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    out_node = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(build(mat.node_tree), out_node.inputs["Surface"])
    return mat


def diffuse(rgb):
    def build(nt):
        node = nt.nodes.new("ShaderNodeBsdfDiffuse")
        node.inputs["Color"].default_value = (*rgb, 1.0)
        return node.outputs["BSDF"]
    return build


def quad(name, corners, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, coord in zip(mesh.loops, ((0, 0), (1, 0), (1, 1), (0, 1))):
        uv.data[loop.index].uv = coord
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def pattern_image(n=64):
    """RGBA float image: colour bands; alpha 1 in two discs, 0.5 in a band, 0 elsewhere."""
    y, x = np.mgrid[0:n, 0:n] / (n - 1.0)
    alpha = np.zeros((n, n))
    alpha[(x - 0.3) ** 2 + (y - 0.65) ** 2 < 0.05] = 1.0
    alpha[(x - 0.7) ** 2 + (y - 0.3) ** 2 < 0.03] = 1.0
    alpha[(y > 0.85) & (y < 0.95)] = 0.5
    rgba = np.stack([0.2 + 0.7 * x, 0.8 - 0.6 * y, np.full_like(x, 0.3), alpha], axis=-1)
    image = bpy.data.images.new("AlphaPattern", n, n, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(rgba.astype(np.float32).ravel())
    image.pack()
    return image


def alpha_clip(nt):
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = pattern_image()
    tex.interpolation = "Closest"
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Roughness"].default_value = 0.6
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    return bsdf.outputs["BSDF"]


def translucent(nt):
    node = nt.nodes.new("ShaderNodeBsdfTranslucent")
    node.inputs["Color"].default_value = (0.3, 0.8, 0.2, 1.0)
    return node.outputs["BSDF"]


def tinted_pane(nt):
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.3
    clear = nt.nodes.new("ShaderNodeBsdfTransparent")
    clear.inputs["Color"].default_value = (0.9, 0.5, 0.5, 1.0)
    dif = nt.nodes.new("ShaderNodeBsdfDiffuse")
    dif.inputs["Color"].default_value = (0.2, 0.2, 0.8, 1.0)
    nt.links.new(clear.outputs["BSDF"], mix.inputs[1])
    nt.links.new(dif.outputs["BSDF"], mix.inputs[2])
    return mix.outputs["Shader"]


def holdout(nt):
    return nt.nodes.new("ShaderNodeHoldout").outputs["Holdout"]


def emission(rgb):
    def build(nt):
        node = nt.nodes.new("ShaderNodeEmission")
        node.inputs["Color"].default_value = (*rgb, 1.0)
        return node.outputs["Emission"]
    return build


def clear_red(nt):
    node = nt.nodes.new("ShaderNodeBsdfTransparent")
    node.inputs["Color"].default_value = (0.2, 0.6, 0.9, 1.0)
    return node.outputs["BSDF"]


def half_holdout(nt):
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    nt.links.new(holdout(nt), mix.inputs[1])
    nt.links.new(emission((0.4, 0.8, 0.2))(nt), mix.inputs[2])
    return mix.outputs["Shader"]


def build_nodes_scene():
    quad("Glow", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], material("Glow", emission((1.0, 0.5, 0.25))))
    quad("Clear", [(-1, -1, 1), (0, -1, 1), (0, 1, 1), (-1, 1, 1)], material("Clear", clear_red))
    quad("Half", [(0, -1, 1), (1, -1, 1), (1, 1, 1), (0, 1, 1)], material("Half", half_holdout))
    cam = bpy.data.cameras.new("Camera")
    cam.type = "ORTHO"
    cam.ortho_scale = 2.0
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj


def build_main_scene():
    quad("Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], material("Floor", diffuse((0.6, 0.6, 0.6))))
    quad("Wall", [(-4, 2, 0), (4, 2, 0), (4, 2, 4), (-4, 2, 4)], material("Wall", diffuse((0.2, 0.4, 0.7))))
    quad("AlphaClip", [(-2.2, 0, 0.4), (-0.2, 0, 0.4), (-0.2, 0, 2.4), (-2.2, 0, 2.4)], material("AlphaClip", alpha_clip))
    quad("Leaf", [(0.3, 0, 0.6), (1.8, 0, 0.6), (1.8, 0.3, 2.1), (0.3, 0.3, 2.1)], material("Leaf", translucent))
    quad("Pane", [(-0.6, -1.2, 0.2), (0.6, -1.2, 0.2), (0.6, -1.2, 1.0), (-0.6, -1.2, 1.0)],
         material("Pane", tinted_pane))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.35, location=(1.6, -1.4, 0.35), segments=24, ring_count=12)
    bpy.context.active_object.data.materials.append(material("Holdout", holdout))

    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = math.radians(2.0)
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (math.radians(60.0), 0.0, math.radians(20.0))  # from the camera side, down onto the wall
    scene.collection.objects.link(sun_obj)
    point = bpy.data.lights.new("BackLight", "POINT")
    point.energy = 150.0
    point.shadow_soft_size = 0.1
    point_obj = bpy.data.objects.new("BackLight", point)
    point_obj.location = (1.0, 1.3, 1.4)  # between the leaf and the wall
    scene.collection.objects.link(point_obj)

    cam = bpy.data.cameras.new("Camera")
    cam.angle = math.radians(50.0)
    cam_obj = bpy.data.objects.new("Camera", cam)
    cam_obj.location = (0.0, -6.0, 1.6)
    cam_obj.rotation_euler = (math.radians(85.0), 0.0, 0.0)
    scene.collection.objects.link(cam_obj)
    scene.camera = cam_obj


def render_case(nodes_case, path, spp, pixels):
    # (A second read_factory_settings() would unregister the add-on.)
    for ob in list(scene.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    background = (0.0, 0.0, 0.0, 1.0) if nodes_case else (0.05, 0.05, 0.06, 1.0)
    world.node_tree.nodes["Background"].inputs["Color"].default_value = background
    scene.world = world
    if nodes_case:
        build_nodes_scene()
    else:
        build_main_scene()

    r = scene.render
    r.engine = engine
    r.resolution_x = r.resolution_y = pixels
    r.resolution_percentage = 100
    r.film_transparent = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_mode = "RGBA"
    r.image_settings.color_depth = "32"
    r.filepath = path
    scene.view_settings.view_transform = "Standard"

    configure_comparison(scene, engine, spp, seed, BOUNCES)
    bpy.ops.render.render(write_still=True)
    print("ALPHA_SCENE_WRITTEN", r.filepath)


render_case(False, out + ".exr", samples, size)
render_case(True, out + "_nodes.exr", 1, 32)
