# SPDX-License-Identifier: Apache-2.0
"""Tables and plot of bench/efficiency_vs_cycles.py, from its CSV rows.

Kept apart from the rendering so the arithmetic can be tested on synthetic
rows (tests/cli/test_efficiency_bench.py) and the report redrawn without
rendering (--report-only). Text after the NOTES_MARKER heading of an
existing efficiency_vs_cycles.md is hand-written and kept on regeneration.
"""
import math
from pathlib import Path

import numpy as np

NOTES_MARKER = "## Notes (hand-written; kept when the script regenerates this file)"
RULE_SAMPLERS = ["spt", "cpt", "icpt"]


def summarise(rows):
    """(scene, engine, sampler, pattern, spp) -> {"mse", "seconds", "n"}:
    the mean MSE and mean seconds over repetitions."""
    groups = {}
    for r in rows:
        groups.setdefault((r["scene"], r["engine"], r["sampler"], r["pattern"], int(r["spp"])), []).append(r)
    return {k: dict(mse=float(np.mean([r["mse"] for r in v])), seconds=float(np.mean([r["seconds"] for r in v])),
                    n=len(v)) for k, v in groups.items()}


def efficiency(point):
    """1 / (MSE x seconds): how fast error falls; the same at any spp for an
    estimator whose MSE falls as 1/spp and whose time grows as spp."""
    return 1.0 / (point["mse"] * point["seconds"])


def efficiency_ratio(cycles, ours):
    """(Cycles' MSE x seconds) / (ours): > 1 means we reach an error sooner."""
    return (cycles["mse"] * cycles["seconds"]) / (ours["mse"] * ours["seconds"])


def time_per_sample(points):
    """Least-squares fit seconds = setup + per_sample x spp over (spp,
    seconds) points; returns (setup, per_sample). Needs two spp levels."""
    spp = np.array([p[0] for p in points], dtype=np.float64)
    sec = np.array([p[1] for p in points], dtype=np.float64)
    if len(set(spp)) < 2:
        return float("nan"), float("nan")
    per_sample, setup = np.polyfit(spp, sec, 1)
    return float(setup), float(per_sample)


def geometric_mean(values):
    return float(math.exp(np.mean([math.log(v) for v in values])))


class Report:
    """The summarised rows and what the tables ask of them."""

    def __init__(self, rows, info):
        self.s = summarise(rows)
        self.info = info
        self.scenes = list(dict.fromkeys(r["scene"] for r in rows))
        self.spps = sorted({int(r["spp"]) for r in rows})
        self.patterns = [p for p in ("white", "sobol") if any(r["pattern"] == p for r in rows)]
        self.default_pattern = info.get("defaults", {}).get("pattern", "white")

    def get(self, scene, engine, sampler, pattern, spp):
        return self.s.get((scene, engine, sampler, pattern, spp))

    def cycles(self, scene, spp):
        return self.get(scene, "cycles", "-", "-", spp)

    def series(self, scene, engine, sampler, pattern):
        pts = [(n, self.get(scene, engine, sampler, pattern, n)) for n in self.spps]
        return [(n, p) for n, p in pts if p is not None]

    def auto_twin(self, scene, pattern, spp):
        """The explicit sampler whose image equals Auto's (same seed, same
        MSE): what Auto resolved to at this spp, or None."""
        auto = self.get(scene, "coherent", "auto", pattern, spp)
        for sampler in RULE_SAMPLERS:
            p = self.get(scene, "coherent", sampler, pattern, spp)
            if auto and p and math.isclose(auto["mse"], p["mse"], rel_tol=1e-9):
                return sampler
        return None


def fmt(x, digits=2):
    return "-" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def headline_table(rep):
    pats = rep.patterns
    head = "| scene | spp | Cycles RMSE | Cycles s |" + "".join(
        f" Auto {p} RMSE | s | RMSE / Cycles | **efficiency ratio** |" for p in pats)
    lines = [head, "|---|---:|---:|---:|" + "---:|---:|---:|---:|" * len(pats)]
    for scene in rep.scenes:
        for n in rep.spps:
            c = rep.cycles(scene, n)
            if c is None:
                continue
            cells = [scene, str(n), fmt(c["mse"] ** 0.5, 5), fmt(c["seconds"])]
            for p in pats:
                o = rep.get(scene, "coherent", "auto", p, n)
                cells += ([fmt(o["mse"] ** 0.5, 5), fmt(o["seconds"]), fmt((o["mse"] / c["mse"]) ** 0.5),
                           f"**{fmt(efficiency_ratio(c, o))}**"] if o else ["-"] * 4)
            lines.append("| " + " | ".join(cells) + " |")
    return lines


def time_table(rep):
    configs = [("Cycles", "cycles", "-", "-")] + [(f"Auto {p}", "coherent", "auto", p) for p in rep.patterns]
    lines = ["| scene |" + "".join(f" {c[0]} ms/spp | {c[0]} setup s |" for c in configs),
             "|---|" + "---:|---:|" * len(configs)]
    for scene in rep.scenes:
        cells = [scene]
        for _, engine, sampler, pattern in configs:
            setup, per = time_per_sample([(n, p["seconds"]) for n, p in rep.series(scene, engine, sampler, pattern)])
            cells += [fmt(per * 1e3, 1), fmt(setup)]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def rule_numbers(rep):
    """Per (spp, pattern) with all three samplers on every scene: each
    sampler's efficiency relative to the best of the three on that scene,
    geometric mean over scenes, and how many scenes it wins."""
    out = []
    for n in rep.spps:
        for p in rep.patterns:
            rel = {s: [] for s in RULE_SAMPLERS}
            wins = {s: 0 for s in RULE_SAMPLERS}
            for scene in rep.scenes:
                pts = {s: rep.get(scene, "coherent", s, p, n) for s in RULE_SAMPLERS}
                if any(v is None for v in pts.values()):
                    continue
                eff = {s: efficiency(v) for s, v in pts.items()}
                best = max(eff.values())
                for s in RULE_SAMPLERS:
                    rel[s].append(eff[s] / best)
                wins[max(eff, key=eff.get)] += 1
            if rel["spt"]:
                gm = {s: geometric_mean(v) for s, v in rel.items()}
                twins = [rep.auto_twin(scene, p, n) for scene in rep.scenes]
                out.append(dict(spp=n, pattern=p, scenes=len(rel["spt"]), relative=gm, wins=wins,
                                best=max(gm, key=gm.get), auto=next((t for t in twins if t), None)))
    return out


def rule_table(rep):
    lines = ["| spp | pattern | scenes | SPT | CPT | ICPT | CPT / ICPT | wins SPT / CPT / ICPT | best | Auto picked |",
             "|---:|---|---:|---:|---:|---:|---:|---|---|---|"]
    for r in rule_numbers(rep):
        g, w = r["relative"], r["wins"]
        lines.append(f"| {r['spp']} | {r['pattern']} | {r['scenes']} | {fmt(g['spt'])} | {fmt(g['cpt'])} | "
                     f"{fmt(g['icpt'])} | {fmt(g['cpt'] / g['icpt'])} | {w['spt']} / {w['cpt']} / {w['icpt']} | "
                     f"{r['best'].upper()} | "
                     f"{(r['auto'] or '?').upper()} |")
    return lines


def all_configs_table(rep):
    lines = ["| scene | spp | sampler | pattern | RMSE | s | RMSE / Cycles | efficiency ratio |",
             "|---|---:|---|---|---:|---:|---:|---:|"]
    for scene in rep.scenes:
        for n in rep.spps:
            c = rep.cycles(scene, n)
            for sampler in RULE_SAMPLERS + ["auto"]:
                for p in rep.patterns:
                    o = rep.get(scene, "coherent", sampler, p, n)
                    if o is None or c is None:
                        continue
                    lines.append(f"| {scene} | {n} | {sampler.upper()} | {p} | {fmt(o['mse'] ** 0.5, 5)} | "
                                 f"{fmt(o['seconds'])} | {fmt((o['mse'] / c['mse']) ** 0.5)} | "
                                 f"{fmt(efficiency_ratio(c, o))} |")
    return lines


def timing_noise(rep):
    """Auto and the sampler it resolves to render the same image: their
    seconds differ by machine noise only. Median |difference| / mean."""
    diffs = []
    for scene in rep.scenes:
        for n in rep.spps:
            for p in rep.patterns:
                twin = rep.auto_twin(scene, p, n)
                if twin:
                    a = rep.get(scene, "coherent", "auto", p, n)["seconds"]
                    b = rep.get(scene, "coherent", twin, p, n)["seconds"]
                    if a != b:  # a copied row (Auto not rendered twice) says nothing about noise
                        diffs.append(abs(a - b) / ((a + b) / 2))
    return (float(np.median(diffs)), len(diffs)) if diffs else (float("nan"), 0)


def tick_label(value, _position):
    mantissa = value / 10 ** math.floor(math.log10(value)) if value > 0 else 0
    return f"{value:g}" if round(mantissa, 6) in (1, 2, 5) else ""


def show_context(ax, cycles_points):
    """Every axis spans at least a factor of 4 (a run at one spp otherwise
    puts its two points in opposite corners, without a tick between them),
    and a grey line of Cycles' efficiency, RMSE proportional to 1/sqrt(s),
    goes through its point at 256 spp (else its last): a point below the
    line reaches its error sooner than Cycles does."""
    (x0, y0), (x1, y1) = ax.dataLim.get_points()
    for lo, hi, setter in ((x0, x1, ax.set_xlim), (y0, y1, ax.set_ylim)):
        if lo > 0 and hi / lo < 4.0:
            centre = math.sqrt(lo * hi)
            setter(centre / 2.0, centre * 2.0)
    if not cycles_points:
        return
    spp, q = next(((n, q) for n, q in cycles_points if n == 256), cycles_points[-1])
    t0, e0 = q["seconds"], q["mse"] ** 0.5
    xs = ax.get_xlim()
    ax.loglog(xs, [e0 * math.sqrt(t0 / x) for x in xs], color="grey", lw=0.8, ls="--",
              label=f"Cycles' efficiency at {spp} spp")
    ax.set_xlim(xs)


def plot(rep, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker
    cols = min(3, len(rep.scenes))
    rows = math.ceil(len(rep.scenes) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.3 * rows), squeeze=False)
    colours = {"white": "tab:blue", "sobol": "tab:orange"}
    markers = {"spt": "s", "cpt": "^", "icpt": "v"}
    for i, scene in enumerate(rep.scenes):
        ax = axes[i // cols][i % cols]
        for sampler in RULE_SAMPLERS:
            for p in rep.patterns:
                pts = rep.series(scene, "coherent", sampler, p)
                if pts:
                    ax.loglog([q["seconds"] for _, q in pts], [q["mse"] ** 0.5 for _, q in pts], ":",
                              marker=markers[sampler], color=colours[p], alpha=0.45, lw=1, ms=4,
                              label=f"{sampler.upper()} {p}")
        for p in rep.patterns:
            pts = rep.series(scene, "coherent", "auto", p)
            ax.loglog([q["seconds"] for _, q in pts], [q["mse"] ** 0.5 for _, q in pts], "-o", color=colours[p],
                      lw=2, label=f"COHERENT Auto {p}" + (" (default)" if p == rep.default_pattern else ""))
        pts = rep.series(scene, "cycles", "-", "-")
        ax.loglog([q["seconds"] for _, q in pts], [q["mse"] ** 0.5 for _, q in pts], "-o", color="black", lw=2,
                  label="Cycles 3.4")
        for n, q in pts:
            ax.annotate(f"{n}", (q["seconds"], q["mse"] ** 0.5), textcoords="offset points", xytext=(4, 4),
                        fontsize=7)
        show_context(ax, pts)
        ax.set_title(scene)
        ax.set_xlabel("seconds (bpy.ops.render.render, 2 threads)")
        ax.set_ylabel("RMSE (linear RGB)")
        ax.grid(True, which="both", alpha=0.3)
        for axis in (ax.xaxis, ax.yaxis):  # plain numbers (not 2x10^0) at 1, 2 and 5 per decade
            axis.set_major_formatter(ticker.FuncFormatter(tick_label))
            axis.set_minor_formatter(ticker.FuncFormatter(tick_label))
    for j in range(len(rep.scenes), rows * cols):
        axes[j // cols][j % cols].axis("off")
    axes[0][0].legend(fontsize=7)
    fig.suptitle("RMSE against render time, Cycles 3.4 and COHERENT (numbers: spp of the Cycles points)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def kept_notes(md_path):
    if not md_path.exists():
        return []
    text = md_path.read_text()
    return text[text.index(NOTES_MARKER):].rstrip("\n").splitlines() if NOTES_MARKER in text else []


def setup_text(rep):
    i = rep.info
    return [f"Blender {i.get('blender', '?')}, {i.get('res', '?')}x{i.get('res', '?')} pixels, "
            f"{i.get('threads', '?')} threads, max/diffuse/glossy/transmission bounces {i.get('max_bounces', '?')}, "
            "1-pixel box filter, no denoising, adaptive sampling or clamping, Standard view transform, linear "
            f"32-bit EXR; Cycles' pattern {i.get('cycles_pattern', '?')}, COHERENT's default pattern "
            f"{rep.default_pattern}; {i.get('reps', '?')} repetition(s) per point. "
            f"Reference: Cycles at {i.get('reference_spp', '?')} spp (two halves with other seeds); its own "
            "noise, a quarter of the halves' mean squared difference, is subtracted from each MSE. "
            "Seconds: `bpy.ops.render.render()` in one Blender process per scene (sync or export, BVH "
            "build and sampling; no Blender start-up). Engines and configurations alternate in one loop. "
            + ("**Seconds here are CPU seconds** (`--clock cpu`: the Blender process's CPU time over all "
               "threads during that call), steadier than wall time on a loaded machine but blind to time "
               "threads spend waiting. " if i.get("clock") == "cpu" else "") +
            "Where SPT, CPT and ICPT are rendered, Auto's row is that of the sampler it resolves to (same seed, "
            "same image), not a second render.", "",
            "Efficiency = 1 / (MSE x seconds); **efficiency ratio = (Cycles' MSE x s) / (ours)**, > 1: we "
            "reach a given error sooner. Issue 10's targets: >= 1 on every scene at 256 spp (aim 2), RMSE at "
            "equal spp within 1.1x of Cycles'."]


def write(out_dir, rows, info):
    out_dir = Path(out_dir)
    rep = Report(rows, info)
    plot(rep, out_dir / "efficiency_vs_cycles.png")
    md_path = out_dir / "efficiency_vs_cycles.md"
    noise, pairs = timing_noise(rep)
    lines = ["# Efficiency against Cycles 3.4", "", "![RMSE against seconds per scene](efficiency_vs_cycles.png)",
             "", *setup_text(rep), "", "Made by (renders, then writes this file, the CSV and the plot):", "",
             *("    " + c for c in info.get("commands", ["?"])), "",
             "## Efficiency ratio and RMSE at equal spp (COHERENT's Auto sampler)", "", *headline_table(rep), "",
             "## Time per sample", "",
             "A least-squares line seconds = setup + spp x time per sample over the spp levels above.", "",
             *time_table(rep), "",
             "## Auto sampler: error per second of SPT, CPT and ICPT", "",
             "Each sampler's efficiency relative to the best of the three on the same scene, geometric mean "
             "over scenes (1.00: best everywhere), CPT's over ICPT's (geometric mean of the per-scene ratios), "
             "the scenes each wins, and what Auto resolved to (Auto and that sampler render the same image at "
             "the same seed).", "", *rule_table(rep), "",
             *([f"Timing noise: Auto and its twin render identical images, and their seconds differ by a median "
                f"{fmt(100 * noise, 1)} % ({pairs} pairs); smaller differences in the tables are noise.", ""]
               if pairs else []),
             "## Every configuration", "", *all_configs_table(rep), ""]
    lines += kept_notes(md_path) or [NOTES_MARKER, "", "(none yet)"]
    md_path.write_text("\n".join(lines) + "\n")
    print("\n".join(lines[:lines.index("## Every configuration")]))
