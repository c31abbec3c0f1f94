# Drives a ViewportSession through the edits a user makes in a Rendered
# viewport (headless: the depsgraph_update_post handler stands in for
# RenderEngine.view_update) and prints, for each edit, what the session did
# and how its incrementally updated scene renders compared with a scene
# exported from scratch. Run by test_viewport.py:
#   blender -b blend_scenes/cornell_box.blend --addons coherent --python viewport_updates.py -- OUT.json

import json
import sys

import bpy
import numpy as np

import coherent
from coherent import export, viewport

native = coherent.native_module()
scene = bpy.context.scene
view_layer = bpy.context.view_layer
session = viewport.ViewportSession()
SIZE = 40


def on_update(_scene, depsgraph):
    session.update(None, None, depsgraph)


bpy.app.handlers.depsgraph_update_post.append(on_update)
session.update(None, None, bpy.context.evaluated_depsgraph_get())


def camera():
    depsgraph = bpy.context.evaluated_depsgraph_get()
    return export.camera_parameters(scene.camera.evaluated_get(depsgraph), scene.render, SIZE, SIZE)


def render(nscene):
    """(Combined pixels, whether the BVH was reused) at SIZE x SIZE, 4 spp, from the scene camera."""
    nscene.set_camera(**camera())
    r = native.Renderer(nscene, width=SIZE, height=SIZE, spp=4, seed=3, threads=2)
    r.render()
    return r.pass_pixels("Combined"), r.bvh_reused


def state():
    return dict(counters=dict(session.counters), extracted=session.mesh_cache.extracted,
                cached_meshes=len(session.mesh_cache), triangles=session.scene.triangle_count,
                has_bvh=session.scene.has_bvh)


results = {}


def step(name, edit):
    before = state()
    edit()
    view_layer.update()  # evaluates the depsgraph: on_update sees its updates
    after = state()
    incremental, reused = render(session.scene)
    fresh_scene = export.export_scene(native, bpy.context.evaluated_depsgraph_get(), SIZE, SIZE).scene
    fresh, _ = render(fresh_scene)
    results[name] = dict(
        before=before, after=after, bvh_reused=reused,
        max_diff=float(np.abs(incremental - fresh).max()),
        mean=float(incremental[:, :3].mean()))


render(session.scene)  # builds the BVH the next renders may reuse
tall = bpy.data.objects["TallBox"]
short = bpy.data.objects["ShortBox"]
light = bpy.data.objects["CeilingLight"]
white = tall.active_material


def set_color(material, rgb):
    node = next(n for n in material.node_tree.nodes if n.type in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE"))
    node.inputs["Color" if node.type == "BSDF_DIFFUSE" else "Base Color"].default_value = (*rgb, 1.0)


def set_world(rgb):
    world = scene.world
    if world is None:
        world = scene.world = bpy.data.worlds.new("World")
    if world.use_nodes and world.node_tree is not None:
        node = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
        node.inputs["Color"].default_value = (*rgb, 1.0)
    else:
        world.color = rgb


def move_vertex():
    tall.data.vertices[0].co.z += 0.2
    tall.data.update()


step("camera", lambda: None)  # no edit: only a new camera, the BVH must be reused
step("transform", lambda: setattr(tall.location, "x", tall.location.x + 0.2))
step("material", lambda: set_color(white, (0.2, 0.7, 0.3)))
step("light_energy", lambda: setattr(light.data, "energy", light.data.energy * 2.0))
step("light_move", lambda: setattr(light.location, "z", light.location.z - 0.05))
step("world", lambda: set_world((0.3, 0.2, 0.1)))
# Rotated and scaled about its origin: every triangle of the box moves.
step("rotate_scale", lambda: (setattr(short.rotation_euler, "z", short.rotation_euler.z + 0.6),
                              setattr(short, "scale", (1.3, 0.8, 1.1))))
step("mesh_edit", move_vertex)
step("delete", lambda: bpy.data.objects.remove(short))

def view_camera_agreement():
    """view_camera() (a 3D View's matrices) against camera_parameters() (F12) for the same camera.

    Blender's own projection matrix (calc_matrix_camera) stands in for the
    3D View's window matrix in camera view, so the two code paths share no
    arithmetic. Non-square size: exercises the sensor fit.
    """
    from types import SimpleNamespace

    cam = scene.camera
    depsgraph = bpy.context.evaluated_depsgraph_get()
    out = {}
    cases = {
        "persp": dict(type="PERSP", lens=35.0, shift_x=0.1, shift_y=-0.05, clip_start=0.5, clip_end=20.0),
        "persp_vertical_fit": dict(type="PERSP", lens=50.0, shift_x=0.0, shift_y=0.2, clip_start=0.1,
                                   clip_end=100.0, sensor_fit="VERTICAL"),
        "ortho": dict(type="ORTHO", ortho_scale=3.0, shift_x=-0.1, shift_y=0.0, clip_start=0.2, clip_end=30.0),
    }
    for name, settings in cases.items():
        for key, value in settings.items():
            setattr(cam.data, key, value)
        view_layer.update()
        cam_eval = cam.evaluated_get(depsgraph)
        width, height = 64, 48
        window = cam_eval.calc_matrix_camera(depsgraph, x=width, y=height)
        region_data = SimpleNamespace(view_matrix=cam_eval.matrix_world.inverted(), window_matrix=window,
                                      is_perspective=cam.data.type != "ORTHO", view_perspective="PERSP")
        got = viewport.view_camera(region_data)
        want = export.camera_parameters(cam_eval, scene.render, width, height)
        # Relative to the magnitude: the matrices are float32 (far clips of 100 m).
        out[name] = {k: float(np.max(np.abs(np.subtract(got[k], want[k]))) / max(1.0, np.max(np.abs(want[k]))))
                     for k in got if k != "projection"}
        out[name]["projection_equal"] = got["projection"] == want["projection"]
    return out


results["view_camera"] = view_camera_agreement()

with open(sys.argv[sys.argv.index("--") + 1], "w") as f:
    json.dump(results, f, indent=1)
session.free()
print("viewport_updates: done")
