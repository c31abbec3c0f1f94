# SPDX-License-Identifier: Apache-2.0
"""Times the Blender -> native scene export of a ~1M-triangle mesh.

Run from the repository root (needs the built _coherent module):

    blender -b --factory-startup --python bench/blender_export_bench.py -- [--triangles N] [--instances K]

Prints one line per case with the export time (depsgraph -> coherent.Scene,
i.e. foreach_get extraction, material conversion and native validation) and a
JSON summary line prefixed with "RESULT ". The target is < 1.5 s for 1M
triangles. Cases: flat-shaded grid, smooth-shaded grid (split normals), the
same smooth grid with a Subdivision modifier evaluated by the depsgraph,
K linked duplicates of the grid (instancing reuses the extracted arrays), and
the smooth grid under an Image Texture on UVs plus a tangent-space Normal Map
(the export then also extracts UVs and MikkTSpace tangents).

--profile prints the 25 costliest functions (cProfile) of one export per case.
--baseline FILE times another version of export.py (e.g. `git show
main:addon/coherent/export.py > /tmp/export_main.py`) interleaved with this
one, so that the two meet the same machine load. The UV + tangents case also
times Blender's own mesh.calc_tangents (MikkTSpace) alone.
"""

import argparse
import json
import math
import os
import sys
import time

import bpy

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "addon"))

import coherent  # noqa: E402
from coherent import export  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser()
    parser.add_argument("--triangles", type=int, default=1_000_000)
    parser.add_argument("--instances", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=3, help="best of N exports per case")
    parser.add_argument("--profile", action="store_true", help="cProfile one extra export per case")
    parser.add_argument("--only", default=None, help="run only the cases whose name contains this")
    parser.add_argument("--baseline", default=None, help="another export.py to time interleaved with this one")
    return parser.parse_args(argv)


def reset_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    cam_data = bpy.data.cameras.new("Camera")
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -3.0, 2.0)
    scene.camera = cam
    scene.render.engine = "COHERENT"
    return scene


def add_grid(triangles, smooth):
    # A grid of n x n quads has 2 n^2 triangles.
    n = max(1, int(round(math.sqrt(triangles / 2.0))))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=n + 1, y_subdivisions=n + 1, size=2.0)
    ob = bpy.context.object
    if smooth:
        bpy.ops.object.shade_smooth()
    mat = bpy.data.materials.new("Grid")
    mat.use_nodes = True
    ob.data.materials.append(mat)
    return ob


def add_uv_normal_map(mat):
    """Image Texture on the UV map into Base Color, and a tangent-space Normal
    Map from the same image: the material then reads UVs and tangents."""
    image = bpy.data.images.new("Bench", 64, 64, float_buffer=False)
    image.generated_type = "COLOR_GRID"
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes.get("Principled BSDF")
    coord = nodes.new("ShaderNodeTexCoord")
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    normal_map = nodes.new("ShaderNodeNormalMap")
    normal_map.space = "TANGENT"
    links.new(coord.outputs["UV"], tex.inputs["Vector"])
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(tex.outputs["Color"], normal_map.inputs["Color"])
    links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])


def profile_export(top=25):
    import cProfile
    import pstats
    native = coherent.native_module()
    depsgraph = bpy.context.evaluated_depsgraph_get()
    profiler = cProfile.Profile()
    profiler.enable()
    result = export.export_scene(native, depsgraph, 512, 512)
    profiler.disable()
    del result
    pstats.Stats(profiler).sort_stats("tottime").print_stats(top)


def load_baseline(path):
    """export.py at `path` as a module of the coherent package (its relative imports resolve there)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("coherent.export_baseline", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def time_export(repeat, modules):
    """Best of `repeat` exports for each module, the modules taking turns."""
    native = coherent.native_module()
    best = [None] * len(modules)
    for _ in range(repeat):
        for i, module in enumerate(modules):
            depsgraph = bpy.context.evaluated_depsgraph_get()
            start = time.perf_counter()
            result = module.export_scene(native, depsgraph, 512, 512)
            seconds = time.perf_counter() - start
            if best[i] is None or seconds < best[i][0]:
                best[i] = (seconds, result.scene.triangle_count, result.instances, result.meshes)
            del result
    return best


def time_calc_tangents(ob, repeat):
    """Best of `repeat` calls of Blender's MikkTSpace on the evaluated mesh (no export code involved)."""
    mesh = ob.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    mesh.calc_normals_split()  # as the export has done before it
    best = None
    for _ in range(repeat):
        start = time.perf_counter()
        mesh.calc_tangents(uvmap=mesh.uv_layers[0].name)
        seconds = time.perf_counter() - start
        mesh.free_tangents()
        best = seconds if best is None else min(best, seconds)
    return best


def main():
    args = parse_args()
    coherent.register()
    modules = [export] + ([load_baseline(args.baseline)] if args.baseline else [])
    results = {}

    cases = [
        ("flat", dict(smooth=False, subdiv=0, instances=1)),
        ("smooth", dict(smooth=True, subdiv=0, instances=1)),
        ("smooth+subsurf", dict(smooth=True, subdiv=1, instances=1)),
        (f"smooth x{args.instances} linked", dict(smooth=True, subdiv=0, instances=args.instances)),
        ("smooth+UV+tangents", dict(smooth=True, subdiv=0, instances=1, normal_map=True)),
    ]
    for name, case in cases:
        if args.only and args.only not in name:
            continue
        reset_scene()
        tris = args.triangles // (4 if case["subdiv"] else 1) // case["instances"]
        ob = add_grid(tris, case["smooth"])
        if case.get("normal_map"):
            add_uv_normal_map(ob.data.materials[0])
        if case["subdiv"]:
            mod = ob.modifiers.new("Subdivision", "SUBSURF")
            mod.levels = mod.render_levels = case["subdiv"]
        for i in range(1, case["instances"]):
            dup = ob.copy()  # linked duplicate: shares the mesh datablock
            dup.location = (2.5 * i, 0.0, 0.0)
            bpy.context.scene.collection.objects.link(dup)
        bpy.context.view_layer.update()
        timings = time_export(args.repeat, modules)
        seconds, triangles, instances, meshes = timings[0]
        print(f"export {name:>20}: {triangles:>9,} triangles ({meshes} mesh, {instances} instances) "
              f"in {seconds:.3f} s = {triangles / seconds / 1e6:.2f} M triangles/s")
        results[name] = dict(seconds=seconds, triangles=triangles, instances=instances, meshes=meshes)
        if args.baseline:
            base = timings[1][0]
            print(f"  baseline {base:.3f} s, this / baseline = {seconds / base:.2f}")
            results[name]["baseline_seconds"] = base
        if case.get("normal_map"):
            tangents = time_calc_tangents(ob, args.repeat)
            print(f"  Blender mesh.calc_tangents alone: {tangents:.3f} s")
            results[name]["calc_tangents_seconds"] = tangents
        if args.profile:
            profile_export()

    print("RESULT " + json.dumps(results))
    coherent.unregister()


if __name__ == "__main__":
    main()
