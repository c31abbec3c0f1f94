# Builds the repository's own Blender test scenes from nothing.
#
#   blender -b --factory-startup --python blend_scenes/make_scenes.py
#
# (run from the repository root; the .blend files are written next to this
# script). Every object, material and setting is created here, so the files
# can be regenerated bit-for-bit in intent and reviewed as code.
#
# The COHERENT add-on is optional: when addon/coherent can be imported and
# registered, the scenes are saved with render engine COHERENT and their
# scene.coherent settings filled in. Otherwise they are saved with CYCLES and a
# note is printed; the test suite and the main job select the engine with
# `-E COHERENT` on the command line anyway, so both variants are usable.
#
# Cycles settings are always written so that a plain Cycles render of these
# files is a fair reference for the agreement test (no adaptive sampling, no
# denoising, no clamping, box pixel filter of width 1, fixed seed).

import math
import os
import sys

import bmesh
import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from cycles_reference import configure_cycles_reference  # noqa: E402

# Light path limits shared by Cycles and COHERENT in every scene (Blender's
# defaults, written explicitly so a change of defaults cannot desynchronise
# the two renderers).
BOUNCES = dict(max_bounces=12, diffuse_bounces=4, glossy_bounces=4, transmission_bounces=12)


def addon_available():
    """Registers addon/coherent if it imports and is not registered yet.

    Returns True when the COHERENT engine and scene.coherent are usable.
    """
    if hasattr(bpy.types.Scene, "coherent"):
        return True
    addon_dir = os.path.join(REPO, "addon")
    if addon_dir not in sys.path:
        sys.path.insert(0, addon_dir)
    try:
        import coherent
        coherent.register()
    except Exception as exc:  # the add-on (or its native module) is not built yet
        print(f"make_scenes: COHERENT add-on not available ({exc!r}); "
              "saving the scenes with render engine CYCLES")
        return False
    return hasattr(bpy.types.Scene, "coherent")


def new_empty_scene(name):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = name
    world = bpy.data.worlds.new("World")
    scene.world = world
    return scene


def set_world_color(scene, rgb):
    world = scene.world
    world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    bg.inputs["Color"].default_value = (*rgb, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    world.color = rgb  # viewport/workbench colour


def diffuse_material(name, rgb):
    """A plain Lambertian material (Diffuse BSDF, roughness 0 = Lambert in Cycles)."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    mat.diffuse_color = (*rgb, 1.0)
    return mat


def principled_material(name, **inputs):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    for key, value in inputs.items():
        if key == "Base Color":
            mat.diffuse_color = value
        bsdf.inputs[key].default_value = value
    return mat


def mesh_object(scene, name, verts, faces, material, smooth=False):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    mesh.update()
    for poly in mesh.polygons:
        poly.use_smooth = smooth
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    return obj


def uv_sphere_object(scene, name, center, radius, material, segments=64, rings=32):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=radius)
    bm.to_mesh(mesh)
    bm.free()
    for poly in mesh.polygons:
        poly.use_smooth = True
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = center
    scene.collection.objects.link(obj)
    return obj


def camera_object(scene, location, rotation_deg, fov_deg):
    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit = 'AUTO'  # square images: horizontal = vertical FOV
    cam.angle = math.radians(fov_deg)
    cam.clip_start = 0.01
    cam.clip_end = 1000.0
    obj = bpy.data.objects.new("Camera", cam)
    obj.location = location
    obj.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def configure_render(scene, samples):
    r = scene.render
    r.resolution_x = 512
    r.resolution_y = 512
    r.resolution_percentage = 100
    r.film_transparent = False
    r.image_settings.file_format = 'PNG'
    r.use_file_extension = True
    scene.frame_start = 1
    scene.frame_end = 1
    scene.view_settings.view_transform = 'Standard'  # no Filmic: tests compare linear data
    scene.view_settings.look = 'None'

    c = configure_cycles_reference(scene, samples)
    c.preview_samples = 16
    c.use_preview_denoising = False
    c.seed = 0
    for key, value in BOUNCES.items():
        setattr(c, key, value)
    c.volume_bounces = 0
    c.transparent_max_bounces = 8

    # read_factory_settings() may drop add-ons registered by hand: check anew.
    if addon_available():
        s = scene.coherent
        s.samples = samples
        s.seed = 0
        for key, value in BOUNCES.items():
            setattr(s, key, value)
        r.engine = 'COHERENT'
    else:
        r.engine = 'CYCLES'


# --- Cornell box -------------------------------------------------------------
#
# Benedikt Bitterli's Mitsuba Cornell box (see ../shared/scenes/SOURCES.md):
# the box spans [-1,1] x [0,2] x [-1,1] in glTF Y-up, which is
# [-1,1] x [-1,1] x [0,2] in Blender Z-up (x, y, z)_blender = (x, -z, y)_gltf.
# The two boxes are the source's cubes after their toWorld transforms, given
# here as their measured Blender-space corners.

WHITE = (0.725, 0.71, 0.68)
RED = (0.63, 0.065, 0.05)
GREEN = (0.14, 0.45, 0.091)

# Source emitter: radiance (17, 12, 4) = 17 * (1, 0.706, 0.235) over the
# rectangle x in [-0.24, 0.23], y in [-0.16, 0.22] at z = 1.98. We use a square
# Blender area light of the same area, centred on the source rectangle.
LIGHT_RADIANCE = 17.0
LIGHT_COLOR = (1.0, 12.0 / 17.0, 4.0 / 17.0)
LIGHT_AREA = 0.47 * 0.38
LIGHT_SIZE = math.sqrt(LIGHT_AREA)
LIGHT_CENTER = (-0.005, 0.03, 1.98)


def rotated_box(corners_bottom, height):
    """A box from its 4 bottom corners (CCW seen from above) and its height."""
    verts = [(x, y, 0.0) for x, y in corners_bottom] + [(x, y, height) for x, y in corners_bottom]
    faces = [(0, 3, 2, 1), (4, 5, 6, 7)] + [(i, (i + 1) % 4, 4 + (i + 1) % 4, 4 + i) for i in range(4)]
    return verts, faces


def make_cornell_box():
    scene = new_empty_scene("Cornell Box")
    set_world_color(scene, (0.0, 0.0, 0.0))

    white = diffuse_material("White", WHITE)
    red = diffuse_material("Red", RED)
    green = diffuse_material("Green", GREEN)

    # Walls are single-sided quads facing the inside of the box.
    mesh_object(scene, "Floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2, 3)], white)
    mesh_object(scene, "Ceiling", [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)], [(0, 1, 2, 3)], white)
    mesh_object(scene, "BackWall", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], [(0, 1, 2, 3)], white)
    mesh_object(scene, "LeftWall", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)], [(0, 1, 2, 3)], red)
    mesh_object(scene, "RightWall", [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)], [(0, 1, 2, 3)], green)

    # Bottom corners (Blender x, y), counter-clockwise seen from above.
    short_box = [(-0.0461, -0.5730), (0.5330, -0.7461), (0.7033, -0.1762), (0.1243, -0.0031)]
    tall_box = [(-0.5240, -0.0906), (0.0496, 0.1089), (-0.1469, 0.6735), (-0.7204, 0.4739)]
    mesh_object(scene, "ShortBox", *rotated_box(short_box, 0.6), white)
    mesh_object(scene, "TallBox", *rotated_box(tall_box, 1.2), white)

    # Area light. Cycles 3.4 gives an area light of power P [W], colour c and
    # area A the radiance L = c * P / (4 * A) on its front side (measured: an
    # emissive quad of radiance 17 lights the box exactly 4/pi times brighter
    # than an area light of P = pi * A * 17; see README.md). So P = 4 * A * L.
    # Cycles 3.4 never shows lights to camera rays; visible_camera = False
    # states that in the data for exporters that read it.
    light = bpy.data.lights.new("CeilingLight", 'AREA')
    light.shape = 'SQUARE'
    light.size = LIGHT_SIZE
    light.color = LIGHT_COLOR
    light.energy = 4.0 * LIGHT_AREA * LIGHT_RADIANCE
    light_obj = bpy.data.objects.new("CeilingLight", light)
    light_obj.location = LIGHT_CENTER  # identity rotation: emits along -Z (down)
    light_obj.visible_camera = False
    scene.collection.objects.link(light_obj)

    # Mitsuba view: glTF eye (0, 1, 6.8) looking -Z, FOV 19.5 deg.
    camera_object(scene, (0.0, -6.8, 1.0), (90.0, 0.0, 0.0), 19.5)

    configure_render(scene, samples=128)
    return scene


# --- Glass and metal ---------------------------------------------------------

def make_glass_scene():
    scene = new_empty_scene("Glass")
    set_world_color(scene, (0.05, 0.05, 0.05))

    floor_mat = diffuse_material("Floor", (0.6, 0.6, 0.6))
    backdrop_mat = diffuse_material("Backdrop", (0.3, 0.4, 0.6))
    glass = principled_material("Glass", **{
        "Base Color": (1.0, 1.0, 1.0, 1.0), "Metallic": 0.0, "Roughness": 0.0,
        "Transmission": 1.0, "IOR": 1.45})
    metal = principled_material("Metal", **{
        "Base Color": (0.95, 0.64, 0.54, 1.0), "Metallic": 1.0, "Roughness": 0.2})

    mesh_object(scene, "Floor", [(-6, -6, 0), (6, -6, 0), (6, 6, 0), (-6, 6, 0)], [(0, 1, 2, 3)], floor_mat)
    mesh_object(scene, "Backdrop", [(-6, 3, 0), (6, 3, 0), (6, 3, 5), (-6, 3, 5)], [(0, 1, 2, 3)], backdrop_mat)
    uv_sphere_object(scene, "GlassSphere", (-1.1, 0.0, 1.0), 1.0, glass)
    uv_sphere_object(scene, "MetalSphere", (1.1, 0.5, 1.0), 1.0, metal)

    sun = bpy.data.lights.new("Sun", 'SUN')
    sun.energy = 3.0
    sun.angle = math.radians(2.0)
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (math.radians(40.0), 0.0, math.radians(30.0))
    scene.collection.objects.link(sun_obj)

    point = bpy.data.lights.new("Point", 'POINT')
    point.energy = 300.0
    point.shadow_soft_size = 0.25
    point.color = (1.0, 0.85, 0.7)
    point_obj = bpy.data.objects.new("Point", point)
    point_obj.location = (2.5, -3.0, 3.5)
    scene.collection.objects.link(point_obj)

    camera_object(scene, (0.0, -8.0, 2.6), (79.0, 0.0, 0.0), 40.0)

    configure_render(scene, samples=64)
    return scene


# --- Light selection scenes --------------------------------------------------
#
# Small scenes where picking emitters by importance matters (issue 10): a
# bright sun with a dim world, many lights of varied power, one large emissive
# mesh with a dim world, and an HDRI world (issue 11). They share a stage: a
# grey floor, a back wall and three objects.

HDRI_PATH = "/usr/share/blender/datafiles/studiolights/world/forest.exr"


def emission_material(name, rgb, strength):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = (*rgb, 1.0)
    emit.inputs["Strength"].default_value = strength
    mat.node_tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
    return mat


def light_stage(name, wall=True):
    """A new scene with floor, optional back wall, a box, a diffuse and a metal sphere, and a camera."""
    scene = new_empty_scene(name)
    grey = diffuse_material("Grey", (0.6, 0.6, 0.6))
    mesh_object(scene, "Floor", [(-6, -6, 0), (6, -6, 0), (6, 6, 0), (-6, 6, 0)], [(0, 1, 2, 3)], grey)
    if wall:
        mesh_object(scene, "Wall", [(-6, 2.5, 0), (6, 2.5, 0), (6, 2.5, 4), (-6, 2.5, 4)], [(0, 1, 2, 3)],
                    diffuse_material("Blue", (0.3, 0.4, 0.6)))
    box = [(-1.9, -0.6), (-0.9, -0.9), (-0.6, 0.1), (-1.6, 0.4)]
    mesh_object(scene, "Box", *rotated_box(box, 1.0), diffuse_material("Orange", (0.8, 0.45, 0.2)))
    uv_sphere_object(scene, "Sphere", (0.4, 0.3, 0.6), 0.6, diffuse_material("White", (0.8, 0.8, 0.8)),
                     segments=32, rings=16)
    uv_sphere_object(scene, "MetalSphere", (1.7, -0.4, 0.5), 0.5, principled_material("RoughMetal", **{
        "Base Color": (0.9, 0.7, 0.5, 1.0), "Metallic": 1.0, "Roughness": 0.4}), segments=32, rings=16)
    camera_object(scene, (0.0, -7.0, 3.2), (70.0, 0.0, 0.0), 40.0)
    return scene


def make_sun_dim_world():
    scene = light_stage("Sun and dim world")
    set_world_color(scene, (0.03, 0.04, 0.06))
    sun = bpy.data.lights.new("Sun", 'SUN')
    sun.energy = 4.0
    sun.angle = math.radians(3.0)
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (math.radians(50.0), 0.0, math.radians(35.0))
    scene.collection.objects.link(sun_obj)
    configure_render(scene, samples=64)
    return scene


def make_many_lights():
    """40 small lights, point and area, whose powers span 0.5 to 200 W."""
    import random
    rng = random.Random(7)
    scene = light_stage("Many lights")
    set_world_color(scene, (0.0, 0.0, 0.0))
    for i in range(40):
        area = i % 4 == 3
        light = bpy.data.lights.new(f"Light{i:02d}", 'AREA' if area else 'POINT')
        light.energy = 0.5 * 400.0 ** rng.random()
        light.color = (0.6 + 0.4 * rng.random(), 0.6 + 0.4 * rng.random(), 0.6 + 0.4 * rng.random())
        if area:
            light.size = 0.3
        else:
            light.shadow_soft_size = 0.05
        obj = bpy.data.objects.new(f"Light{i:02d}", light)
        obj.location = (rng.uniform(-4.5, 4.5), rng.uniform(-3.0, 2.0), rng.uniform(1.2, 3.5))
        obj.visible_camera = False
        scene.collection.objects.link(obj)
    configure_render(scene, samples=64)
    return scene


def make_emissive_mesh():
    """A large emissive panel (a 16 x 8 grid: 256 triangles) and a dim world."""
    scene = light_stage("Emissive mesh")
    set_world_color(scene, (0.02, 0.02, 0.03))
    nu, nv = 16, 8
    verts = [(-3.0 + 6.0 * i / nu, 1.5 - 1.5 * j / nv, 3.6 - 0.6 * j / nv) for j in range(nv + 1) for i in range(nu + 1)]
    faces = [(j * (nu + 1) + i, j * (nu + 1) + i + 1, (j + 1) * (nu + 1) + i + 1, (j + 1) * (nu + 1) + i)
             for j in range(nv) for i in range(nu)]
    mesh_object(scene, "Panel", verts, faces, emission_material("Panel", (1.0, 0.9, 0.8), 3.0))
    configure_render(scene, samples=64)
    return scene


def make_hdri_world():
    """Blender's forest.exr as the world, rotated 40 degrees about Z through a Mapping node."""
    scene = light_stage("HDRI world", wall=False)
    world = scene.world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes.get("Background")
    env = nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(HDRI_PATH, check_existing=True)
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(40.0))
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], env.inputs["Vector"])
    links.new(env.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 1.5
    configure_render(scene, samples=64)
    return scene


def make_sky_world():
    """A Nishita sky (sun 35 degrees up, rotated 40 degrees, default sun disc) as the only light."""
    scene = light_stage("Sky world", wall=False)
    world = scene.world
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes.get("Background")
    sky = nodes.new("ShaderNodeTexSky")
    sky.sky_type = 'NISHITA'
    sky.sun_elevation = math.radians(35.0)
    sky.sun_rotation = math.radians(40.0)
    sky.altitude = 100.0
    links.new(sky.outputs["Color"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = 0.1  # the Nishita sun is bright: keep pixels near 1
    configure_render(scene, samples=64)
    return scene


def save(scene, filename):
    path = os.path.join(HERE, filename)
    bpy.context.preferences.filepaths.save_version = 0  # no .blend1 backups next to the scenes
    # Absolute paths for external files (Blender's HDRIs): a relative one
    # would only resolve from a clone at the same depth below /.
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=True, check_existing=False, relative_remap=False)
    print(f"make_scenes: wrote {path} (engine {scene.render.engine})")


SCENES = {"cornell_box.blend": make_cornell_box, "glass_scene.blend": make_glass_scene,
          "sun_dim_world.blend": make_sun_dim_world, "many_lights.blend": make_many_lights,
          "emissive_mesh.blend": make_emissive_mesh, "hdri_world.blend": make_hdri_world,
          "sky_world.blend": make_sky_world}


def main():
    """Writes every scene, or those named after `--` (e.g. -- hdri_world.blend)."""
    names = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else list(SCENES)
    for filename in names:
        scene = SCENES[filename]()
        save(scene, filename)


if __name__ == "__main__":
    main()
