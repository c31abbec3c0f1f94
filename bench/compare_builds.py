#!/usr/bin/python3
"""Reads bench/compare_builds.sh output; prints a markdown table of Mrays/s per
bench, scene and configuration (medians over the alternated runs) with the
new/old ratio, and a summary line."""
import collections
import json
import statistics
import sys


def main(path):
    rows = collections.defaultdict(lambda: collections.defaultdict(list))
    for line in open(path):
        line = line.strip()
        if "|" in line:
            version, _, text = line.split("|", 2)
            d = json.loads(text)
            if "mrays_per_s" in d:
                rows[("coherent-bench", d["scene"], d["rays"] + " rays")][version].append(d["mrays_per_s"])
        elif line.startswith(("old,", "new,")) and ",scene," not in line:  # skip CSV headers
            f = line.split(",")
            rows[("render-bench", f[2], f"{f[3]} bounces {f[4]}")][f[0]].append(float(f[8]))
    print("| bench | scene | rays / configuration | old Mrays/s | new Mrays/s | new / old |")
    print("|---|---|---|---:|---:|---:|")
    ratios = {}
    for key, runs in rows.items():
        old, new = statistics.median(runs["old"]), statistics.median(runs["new"])
        ratios[key] = new / old
        print(f"| {key[0]} | {key[1]} | {key[2]} | {old:.3f} | {new:.3f} | {new / old:.3f} |")
    for bench in ("coherent-bench", "render-bench"):
        for scene in sorted({k[1] for k in ratios if k[0] == bench}):
            r = [v for k, v in ratios.items() if k[0] == bench and k[1] == scene]
            print(f"\n{bench}, {scene}: {len(r)} rows, geometric mean new/old {statistics.geometric_mean(r):.3f} "
                  f"(min {min(r):.3f}, max {max(r):.3f})", end="")
    print()


if __name__ == "__main__":
    main(sys.argv[1])
