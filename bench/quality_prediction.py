#!/usr/bin/env python3
"""How well does the "what does quality cost" helper predict render time?

For each scene and sampler (SPT, CPT, ICPT): a short pilot render records
(seconds, spp, error_estimate) per pass (`coherent render --convergence`),
the add-on's model (addon/coherent/quality_model.py, loaded without Blender) fits
it and predicts, per error level, the passes and seconds to reach it. Then a
real render per sampler and level runs with `--target-error E` and reports
the seconds and passes it actually took (one render per seed). Three pilots
per sampler: at the render's resolution, and at 1/2 and 1/4 of its width and
height, their time per pass scaled back up by the pixel ratio (4, 16) and
their spp carried over, as the add-on does when the frame is larger than its
Pilot Pixels.

Writes docs/results/quality_prediction.{csv,md,png}. Progress goes to stderr.

    /usr/bin/python3 bench/quality_prediction.py --cli build-quality/coherent
"""

import argparse
import csv
import importlib.util
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO.parent / "shared" / "scenes"
SAMPLERS = ("SPT", "CPT", "ICPT")

# (name, glb, width, height, error levels). Levels are chosen so the actual
# renders take about 0.5 to 20 s each with one thread on this machine.
CASES = (
    ("cornell_box", SCENES / "cornell_box.glb", 64, 64, (0.40, 0.30, 0.20, 0.15)),
    ("stanford_bunny", SCENES / "stanford_bunny.glb", 96, 96, (0.12, 0.08, 0.05, 0.035)),
)


def load_model():
    path = REPO / "addon" / "coherent" / "quality_model.py"
    spec = importlib.util.spec_from_file_location("coherent_quality_model", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def render(cli, scene, out, width, height, sampler, threads, seed, extra):
    cmd = [str(cli), "render", str(scene), "-o", str(out), "--res", str(width), str(height),
           "--sampler", sampler.lower(), "--threads", str(threads), "--seed", str(seed), "--json", *map(str, extra)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stderr}")
    return json.loads(proc.stdout), cmd


def read_convergence(path):
    with open(path, newline="") as f:
        return [(float(r["seconds"]), int(r["spp"]), float(r["error_estimate"])) for r in csv.DictReader(f)]


# Pilot kinds: the divisor of the render's width and height.
PILOTS = {"full": 1, "half": 2, "quarter": 4}


def pilot(cli, model, work, name, scene, width, height, sampler, args, kind):
    pw, ph = width // PILOTS[kind], height // PILOTS[kind]
    conv = work / f"{name}_{sampler}_pilot_{kind}.csv"
    _, cmd = render(cli, scene, work / "pilot.exr", pw, ph, sampler, args.threads, args.pilot_seed,
                    ["--spp", 1 << 20, "--time-limit", args.pilot_seconds, "--convergence", conv])
    points = read_convergence(conv)
    fit = model.fit_convergence(points, pixel_scale=(width * height) / (pw * ph))
    return fit, cmd


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default=str(REPO / "build" / "coherent"))
    ap.add_argument("--work", default="/tmp/coherent_quality_prediction")
    ap.add_argument("--out", default=str(REPO / "docs" / "results"))
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--pilot-seconds", type=float, default=2.0)
    ap.add_argument("--pilot-seed", type=int, default=1)
    ap.add_argument("--seeds", type=int, nargs="+", default=[2, 3],
                    help="seeds of the actual renders (differ from the pilot's); one render per seed")
    ap.add_argument("--cases", nargs="*", help="subset of case names")
    args = ap.parse_args()

    model = load_model()
    load_before = os.getloadavg()
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    out = Path(args.out)
    cases = [c for c in CASES if not args.cases or c[0] in args.cases]
    rows, commands = [], {}
    start = time.monotonic()
    for name, scene, width, height, levels in cases:
        for sampler in SAMPLERS:
            fits = {}
            for kind in PILOTS:
                fit, cmd = pilot(args.cli, model, work, name, scene, width, height, sampler, args, kind)
                fits[kind] = fit
                commands.setdefault(f"pilot_{kind}", cmd)
                log(f"[{time.monotonic() - start:6.1f} s] {name} {sampler} pilot {kind}: "
                    f"{fit.pilot_spp} passes in {fit.pilot_seconds:.2f} s, c={fit.c:.3f}, exponent {fit.exponent:.2f}, "
                    f"{fit.seconds_per_pass * fit.pixel_scale * 1e3:.1f} ms/pass at {width}x{height}")
            for level, seed in ((lv, sd) for lv in levels for sd in args.seeds):
                res, cmd = render(args.cli, scene, work / "actual.exr", width, height, sampler, args.threads,
                                  seed, ["--spp", 1 << 20, "--target-error", level])
                commands.setdefault("actual", cmd)
                for pilot_kind, fit in fits.items():
                    p_spp, p_sec = fit.spp_for(level), fit.seconds_for(level)
                    rows.append(dict(scene=name, width=width, height=height, sampler=sampler, pilot=pilot_kind,
                                     level=level, seed=seed, predicted_spp=p_spp, predicted_seconds=p_sec,
                                     actual_spp=res["spp"], actual_seconds=res["seconds"],
                                     actual_error=res["error_estimate"], spp_ratio=p_spp / res["spp"],
                                     seconds_ratio=p_sec / res["seconds"],
                                     pass_time_ratio=(p_sec / p_spp) / (res["seconds"] / res["spp"]), fit_c=fit.c, fit_exponent=fit.exponent,
                                     pilot_spp=fit.pilot_spp, pilot_seconds=fit.pilot_seconds,
                                     ms_per_pass=fit.seconds_per_pass * fit.pixel_scale * 1e3))
                full = rows[-len(PILOTS)]
                log(f"[{time.monotonic() - start:6.1f} s] {name} {sampler} {level:.1%}: predicted "
                    f"{full['predicted_seconds']:.2f} s / {full['predicted_spp']} spp, actual {res['seconds']:.2f} s / "
                    f"{res['spp']} spp (error {res['error_estimate']:.4f}, seed {seed})")

    out.mkdir(parents=True, exist_ok=True)
    with open(out / "quality_prediction.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    plot(rows, out / "quality_prediction.png")
    write_markdown(rows, commands, args, out / "quality_prediction.md", time.monotonic() - start,
                   (load_before, os.getloadavg()))
    log(f"wrote {out / 'quality_prediction.md'}")


def plot(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    markers = {"SPT": "o", "CPT": "s", "ICPT": "^"}
    colors = {"cornell_box": "tab:red", "stanford_bunny": "tab:blue"}
    for ax, key, unit in ((axes[0], "seconds", "s"), (axes[1], "spp", "passes")):
        lo, hi = math.inf, 0.0
        for r in rows:
            if r["pilot"] != "full":
                continue
            x, y = r[f"actual_{key}"], r[f"predicted_{key}"]
            lo, hi = min(lo, x, y), max(hi, x, y)
            ax.scatter(x, y, marker=markers[r["sampler"]], color=colors.get(r["scene"], "k"), s=30, alpha=0.8)
        ax.plot([lo / 1.5, hi * 1.5], [lo / 1.5, hi * 1.5], "k--", lw=1, label="y = x")
        ax.plot([lo / 1.5, hi * 1.5], [lo / 1.5 * 2, hi * 1.5 * 2], ":", color="gray", lw=1, label="factor 2")
        ax.plot([lo / 1.5, hi * 1.5], [lo / 1.5 / 2, hi * 1.5 / 2], ":", color="gray", lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"actual ({unit}, render with --target-error)")
        ax.set_ylabel(f"predicted from the pilot ({unit})")
        ax.set_title(f"Render {key}: predicted vs actual")
        ax.grid(True, which="both", alpha=0.3)
    handles = [plt.Line2D([], [], ls="", marker=m, color="k", label=s) for s, m in markers.items()]
    handles += [plt.Line2D([], [], ls="", marker="o", color=c, label=n) for n, c in colors.items()]
    axes[0].legend(handles=handles + axes[0].get_legend_handles_labels()[0], loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def summary(rows, key):
    """Geometric mean of predicted/actual, and the share within factors 1.5 and 2."""
    logs = [math.log(r[key]) for r in rows]
    gm = math.exp(statistics.fmean(logs))
    within = lambda f: sum(abs(l) <= math.log(f) for l in logs) / len(logs)
    return gm, math.exp(statistics.median(abs(l) for l in logs)), within(1.5), within(2.0), \
        math.exp(max(abs(l) for l in logs))


def shown(cmd):
    """A command line as run from the repository root (scenes by their ../shared path)."""
    return " ".join(map(str, cmd)).replace(str(SCENES), "../shared/scenes").replace(str(REPO) + "/", "")


def write_markdown(rows, commands, args, path, elapsed, loads):
    lines = ["# Quality cost prediction: predicted vs actual render time", "",
             f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Shared 2-core VM, "
             f"`--threads {args.threads}`; the bench took {elapsed:.0f} s; load average (1/5/15 min) "
             f"{'/'.join(f'{v:.1f}' for v in loads[0])} before, {'/'.join(f'{v:.1f}' for v in loads[1])} after "
             "(other engineers compiling and testing on the same 2 cores).", "",
             "The add-on's Quality Cost panel (addon/coherent/operators.py) renders a short pilot per sampler and "
             "predicts the render time to reach each error level (the Target Error stopping rule: the even/odd "
             "half-buffer estimate of the image's relative RMSE). Model: error = c / sqrt(spp) fitted in log space "
             "on the later half of the pilot's passes; seconds = overhead + spp * seconds per pass; predicted spp "
             "= (c / E)^2 rounded up to even. Here each prediction is checked against a real render with "
             "`--target-error E` (different seed from the pilot).", "",
             "Pilots: " + f"{args.pilot_seconds} s each (`--time-limit`), seed {args.pilot_seed}. \"full\": pilot at "
             "the render's resolution; \"half\" / \"quarter\": at 1/2 / 1/4 of the width and height, time per pass "
             "scaled by the pixel ratio (4 / 16), spp carried over unchanged (the add-on scales frames larger than "
             "its Pilot Pixels down the same way).", "",
             "## Command", "", "```sh",
             f"/usr/bin/python3 bench/quality_prediction.py --cli {args.cli} --threads {args.threads} "
             f"--pilot-seconds {args.pilot_seconds} --seeds {' '.join(map(str, args.seeds))}",
             "# pilot, e.g.:", shown(commands["pilot_full"]),
             "# pilot at half resolution, e.g.:", shown(commands["pilot_half"]),
             "# pilot at quarter resolution, e.g.:",
             shown(commands["pilot_quarter"]),
             "# actual render, e.g.:", shown(commands["actual"]),
             "```", "", "## Accuracy", "",
             "Ratio = predicted / actual. gm: geometric mean (bias); median factor: median factor off either way; "
             "worst: largest factor off. seconds ratio = spp ratio x pass-time ratio: the spp ratio is the model "
             "(how many passes the error estimate needs), the pass-time ratio is how the machine's speed changed "
             "between the pilot and the render.", "",
             "| scene | pilot | sampler | seconds: gm | median factor | within 1.5x | within 2x | worst | spp: gm | "
             "median factor | within 1.5x | worst | pass time: gm | median factor |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    groups = {}
    for r in rows:
        groups.setdefault((r["scene"], r["pilot"], r["sampler"]), []).append(r)
        groups.setdefault((r["scene"], r["pilot"], "all"), []).append(r)
        groups.setdefault(("all", r["pilot"], "all"), []).append(r)
    order = lambda k: (k[0] == "all", k[0], list(PILOTS).index(k[1]), k[2] == "all", SAMPLERS.index(k[2]) if k[2] in SAMPLERS else 0)
    for key in sorted(groups, key=order):
        scene, pilot_kind, sampler = key
        g = groups[key]
        sg, sm, s15, s2, sw = summary(g, "seconds_ratio")
        pg, pm, p15, _, pw = summary(g, "spp_ratio")
        tg, tm, _, _, _ = summary(g, "pass_time_ratio")
        lines.append(f"| {scene} | {pilot_kind} | {sampler} | {sg:.2f} | {sm:.2f} | {s15:.0%} | {s2:.0%} | {sw:.2f} | "
                     f"{pg:.2f} | {pm:.2f} | {p15:.0%} | {pw:.2f} | {tg:.2f} | {tm:.2f} |")
    # How much the actual renders themselves vary: the same level and sampler
    # with different seeds stop after different pass counts (the error
    # estimate is itself noisy). No prediction can beat this spread.
    spread = {}
    for r in rows:
        if r["pilot"] == "full":
            spread.setdefault((r["scene"], r["sampler"], r["level"]), []).append(r["actual_spp"])
    lines += ["", "Spread of the actual renders between seeds (max / min passes for the same scene, sampler and "
              "level): the floor under any prediction's accuracy.", "",
              "| scene | sampler | median max/min | worst max/min |", "|---|---|---:|---:|"]
    for scene in sorted({k[0] for k in spread}):
        for sampler in SAMPLERS:
            ratios = [max(v) / min(v) for k, v in spread.items() if k[0] == scene and k[1] == sampler]
            if ratios:
                lines.append(f"| {scene} | {sampler} | {statistics.median(ratios):.2f} | {max(ratios):.2f} |")
    lines += ["", "![predicted vs actual](quality_prediction.png)", "",
              "(Plot: the \"full\" pilots; dashed y = x, dotted factor 2.)", "",
              "## Every render (full pilots; quality_prediction.csv has the half and quarter pilots too)", "",
              "| scene | sampler | level | seed | pilot | predicted s | actual s | ratio | predicted spp | actual spp | "
              "ratio | actual error | fit c | exponent | ms/pass |",
              "|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in (r for r in rows if r["pilot"] == "full"):
        lines.append(f"| {r['scene']} | {r['sampler']} | {r['level']:.1%} | {r['seed']} | {r['pilot']} | {r['predicted_seconds']:.2f} | "
                     f"{r['actual_seconds']:.2f} | {r['seconds_ratio']:.2f} | {r['predicted_spp']} | {r['actual_spp']} | "
                     f"{r['spp_ratio']:.2f} | {r['actual_error']:.4f} | {r['fit_c']:.3f} | {r['fit_exponent']:.2f} | "
                     f"{r['ms_per_pass']:.1f} |")
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
