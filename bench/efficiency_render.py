# SPDX-License-Identifier: Apache-2.0
"""Blender side of bench/efficiency_vs_cycles.py: renders one .blend with
Cycles and COHERENT, job by job, in the order the driver gave.

    blender -b --factory-startup --addons coherent SCENE.blend \
        --python bench/efficiency_render.py -- JOBS.json

JOBS.json holds the common settings (resolution, threads, light paths) and a
list of renders {engine, spp, seed, sampler, pattern, out}. Each render's
seconds are those of bpy.ops.render.render() in this process: scene sync or
export, BVH build and sample passes, what a user waits for after F12, and
none of Blender's start-up; cpu_seconds is the process's CPU time over the
same call (all threads). The image is then written as a linear 32-bit
float EXR (Standard view transform, not timed). One line per render on
stdout: "EFFBENCH_RENDER {json}"; the driver reads those.
"""
import json
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "blend_scenes"))
from cycles_reference import configure_cycles_reference  # noqa: E402


def light_paths(max_bounces):
    return dict(max_bounces=max_bounces, diffuse_bounces=max_bounces, glossy_bounces=max_bounces,
                transmission_bounces=max_bounces)


def configure_common(scene, job):
    r = scene.render
    r.resolution_x, r.resolution_y = job["res"], job["res"]
    r.resolution_percentage = 100
    r.use_border = False
    r.film_transparent = False
    r.threads_mode = "FIXED"
    r.threads = job["threads"]
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    c = configure_cycles_reference(scene, 1)
    for key, value in light_paths(job["max_bounces"]).items():
        setattr(c, key, value)
    c.use_auto_tile = False
    s = scene.coherent
    for key, value in light_paths(job["max_bounces"]).items():
        setattr(s, key, value)
    s.threads = job["threads"]
    s.use_animated_seed = False
    s.use_adaptive_sampling = False
    s.clamp_direct = 0.0
    s.clamp_indirect = 0.0
    s.target_error = 0.0
    s.time_limit = 0.0
    # Settings other work may add: keep the comparison plain and unbiased.
    for name, value in (("use_denoising", False), ("filter_width", 1.0), ("filter_type", "BOX")):
        if hasattr(s, name):
            setattr(s, name, value)


def configure_render(scene, render):
    scene.render.engine = render["engine"]
    scene.cycles.samples = render["spp"]
    scene.cycles.seed = render["seed"]
    if render["engine"] == "COHERENT":
        s = scene.coherent
        s.samples = render["spp"]
        s.seed = render["seed"]
        s.sampler = render["sampler"].upper()
        s.pattern = render["pattern"].upper()


def coherent_defaults(scene):
    """The add-on's defaults of the settings the benchmark varies."""
    props = type(scene.coherent).bl_rna.properties
    return {name: props[name].default.lower() for name in ("sampler", "pattern")}


def main():
    with open(sys.argv[sys.argv.index("--") + 1]) as f:
        job = json.load(f)
    scene = bpy.context.scene
    if not hasattr(scene, "coherent"):
        sys.exit("efficiency_render: the COHERENT add-on is not registered (run Blender with --addons coherent)")
    configure_common(scene, job)
    print("EFFBENCH_INFO " + json.dumps(dict(blender=bpy.app.version_string, defaults=coherent_defaults(scene),
                                             cycles_pattern=scene.cycles.sampling_pattern)), flush=True)
    for render in job["renders"]:
        configure_render(scene, render)
        start, cpu_start = time.perf_counter(), time.process_time()
        result = bpy.ops.render.render()
        seconds = time.perf_counter() - start
        cpu_seconds = time.process_time() - cpu_start  # every thread of this process
        if "FINISHED" not in result:
            sys.exit(f"efficiency_render: {render['engine']} render of {render['out']} returned {sorted(result)}")
        bpy.data.images["Render Result"].save_render(render["out"], scene=scene)
        print("EFFBENCH_RENDER " + json.dumps(dict(render, seconds=seconds, cpu_seconds=cpu_seconds)), flush=True)


if __name__ == "__main__":  # bench/efficiency_gap_render.py imports the settings
    main()
