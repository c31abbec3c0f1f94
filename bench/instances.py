# SPDX-License-Identifier: Apache-2.0
"""Instancing benchmark (issue 14): a Geometry Nodes scatter of many
unrealized instances of one Ico Sphere, COHERENT against Cycles in the same
run, plus single-ray throughput of a few large instances against the same
triangles flattened.

Run from the repository root after building (the add-on's _coherent module):

    /usr/bin/python3 bench/instances.py [--grid 100] [--subdivisions 6] [--size 128] [--samples 16]
                                        [--million] [--out docs/results/instances.json]

Cases:
  scatter   GRID x GRID instances of a 20 * 4^(SUBDIVISIONS-1)-triangle ico
            sphere (tests/blender/scatter_scene.py), rendered by a fresh
            Blender per engine: peak RSS of the Blender process (wait4),
            F12 time (export + build + render for COHERENT, sync + render for
            Cycles), image mean. A Blender that only builds the scene gives
            the RSS baseline that both carry.
  export    depsgraph -> native scene only, for GRID^2 instances and, with
            --million, 1,000,000 (then also a 1M render by each engine).
  throughput  Renderer single-ray Mrays/s (ray casting with shadows) on 4
            large overlapping instances of a ~200k-triangle mesh against the
            same triangles flattened, alternated 3 times, median ratio.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "blender"))
sys.path.insert(0, str(ROOT / "addon" / "coherent"))
import blender_helpers as bh  # noqa: E402

SCATTER = ROOT / "tests" / "blender" / "scatter_scene.py"


def run_measured(cmd, env):
    """Runs cmd; returns (stdout + stderr, wall seconds, peak RSS in MiB of that process)."""
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as log:
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env, cwd=tempfile.gettempdir())
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        output = log.read()
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed:\n{output[-3000:]}")
    return output, seconds, usage.ru_maxrss / 1024.0


def scatter(engine, grid, args, scripts, extra=()):
    cmd = [bh.blender_binary(), "-b", "--factory-startup", "--python-exit-code", "1", "--addons", "coherent",
           "--python", str(SCATTER), "--", engine, os.path.join(tempfile.gettempdir(), f"scatter_{engine}"),
           str(grid), str(args.subdivisions), str(args.samples), str(args.size), *extra]
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(scripts), BLENDER_USER_CONFIG=str(Path(scripts).parent / "config"))
    env.pop("PYTHONPATH", None)
    output, wall, rss = run_measured(cmd, env)
    row = {"engine": engine, "grid": grid, "instances": grid * grid, "wall_seconds": round(wall, 2),
           "wait4_maxrss_mib": round(rss, 1)}
    m = re.search(r"SCATTER_SECONDS (\S+)", output)
    row["seconds"] = float(m.group(1))
    m = re.search(r"SCATTER_MEMORY peak_kib=(\d+) current_kib=(\d+)", output)
    row["peak_rss_mib"] = round(int(m.group(1)) / 1024.0, 1)  # VmHWM of Blender itself
    row["end_rss_mib"] = round(int(m.group(2)) / 1024.0, 1)
    m = re.search(r"Coherent: finished .*", output)
    if m:  # the engine's own split: export, BVH (top level and prototypes), render
        row["engine_report"] = m.group(0)
    m = re.search(r"SCATTER_EXPORT (.*)", output)
    if m:
        row.update({k: float(v) for k, v in (kv.split("=") for kv in m.group(1).split())})
    if not extra:
        channels = bh.read_image_channels(Path(os.path.join(tempfile.gettempdir(), f"scatter_{engine}.exr")))
        row["mean"] = float(np.mean([channels[c].mean() for c in "RGB"]))
    print(json.dumps(row), flush=True)
    return row


def bumpy_sphere(rings, segments, seed=3):
    """A UV sphere with radial noise: (positions, indices) of ~2 * rings * segments triangles."""
    rng = np.random.default_rng(seed)
    theta = np.linspace(0.0, np.pi, rings + 1)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)[None, :]
    radius = 1.0 + 0.05 * rng.random((rings + 1, segments))
    pos = np.stack([radius * np.sin(theta) * np.cos(phi), radius * np.sin(theta) * np.sin(phi),
                    radius * np.cos(theta) * np.ones_like(phi)], axis=-1).reshape(-1, 3).astype(np.float32)
    r, k = np.meshgrid(np.arange(rings), np.arange(segments), indexing="ij")
    a, b = r * segments + k, r * segments + (k + 1) % segments
    c, d = a + segments, b + segments
    idx = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return pos, idx


def throughput(native, repeats=3):
    pos, idx = bumpy_sphere(300, 340)  # 204,000 triangles
    mats = [np.diag([s, s, s, 1.0]).astype(np.float32) for s in (1.6, 1.3, 1.0, 0.8)]
    for m, x in zip(mats, (-1.2, 1.2, -0.4, 0.6)):
        m[0, 3], m[1, 3] = x, 0.3 * x

    def scene(instanced):
        s = native.Scene()
        if instanced:
            proto = s.add_prototype("rock", pos, idx)
            s.add_instances(proto, np.stack(mats))
        else:
            for m in mats:
                s.add_mesh("rock", pos, idx, m)
        s.add_light("SUN", direction=(0.3, 0.2, -1.0), power=2.0)
        s.world_color = (0.2, 0.2, 0.2)
        s.set_camera(position=(0.0, -6.0, 1.0), forward=(0.0, 1.0, -0.15), up=(0.0, 0.0, 1.0))
        return s

    scenes = {"instanced": scene(True), "flattened": scene(False)}
    rates = {k: [] for k in scenes}
    for _ in range(repeats):
        for name, s in scenes.items():
            r = native.Renderer(s, width=256, height=256, spp=4, traversal="single", integrator="rcs")
            r.render()
            rates[name].append(r.stats()["mrays_per_s"])
    ratio = float(np.median(np.array(rates["instanced"]) / np.array(rates["flattened"])))
    row = {"case": "throughput", "triangles": int(len(idx)) * 4, "mrays_per_s": rates, "instanced_over_flattened": ratio}
    print(json.dumps(row), flush=True)
    return row


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--grid", type=int, default=100)
    parser.add_argument("--subdivisions", type=int, default=6)
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--samples", type=int, default=16)
    parser.add_argument("--million", action="store_true", help="also export and render 1,000,000 instances")
    parser.add_argument("--out", default=str(ROOT / "docs" / "results" / "instances.json"))
    args = parser.parse_args()
    import _coherent as native

    rows = {"command": " ".join(sys.argv), "throughput": throughput(native)}
    with tempfile.TemporaryDirectory() as tmp:
        scripts = bh.make_user_scripts(tmp)
        rows["baseline"] = scatter("CYCLES", 2, argparse.Namespace(**{**vars(args), "samples": 1, "size": 8}),
                                   scripts)
        rows["export"] = [scatter("COHERENT", args.grid, args, scripts, extra=("1",))]
        rows["coherent"] = scatter("COHERENT", args.grid, args, scripts)
        rows["cycles"] = scatter("CYCLES", args.grid, args, scripts)
        if args.million:
            rows["export"].append(scatter("COHERENT", 1000, args, scripts, extra=("1",)))
            rows["million"] = scatter("COHERENT", 1000, args, scripts)
            rows["million_cycles"] = scatter("CYCLES", 1000, args, scripts)
    c, y = rows["coherent"], rows["cycles"]
    rows["summary"] = {"time_ratio": c["seconds"] / y["seconds"], "mean_ratio": c["mean"] / y["mean"],
                       "coherent_peak_rss_mib": c["peak_rss_mib"], "cycles_peak_rss_mib": y["peak_rss_mib"]}
    print(json.dumps(rows["summary"]))
    Path(args.out).write_text(json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
