#!/usr/bin/env python3
"""Plots of reorder-bench results (docs/results/reorder.md).

    python3 bench/plot_reorder.py [--prefix docs/results/reorder] [--out docs/results/reorder.png] [--tables]

--tables prints the markdown tables of docs/results/reorder.md instead of plotting.

Reads PREFIX_main_render.csv (1 thread), PREFIX_frame_sort.csv and, when
present, PREFIX_t2_render.csv, PREFIX_waves_direction_render.csv,
PREFIX_waves_origin_render.csv, PREFIX_nogather_render.csv,
PREFIX_packet{8,16,32,64}_render.csv, and draws:
  (a) total time vs key bits per scene (1 thread; 0 bits = none/static orders),
  (b) where the time goes per mode (trace, reorder, rest) on one thread,
  (c) reorder time of the whole frame's AO rays per mode: radix vs
      comparison sort, full (paper: fixed ray slots) vs compact layout,
  (d) speed-up over no reordering against the wave size (Sponza).
"""
import argparse
import csv
import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MODES = ["none", "static1d", "static3d", "hash32", "hash192", "csd32"]


def read(path):
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def fmt(x, digits=3):
    return ("%%.%df" % digits) % float(x)


def tables(prefix):
    render = read(prefix + "_main_render.csv")
    sort = read(prefix + "_frame_sort.csv")
    print("### Render (Table 1 top, Fig. 6 left)\n")
    print("| scene | threads | wave | mode | total s | trace s | reorder s | of which keys | speed-up vs none | trace speed-up | bytes/path |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in render:
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["scene"], r["threads"], r["wave_size"], r["mode"], fmt(r["seconds"]), fmt(r["trace_seconds"]),
            fmt(r["reorder_seconds"]), fmt(r["key_seconds"]), fmt(r["speedup_vs_none"], 2),
            fmt(r["trace_speedup_vs_none"], 2), r["bytes_per_path"]))
    print("\n### Reorder of the whole frame's AO rays (Table 1 bottom, Fig. 6 right)\n")
    print("| scene | layout | mode | sort | digit bits | rays | sorted elements | total s | keys s | compress s | sort s | decompress s | gather rays s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in sort:
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            r["scene"], r["layout"], r["mode"], r["sort"], r["digit_bits"] if r["sort"] == "radix" else "-", r["rays"],
            r["sorted_elements"], fmt(r["reorder_seconds"]), fmt(r["key_seconds"]), fmt(r["compress_seconds"]),
            fmt(r["sort_seconds"]), fmt(r["decompress_seconds"]), fmt(r["gather_rays_seconds"])))
    t2 = read(prefix + "_t2_render.csv")
    if t2:
        print("\n### Two threads (%s_t2_render.csv)\n" % prefix)
        print("| scene | wave | mode | wall s | CPU s (both threads) | trace CPU s | reorder CPU s | CPU speed-up vs none | wall speed-up |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in t2:
            print("| %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                r["scene"], r["wave_size"], r["mode"], fmt(r["seconds"]), fmt(r["cpu_seconds"]),
                fmt(r["trace_seconds"]), fmt(r["reorder_seconds"]), fmt(r["cpu_speedup_vs_none"], 2),
                fmt(r["speedup_vs_none"], 2)))
    for extra in ["_waves_direction_render.csv", "_waves_origin_render.csv", "_nogather_render.csv",
                  "_packet8_render.csv", "_packet16_render.csv", "_packet32_render.csv", "_packet64_render.csv"]:
        rows = read(prefix + extra)
        if not rows:
            continue
        print("\n### %s\n" % (prefix + extra))
        print("| wave | packet | mode | key layout | total s | trace s | reorder s | speed-up vs none | trace speed-up |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            print("| %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
                r["wave_size"], r["packet"], r["mode"], r["key_layout"], fmt(r["seconds"]), fmt(r["trace_seconds"]),
                fmt(r["reorder_seconds"]), fmt(r["speedup_vs_none"], 2), fmt(r["trace_speedup_vs_none"], 2)))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--prefix", default="docs/results/reorder")
    ap.add_argument("--out", default="docs/results/reorder.png")
    ap.add_argument("--tables", action="store_true")
    args = ap.parse_args()
    if args.tables:
        tables(args.prefix)
        return
    render = read(args.prefix + "_main_render.csv")
    sort = read(args.prefix + "_frame_sort.csv")
    waves = read(args.prefix + "_waves_direction_render.csv") + read(args.prefix + "_waves_origin_render.csv")

    fig, axes = plt.subplots(2, 2, figsize=(13, 9.5))
    scenes = sorted({r["scene"] for r in render})
    wave_sizes = sorted({int(r["wave_size"]) for r in render})

    # (a) total time vs key bits, one thread.
    ax = axes[0][0]
    markers = {"none": "o", "static1d": "s", "static3d": "D", "hash32": "^", "hash192": "v", "csd32": "P"}
    for si, scene in enumerate(scenes):
        for wave in wave_sizes:
            rows = [r for r in render if r["scene"] == scene and r["threads"] == "1" and int(r["wave_size"]) == wave]
            for r in rows:
                ax.scatter(int(r["key_bits"]) + (wave_sizes.index(wave) - 0.5) * 4, float(r["seconds"]),
                           marker=markers[r["mode"]], color="C%d" % si, alpha=0.9 if wave == wave_sizes[0] else 0.45)
        ax.plot([], [], color="C%d" % si, label=scene)
    for m, mk in markers.items():
        ax.scatter([], [], marker=mk, color="gray", label=m)
    ax.set_xlabel("key bits (0: none / static orders); left/right dot = wave %s" % "/".join(map(str, wave_sizes)))
    ax.set_ylabel("render + reorder seconds (1 thread, CPU)")
    ax.set_title("(a) total time vs key size, 1024x1024, 1+16 AO rays/pixel")
    ax.legend(fontsize=7, ncol=2)

    # (b) time breakdown per mode, one thread, smallest wave size.
    ax = axes[0][1]
    wave = wave_sizes[0] if wave_sizes else 0
    width = 0.8 / max(1, len(scenes))
    for si, scene in enumerate(scenes):
        rows = {r["mode"]: r for r in render
                if r["scene"] == scene and r["threads"] == "1" and int(r["wave_size"]) == wave}
        xs, trace, reorder, rest = [], [], [], []
        for mi, m in enumerate(MODES):
            if m not in rows:
                continue
            r = rows[m]
            xs.append(mi + (si - (len(scenes) - 1) / 2) * width)
            trace.append(float(r["trace_seconds"]))
            reorder.append(float(r["reorder_seconds"]))
            rest.append(float(r["seconds"]) - float(r["trace_seconds"]) - float(r["reorder_seconds"]))
        ax.bar(xs, trace, width, color="C%d" % si, label=scene + " trace")
        ax.bar(xs, reorder, width, bottom=trace, color="C%d" % si, alpha=0.45, hatch="//", label=scene + " reorder")
        ax.bar(xs, rest, width, bottom=[a + b for a, b in zip(trace, reorder)], color="lightgray")
    ax.set_xticks(range(len(MODES)))
    ax.set_xticklabels(MODES)
    ax.set_ylabel("CPU seconds (gray: generate + shade + rest)")
    ax.set_title("(b) where the time goes, 1 thread, wave %d" % wave)
    ax.legend(fontsize=7)

    # (c) reorder time of the whole frame's AO rays.
    ax = axes[1][0]
    labels, groups = [], defaultdict(list)
    for scene in scenes:
        for layout in ["full", "compact"]:
            labels.append("%s\n%s" % (scene.replace("stanford_", "").replace("crytek_", ""), layout))
            for m in MODES[1:]:
                for alg, bits in [("radix", "8"), ("comparison", "8")]:
                    v = [float(r["reorder_seconds"]) for r in sort if r["scene"] == scene and r["layout"] == layout
                         and r["mode"] == m and r["sort"] == alg and r["digit_bits"] == bits]
                    groups[(m, alg)].append(v[0] if v else 0.0)
    keys = [k for k in groups if any(groups[k])]
    width = 0.8 / max(1, len(keys))
    for ki, k in enumerate(keys):
        ax.bar([i + (ki - (len(keys) - 1) / 2) * width for i in range(len(labels))], groups[k], width,
               label="%s %s" % k, color="C%d" % (MODES.index(k[0])), alpha=1.0 if k[1] == "radix" else 0.4)
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel("reorder seconds (keys + sort), 1 thread")
    ax.set_title("(c) reordering all AO rays of the frame (light: comparison sort)")
    ax.legend(fontsize=6, ncol=2)

    # (d) wave size sweep.
    ax = axes[1][1]
    series = defaultdict(list)
    for r in waves:
        series[(r["mode"], r.get("key_layout", "direction"))].append((int(r["wave_size"]), float(r["speedup_vs_none"])))
    for (m, layout), pts in sorted(series.items()):
        if m == "none":
            continue
        pts.sort()
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker=markers.get(m, "o"),
                linestyle="-" if layout == "direction" else "--", color="C%d" % MODES.index(m),
                label="%s%s" % (m, " (origin-major key)" if layout == "origin" and m in ("hash32", "csd32") else ""))
    ax.axhline(1.0, color="gray", lw=0.8)
    ax.axhline(1.5, color="red", lw=0.8, ls=":", label="target 1.5x")
    ax.set_xscale("log", base=2)
    ax.set_xlabel("wave size (paths in flight)")
    ax.set_ylabel("speed-up over none, counting reorder time")
    ax.set_title("(d) crytek_sponza, 1 thread: wave size and key layout")
    ax.legend(fontsize=7)

    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print("wrote", args.out)


if __name__ == "__main__":
    main()
