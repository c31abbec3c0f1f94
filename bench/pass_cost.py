# SPDX-License-Identifier: Apache-2.0
"""What Cycles' passes cost (issue 13: "a pass that isn't ticked costs
nothing: no accumulation and no extra rays; only the AO pass traces its own
rays").

Renders each scene with the same seed and settings under several pass
configurations, alternating them in every repeat and keeping the best time
of each (the machine is shared), and reports each as a ratio to the render
without passes, with the rays traced and whether Combined stayed
bit-identical (passes only copy contributions; the AO pass's own rays draw
no number the path uses). Times are the process's CPU seconds (one render
thread), which other programs on a shared machine disturb less than the
wall clock; wall seconds are in the CSV. The ray count is the tracer's
statistics, which do not count the AO pass's own occlusion rays (one per
camera sample that hits).

Run from the repository root after building (needs addon/coherent/_coherent*.so):

    blender -b --factory-startup --python bench/pass_cost.py -- \
        [--res 256] [--spp 16] [--repeat 3] [--threads 1] [--out docs/results/pass_cost]

Writes OUT.csv and OUT.md and prints the table.
"""

import argparse
import csv
import os
import sys
import time

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "addon"))

import coherent  # noqa: E402
from coherent import engine, export  # noqa: E402

SCENES = ["cornell_box", "glass_scene"]
LIGHT = ["DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol", "TransDir", "TransInd", "TransCol",
         "Emit", "Env"]
DATA = ["Mist", "UV", "Position", "IndexOB", "IndexMA", "Vector"]
# Configuration name -> Renderer keyword arguments.
CONFIGS = {
    "no passes": {},
    "light + data": dict(passes=LIGHT + DATA),
    "AO": dict(passes=["AO"]),
    "Cryptomatte (3 types, 6 levels)": dict(cryptomatte=["object", "material", "asset"], cryptomatte_levels=6),
    "all of them": dict(passes=LIGHT + DATA + ["AO"], cryptomatte=["object", "material", "asset"],
                        cryptomatte_levels=6),
}


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", default=os.path.join(ROOT, "docs", "results", "pass_cost"))
    return p.parse_args(argv)


def render_once(native, nscene, args, kwargs):
    renderer = native.Renderer(nscene, width=args.res, height=args.res, spp=args.spp, seed=7, threads=args.threads,
                               **kwargs)
    start, cpu_start = time.perf_counter(), time.process_time()
    renderer.render()
    cpu = time.process_time() - cpu_start
    return (cpu, time.perf_counter() - start), renderer.pass_pixels("Combined"), renderer.stats()


def measure_scene(native, name, args):
    bpy.ops.wm.open_mainfile(filepath=os.path.join(ROOT, "blend_scenes", name + ".blend"))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    nscene = export.export_scene(native, depsgraph, args.res, args.res).scene
    engine.set_data_pass_inputs(nscene, depsgraph.scene)
    best = {c: (float("inf"), float("inf")) for c in CONFIGS}  # (CPU, wall) seconds
    images, stats = {}, {}
    for rep in range(args.repeat):
        for config, kwargs in CONFIGS.items():
            seconds, images[config], stats[config] = render_once(native, nscene, args, kwargs)
            best[config] = tuple(min(b, s) for b, s in zip(best[config], seconds))
        print(f"{name}: repeat {rep + 1}/{args.repeat}", file=sys.stderr)
    base = "no passes"
    return [{
        "scene": name,
        "config": config,
        "cpu_seconds": round(best[config][0], 4),
        "ratio": round(best[config][0] / best[base][0], 3),
        "wall_seconds": round(best[config][1], 4),
        "wall_ratio": round(best[config][1] / best[base][1], 3),
        "rays": stats[config]["total_rays"],
        "extra_rays": stats[config]["total_rays"] - stats[base]["total_rays"],
        "combined_identical": bool(np.array_equal(images[config], images[base])),
    } for config in CONFIGS]


def write_results(rows, args):
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out + ".csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    header = ("| scene | passes | best CPU s | CPU time / no passes | wall / no passes | rays | extra rays | "
              "Combined bit-identical |\n|---|---|---:|---:|---:|---:|---:|---|\n")
    table = header + "".join(
        f"| {r['scene']} | {r['config']} | {r['cpu_seconds']:.3f} | {r['ratio']:.3f} | {r['wall_ratio']:.3f} | "
        f"{r['rays']:,} | "
        f"{r['extra_rays']:,} | {'yes' if r['combined_identical'] else 'NO'} |\n" for r in rows)
    with open(args.out + ".md", "w") as f:
        f.write("# What Cycles' passes cost\n\n")
        f.write(f"Command (from the repository root, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}):\n\n")
        f.write("```\nblender -b --factory-startup --python bench/pass_cost.py -- "
                f"--res {args.res} --spp {args.spp} --repeat {args.repeat} --threads {args.threads}\n```\n\n")
        f.write(f"{args.res}x{args.res}, {args.spp} spp, {args.threads} thread(s), same seed; best of "
                f"{args.repeat} runs, the configurations alternating within each run. Light passes: "
                f"{', '.join(LIGHT)}; data passes: {', '.join(DATA)}. Rays: the tracer's count, without the "
                f"AO pass's own occlusion rays.\n\n")
        f.write(table)
    print(table)


def main():
    args = parse_args()
    coherent.register()
    native = coherent.native_module()
    rows = []
    for name in SCENES:
        rows += measure_scene(native, name, args)
    coherent.unregister()
    write_results(rows, args)


if __name__ == "__main__":
    main()
