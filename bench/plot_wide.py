#!/usr/bin/env python3
"""Plots of docs/results/wide_bvh.csv (written by wide-bench --csv).

    python3 bench/plot_wide.py [docs/results/wide_bvh.csv] [docs/results/wide_bvh]

Writes PREFIX_streams.png (one panel per scene and ray set: stream
throughput against batch size, 1 and 2 threads, with the single-ray widths
and Embree as horizontal lines) and PREFIX_widths.png (throughput of the
single-ray kernels of width 2, 4 and 8 relative to Embree rtcIntersect1 /
rtcOccluded1, per scene and ray set, 1 and 2 threads).
"""
import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SETS = ["primary", "ao", "diffuse"]


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        r["threads"] = int(r["threads"])
        r["width"] = int(r["width"])
        r["batch"] = int(r["batch"])
        r["mrays_per_s"] = float(r["mrays_per_s"])
        r["ratio_vs_embree"] = float(r["ratio_vs_embree"])
    return rows


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "docs/results/wide_bvh.csv"
    prefix = sys.argv[2] if len(sys.argv) > 2 else "docs/results/wide_bvh"
    rows = load(path)
    # The last row wins when a configuration was measured more than once.
    latest = {}
    for r in rows:
        latest[(r["scene"], r["rays"], r["threads"], r["method"], r["width"], r["batch"])] = r
    rows = list(latest.values())
    scenes = sorted({r["scene"] for r in rows})
    threads = sorted({r["threads"] for r in rows})

    # Streams against batch size.
    fig, axes = plt.subplots(len(scenes), len(SETS), figsize=(4.2 * len(SETS), 3.2 * len(scenes)), squeeze=False)
    styles = {1: "-", 2: "--"}
    for i, scene in enumerate(scenes):
        for j, rays in enumerate(SETS):
            ax = axes[i][j]
            sel = [r for r in rows if r["scene"] == scene and r["rays"] == rays]
            for t in threads:
                st = sorted((r for r in sel if r["method"] == "stream" and r["threads"] == t), key=lambda r: r["batch"])
                if st:
                    ax.plot([r["batch"] for r in st], [r["mrays_per_s"] for r in st], "o" + styles.get(t, ":"),
                            color="C0", label=f"stream, {t} thr")
                for r in sel:
                    if r["threads"] != t:
                        continue
                    if r["method"] == "single":
                        color = {2: "C3", 4: "C2", 8: "C1"}[r["width"]]
                        ax.axhline(r["mrays_per_s"], color=color, ls=styles.get(t, ":"), lw=1,
                                   label=f"single w{r['width']}, {t} thr")
                    elif r["method"] == "embree":
                        ax.axhline(r["mrays_per_s"], color="k", ls=styles.get(t, ":"), lw=1.5,
                                   label=f"Embree, {t} thr")
            ax.set_xscale("log", base=2)
            ax.set_title(f"{scene}: {rays}", fontsize=9)
            ax.set_xlabel("rays per stream batch", fontsize=8)
            ax.set_ylabel("Mrays/s", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=5, fontsize=7)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(prefix + "_streams.png", dpi=110)

    # Width sweep, relative to Embree.
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.5 * len(scenes), 3.4), squeeze=False)
    for i, scene in enumerate(scenes):
        ax = axes[0][i]
        xs, labels = [], []
        k = 0
        for rays in SETS:
            for t in threads:
                for w, color in ((2, "C3"), (4, "C2"), (8, "C1")):
                    r = latest.get((scene, rays, t, "single", w, 0))
                    if r is None:
                        continue
                    ax.bar(k, r["ratio_vs_embree"], color=color, hatch="" if t == 1 else "//",
                           label=f"width {w}" if (rays, t) == (SETS[0], threads[0]) else None)
                    k += 1
                xs.append(k - 1.5)
                labels.append(f"{rays}\n{t} thr")
                k += 1
        ax.axhline(1.0, color="k", lw=1)
        ax.set_xticks(xs)
        ax.set_xticklabels(labels, fontsize=7)
        ax.set_ylabel("Mrays/s relative to Embree", fontsize=8)
        ax.set_title(scene, fontsize=9)
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(prefix + "_widths.png", dpi=110)


if __name__ == "__main__":
    main()
