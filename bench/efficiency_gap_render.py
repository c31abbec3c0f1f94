# SPDX-License-Identifier: Apache-2.0
"""Blender side of bench/efficiency_gap.py: renders one .blend with Cycles
and COHERENT for a list of jobs, each with its own bounce limit, seed and
(COHERENT only) native setting overrides.

    blender -b --factory-startup --addons coherent SCENE.blend \
        --python bench/efficiency_gap_render.py -- JOBS.json

Common settings are bench/efficiency_render.py's (2 threads, box filter,
no denoising/adaptive/clamping, Standard view, 32-bit EXR). A job's
"native" dict is merged into the keyword arguments the add-on passes to
_coherent.Renderer, so settings that are not Blender properties (for
example rr_min_bounces) can be varied too. One line per render on stdout:
"EFFGAP_RENDER {json}" with the seconds of bpy.ops.render.render().
"""
import json
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from efficiency_render import configure_common, light_paths  # noqa: E402

_native_overrides = {}
_env_set = []


def install_override_hook(scene):
    """Makes the add-on pass _native_overrides to the native Renderer."""
    cls = type(scene.coherent)
    original = cls.renderer_kwargs

    def renderer_kwargs(self, scene):
        kwargs = original(self, scene)
        kwargs.update(_native_overrides)
        return kwargs

    cls.renderer_kwargs = renderer_kwargs


def configure_job(scene, job):
    scene.render.engine = job["engine"]
    for target in (scene.cycles, scene.coherent):
        for key, value in light_paths(job["max_bounces"]).items():
            setattr(target, key, value)
    scene.cycles.samples = job["spp"]
    scene.cycles.seed = job["seed"]
    scene.coherent.samples = job["spp"]
    scene.coherent.seed = job["seed"]
    _native_overrides.clear()
    _native_overrides.update(job.get("native", {}))
    for key, value in job.get("env", {}).items():  # experiments behind environment switches
        os.environ[key] = value
    for key in set(_env_set) - set(job.get("env", {})):
        os.environ.pop(key, None)
    _env_set[:] = list(job.get("env", {}))


def main():
    with open(sys.argv[sys.argv.index("--") + 1]) as f:
        spec = json.load(f)
    scene = bpy.context.scene
    if not hasattr(scene, "coherent"):
        sys.exit("efficiency_gap_render: the COHERENT add-on is not registered (run Blender with --addons coherent)")
    configure_common(scene, dict(spec, max_bounces=4))
    install_override_hook(scene)
    for job in spec["jobs"]:
        configure_job(scene, job)
        start = time.perf_counter()
        result = bpy.ops.render.render()
        seconds = time.perf_counter() - start
        if "FINISHED" not in result:
            sys.exit(f"efficiency_gap_render: {job['engine']} render of {job['out']} returned {sorted(result)}")
        bpy.data.images["Render Result"].save_render(job["out"], scene=scene)
        print("EFFGAP_RENDER " + json.dumps(dict(job, seconds=seconds)), flush=True)


if __name__ == "__main__":
    main()
