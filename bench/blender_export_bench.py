# SPDX-License-Identifier: Apache-2.0
"""Times the Blender -> native scene export of a ~1M-triangle mesh.

Run from the repository root (needs the built _coherent module):

    blender -b --factory-startup --python bench/blender_export_bench.py -- [--triangles N] [--instances K]

Prints one line per case with the export time (depsgraph -> coherent.Scene,
i.e. foreach_get extraction, material conversion and native validation) and a
JSON summary line prefixed with "RESULT ". The target is < 1.5 s for 1M
triangles. Cases: flat-shaded grid, smooth-shaded grid (split normals), the
same smooth grid with a Subdivision modifier evaluated by the depsgraph, and
K linked duplicates of the grid (instancing reuses the extracted arrays).
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


def time_export(repeat):
    native = coherent.native_module()
    best = None
    for _ in range(repeat):
        depsgraph = bpy.context.evaluated_depsgraph_get()
        start = time.perf_counter()
        result = export.export_scene(native, depsgraph, 512, 512)
        seconds = time.perf_counter() - start
        if best is None or seconds < best[0]:
            best = (seconds, result.scene.triangle_count, result.instances, result.meshes)
        del result
    return best


def main():
    args = parse_args()
    coherent.register()
    results = {}

    cases = [
        ("flat", dict(smooth=False, subdiv=0, instances=1)),
        ("smooth", dict(smooth=True, subdiv=0, instances=1)),
        ("smooth+subsurf", dict(smooth=True, subdiv=1, instances=1)),
        (f"smooth x{args.instances} linked", dict(smooth=True, subdiv=0, instances=args.instances)),
    ]
    for name, case in cases:
        reset_scene()
        tris = args.triangles // (4 if case["subdiv"] else 1) // case["instances"]
        ob = add_grid(tris, case["smooth"])
        if case["subdiv"]:
            mod = ob.modifiers.new("Subdivision", "SUBSURF")
            mod.levels = mod.render_levels = case["subdiv"]
        for i in range(1, case["instances"]):
            dup = ob.copy()  # linked duplicate: shares the mesh datablock
            dup.location = (2.5 * i, 0.0, 0.0)
            bpy.context.scene.collection.objects.link(dup)
        bpy.context.view_layer.update()
        seconds, triangles, instances, meshes = time_export(args.repeat)
        print(f"export {name:>20}: {triangles:>9,} triangles ({meshes} mesh, {instances} instances) "
              f"in {seconds:.3f} s = {triangles / seconds / 1e6:.2f} M triangles/s")
        results[name] = dict(seconds=seconds, triangles=triangles, instances=instances, meshes=meshes)

    print("RESULT " + json.dumps(results))
    coherent.unregister()


if __name__ == "__main__":
    main()
