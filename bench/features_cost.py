# SPDX-License-Identifier: Apache-2.0
"""What simulating only the effects a scene calls for buys.

Renders each blend_scenes file twice with the same seed: once with the path
kernel specialised for the scene's SceneFeatures and once with every feature
forced on (the general kernel). Both must give the same image (the forced
kernel only adds code paths the scene never exercises); the time ratio is
what specialisation buys. Runs alternate and the best of N is kept, because
the machine is shared.

Run from the repository root after building (needs addon/coherent/_coherent*.so):

    blender -b --factory-startup --python bench/features_cost.py -- \
        [--res 256] [--spp 16] [--repeat 3] [--out docs/results/features_cost]

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
from coherent import export  # noqa: E402

SCENES = ["cornell_box", "glass_scene"]


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--res", type=int, default=256)
    p.add_argument("--spp", type=int, default=16)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--out", default=os.path.join(ROOT, "docs", "results", "features_cost"))
    return p.parse_args(argv)


def render_once(native, nscene, args, force_all):
    renderer = native.Renderer(nscene, width=args.res, height=args.res, spp=args.spp, seed=7,
                               threads=args.threads, force_all_features=force_all)
    start = time.perf_counter()
    renderer.render()
    seconds = time.perf_counter() - start
    return seconds, renderer.pass_pixels("Combined"), renderer.stats(), list(renderer.features)


def main():
    args = parse_args()
    coherent.register()
    native = coherent.native_module()
    rows = []
    for name in SCENES:
        bpy.ops.wm.open_mainfile(filepath=os.path.join(ROOT, "blend_scenes", name + ".blend"))
        depsgraph = bpy.context.evaluated_depsgraph_get()
        nscene = export.export_scene(native, depsgraph, args.res, args.res).scene
        best = {False: float("inf"), True: float("inf")}
        images, stats, features = {}, {}, {}
        for rep in range(args.repeat):
            for force_all in (False, True):
                seconds, image, st, feats = render_once(native, nscene, args, force_all)
                best[force_all] = min(best[force_all], seconds)
                images[force_all], stats[force_all], features[force_all] = image, st, feats
            print(f"{name}: repeat {rep + 1}/{args.repeat}", file=sys.stderr)
        diff = np.abs(images[False] - images[True])
        rows.append({
            "scene": name,
            "features": " ".join(features[False]),
            "specialised_s": round(best[False], 4),
            "all_features_s": round(best[True], 4),
            "speedup": round(best[True] / best[False], 3),
            "rays_specialised": stats[False]["total_rays"],
            "rays_all_features": stats[True]["total_rays"],
            "max_abs_pixel_diff": float(diff.max()),
            "refraction_rays": stats[False]["rays"]["refraction"],
        })
    coherent.unregister()

    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out + ".csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    header = ("| scene | active features | specialised s | all features s | speed-up | "
              "rays (specialised / all) | refraction rays | max pixel difference |\n|---|---|---:|---:|---:|---:|---:|---:|\n")
    table = header + "".join(
        f"| {r['scene']} | {r['features']} | {r['specialised_s']:.3f} | {r['all_features_s']:.3f} | "
        f"{r['speedup']:.2f}x | {r['rays_specialised']:,} / {r['rays_all_features']:,} | {r['refraction_rays']:,} | "
        f"{r['max_abs_pixel_diff']:.2e} |\n" for r in rows)
    with open(args.out + ".md", "w") as f:
        f.write("# What simulating only the needed effects buys\n\n")
        f.write(f"Command (from the repository root, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}):\n\n")
        f.write("```\nblender -b --factory-startup --python bench/features_cost.py -- "
                f"--res {args.res} --spp {args.spp} --repeat {args.repeat} --threads {args.threads}\n```\n\n")
        f.write(f"{args.res}x{args.res}, {args.spp} spp, {args.threads} thread(s), same seed, best of "
                f"{args.repeat} alternating runs.\n\n")
        f.write(table)
    print(table)


if __name__ == "__main__":
    main()
