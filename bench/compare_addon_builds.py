#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Seconds per render of two or more builds of the add-on on one scene,
alternating build by build so that the machine's noise falls on all alike.

A build is a folder holding the add-on package (the `coherent` folder with its
compiled `_coherent*.so`), for example a copy of this checkout's
`addon/coherent` taken before a change:

    cp -rL addon/coherent /tmp/before/coherent       # before the change
    ... change, rebuild ...
    /usr/bin/python3 bench/compare_addon_builds.py --scene stanford_bunny \\
        --build before /tmp/before --build after addon --rounds 4

Each round starts one Blender per build (in the order given) that renders
the scene --renders times with bench/efficiency_render.py's settings (2
threads, box filter, no adaptive sampling, denoising or clamping; Auto
sampler and traversal) and reports the median of all renders but the first
(warm-up). Prints every round's medians, then per build the median over
rounds and its ratio to the first build's. (bench/compare_builds.sh does
the same for the command-line benches of two source trees.)
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared" / "scenes"

RENDER_SCRIPT = r"""
import json, os, sys, time
import bpy
sys.path.insert(0, os.environ["COMPARE_BENCH_DIR"])
from efficiency_render import configure_common, configure_render
job = json.loads(os.environ["COMPARE_JOB"])
scene = bpy.context.scene
if not hasattr(scene, "coherent"):
    sys.exit("compare_addon_builds: the add-on did not register")
configure_common(scene, job)
configure_render(scene, {"engine": "COHERENT", "spp": job["spp"], "seed": 1, "sampler": "auto", "pattern": "sobol"})
for _ in range(job["renders"]):
    t = time.perf_counter()
    bpy.ops.render.render()
    print("COMPARE_RENDER", time.perf_counter() - t, flush=True)
"""


def scene_path(name):
    p = Path(name)
    if p.suffix == ".blend" and p.exists():
        return p
    candidate = SHARED / f"{name}.blend"
    if candidate.exists():
        return candidate
    sys.exit(f"compare_addon_builds: no scene {name!r} (a .blend path, or a name in {SHARED})")


def addon_dir(path):
    """The folder that contains the `coherent` package, checked."""
    p = Path(path).resolve()
    if (p / "coherent" / "__init__.py").exists():
        return p
    if (p / "__init__.py").exists() and p.name == "coherent":
        return p.parent
    sys.exit(f"compare_addon_builds: {path} holds no `coherent` add-on package")


def render_times(blender, blend, addons, job):
    with tempfile.TemporaryDirectory() as user:
        (Path(user) / "addons").mkdir()
        os.symlink(addons / "coherent", Path(user) / "addons" / "coherent")
        env = dict(os.environ, BLENDER_USER_SCRIPTS=user, COMPARE_JOB=json.dumps(job),
                   COMPARE_BENCH_DIR=str(REPO / "bench"))
        out = subprocess.run([blender, "-b", "--factory-startup", str(blend), "--addons", "coherent",
                              "--python-exit-code", "1", "--python-expr", RENDER_SCRIPT],
                             env=env, capture_output=True, text=True)
    times = [float(line.split()[1]) for line in out.stdout.splitlines() if line.startswith("COMPARE_RENDER")]
    if out.returncode != 0 or len(times) != job["renders"]:
        sys.exit(f"compare_addon_builds: Blender failed ({out.returncode}):\n{out.stdout[-2000:]}\n{out.stderr[-2000:]}")
    return times


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", required=True, help="a .blend path, or a name in ../shared/scenes")
    ap.add_argument("--build", nargs=2, action="append", metavar=("NAME", "DIR"), required=True,
                    help="a name and a folder with the `coherent` add-on package (repeat; the first is the baseline)")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--renders", type=int, default=5, help="renders per Blender; the first is not counted")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--bounces", type=int, default=4)
    ap.add_argument("--blender", default="blender")
    args = ap.parse_args()
    if len(args.build) < 2:
        ap.error("give at least two --build")
    if args.renders < 2:
        ap.error("--renders must be at least 2 (the first is a warm-up)")
    blend = scene_path(args.scene)
    builds = [(name, addon_dir(path)) for name, path in args.build]
    job = {"res": args.res, "threads": args.threads, "max_bounces": args.bounces, "spp": args.spp,
           "renders": args.renders}
    medians = {name: [] for name, _ in builds}
    total = args.rounds * len(builds)
    for r in range(args.rounds):
        for i, (name, path) in enumerate(builds):
            times = render_times(args.blender, blend, path, job)
            medians[name].append(statistics.median(times[1:]))
            print(f"[{r * len(builds) + i + 1}/{total}] round {r + 1} {name}: {medians[name][-1]:.3f} s "
                  f"(renders {' '.join(f'{t:.3f}' for t in times)})", file=sys.stderr, flush=True)
    base = statistics.median(medians[builds[0][0]])
    print(f"{blend.name}: {args.res}x{args.res}, {args.spp} spp, {args.bounces} bounces, {args.threads} threads; "
          f"median of {args.renders - 1} renders per Blender, {args.rounds} rounds\n")
    print("| build | seconds per render (median of rounds) | / " + builds[0][0] + " | rounds |")
    print("|---|---:|---:|---|")
    for name, _ in builds:
        m = statistics.median(medians[name])
        print(f"| {name} | {m:.3f} | {m / base:.3f} | {' '.join(f'{t:.3f}' for t in medians[name])} |")


if __name__ == "__main__":
    main()
