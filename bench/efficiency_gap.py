#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Where COHERENT's noise exceeds Cycles': variance per bounce limit and per
variant of our settings, both engines in one Blender process.

For each max-bounces value and each of K seeds, renders the scene with
Cycles and with every COHERENT variant at the same spp (bench/
efficiency_gap_render.py; engines alternate render by render). With no
reference needed, the error of one render is measured as its variance over
seeds: the mean over pixels and RGB of the unbiased per-pixel variance of
the K images, which equals the MSE of one render when the estimator is
unbiased. The bias check is the squared difference of the engines' seed
means, less what their noise explains ((var_a + var_b) / K), relative to
Cycles' variance: near 0 when both converge to the same image.

    /usr/bin/python3 bench/efficiency_gap.py --scene crytek_sponza \
        --bounces 1 2 3 4 --spp 16 --seeds 8 \
        --variant default '{}' --variant rr1 '{"rr_min_bounces": 1}'

Prints a markdown table: per bounce limit and engine, RMSE (sqrt of the
variance), seconds per render (median, setup included), RMSE / Cycles' and
the efficiency ratio (Cycles' var x s) / (ours).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
from efficiency_vs_cycles import read_rgb, user_scripts  # noqa: E402


def variance_over_seeds(images):
    """Mean over pixels and channels of the unbiased per-pixel variance."""
    stack = np.stack(images)
    return float(np.mean(np.var(stack, axis=0, ddof=1)))


def jobs_for(args, work):
    jobs = []
    for bounces in args.bounces:
        for seed in range(1, args.seeds + 1):
            engines = [("cycles", "CYCLES", {})] + [(name, "COHERENT", json.loads(js)) for name, js in args.variant]
            for name, engine, native in engines:
                env = native.pop("env", {})
                jobs.append(dict(engine=engine, name=name, max_bounces=bounces, spp=args.spp, seed=seed,
                                 native=native, env=env, out=str(work / f"{name}_b{bounces}_s{seed}.exr")))
    return jobs


def run(args, scene_path, work):
    warm = [dict(engine=e, name="warmup", max_bounces=1, spp=1, seed=0, native={}, out=str(work / f"warm_{e}.exr"))
            for e in ("CYCLES", "COHERENT")]
    spec = dict(res=args.res, threads=args.threads, jobs=warm + jobs_for(args, work))
    with tempfile.NamedTemporaryFile("w", suffix=".json", dir=work, delete=False) as f:
        json.dump(spec, f)
    scripts = user_scripts(work)
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(scripts), BLENDER_USER_CONFIG=str(scripts.parent / "config"))
    env.pop("PYTHONPATH", None)
    cmd = [args.blender, "-b", "--factory-startup", "--python-exit-code", "1", "--addons", "coherent",
           str(scene_path), "--python", str(REPO / "bench" / "efficiency_gap_render.py"), "--", f.name]
    done, tail = [], []
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env) as p:
        for line in p.stdout:
            tail = (tail + [line])[-40:]
            if line.startswith("EFFGAP_RENDER "):
                job = json.loads(line.split(" ", 1)[1])
                if job["name"] != "warmup":
                    done.append(job)
    os.unlink(f.name)
    if p.returncode != 0:
        sys.exit(f"Blender failed on {scene_path} (exit {p.returncode}):\n{''.join(tail)}")
    return done


def summarise(args, done):
    rows = []
    names = ["cycles"] + [name for name, _ in args.variant]
    for bounces in args.bounces:
        stats = {}
        for name in names:
            jobs = [j for j in done if j["name"] == name and j["max_bounces"] == bounces]
            images = [read_rgb(j["out"]) for j in jobs]
            stats[name] = dict(var=variance_over_seeds(images), mean=np.mean(np.stack(images), axis=0),
                               seconds=statistics.median(j["seconds"] for j in jobs))
        cyc = stats["cycles"]
        for name in names:
            s = stats[name]
            d2 = float(np.mean((s["mean"] - cyc["mean"]) ** 2)) - (s["var"] + cyc["var"]) / args.seeds
            rows.append(dict(bounces=bounces, engine=name, rmse=s["var"] ** 0.5, seconds=s["seconds"],
                             rmse_ratio=(s["var"] / cyc["var"]) ** 0.5,
                             efficiency_ratio=cyc["var"] * cyc["seconds"] / (s["var"] * s["seconds"]),
                             bias2_over_var=d2 / cyc["var"]))
    return rows


def markdown(args, rows):
    out = [f"scene {args.scene}, {args.res}x{args.res}, {args.threads} threads, {args.spp} spp per render, "
           f"{args.seeds} seeds", "",
           "| max bounces | engine | RMSE (seed std) | s / render | RMSE / Cycles | efficiency ratio | bias^2 / Cycles var |",
           "|---:|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        bias = "-" if r["engine"] == "cycles" else f"{r['bias2_over_var']:+.3f}"
        out.append(f"| {r['bounces']} | {r['engine']} | {r['rmse']:.5f} | {r['seconds']:.2f} | {r['rmse_ratio']:.2f} | "
                   f"{r['efficiency_ratio']:.2f} | {bias} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", required=True, help="a .blend path, or a name in --shared")
    ap.add_argument("--shared", type=Path, default=REPO.parent / "shared" / "scenes")
    ap.add_argument("--bounces", type=int, nargs="+", default=[4])
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--variant", nargs=2, action="append", metavar=("NAME", "JSON"),
                    help="a COHERENT configuration: native setting overrides as JSON, and under the key "
                         "\"env\" environment variables set for its renders (repeatable)")
    ap.add_argument("--work", type=Path, default=REPO / "build" / "efficiency_gap")
    ap.add_argument("--json", type=Path, help="also write the rows here")
    ap.add_argument("--blender", default="blender")
    args = ap.parse_args()
    args.variant = args.variant or [["default", "{}"]]
    path = Path(args.scene)
    if not path.suffix:
        path = args.shared / f"{args.scene}.blend"
    work = (args.work / path.stem).resolve()
    work.mkdir(parents=True, exist_ok=True)
    rows = summarise(args, run(args, path, work))
    print(markdown(args, rows))
    if args.json:
        args.json.write_text(json.dumps(dict(args=vars(args) | dict(work=str(work), shared=str(args.shared),
                                                                        json=str(args.json)), rows=rows), indent=1))


if __name__ == "__main__":
    main()
