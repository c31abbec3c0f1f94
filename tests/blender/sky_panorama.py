# The Sky Texture cases of test_sky.py and their Cycles references.
#
#   blender -b --factory-startup --python sky_panorama.py -- OUT_DIR
#
# renders, with a Cycles equirectangular panoramic camera at 1 spp (256 x 128,
# the whole sphere), first the world direction each pixel's ray took (the
# world's Generated coordinate, encoded as 0.5 d + 0.5) and then each case's
# sky, to OUT_DIR/directions.exr and OUT_DIR/<case>.exr (32-bit float,
# linear). Cycles draws a pixel's camera ray from the seed, sample and pixel
# only, so every render's pixel (x, y) saw the same direction.

import math
import sys

# Blender's node settings per case. Nishita has a large sun (12 degrees) so
# that many pixels land in the disc and on its edge.
CASES = {
    "preetham": dict(sky_type="PREETHAM", sun_direction=(0.3, -0.5, 0.6), turbidity=3.0),
    "hosek_wilkie": dict(sky_type="HOSEK_WILKIE", sun_direction=(-0.4, 0.2, 0.5), turbidity=4.5,
                         ground_albedo=0.4),
    "nishita": dict(sky_type="NISHITA", sun_size=math.radians(12.0), sun_intensity=0.7,
                    sun_elevation=math.radians(20.0), sun_rotation=math.radians(-110.0), altitude=2000.0,
                    air_density=2.0, dust_density=3.0, ozone_density=0.5),
    "nishita_low_sun": dict(sky_type="NISHITA", sun_elevation=math.radians(1.0), sun_rotation=math.radians(400.0),
                            sun_size=math.radians(4.0)),
}
# A Mapping node in front of this case's texture (rotation in degrees). Blender
# disables the Vector input of a Nishita sky with a sun disc, and Cycles then
# ignores the link: the second case checks that we do too.
MAPPING_ROTATION = {"hosek_wilkie": (0.0, 0.0, 30.0), "nishita_low_sun": (20.0, 0.0, 50.0)}
WIDTH, HEIGHT = 256, 128
MATERIAL_SIZE = 96


def make_world(bpy, case):
    """A World whose Background (strength 1) shows `case`'s Sky Texture."""
    world = bpy.data.worlds.new(f"Sky {case}")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    sky = nodes.new("ShaderNodeTexSky")
    for key, value in CASES[case].items():
        setattr(sky, key, value)
    if case in MAPPING_ROTATION:
        mapping = nodes.new("ShaderNodeMapping")
        mapping.inputs["Rotation"].default_value = tuple(math.radians(a) for a in MAPPING_ROTATION[case])
        coords = nodes.new("ShaderNodeTexCoord")
        links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
        links.new(mapping.outputs["Vector"], sky.inputs["Vector"])
    links.new(sky.outputs["Color"], nodes["Background"].inputs["Color"])
    return world


def make_material_scene(bpy):
    """The current scene becomes a sphere whose emission is the Nishita case's sky (a Sky Texture in a
    material), seen by an orthographic camera, black world. Its Vector input is disabled (sun disc), so the
    link from the normals is ignored and the sky reads the Generated coordinates, unnormalised, as in Cycles."""
    scene = bpy.context.scene
    for obj in list(scene.objects):
        bpy.data.objects.remove(obj)
    scene.world = bpy.data.worlds.new("Black")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=1.0)
    sphere = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    mat = bpy.data.materials.new("SkyEmission")
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    sky = nodes.new("ShaderNodeTexSky")
    for key, value in CASES["nishita"].items():
        setattr(sky, key, value)
    emission = nodes.new("ShaderNodeEmission")
    links.new(nodes.new("ShaderNodeTexCoord").outputs["Normal"], sky.inputs["Vector"])
    links.new(sky.outputs["Color"], emission.inputs["Color"])
    links.new(emission.outputs["Emission"], nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    sphere.data.materials.append(mat)
    camera = bpy.data.cameras.new("Ortho")
    camera.type = 'ORTHO'
    camera.ortho_scale = 2.2
    obj = bpy.data.objects.new("Ortho", camera)
    obj.location = (0.0, -5.0, 0.0)
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(obj)
    scene.camera = obj
    scene.render.resolution_x = scene.render.resolution_y = MATERIAL_SIZE
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'


def direction_world(bpy):
    world = bpy.data.worlds.new("Directions")
    world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    encode = nodes.new("ShaderNodeVectorMath")
    encode.operation = 'MULTIPLY_ADD'
    encode.inputs[1].default_value = (0.5, 0.5, 0.5)
    encode.inputs[2].default_value = (0.5, 0.5, 0.5)
    links.new(nodes.new("ShaderNodeTexCoord").outputs["Generated"], encode.inputs[0])
    links.new(encode.outputs["Vector"], nodes["Background"].inputs["Color"])
    return world


def main(out_dir):
    import bpy
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.samples = 1
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.seed = 0
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth = 'OPEN_EXR', '32'
    camera = bpy.data.cameras.new("Panorama")
    camera.type = 'PANO'
    camera.cycles.panorama_type = 'EQUIRECTANGULAR'
    obj = bpy.data.objects.new("Panorama", camera)
    obj.rotation_euler = (math.pi / 2, 0.0, 0.3)  # horizon across the middle; an arbitrary heading
    scene.collection.objects.link(obj)
    scene.camera = obj
    for name, world in [("directions", direction_world(bpy))] + [(case, make_world(bpy, case)) for case in CASES]:
        scene.world = world
        scene.render.filepath = f"{out_dir}/{name}.exr"
        bpy.ops.render.render(write_still=True)
        print(f"SKY_PANORAMA {name} -> {scene.render.filepath}")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1])
