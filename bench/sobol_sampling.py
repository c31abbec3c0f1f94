#!/usr/bin/python3
"""Owen-scrambled Sobol against white noise under SPT, CPT and ICPT.

Renders each scene through the `coherent` CLI with both patterns
(`--pattern white` and `--pattern sobol`, see native/sample/sampler.h) at
several spp and seeds, and measures the RMSE
of the linear Combined pass against a high-spp reference, and the render
seconds the CLI reports (sample passes only, no scene load or BVH build).

Efficiency = 1 / (MSE x seconds); the table gives Sobol's over white noise's
per sampler and spp. Writes docs/results/sobol_sampling.{csv,md,png}.

Run from the repository root (the Cornell box fixture comes from
tests/fixtures/make_gltf.py):
    /usr/bin/python3 tests/fixtures/make_gltf.py /tmp/sobol_fix
    /usr/bin/python3 bench/sobol_sampling.py --cli build/coherent \
        --scene generated=/tmp/sobol_fix/cornell_box.glb --scene public=../shared/scenes/cornell_box.glb
"""
import argparse
import csv
import json
import os
import subprocess
import sys

import numpy as np
import OpenImageIO as oiio

SEQUENCES = {"sobol": "sobol", "white": "white"}  # label -> --pattern
SAMPLERS = ["spt", "cpt", "icpt"]


def render(cli, scene, out, sampler, spp, seed, res, threads, sequence):
    cmd = [cli, "render", scene, "--res", str(res), str(res), "--spp", str(spp), "--seed", str(seed),
           "--sampler", sampler, "--threads", str(threads), "--pattern", sequence, "--json", "-o", out]
    p = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def read_rgb(path):
    px = oiio.ImageBuf(path).get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        sys.exit(f"cannot read {path}: {oiio.geterror()}")
    return np.asarray(px, dtype=np.float64)[:, :, :3]


def measure(args, name, scene):
    os.makedirs(args.work, exist_ok=True)
    ref_path = os.path.join(args.work, f"{name}_ref_{args.res}_{args.ref_spp}.exr")
    if not os.path.exists(ref_path):
        render(args.cli, scene, ref_path, "spt", args.ref_spp, 1000, args.res, args.threads, "sobol")
    ref = read_rgb(ref_path)
    rows = []
    # Sequences alternate innermost, so load on a shared machine affects both alike.
    for sampler in SAMPLERS:
        for spp in args.spps:
            for seed in range(1, args.seeds + 1):
                for seq in SEQUENCES:
                    out = os.path.join(args.work, f"{name}_{seq}_{sampler}_{spp}_{seed}.exr")
                    stats = render(args.cli, scene, out, sampler, spp, seed, args.res, args.threads, seq)
                    mse = float(np.mean((read_rgb(out) - ref) ** 2))
                    rows.append(dict(scene=name, sequence=seq, sampler=sampler, spp=spp, seed=seed, mse=mse,
                                     seconds=stats["seconds"]))
                    print(f"{name} {seq} {sampler} {spp} spp seed {seed}: rmse {mse ** 0.5:.5f} "
                          f"{stats['seconds']:.2f} s", flush=True)
    return rows


def summarise(rows):
    """(scene, sequence, sampler, spp) -> (mean MSE, mean seconds) over seeds."""
    out = {}
    for r in rows:
        out.setdefault((r["scene"], r["sequence"], r["sampler"], r["spp"]), []).append((r["mse"], r["seconds"]))
    return {k: (float(np.mean([m for m, _ in v])), float(np.mean([s for _, s in v]))) for k, v in out.items()}


def slope(xs, ys):
    return float(np.polyfit(np.log(xs), np.log(ys), 1)[0])


def write_outputs(args, rows, command):
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "sobol_sampling.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    s = summarise(rows)
    scenes = list(dict.fromkeys(r["scene"] for r in rows))

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, len(scenes), figsize=(5.5 * len(scenes), 8.5), squeeze=False)
    colours = {"spt": "tab:blue", "cpt": "tab:orange", "icpt": "tab:green"}
    for j, scene in enumerate(scenes):
        for sampler in SAMPLERS:
            for seq, style in (("sobol", "-o"), ("white", "--x")):
                spps = args.spps
                rmse = [s[(scene, seq, sampler, n)][0] ** 0.5 for n in spps]
                secs = [s[(scene, seq, sampler, n)][1] for n in spps]
                label = f"{sampler.upper()} {seq}"
                axes[0][j].loglog(spps, rmse, style, color=colours[sampler], label=label)
                axes[1][j].loglog(secs, rmse, style, color=colours[sampler], label=label)
        axes[0][j].set_title(f"{scene}: RMSE vs spp")
        axes[0][j].set_xlabel("samples per pixel")
        axes[1][j].set_title(f"{scene}: RMSE vs seconds")
        axes[1][j].set_xlabel("render seconds (2 threads)")
        for a in (axes[0][j], axes[1][j]):
            a.set_ylabel("RMSE (linear Combined)")
            a.grid(True, which="both", alpha=0.3)
            a.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "sobol_sampling.png"), dpi=110)

    lines = ["# Owen-scrambled Sobol vs white noise under SPT, CPT and ICPT", "",
             f"{args.res}x{args.res} pixels, default light paths (12 bounces, 4 diffuse), {args.threads} threads, "
             f"{args.seeds} seeds per point, RMSE of the linear Combined pass against a {args.ref_spp}-spp SPT "
             "reference (Sobol, another seed). Seconds: the CLI's render time (sample passes). "
             "Efficiency = 1 / (MSE x seconds); the ratio is Sobol's over white noise's (> 1: Sobol wins).", "",
             "![RMSE vs spp and vs seconds](sobol_sampling.png)", "",
             "Made by:", "", "    " + command, "",
             "| scene | sampler | spp | RMSE white | RMSE Sobol | s white | s Sobol | efficiency ratio |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for scene in scenes:
        for sampler in SAMPLERS:
            for n in args.spps:
                mw, tw = s[(scene, "white", sampler, n)]
                ms, ts = s[(scene, "sobol", sampler, n)]
                lines.append(f"| {scene} | {sampler.upper()} | {n} | {mw ** 0.5:.5f} | {ms ** 0.5:.5f} | {tw:.2f} | "
                             f"{ts:.2f} | {(mw * tw) / (ms * ts):.2f} |")
    lines += ["", "Log-log slope of RMSE against spp (white noise: -0.5 in theory):", "",
              "| scene | sampler | slope white | slope Sobol | time per sample Sobol / white |", "|---|---|---:|---:|---:|"]
    for scene in scenes:
        for sampler in SAMPLERS:
            sl = {q: slope(args.spps, [s[(scene, q, sampler, n)][0] ** 0.5 for n in args.spps]) for q in SEQUENCES}
            t = {q: sum(s[(scene, q, sampler, n)][1] for n in args.spps) for q in SEQUENCES}
            lines.append(f"| {scene} | {sampler.upper()} | {sl['white']:.3f} | {sl['sobol']:.3f} | "
                         f"{t['sobol'] / t['white']:.3f} |")
    with open(os.path.join(args.out, "sobol_sampling.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default="build/coherent")
    ap.add_argument("--scene", action="append", required=True, help="NAME=PATH (repeatable)")
    ap.add_argument("--res", type=int, default=48)
    ap.add_argument("--spps", type=int, nargs="+", default=[4, 16, 64, 256])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="/tmp/coherent_sobol_sampling")
    ap.add_argument("--out", default="docs/results")
    args = ap.parse_args()
    command = "/usr/bin/python3 bench/sobol_sampling.py " + " ".join(sys.argv[1:])
    rows = []
    for spec in args.scene:
        name, path = spec.split("=", 1)
        rows += measure(args, name, path)
    write_outputs(args, rows, command)


if __name__ == "__main__":
    main()
