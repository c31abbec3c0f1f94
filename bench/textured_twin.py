# SPDX-License-Identifier: Apache-2.0
"""Textured scene vs its untextured twin (issue 11 target): "a textured scene
renders no slower relative to its untextured twin than Cycles does on the
same pair".

Run from the repository root after building (the add-on's _coherent module):

    /usr/bin/python3 bench/textured_twin.py [--size 128] [--samples 64] [--threads 2] [--repeats 3] [--files]

Scene (built by this file run inside one Blender, factory startup): three UV
spheres, two cubes and a floor, a sun and a grey world. Textured: every
Principled BSDF takes its Base Color from an Image Texture on UVs (generated
images written through numpy: 2048x2048 on the floor, 1024x1024 on the
objects, sRGB bytes) and its Normal from a 1024x1024 Non-Color normal map
through a Normal Map node (tangent space). Untextured twin: the same
materials with the images' mean colours as constant Base Colors and no
Normal Map. Both engines render both scenes (no denoising, fixed seed, fixed
thread count); one warm-up render per engine and scene is not counted, then
the loop alternates engine and scene REPEATS times. The images are packed
into the .blend (held in memory, filtered by COHERENT straight from Blender's
pixels), or with --files saved as PNG files in a temporary folder and loaded
from there (COHERENT: the Non-Color normal map through OpenImageIO's texture
cache; the sRGB albedos, straight alpha, are associated and handed over in
memory as Cycles associates them on load). Times are the wall time of
bpy.ops.render.render (sync/export, image hand-over, BVH, render), medians.
ratio = textured / untextured seconds per engine; the target is
COHERENT's ratio <= Cycles' ratio. Also printed: that quotient per repetition
(paired_ratios), whose median and bootstrap interval are steadier than the
quotient of the per-column medians on a machine whose speed drifts.
"""

import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

ENGINES = ("CYCLES", "COHERENT")
IMAGE_DIR = None  # None: images packed; else the folder their PNG files are saved in
SCENES = ("untextured", "textured")


def make_albedo(name, size, tint, seed):
    """A byte sRGB image: tiles of tinted noise (so MIP levels differ) and its mean linear colour."""
    import bpy
    import numpy as np

    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:size, 0:size] / size
    tiles = ((np.floor(x * 16) + np.floor(y * 16)) % 2)[..., None]
    rgb = np.clip(np.asarray(tint) * (0.55 + 0.35 * tiles) + 0.1 * rng.random((size, size, 3)), 0.0, 1.0)
    pixels = np.concatenate([rgb, np.ones((size, size, 1))], axis=-1).astype(np.float32)
    image = bpy.data.images.new(name, size, size, alpha=False, float_buffer=False)
    image.colorspace_settings.name = "sRGB"
    image.pixels.foreach_set(pixels.ravel())
    image = store_image(image, "sRGB")
    linear = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return image, tuple(linear.reshape(-1, 3).mean(axis=0)) + (1.0,)


def make_normal_map(size):
    """A Non-Color tangent-space normal map of bumps (byte image)."""
    import bpy
    import numpy as np

    y, x = np.mgrid[0:size, 0:size] * (2.0 * np.pi * 24.0 / size)
    nx, ny = 0.35 * np.cos(x) * np.sin(y), 0.35 * np.sin(x) * np.cos(y)
    n = np.stack([nx, ny, np.ones_like(nx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    pixels = np.concatenate([0.5 * n + 0.5, np.ones((size, size, 1))], axis=-1).astype(np.float32)
    image = bpy.data.images.new("bench_normal", size, size, alpha=False, float_buffer=False)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(pixels.ravel())
    return store_image(image, "Non-Color")


def store_image(image, colorspace):
    """Packs a generated image, or saves it as a PNG in IMAGE_DIR and returns that file loaded instead."""
    import bpy

    if IMAGE_DIR is None:
        image.pack()
        return image
    path = os.path.join(IMAGE_DIR, f"{image.name}.png")
    image.filepath_raw = path
    image.file_format = "PNG"
    image.save()
    bpy.data.images.remove(image)
    loaded = bpy.data.images.load(path)
    loaded.colorspace_settings.name = colorspace
    assert loaded.packed_file is None and loaded.source == "FILE"
    return loaded


def principled(name, base_color=None, albedo=None, normal=None):
    """A Principled BSDF material: constant Base Color, or albedo + normal map images on UVs."""
    import bpy

    material = bpy.data.materials.new(name)
    material.use_nodes = True
    nt = material.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Roughness"].default_value = 0.45
    if albedo is None:
        bsdf.inputs["Base Color"].default_value = base_color
        return material
    uv = nt.nodes.new("ShaderNodeTexCoord").outputs["UV"]
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = albedo
    nt.links.new(uv, tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    ntex = nt.nodes.new("ShaderNodeTexImage")
    ntex.image = normal
    nt.links.new(uv, ntex.inputs["Vector"])
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.space = "TANGENT"
    nt.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    return material


def build_objects():
    """The geometry, each object with its (textured, untextured) material pair."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    normal = make_normal_map(1024)
    specs = [("floor", "plane", dict(size=8.0), 2048, (0.7, 0.6, 0.45)),
             ("sphere_a", "uv_sphere", dict(radius=0.6, location=(-1.5, 0.5, 0.6)), 1024, (0.8, 0.3, 0.2)),
             ("sphere_b", "uv_sphere", dict(radius=0.5, location=(0.2, 1.4, 0.5)), 1024, (0.2, 0.5, 0.8)),
             ("sphere_c", "uv_sphere", dict(radius=0.4, location=(1.6, -0.2, 0.4)), 1024, (0.3, 0.8, 0.3)),
             ("cube_a", "cube", dict(size=0.8, location=(-0.2, -0.6, 0.4), rotation=(0, 0, 0.6)), 1024, (0.8, 0.8, 0.2)),
             ("cube_b", "cube", dict(size=0.6, location=(1.2, 1.6, 0.3), rotation=(0, 0, 0.3)), 1024, (0.6, 0.3, 0.7))]
    pairs = []
    for k, (name, kind, kwargs, size, tint) in enumerate(specs):
        getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**kwargs)
        ob = bpy.context.active_object
        if kind == "uv_sphere":
            bpy.ops.object.shade_smooth()
        albedo, mean = make_albedo(f"{name}_albedo", size, tint, seed=k)
        textured = principled(f"{name}_textured", albedo=albedo, normal=normal)
        plain = principled(f"{name}_plain", base_color=mean)
        ob.data.materials.append(plain)
        pairs.append((ob, textured, plain))
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "blender"))
    from node_scenes import add_sun_camera_and_grey_world

    add_sun_camera_and_grey_world(scene, (5.0, -5.0, 4.0), (0.2, 0.2, 0.22))
    return scene, pairs


def configure(scene, size, samples, threads):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "blend_scenes"))
    from cycles_reference import configure_cycles_reference

    r = scene.render
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    r.threads_mode = "FIXED"
    r.threads = threads
    r.image_settings.file_format = "OPEN_EXR"
    configure_cycles_reference(scene, samples)
    scene.coherent.samples = samples
    scene.coherent.threads = threads
    if hasattr(scene.coherent, "use_denoising"):
        scene.coherent.use_denoising = False


def bench_in_blender(size, samples, threads, repeats, out_dir, image_dir):
    import bpy

    global IMAGE_DIR
    IMAGE_DIR = image_dir or None
    scene, pairs = build_objects()
    configure(scene, size, samples, threads)

    def render(engine, which):
        for ob, textured, plain in pairs:
            ob.data.materials[0] = textured if which == "textured" else plain
        scene.render.engine = engine
        scene.render.filepath = os.path.join(out_dir, f"{which}_{engine.lower()}.exr")
        start = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        return time.perf_counter() - start

    for engine in ENGINES:  # warm-up: kernels, images, caches
        for which in SCENES:
            render(engine, which)
    for rep in range(repeats):
        for engine in ENGINES:
            for which in SCENES:
                seconds = render(engine, which)
                print(f"TWIN_SECONDS {engine} {which} {rep} {seconds:.4f}", flush=True)


def paired_ratios(times):
    """Per repetition: (COHERENT textured / untextured) / (Cycles textured / untextured). The machine's speed
    drifts over seconds to minutes (other jobs share its cores and L3), which moves the per-column medians
    apart; one repetition's four renders share their minute, so their ratio cancels most of the drift."""
    per_engine = {e: [t / u for u, t in zip(times[(e, "untextured")], times[(e, "textured")])] for e in ENGINES}
    return [c / y for c, y in zip(per_engine["COHERENT"], per_engine["CYCLES"])]


def bootstrap_interval(values, level=0.9, rounds=4000, seed=1):
    """The `level` interval of the median of `values`, by resampling them with replacement."""
    import random

    rng = random.Random(seed)
    medians = sorted(statistics.median(rng.choices(values, k=len(values))) for _ in range(rounds))
    tail = (1.0 - level) / 2.0
    return medians[int(tail * rounds)], medians[int((1.0 - tail) * rounds) - 1]


def main():
    import argparse

    root = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(root / "tests" / "blender"))
    import blender_helpers as bh

    parser = argparse.ArgumentParser()
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--samples", type=int, default=64)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--files", action="store_true", help="images as PNG files on disk instead of packed")
    args = parser.parse_args()
    scripts = bh.make_user_scripts(tempfile.mkdtemp(prefix="twin_bench_"))
    out_dir = tempfile.mkdtemp(prefix="twin_out_")
    image_dir = tempfile.mkdtemp(prefix="twin_images_") if args.files else ""
    proc = bh.run_blender(["--python", __file__, "--", args.size, args.samples, args.threads, args.repeats, out_dir,
                           image_dir], scripts, timeout=None)
    if proc.returncode != 0:
        raise RuntimeError(proc.describe())
    times = {}
    for engine, which, _, seconds in re.findall(r"TWIN_SECONDS (\S+) (\S+) (\d+) ([\d.]+)", proc.stdout):
        times.setdefault((engine, which), []).append(float(seconds))
    splits = re.findall(r"Coherent: finished .*", proc.stdout)
    print(f"{args.size}x{args.size}, {args.samples} spp, {args.threads} threads, no denoising, "
          f"images {'as PNG files on disk' if args.files else 'packed'}; "
          f"medians of {args.repeats} alternated runs (seconds, wall of bpy.ops.render.render)")
    print("| engine | untextured | textured | ratio textured/untextured | runs (untextured; textured) |")
    print("|---|---|---|---|---|")
    ratio = {}
    for engine in ENGINES:
        u, t = (statistics.median(times[(engine, w)]) for w in SCENES)
        ratio[engine] = t / u
        runs = "; ".join(" ".join(f"{s:.2f}" for s in times[(engine, w)]) for w in SCENES)
        print(f"| {engine} | {u:.2f} | {t:.2f} | {ratio[engine]:.3f} | {runs} |")
    print(f"COHERENT ratio / Cycles ratio = {ratio['COHERENT'] / ratio['CYCLES']:.3f} "
          f"(target <= 1: {'met' if ratio['COHERENT'] <= ratio['CYCLES'] else 'NOT met'})")
    paired = paired_ratios(times)
    low, high = bootstrap_interval(paired)
    print(f"Paired, per repetition (the four renders of one repetition run back to back, so a slow minute of "
          f"this shared machine slows all four): median {statistics.median(paired):.3f}, 90 % interval of the "
          f"median {low:.3f}-{high:.3f} (bootstrap), {sum(q <= 1.0 for q in paired)} of {len(paired)} at or below 1")
    if splits:
        print("COHERENT's own split, last untextured and textured runs:")
        print("  " + splits[-2])
        print("  " + splits[-1])
        memory = [re.search(r"\d+ images.*", line).group(0) for line in splits if "images" in line]
        print(f"Texture memory, first and last of {len(memory)} textured runs: {memory[0]}; {memory[-1]}")


if __name__ == "__main__":
    if "bpy" in sys.modules:  # run by Blender (--python): build the scenes and time the renders
        size, samples, threads, repeats, out_dir, image_dir = (sys.argv[sys.argv.index("--") + 1:] + [""])[:6]
        bench_in_blender(int(size), int(samples), int(threads), int(repeats), out_dir, image_dir)
    else:
        main()
