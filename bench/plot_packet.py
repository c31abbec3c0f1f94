#!/usr/bin/python3
"""Plot packet-bench results (docs/results/packet_traversal.csv).

    python3 bench/plot_packet.py docs/results/packet_traversal.csv docs/results/packet_traversal.png
    python3 bench/plot_packet.py --table docs/results/packet_traversal.csv   (markdown tables, with ratios)

One panel per scene: Mrays/s of every method on every ray set (one thread),
grouped by ray set; our packets in blue shades, our single-ray kernel in
grey, Embree in orange (rtcIntersect1) and red (rtcIntersect8).
"""
import csv
import sys
from collections import OrderedDict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def colour(method, packet):
    if method == "single ray":
        return "0.55"
    if method.startswith("Embree rtcIntersect1"):
        return "tab:orange"
    if method.startswith("Embree rtcIntersect8"):
        return "tab:red"
    shades = {"2x2": "#c6dbef", "4x2": "#9ecae1", "4x4": "#6baed6", "8x8": "#3182bd", "16x16": "#08519c"}
    return shades.get(packet, "tab:blue")


def table(path):
    rows = list(csv.DictReader(open(path)))
    print("| scene | rays | method | packet | Mrays/s | vs single | vs Embree 1 | vs Embree 8 | box/ray | tri/ray "
          "| box util | tri util | agreement |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        same = [q for q in rows if q["scene"] == r["scene"] and q["rays"] == r["rays"]]
        ref = {q["method"]: float(q["mrays_per_s"]) for q in same}
        m = float(r["mrays_per_s"])

        def ratio(name):
            return f"{m / ref[name]:.2f}" if name in ref else "-"

        def num(key, fmt):
            v = float(r[key])
            return fmt % v if v >= 0 else "-"

        print(f"| {r['scene']} | {r['rays']} | {r['method']} | {r['packet']} | {m:.2f} | {ratio('single ray')} | "
              f"{ratio('Embree rtcIntersect1')} | {ratio('Embree rtcIntersect8')} | {num('box_per_ray', '%.1f')} | "
              f"{num('tri_per_ray', '%.1f')} | {num('box_util', '%.2f')} | {num('tri_util', '%.2f')} | "
              f"{100 * float(r['agreement']):.2f}% |")


def main():
    if len(sys.argv) == 3 and sys.argv[1] == "--table":
        table(sys.argv[2])
        return
    if len(sys.argv) != 3:
        print(__doc__)
        sys.exit(2)
    rows = list(csv.DictReader(open(sys.argv[1])))
    scenes = list(OrderedDict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(len(scenes), 1, figsize=(11, 4.2 * len(scenes)), squeeze=False)
    for ax, scene in zip(axes[:, 0], scenes):
        sets = list(OrderedDict.fromkeys(r["rays"] for r in rows if r["scene"] == scene))
        x = 0.0
        ticks, labels = [], []
        for s in sets:
            group = [r for r in rows if r["scene"] == scene and r["rays"] == s]
            start = x
            for r in group:
                label = "single" if r["method"] == "single ray" else (
                    "E1" if "Intersect1" in r["method"] else ("E8" if "Intersect8" in r["method"] else r["packet"]))
                ax.bar(x, float(r["mrays_per_s"]), width=0.8, color=colour(r["method"], r["packet"]))
                ax.text(x, float(r["mrays_per_s"]), label, ha="center", va="bottom", fontsize=6, rotation=90)
                x += 1.0
            ticks.append((start + x - 1.0) / 2.0)
            labels.append(s)
            x += 1.0
        ax.set_xticks(ticks)
        ax.set_xticklabels(labels, fontsize=8)
        ax.set_ylabel("Mrays/s (1 thread)")
        ax.set_title(f"{scene}: packets (blue, by pixel block) vs single rays (grey), Embree 1 (orange) / 8 (red)",
                     fontsize=9)
        ax.margins(y=0.15)
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
