#!/usr/bin/python3
"""What coherent path tracing and packets cost and buy, on whole renders.

Runs `render-bench` (bench/render_bench.cpp) on the shared scenes and writes
docs/results/coherent_paths.{md,csv} plus plots:

* speed (the coherent path tracing paper's Fig. 6 and Fig. 7): relative speed
  CPT/SPT, ICPT/SPT and CPT/ICPT (all with packets) and against SPT with
  single rays, and SIMD utilisation, for 0..4 bounces, 4x4 packets, 64 spp;
  plus the paper's 16x16 Sponza 3-bounce CPT/SPT ratio (paper: 6.2x);
* assembly (the packets paper's Fig. 8): box and triangle tests per ray at
  each bounce depth for ray-type and runs assembly;
* error versus time: relative RMSE against a high-sample SPT reference
  against thread CPU seconds, log-log, per method and scene, and the
  equal-error time (when each method reaches SPT single rays' RMSE at 256 spp).

Run from the repository root (one thread; takes a while, progress on stderr):
    /usr/bin/python3 bench/coherent_paths.py --bench build/render-bench
"""
import argparse
import csv
import io
import os
import subprocess
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SCENES = ["cornell_box", "crytek_sponza", "stanford_bunny", "stanford_dragon"]
RESULTS = "docs/results"


def run(bench, args):
    cmd = [bench] + args
    print("+ " + " ".join(cmd), file=sys.stderr, flush=True)
    p = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True)
    return list(csv.DictReader(io.StringIO(p.stdout))), " ".join(cmd)


def scene_path(name):
    return os.path.join("..", "shared", "scenes", name + ".glb")


def speed_plots(rows, path):
    fig, axes = plt.subplots(2, len(SCENES), figsize=(4 * len(SCENES), 7), squeeze=False)
    for k, scene in enumerate(SCENES):
        r = [x for x in rows if x["scene"] == scene and x["packet"] == "4x4"]
        if not r:
            continue
        sec = {(int(x["bounces"]), x["method"]): float(x["seconds"]) for x in r}
        util = {(int(x["bounces"]), x["method"]): float(x["box_utilisation"]) for x in r}
        bounces = sorted({int(x["bounces"]) for x in r})
        ax = axes[0][k]
        for label, num, den in [("CPT/SPT", "cpt-packet", "spt-packet"), ("ICPT/SPT", "icpt-packet", "spt-packet"),
                                ("CPT/ICPT", "cpt-packet", "icpt-packet"),
                                ("CPT packets / SPT single", "cpt-packet", "spt-single")]:
            ax.plot(bounces, [sec[(b, den)] / sec[(b, num)] for b in bounces], marker="o", label=label)
        ax.axhline(1.0, color="grey", lw=0.8)
        ax.set_title(f"{scene}: relative speed")
        ax.set_xlabel("bounces")
        ax.set_xticks(bounces)
        if k == 0:
            ax.set_ylabel("speed-up (time ratio)")
            ax.legend(fontsize=7)
        ax = axes[1][k]
        for m in ["spt-packet", "cpt-packet", "icpt-packet"]:
            ax.plot(bounces, [util[(b, m)] for b in bounces], marker="o", label=m)
        ax.set_ylim(0, 1.05)
        ax.set_title(f"{scene}: SIMD utilisation (box tests)")
        ax.set_xlabel("bounces")
        ax.set_xticks(bounces)
        if k == 0:
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def assembly_plot(rows, path):
    scenes = [s for s in SCENES if any(x["scene"] == s for x in rows)]
    fig, axes = plt.subplots(1, len(scenes), figsize=(4 * len(scenes), 3.5), squeeze=False)
    for k, scene in enumerate(scenes):
        ax = axes[0][k]
        for m, style in [("types", "-"), ("runs", "--"), ("single", ":")]:
            r = [x for x in rows if x["scene"] == scene and x["assembly"] == m]
            d = [int(x["depth"]) for x in r]
            ax.plot(d, [float(x["box_tests_per_ray"]) for x in r], style, marker="o", label=f"{m}: box")
            ax.plot(d, [float(x["triangle_tests_per_ray"]) for x in r], style, marker="s", label=f"{m}: triangle")
        ax.set_title(f"{scene} (CPT)")
        ax.set_xlabel("bounce depth")
        ax.set_ylabel("tests per ray")
        if k == 0:
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def error_plot(rows, path):
    scenes = [s for s in SCENES if any(x["scene"] == s for x in rows)]
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.5 * len(scenes), 4), squeeze=False)
    for k, scene in enumerate(scenes):
        ax = axes[0][k]
        for m in ["spt-single", "spt-packet", "cpt-packet", "icpt-packet"]:
            r = [x for x in rows if x["scene"] == scene and x["method"] == m]
            ax.loglog([float(x["seconds"]) for x in r], [float(x["relative_rmse"]) for x in r], marker="o", ms=3,
                      label=m)
        r = [x for x in rows if x["scene"] == scene and x["method"] == "spt-single"]
        if r:
            t0, e0 = float(r[0]["seconds"]), float(r[0]["relative_rmse"])
            ts = [t0, float(r[-1]["seconds"])]
            ax.loglog(ts, [e0 * (t / t0) ** -0.5 for t in ts], color="grey", lw=0.8, ls=":", label="1/sqrt(t)")
        ax.set_title(scene)
        ax.set_xlabel("thread CPU seconds")
        ax.set_ylabel("relative RMSE vs reference")
        ax.grid(True, which="both", lw=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bench", default="build/render-bench")
    ap.add_argument("--res", type=int, nargs=2, default=[128, 128])
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--error-spp", type=int, default=256)
    ap.add_argument("--error-res", type=int, nargs=2, default=[64, 64],
                    help="resolution of the error-versus-time runs (their reference is expensive)")
    ap.add_argument("--reference-spp", type=int, default=2048)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--only", choices=["speed", "assembly", "error"], help="run one part")
    ap.add_argument("--scenes", nargs="*", default=SCENES)
    args = ap.parse_args()
    os.makedirs(RESULTS, exist_ok=True)
    res = [str(args.res[0]), str(args.res[1])]
    md = ["# Coherent paths: speed, SIMD utilisation, assembly and error versus time", "",
          "Made by `/usr/bin/python3 bench/coherent_paths.py " + " ".join(sys.argv[1:]) + "` (render-bench, "
          "bench/render_bench.cpp): whole renders through the Renderer, one thread, thread CPU time, bounce "
          "limits all set to the bounce count, no Russian roulette.", ""]

    if args.only in (None, "speed"):
        rows, cmds = [], []
        for scene in args.scenes:
            r, c = run(args.bench, ["speed", scene_path(scene), "--res", *res, "--spp", str(args.spp),
                                    "--packet", "4x4", "--max-bounces", "4", "--runs", str(args.runs)])
            rows += r
            cmds.append(c)
        if "crytek_sponza" in args.scenes:
            r, c = run(args.bench, ["speed", scene_path("crytek_sponza"), "--res", *res, "--spp", str(args.spp),
                                    "--packet", "16x16", "--max-bounces", "3", "--runs", str(args.runs)])
            rows += [x for x in r if x["bounces"] == "3"]
            cmds.append(c)
        with open(os.path.join(RESULTS, "coherent_paths_speed.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
        speed_plots(rows, os.path.join(RESULTS, "coherent_paths_speed.png"))
        md += ["## Fig. 6 and Fig. 7: relative speed and SIMD utilisation (4x4 packets, "
               f"{args.spp} spp, {res[0]}x{res[1]})", "", "Commands:", ""] + ["    " + c for c in cmds] + [""]
        md += ["| scene | bounces | CPT/SPT | ICPT/SPT | CPT/ICPT | CPT packets / SPT single | SPT packets / SPT single "
               "| SIMD util SPT / CPT / ICPT | Mrays/s SPT single / CPT packets |", "|---|---|---|---|---|---|---|---|---|"]
        for scene in args.scenes:
            r = [x for x in rows if x["scene"] == scene and x["packet"] == "4x4"]
            sec = {(int(x["bounces"]), x["method"]): float(x["seconds"]) for x in r}
            util = {(int(x["bounces"]), x["method"]): float(x["box_utilisation"]) for x in r}
            mr = {(int(x["bounces"]), x["method"]): float(x["mrays_per_s"]) for x in r}
            for b in sorted({int(x["bounces"]) for x in r}):
                md.append(f"| {scene} | {b} | {sec[(b, 'spt-packet')] / sec[(b, 'cpt-packet')]:.2f} | "
                          f"{sec[(b, 'spt-packet')] / sec[(b, 'icpt-packet')]:.2f} | "
                          f"{sec[(b, 'icpt-packet')] / sec[(b, 'cpt-packet')]:.2f} | "
                          f"{sec[(b, 'spt-single')] / sec[(b, 'cpt-packet')]:.2f} | "
                          f"{sec[(b, 'spt-single')] / sec[(b, 'spt-packet')]:.2f} | "
                          f"{util[(b, 'spt-packet')]:.2f} / {util[(b, 'cpt-packet')]:.2f} / {util[(b, 'icpt-packet')]:.2f} | "
                          f"{mr[(b, 'spt-single')]:.2f} / {mr[(b, 'cpt-packet')]:.2f} |")
        big = [x for x in rows if x["packet"] == "16x16"]
        if big:
            sec = {x["method"]: float(x["seconds"]) for x in big}
            md += ["", f"16x16 packets, Sponza, 3 bounces: CPT/SPT (packets) = "
                       f"{sec['spt-packet'] / sec['cpt-packet']:.2f}x, CPT packets / SPT single rays = "
                       f"{sec['spt-single'] / sec['cpt-packet']:.2f}x (paper: 6.2x)."]
        md += ["", "![speed](coherent_paths_speed.png)", ""]

    if args.only in (None, "assembly"):
        rows, cmds = [], []
        for scene in args.scenes:
            r, c = run(args.bench, ["assembly", scene_path(scene), "--res", *res, "--spp", str(max(args.spp // 4, 1)),
                                    "--packet", "4x4", "--max-bounces", "4"])
            rows += r
            cmds.append(c)
        with open(os.path.join(RESULTS, "coherent_paths_assembly.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
        assembly_plot(rows, os.path.join(RESULTS, "coherent_paths_assembly.png"))
        md += ["## Fig. 8: ray-type versus runs assembly over bounce depth", "", "Commands:", ""] + \
              ["    " + c for c in cmds] + ["", "| scene | assembly | depth | box/ray | tri/ray | SIMD util (box) | seconds |",
                                           "|---|---|---|---|---|---|---|"]
        for x in rows:
            md.append(f"| {x['scene']} | {x['assembly']} | {x['depth']} | {float(x['box_tests_per_ray']):.2f} | "
                      f"{float(x['triangle_tests_per_ray']):.2f} | {float(x['box_utilisation']):.3f} | "
                      f"{float(x['seconds']):.3f} |")
        md += ["", "![assembly](coherent_paths_assembly.png)", ""]

    if args.only in (None, "error"):
        rows, cmds = [], []
        for scene in args.scenes:
            r, c = run(args.bench, ["error", scene_path(scene), "--res", str(args.error_res[0]), str(args.error_res[1]),
                                    "--spp", str(args.error_spp),
                                    "--reference-spp", str(args.reference_spp), "--packet", "4x4", "--max-bounces", "4"])
            rows += r
            cmds.append(c)
        curve = [x for x in rows if "equal-error" not in x["method"]]
        equal = [x for x in rows if "equal-error" in x["method"]]
        with open(os.path.join(RESULTS, "coherent_paths_error.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
        error_plot(curve, os.path.join(RESULTS, "coherent_paths_error.png"))
        md += ["## Error versus time", "", "Commands:", ""] + ["    " + c for c in cmds] + [
            "", f"Equal-error time: seconds each method needs to reach the relative RMSE of SPT with single rays at "
                f"{args.error_spp} spp (log-log interpolation between passes; extrap. = not reached within the run, "
                f"extrapolated from the last pass by the t^-1/2 rate; target: CPT in at most half of SPT's time).",
            "", "| scene | target RMSE | SPT single | SPT packets | CPT packets | ICPT packets | CPT / SPT single time |",
            "|---|---|---|---|---|---|---|"]
        for scene in args.scenes:
            e = {x["method"].split("-equal-error")[0]: float(x["seconds"]) for x in equal if x["scene"] == scene}
            extra = {x["method"].split("-equal-error")[0] for x in equal
                     if x["scene"] == scene and x["method"].endswith("extrapolated")}
            tgt = [float(x["relative_rmse"]) for x in equal if x["scene"] == scene]
            if not e:
                continue
            fmt = lambda v, m: f"{v:.3f} s" + (" (extrap.)" if m in extra else "")  # noqa: E731
            md.append(f"| {scene} | {tgt[0]:.4f} | {fmt(e['spt-single'], 'spt-single')} | "
                      f"{fmt(e['spt-packet'], 'spt-packet')} | {fmt(e['cpt-packet'], 'cpt-packet')} | "
                      f"{fmt(e['icpt-packet'], 'icpt-packet')} | {e['cpt-packet'] / e['spt-single']:.2f} |")
        md += ["", "![error versus time](coherent_paths_error.png)", ""]

    out = os.path.join(RESULTS, "coherent_paths.md" if args.only is None else f"coherent_paths_{args.only}.md")
    with open(out, "w") as f:
        f.write("\n".join(md) + "\n")
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
