# SPDX-License-Identifier: Apache-2.0
"""Whole renders with batch shading on and off (setting shader_batch,
render/batch_shading.h), for the packet, stream and wavefront integrators,
side by side in one Blender run.

Run from the repository root after building (the add-on's _coherent module):

    /usr/bin/python3 bench/shader_batch_render.py [--size 160] [--samples 16] [--threads 2] [--repeats 3]

Scene (built inside one Blender, factory startup): a floor and four objects
whose materials all run shader programs: a procedural one (Object coordinates
-> Mapping -> Noise Texture (detail 2) -> ColorRamp, mixed with the noise
colour by a clamped Math factor; roughness from Math), a texture-heavy one
(UV -> Image Texture 1024x1024 sRGB bytes -> RGB to BW -> ColorRamp -> Mix),
and an arithmetic one (Mapping -> Vector Math -> Math chain -> ColorRamp ->
Mix); a sun and a grey world. Each traversal renders with shader_batch off
and on, alternated, REPEATS times after one warm-up each. Times are the
renderer's own render seconds (the add-on's "render X s": no export or BVH
build), medians; ratio = off / on (> 1: batches faster). The first off and on
images of each traversal are compared float for float (they must be
identical).
"""

import os
import re
import statistics
import sys
import tempfile
from pathlib import Path

TRAVERSALS = ("PACKET", "STREAM", "WAVEFRONT")


def link(nt, a, b):
    nt.links.new(a, b)


def procedural_material():
    import bpy

    m = bpy.data.materials.new("procedural")
    m.use_nodes = True
    nt = m.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (3.0, 3.0, 3.0)
    mapping.inputs["Rotation"].default_value = (0.3, 0.5, 0.7)
    noise = nt.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Detail"].default_value = 2.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.3, 0.05, 0.02, 1.0)
    ramp.color_ramp.elements[1].color = (1.0, 0.85, 0.6, 1.0)
    math = nt.nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY"
    math.use_clamp = True
    math.inputs[1].default_value = 1.5
    mix = nt.nodes.new("ShaderNodeMixRGB")
    link(nt, coord.outputs["Object"], mapping.inputs["Vector"])
    link(nt, mapping.outputs["Vector"], noise.inputs["Vector"])
    link(nt, noise.outputs["Fac"], ramp.inputs["Fac"])
    link(nt, noise.outputs["Fac"], math.inputs[0])
    link(nt, math.outputs["Value"], mix.inputs["Fac"])
    link(nt, ramp.outputs["Color"], mix.inputs["Color1"])
    link(nt, noise.outputs["Color"], mix.inputs["Color2"])
    link(nt, mix.outputs["Color"], bsdf.inputs["Base Color"])
    link(nt, math.outputs["Value"], bsdf.inputs["Roughness"])
    return m


def texture_material():
    import bpy
    import numpy as np

    size = 1024
    rng = np.random.default_rng(1)
    y, x = np.mgrid[0:size, 0:size] / size
    tiles = ((np.floor(x * 16) + np.floor(y * 16)) % 2)[..., None]
    rgb = np.clip((0.4 + 0.4 * tiles) * np.array([0.8, 0.6, 0.4]) + 0.15 * rng.random((size, size, 3)), 0, 1)
    image = bpy.data.images.new("bench_albedo", size, size, alpha=False, float_buffer=False)
    image.pixels.foreach_set(np.concatenate([rgb, np.ones((size, size, 1))], axis=-1).astype(np.float32).ravel())
    image.pack()
    m = bpy.data.materials.new("texture")
    m.use_nodes = True
    nt = m.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    link(nt, nt.nodes.new("ShaderNodeTexCoord").outputs["UV"], tex.inputs["Vector"])
    bw = nt.nodes.new("ShaderNodeRGBToBW")
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.05, 0.1, 0.3, 1.0)
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.inputs["Fac"].default_value = 0.5
    link(nt, tex.outputs["Color"], bw.inputs["Color"])
    link(nt, bw.outputs["Val"], ramp.inputs["Fac"])
    link(nt, ramp.outputs["Color"], mix.inputs["Color1"])
    link(nt, tex.outputs["Color"], mix.inputs["Color2"])
    link(nt, mix.outputs["Color"], bsdf.inputs["Base Color"])
    return m


def math_material():
    import bpy

    m = bpy.data.materials.new("math")
    m.use_nodes = True
    nt = m.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.2, 0.4, 0.1)
    dot = nt.nodes.new("ShaderNodeVectorMath")
    dot.operation = "DOT_PRODUCT"
    dot.inputs[1].default_value = (2.0, 3.0, 1.0)
    mul = nt.nodes.new("ShaderNodeMath")
    mul.operation = "MULTIPLY"
    mul.inputs[1].default_value = 4.0
    frac = nt.nodes.new("ShaderNodeMath")
    frac.operation = "FRACT"
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[1].color = (0.9, 0.3, 0.1, 1.0)
    mix = nt.nodes.new("ShaderNodeMixRGB")
    mix.inputs["Color2"].default_value = (0.1, 0.5, 0.2, 1.0)
    link(nt, coord.outputs["Object"], mapping.inputs["Vector"])
    link(nt, mapping.outputs["Vector"], dot.inputs[0])
    link(nt, dot.outputs["Value"], mul.inputs[0])
    link(nt, mul.outputs["Value"], frac.inputs[0])
    link(nt, frac.outputs["Value"], ramp.inputs["Fac"])
    link(nt, frac.outputs["Value"], mix.inputs["Fac"])
    link(nt, ramp.outputs["Color"], mix.inputs["Color1"])
    link(nt, mix.outputs["Color"], bsdf.inputs["Base Color"])
    return m


def build_scene():
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    materials = {"procedural": procedural_material(), "texture": texture_material(), "math": math_material()}
    specs = [("plane", dict(size=8.0), "procedural"),
             ("uv_sphere", dict(radius=0.6, location=(-1.5, 0.5, 0.6)), "texture"),
             ("uv_sphere", dict(radius=0.5, location=(0.2, 1.4, 0.5)), "math"),
             ("uv_sphere", dict(radius=0.4, location=(1.6, -0.2, 0.4)), "procedural"),
             ("cube", dict(size=0.8, location=(-0.2, -0.6, 0.4)), "math")]
    for kind, kwargs, material in specs:
        getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**kwargs)
        ob = bpy.context.active_object
        if kind == "uv_sphere":
            bpy.ops.object.shade_smooth()
        ob.data.materials.append(materials[material])
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "blender"))
    from node_scenes import add_sun_camera_and_grey_world

    add_sun_camera_and_grey_world(scene, (5.0, -5.0, 4.0), (0.2, 0.2, 0.22))
    return scene


def bench_in_blender(size, samples, threads, repeats, out_dir):
    import bpy

    scene = build_scene()
    r = scene.render
    r.engine = "COHERENT"
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    props = scene.coherent
    props.samples = samples
    props.threads = threads
    if hasattr(props, "use_denoising"):
        props.use_denoising = False

    def render(traversal, batch, tag):
        props.traversal = traversal
        props.shader_batch = batch
        r.filepath = os.path.join(out_dir, f"{traversal.lower()}_{'on' if batch else 'off'}_{tag}.exr")
        print(f"SB_RUN {traversal} {int(batch)} {tag}", flush=True)
        bpy.ops.render.render(write_still=True)

    for traversal in TRAVERSALS:  # warm-up: kernels, images, caches
        for batch in (False, True):
            render(traversal, batch, "warm")
    for rep in range(repeats):
        for traversal in TRAVERSALS:
            for batch in (False, True):
                render(traversal, batch, str(rep))


def parse_runs(stdout):
    """(traversal, batch) -> render seconds of the timed runs, from the add-on's log."""
    times = {}
    current = None
    for line in stdout.splitlines():
        m = re.match(r"SB_RUN (\S+) (\d) (\S+)", line)
        if m:
            current = (m.group(1), m.group(2) == "1", m.group(3))
            continue
        m = re.search(r"Coherent: finished .* render ([\d.]+) s", line)
        if m and current and current[2] != "warm":
            times.setdefault(current[:2], []).append(float(m.group(1)))
    return times


def main():
    import argparse

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "tests" / "blender"))
    import blender_helpers as bh

    parser = argparse.ArgumentParser()
    parser.add_argument("--size", type=int, default=160)
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    scripts = bh.make_user_scripts(tempfile.mkdtemp(prefix="sb_bench_"))
    out_dir = tempfile.mkdtemp(prefix="sb_out_")
    proc = bh.run_blender(["--python", __file__, "--", args.size, args.samples, args.threads, args.repeats, out_dir],
                          scripts, timeout=None)
    if proc.returncode != 0:
        raise RuntimeError(proc.describe())
    times = parse_runs(proc.stdout)
    print(f"{args.size}x{args.size}, {args.samples} spp, {args.threads} threads, no denoising; renderer's render "
          f"seconds, medians of {args.repeats} alternated runs")
    print("| traversal | batch off (s) | batch on (s) | ratio off/on | identical images | runs off; on |")
    print("|---|---|---|---|---|---|")
    for traversal in TRAVERSALS:
        off, on = times[(traversal, False)], times[(traversal, True)]
        a, b = (bh.read_image_channels(os.path.join(out_dir, f"{traversal.lower()}_{s}_0.exr")) for s in ("off", "on"))
        same = a.keys() == b.keys() and all((a[k] == b[k]).all() for k in a)
        runs = " ".join(f"{s:.2f}" for s in off) + "; " + " ".join(f"{s:.2f}" for s in on)
        print(f"| {traversal.lower()} | {statistics.median(off):.2f} | {statistics.median(on):.2f} | "
              f"{statistics.median(off) / statistics.median(on):.3f} | {'yes' if same else 'NO'} | {runs} |")


if __name__ == "__main__":
    if "bpy" in sys.modules:  # run by Blender (--python): build the scene and render it
        size, samples, threads, repeats, out_dir = sys.argv[sys.argv.index("--") + 1:][:5]
        bench_in_blender(int(size), int(samples), int(threads), int(repeats), out_dir)
    else:
        main()
