# SPDX-License-Identifier: Apache-2.0
"""Persistent data benchmark (issue 14 item 3): the second frame of an
animation where one small object moves beside a big static mesh, with
scene.render.use_persistent_data on and off, as a farm worker renders it
(`blender -b -E COHERENT -s 1 -e 3 -a`, one Blender per run).

Run from the repository root after building (the add-on's _coherent module):

    /usr/bin/python3 bench/persistent_data.py [--scene move|deform] [--segments 512] [--size 128] [--samples 4]
        [--repeats 2]

Scene (built by this file run inside Blender): a smooth UV sphere of
2 * SEGMENTS * (SEGMENTS - 1) triangles (523,264 for 512), a cube keyframed
along x, a floor, a sun. `--scene deform` adds what a character animation
brings: an ico sphere of 5,120 triangles whose shape key is keyframed (its
geometry changes every frame), and two linked duplicates of a UV sphere of
SEGMENTS/2 segments (one shared mesh: a prototype with two instances). Runs alternate on/off REPEATS times; for each frame
the table gives the engine's own split (export, BVH build or refit, render,
from its summary lines) and the wall time between Blender's render_pre and
render_post handlers. The medians over repeats are printed.
"""

import os
import re
import sys
import tempfile
import time
from pathlib import Path

FRAMES = (1, 2, 3)


def add_deforming_and_shared(segments):
    """The deform scene's extra objects: a deforming ico sphere and a shared mesh placed twice."""
    import bpy

    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=4, radius=0.5, location=(1.8, 0.0, 0.6))
    blob = bpy.context.active_object
    blob.shape_key_add(name="Basis")
    squash = blob.shape_key_add(name="Squash")
    for point in squash.data:
        point.co.z *= 0.5
    for frame, value in ((1, 0.0), (3, 1.0)):
        squash.value = value
        squash.keyframe_insert("value", frame=frame)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments // 2, ring_count=segments // 2, radius=0.4,
                                         location=(-2.0, 1.0, 0.4))
    bpy.ops.object.duplicate_move_linked(TRANSFORM_OT_translate={"value": (0.0, 1.2, 0.0)})


def build_scene(mode, segments, size, samples, persistent):
    """Inside Blender: the animation, and handlers that time every frame."""
    import bpy

    scene = bpy.context.scene
    for ob in list(scene.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=segments, ring_count=segments, radius=1.0, location=(0, 1.5, 1))
    bpy.ops.object.shade_smooth()
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(-1.5, 0.0, 0.3))
    cube = bpy.context.active_object
    cube.keyframe_insert("location", frame=1)
    cube.location.x = 1.5
    cube.keyframe_insert("location", frame=3)
    bpy.ops.mesh.primitive_plane_add(size=8.0)
    if mode == "deform":
        add_deforming_and_shared(segments)
    bpy.ops.object.light_add(type="SUN", rotation=(0.6, 0.3, 0.0))
    bpy.ops.object.camera_add(location=(0.0, -6.0, 3.0), rotation=(1.15, 0.0, 0.0))
    scene.camera = bpy.context.active_object
    render = scene.render
    render.engine = "COHERENT"
    render.resolution_x = render.resolution_y = size
    render.resolution_percentage = 100
    render.image_settings.file_format = "OPEN_EXR"
    render.use_persistent_data = persistent
    scene.frame_start, scene.frame_end = FRAMES[0], FRAMES[-1]
    scene.coherent.samples = samples
    started = {}

    def pre(scene_, *_):
        started["t"] = time.perf_counter()

    def post(scene_, *_):
        print(f"PERSIST_FRAME {scene_.frame_current} {time.perf_counter() - started['t']:.4f}", flush=True)

    bpy.app.handlers.render_pre.append(pre)
    bpy.app.handlers.render_post.append(post)


SPLIT = re.compile(r"Coherent: finished .*?: export ([\d.]+) s, BVH ([\d.]+) s, render ([\d.]+) s")
REUSE = re.compile(r"^Coherent: persistent data: (.*)$", re.MULTILINE)


def run(bh, scripts, persistent, args):
    out = os.path.join(tempfile.gettempdir(), f"persist_bench_{persistent}_####")
    proc = bh.run_blender(["--python", __file__, "-o", out, "-s", 1, "-e", FRAMES[-1], "-a", "--",
                           args.scene, args.segments, args.size, args.samples, persistent], scripts, timeout=None)
    if proc.returncode != 0:
        raise RuntimeError(proc.describe())
    walls = {int(f): float(s) for f, s in re.findall(r"PERSIST_FRAME (\d+) ([\d.]+)", proc.stdout)}
    splits = [tuple(map(float, m.groups())) for m in SPLIT.finditer(proc.stdout)]
    reuse = REUSE.findall(proc.stdout)
    return [{"frame": f, "wall": walls[f], "export": e, "bvh": b, "render": r,
             "reuse": reuse[k] if reuse else "-"} for k, (f, (e, b, r)) in enumerate(zip(FRAMES, splits))]


def main():
    import argparse
    import statistics

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "tests" / "blender"))
    import blender_helpers as bh

    parser = argparse.ArgumentParser()
    parser.add_argument("--scene", choices=("move", "deform"), default="move")
    parser.add_argument("--segments", type=int, default=512)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=2)
    args = parser.parse_args()
    scripts = bh.make_user_scripts(tempfile.mkdtemp(prefix="persist_bench_"))
    runs = {0: [], 1: []}
    for _ in range(args.repeats):
        for persistent in (1, 0):
            runs[persistent].append(run(bh, scripts, persistent, args))
    triangles = 2 * args.segments * (args.segments - 1)
    extra = " + deforming ico sphere + shared mesh placed twice" if args.scene == "deform" else ""
    print(f"{triangles:,}-triangle static sphere + moving cube{extra}, {args.size}x{args.size}, {args.samples} spp, "
          f"medians of {args.repeats} runs each (seconds)")
    print("| persistent data | frame | wall | export | BVH | render | reuse (last run) |")
    print("|---|---|---|---|---|---|---|")
    for persistent in (0, 1):
        for k, frame in enumerate(FRAMES):
            rows = [r[k] for r in runs[persistent]]
            med = {key: statistics.median(row[key] for row in rows) for key in ("wall", "export", "bvh", "render")}
            print(f"| {'on' if persistent else 'off'} | {frame} | {med['wall']:.2f} | {med['export']:.2f} | "
                  f"{med['bvh']:.2f} | {med['render']:.2f} | {rows[-1]['reuse']} |")
    for frame_index in (1, 2):
        off = statistics.median(r[frame_index]["wall"] for r in runs[0])
        on = statistics.median(r[frame_index]["wall"] for r in runs[1])
        print(f"frame {FRAMES[frame_index]}: off / on wall = {off / on:.2f}x")


if __name__ == "__main__":
    if "bpy" in sys.modules:  # run by Blender (--python): build the scene
        mode, segments, size, samples, persistent = sys.argv[sys.argv.index("--") + 1:][:5]
        build_scene(mode, int(segments), int(size), int(samples), persistent == "1")
    else:
        main()
