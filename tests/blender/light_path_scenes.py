# Builds, in a factory-startup Blender, the small scenes test_light_paths.py
# renders with COHERENT and with Cycles:
#   shadow  a floor lit by a sharp sun (black world, direct light only), two
#           quads above it whose Mix Shader is driven by Light Path > Is
#           Shadow Ray: "Leaf" is diffuse to camera rays and transparent to
#           shadow rays (seen, casts no shadow); "Ghost" the reverse
#           (unseen, casts a shadow).
#   glass / mirror
#           a smooth glass (Principled, transmission 1, IOR 1.45) or mirror
#           (metallic 1, roughness 0) sphere under a point light of radius
#           0.25 (Blender's shadow_soft_size) in a black world, the camera
#           zoomed onto the light's reflection (a shifted 400 mm lens: the same
#           rays as the 50 mm view, 8x magnified), so the highlight covers
#           many pixels instead of a fraction of one.
#   pointiness / islands
#           Geometry > Pointiness and Random Per Island driving an Emission,
#           seen from above by an orthographic camera (build_pointiness,
#           build_islands).
#   terminator / terminator_off
#           two smooth-shaded low-poly wavy sheets under a grazing sun, black
#           world, direct light only: one with Cycles' Shadow Terminator
#           Geometry Offset at 0, the other at its default 0.1 (terminator)
#           or also at 0 (terminator_off); build_terminator.
#
#   blender -b --factory-startup --addons coherent --python light_path_scenes.py -- \
#       ENGINE OUT SAMPLES SIZE SEED CASE [CASE ...]
#
# Writes OUT_<case>.exr (RGB, 32-bit float, linear) per case.
import math
import sys
from pathlib import Path

import bpy

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "blend_scenes"))
from cycles_reference import configure_comparison  # noqa: E402

engine, out, samples, size, seed, *cases = sys.argv[sys.argv.index("--") + 1:]
samples, size, seed = int(samples), int(size), int(seed)
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def material(name, build):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    out_node = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(build(mat.node_tree), out_node.inputs["Surface"])
    return mat


def diffuse(nt, rgb):
    node = nt.nodes.new("ShaderNodeBsdfDiffuse")
    node.inputs["Color"].default_value = (*rgb, 1.0)
    return node.outputs["BSDF"]


def shadow_switch(camera_rgb, shadow_rgb):
    """Mix Shader, Fac = Is Shadow Ray: Diffuse of camera_rgb (None: clear) for
    other rays, that of shadow_rgb (None: clear) for shadow rays."""
    def build(nt):
        mix = nt.nodes.new("ShaderNodeMixShader")
        nt.links.new(nt.nodes.new("ShaderNodeLightPath").outputs["Is Shadow Ray"], mix.inputs["Fac"])
        for slot, rgb in ((1, camera_rgb), (2, shadow_rgb)):
            shader = diffuse(nt, rgb) if rgb else nt.nodes.new("ShaderNodeBsdfTransparent").outputs["BSDF"]
            nt.links.new(shader, mix.inputs[slot])
        return mix.outputs["Shader"]
    return build


def principled(**inputs):
    def build(nt):
        node = nt.nodes.new("ShaderNodeBsdfPrincipled")
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        return node.outputs["BSDF"]
    return build


def quad(name, corners, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new(name, mesh))


def camera(location, rotation, lens, shift=(0.0, 0.0)):
    cam = bpy.data.cameras.new("Camera")
    cam.lens = lens
    cam.shift_x, cam.shift_y = shift
    obj = bpy.data.objects.new("Camera", cam)
    obj.location = location
    obj.rotation_euler = [math.radians(a) for a in rotation]
    scene.collection.objects.link(obj)
    scene.camera = obj


def build_shadow():
    quad("Floor", [(-8, -8, 0), (8, -8, 0), (8, 8, 0), (-8, 8, 0)],
         material("Floor", lambda nt: diffuse(nt, (0.6, 0.6, 0.6))))
    quad("Leaf", [(-1.6, -0.6, 0.8), (-0.2, -0.6, 0.8), (-0.2, 0.6, 0.8), (-1.6, 0.6, 0.8)],
         material("Leaf", shadow_switch((0.2, 0.7, 0.1), None)))
    quad("Ghost", [(0.2, -0.6, 0.8), (1.6, -0.6, 0.8), (1.6, 0.6, 0.8), (0.2, 0.6, 0.8)],
         material("Ghost", shadow_switch(None, (0.8, 0.2, 0.2))))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = 0.0
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (math.radians(45.0), 0.0, math.radians(-30.0))
    scene.collection.objects.link(sun_obj)
    camera((0.0, -6.0, 5.0), (42.0, 0.0, 0.0), 35.0)


def build_sphere(kind):
    if kind == "glass":
        mat = material("Glass", principled(**{"Transmission": 1.0, "Roughness": 0.0, "IOR": 1.45}))
    else:
        mat = material("Mirror", principled(**{"Metallic": 1.0, "Roughness": 0.0,
                                               "Base Color": (1.0, 1.0, 1.0, 1.0)}))
    bpy.ops.mesh.primitive_uv_sphere_add(segments=128, ring_count=64, radius=1.0)
    obj = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    obj.data.materials.append(mat)
    point = bpy.data.lights.new("Point", "POINT")
    point.energy = 1000.0
    point.shadow_soft_size = 0.25
    point_obj = bpy.data.objects.new("Point", point)
    point_obj.location = (1.5, -3.0, 1.5)
    scene.collection.objects.link(point_obj)
    # The reflection sits 0.059 and 0.066 frame widths right of and above the
    # centre of the 50 mm view; 8x the lens and the shift keep it centred.
    camera((0.0, -6.0, 0.0), (90.0, 0.0, 0.0), 400.0, (8 * 0.0586, 8 * 0.0664))


def build_pointiness():
    """A 2 x 2 grid, seen from above by an orthographic camera, its vertices
    lifted by a smooth function and split along x = 0 (duplicate vertices,
    which Cycles welds); Emission = Geometry > Pointiness."""
    import bmesh
    mesh = bpy.data.meshes.new("Bumpy")
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=12, y_segments=12, size=1.0)
    for v in bm.verts:
        x, y = v.co.x, v.co.y
        v.co.z = 0.6 * math.sin(2.5 * x + 0.3) * math.cos(3.0 * y) + 0.2 * x * y
    seam = [e for e in bm.edges if all(abs(v.co.x) < 1e-6 for v in e.verts)]
    bmesh.ops.split_edges(bm, edges=seam)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(material("Pointiness", _emission_of_geometry("Pointiness")))
    scene.collection.objects.link(bpy.data.objects.new("Bumpy", mesh))
    _top_camera()


def build_islands():
    """One mesh of 16 separate small grids of varied resolution (islands whose
    union-find representatives are not simply their first vertices), seen
    from above by an orthographic camera; Emission = Random Per Island."""
    import bmesh
    bm = bmesh.new()
    for i in range(4):
        for j in range(4):
            made = bmesh.ops.create_grid(bm, x_segments=1 + (i + j) % 3, y_segments=1 + (i * j) % 4, size=0.18)
            bmesh.ops.translate(bm, verts=made["verts"], vec=(-0.75 + 0.5 * i, -0.75 + 0.5 * j, 0.0))
    mesh = bpy.data.meshes.new("Islands")
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(material("Islands", _emission_of_geometry("Random Per Island")))
    scene.collection.objects.link(bpy.data.objects.new("Islands", mesh))
    _top_camera()


def _emission_of_geometry(output):
    def build(nt):
        emission = nt.nodes.new("ShaderNodeEmission")
        nt.links.new(nt.nodes.new("ShaderNodeNewGeometry").outputs[output], emission.inputs["Color"])
        return emission.outputs["Emission"]
    return build


def _top_camera():
    cam = bpy.data.cameras.new("Camera")
    cam.type = "ORTHO"
    cam.ortho_scale = 2.0
    obj = bpy.data.objects.new("Camera", cam)
    obj.location = (0.0, 0.0, 2.0)
    scene.collection.objects.link(obj)
    scene.camera = obj


def build_terminator(right_offset):
    """Two low-poly, smooth-shaded wavy sheets (4 vertices per wave) side by
    side, seen from above, under a sun grazing them across the waves: shadow
    rays from the flat triangles run into the next crest unless they start
    from the smooth surface the normals describe."""
    mat = material("White", lambda nt: diffuse(nt, (0.8, 0.8, 0.8)))
    for name, y, offset in (("Left", -1.1, 0.0), ("Right", 1.1, right_offset)):
        columns, rows = 17, 2
        verts = [(-2.0 + 4.0 * i / (columns - 1), y - 1.0 + 2.0 * j / (rows - 1),
                  0.3 * math.sin(2.0 * math.pi * i / 4.0 + 0.5))
                 for j in range(rows) for i in range(columns)]
        faces = [(j * columns + i, j * columns + i + 1, (j + 1) * columns + i + 1, (j + 1) * columns + i)
                 for j in range(rows - 1) for i in range(columns - 1)]
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(verts, [], faces)
        mesh.polygons.foreach_set("use_smooth", [True] * len(faces))
        mesh.materials.append(mat)
        ob = bpy.data.objects.new(name, mesh)
        ob.cycles.shadow_terminator_geometry_offset = offset
        scene.collection.objects.link(ob)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = 0.0
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (0.0, math.radians(-70.0), 0.0)  # 20 degrees above the horizon, from -x
    scene.collection.objects.link(sun_obj)
    camera((0.0, 0.0, 9.0), (0.0, 0.0, 0.0), 50.0)


def render_case(case):
    # (A second read_factory_settings() would unregister the add-on.)
    for ob in list(scene.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    world = bpy.data.worlds.new("World")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    scene.world = world
    if case == "shadow":
        build_shadow()
    elif case == "pointiness":
        build_pointiness()
    elif case == "islands":
        build_islands()
    elif case.startswith("terminator"):
        build_terminator(0.0 if case == "terminator_off" else 0.1)
    else:
        build_sphere(case)
    # Direct light only for the shadow case (deterministic up to pixel
    # coverage); the spheres need the bounces through the glass.
    bounces = 0 if case in ("shadow", "pointiness", "islands", "terminator", "terminator_off") else 4
    limits = dict(max_bounces=bounces, diffuse_bounces=bounces, glossy_bounces=bounces,
                  transmission_bounces=bounces, transparent_max_bounces=8)

    r = scene.render
    r.engine = engine
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    r.film_transparent = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_mode = "RGB"
    r.image_settings.color_depth = "32"
    r.filepath = f"{out}_{case}.exr"
    scene.view_settings.view_transform = "Standard"
    configure_comparison(scene, engine, samples, seed, limits)
    bpy.ops.render.render(write_still=True)
    print("LIGHT_PATH_SCENE_WRITTEN", r.filepath)


for name in cases:
    render_case(name)
