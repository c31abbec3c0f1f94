#!/usr/bin/python3
"""Light selection by power against the uniform selection it replaced, and Cycles 3.4.

For each light selection scene of blend_scenes/make_scenes.py (sun + dim
world, 40 lights of varied power, a large emissive mesh with a dim world, an
HDRI world), renders through Blender, side by side in one run and alternating
per seed:
  * Cycles 3.4 at SPP,
  * COHERENT with uniform light selection (uniform_light_selection = True),
  * COHERENT with selection by power (the default),
all at the same resolution, threads, bounce limits and a 1-pixel box filter,
and a Cycles reference at REF_SPP. Reports per scene: RMSE against the
reference at equal spp (its own noise removed in quadrature: the reference's
variance is estimated from Cycles' seed differences scaled by SPP / REF_SPP),
seconds per render, and RMSE at equal time (scaled to Cycles' seconds with
the 1/sqrt(time) law of unbiased Monte Carlo).

Run from the repository root (the add-on's native module must be built):
    /usr/bin/python3 bench/light_selection.py
Inside Blender (this same file) it is the worker:
    blender -b SCENE --addons coherent --python bench/light_selection.py -- OUT SPP REF_SPP RES SEED...
"""
import json
import os
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["sun_dim_world.blend", "many_lights.blend", "emissive_mesh.blend", "hdri_world.blend"]
# power_sobol: selection by power with the Owen-scrambled Sobol pattern, to
# tell the selection's share of any gap to Cycles from the sampling pattern's.
CONFIGS = ["cycles", "uniform", "power", "power_sobol"]


# --- worker (inside Blender) -----------------------------------------------

def render_one(engine, samples, seed, path, uniform=False, pattern="white"):
    import bpy
    scene = bpy.context.scene
    scene.render.engine = engine
    scene.cycles.samples = samples
    scene.cycles.seed = seed
    if engine == "COHERENT":
        scene.coherent.samples = samples
        scene.coherent.seed = seed
        scene.coherent.sampler = "SPT"
        scene.coherent.uniform_light_selection = uniform
        scene.coherent.pattern = pattern.upper()
    scene.render.filepath = path
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - start


def worker(args):
    import bpy
    sys.path.insert(0, os.path.join(REPO, "blend_scenes"))
    from cycles_reference import configure_cycles_reference
    out, spp, ref_spp, res = args[0], int(args[1]), int(args[2]), int(args[3])
    seeds = [int(s) for s in args[4:]]
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x = r.resolution_y = res
    r.resolution_percentage = 100
    r.threads_mode = "FIXED"
    r.threads = 2
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    configure_cycles_reference(scene, spp)
    scene.coherent.threads = 2
    seconds = {}
    ref = os.path.join(out, "reference.exr")
    if not os.path.exists(ref):
        seconds["reference"] = render_one("CYCLES", ref_spp, 1000, ref)
    for seed in seeds:
        for config in CONFIGS:
            path = os.path.join(out, f"{config}_{seed}.exr")
            engine = "CYCLES" if config == "cycles" else "COHERENT"
            seconds[f"{config}_{seed}"] = render_one(engine, spp, seed, path, uniform=config == "uniform",
                                                     pattern="sobol" if config == "power_sobol" else "white")
            print(f"LIGHT_BENCH {config} seed {seed}: {seconds[f'{config}_{seed}']:.2f} s", flush=True)
    with open(os.path.join(out, "seconds.json"), "w") as f:
        json.dump(seconds, f)


# --- driver ----------------------------------------------------------------

def read_rgb(path):
    import numpy as np
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(path)
    return np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float64)[:, :, :3]


def measure(work, seeds, spp, ref_spp):
    import numpy as np
    with open(os.path.join(work, "seconds.json")) as f:
        seconds = json.load(f)
    ref = read_rgb(os.path.join(work, "reference.exr"))
    images = {(c, s): read_rgb(os.path.join(work, f"{c}_{s}.exr")) for c in CONFIGS for s in seeds}
    # Cycles' per-pixel variance at SPP from its seed difference; the reference's is SPP / REF_SPP of it.
    a, b = images[("cycles", seeds[0])], images[("cycles", seeds[1])]
    ref_var = float(np.mean((a - b) ** 2) / 2) * spp / ref_spp
    row = {}
    for c in CONFIGS:
        mse = np.mean([np.mean((images[(c, s)] - ref) ** 2) for s in seeds])
        row[c] = dict(rmse=float(np.sqrt(max(mse - ref_var, 0.0))), rmse_raw=float(np.sqrt(mse)),
                      seconds=float(np.median([seconds[f"{c}_{s}"] for s in seeds])))
    t_cycles = row["cycles"]["seconds"]
    for c in CONFIGS:
        row[c]["rmse_equal_time"] = row[c]["rmse"] * (row[c]["seconds"] / t_cycles) ** 0.5
    row["reference_rmse"] = ref_var ** 0.5
    return row


def write_markdown(rows, args_line, spp, ref_spp, res, path):
    lines = [
        "| scene | RMSE Cycles | RMSE uniform | RMSE power | RMSE power+Sobol | power / uniform | power / Cycles | "
        "power+Sobol / Cycles | s Cycles | s uniform | s power | equal-time RMSE power / Cycles | ref. noise |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for scene, row in rows.items():
        c, u, p, q = row["cycles"], row["uniform"], row["power"], row["power_sobol"]
        lines.append(f"| {scene} | {c['rmse']:.5f} | {u['rmse']:.5f} | {p['rmse']:.5f} | {q['rmse']:.5f} | "
                     f"{p['rmse'] / u['rmse']:.2f} | {p['rmse'] / c['rmse']:.2f} | {q['rmse'] / c['rmse']:.2f} | "
                     f"{c['seconds']:.2f} | {u['seconds']:.2f} | {p['seconds']:.2f} | "
                     f"{p['rmse_equal_time'] / c['rmse_equal_time']:.2f} | {row['reference_rmse']:.5f} |")
    table = "\n".join(lines)
    with open(path, "w") as f:
        f.write(f"<!-- generated by bench/light_selection.py: {args_line} -->\n"
                f"{res}x{res} px, {spp} spp, reference Cycles {ref_spp} spp, 2 threads each\n\n{table}\n")
    return table


def driver():
    import argparse
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--scenes", nargs="+", default=SCENES)
    ap.add_argument("--work", default="/tmp/coherent_light_selection")
    ap.add_argument("--out", default="docs/results/light_selection_table.md")
    args = ap.parse_args()
    sys.path.insert(0, os.path.join(REPO, "tests", "blender"))
    import blender_helpers as bh
    user_scripts = bh.make_user_scripts(os.path.join(args.work, "user_scripts"))
    rows = {}
    for scene in args.scenes:
        work = os.path.join(args.work, scene.replace(".blend", ""), f"{args.res}_{args.spp}_{args.ref_spp}")
        os.makedirs(work, exist_ok=True)
        cmd = [os.path.join(REPO, "blend_scenes", scene), "--python", os.path.abspath(__file__), "--", work,
               str(args.spp), str(args.ref_spp), str(args.res), *map(str, args.seeds)]
        result = bh.run_blender(cmd, user_scripts, timeout=3600, addons=True)
        if result.returncode != 0:
            sys.exit(result.describe())
        rows[scene] = measure(work, args.seeds, args.spp, args.ref_spp)
        print(scene, json.dumps(rows[scene]), flush=True)
    with open(args.out.replace(".md", ".json"), "w") as f:
        json.dump(rows, f, indent=1)
    print(write_markdown(rows, " ".join(sys.argv[1:]) or "(defaults)", args.spp, args.ref_spp, args.res, args.out))


if __name__ == "__main__":
    try:
        import bpy  # noqa: F401
    except ImportError:
        driver()
    else:
        worker(sys.argv[sys.argv.index("--") + 1:])
