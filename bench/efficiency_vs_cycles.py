#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Efficiency against Cycles 3.4: error per second through Blender.

For each scene, one Blender process (bench/efficiency_render.py) renders it
with Cycles and with COHERENT under the same settings (2 threads, 128x128,
box filter of width 1, the same light-path limits, no denoising, no adaptive
sampling, no clamping, Standard view transform, linear 32-bit EXR) at each
spp, COHERENT once per sampler (SPT, CPT, ICPT, Auto) and sample pattern
(white, sobol). Engines and configurations alternate inside one loop, so
load on a shared machine hits both alike. Seconds are those of
bpy.ops.render.render() in that process: sync or export, BVH build and
sampling, none of Blender's start-up.

Error: the RMSE over pixels and RGB of the linear image against a high-spp
Cycles reference, rendered as two halves with other seeds and cached under
--work keyed by scene file and settings. The reference's own noise
(mean squared half difference / 4) is subtracted from every MSE, so a
reference of finite spp does not flatten the curves.
Efficiency = 1 / (MSE x seconds); the ratio (Cycles' MSE x s) / (ours) > 1
means we reach a given error sooner.

Writes docs/results/efficiency_vs_cycles.{csv,md,png,json}. One command
renders and regenerates all of them (an estimate for 2 free cores: 20-30
minutes, plus about 15 the first time, for the cached references; on a
machine shared with five builds, 16-256 spp alone took 45):

    /usr/bin/python3 bench/efficiency_vs_cycles.py

`--quick` is a check of a few minutes (2 scenes, 16/64 spp, 512-spp
reference, written under --work, not docs/results); `--report-only` redraws
the md and plot from the CSV; `--append --scene NAME` rerenders one scene
and keeps the others' rows. Needs the add-on's native module built
(addon/coherent/_coherent*.so) and `blender` 3.4 on PATH (or --blender).
"""
import argparse
import csv
import hashlib
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "bench"))
import efficiency_report  # noqa: E402

SAMPLERS = ["spt", "cpt", "icpt", "auto"]
PATTERNS = ["white", "sobol"]
REFERENCE_SEEDS = (1000001, 1000002)
CSV_FIELDS = ["scene", "engine", "sampler", "pattern", "spp", "rep", "seconds", "mse_vs_reference",
              "reference_variance", "mse"]


# --- error arithmetic (tests/cli/test_efficiency_bench.py) -------------------------

def mse(image, reference):
    """Mean squared difference over pixels and the first three channels."""
    a = np.asarray(image, dtype=np.float64)[..., :3]
    b = np.asarray(reference, dtype=np.float64)[..., :3]
    if a.shape != b.shape:
        raise ValueError(f"image shape {a.shape} differs from the reference's {b.shape}")
    return float(np.mean((a - b) ** 2))


def reference_from_halves(half_a, half_b):
    """(reference, its noise variance per pixel and channel) from two
    independent renders of half the reference's spp: the mean, and
    E[(a - b)^2] / 4, which is Var((a + b) / 2) for independent a and b."""
    a = np.asarray(half_a, dtype=np.float64)[..., :3]
    b = np.asarray(half_b, dtype=np.float64)[..., :3]
    return (a + b) / 2, mse(a, b) / 4


def corrected_mse(mse_vs_reference, reference_variance):
    """The MSE against the true image: an independent unbiased reference adds
    its own variance to the expected squared difference. Floored at 1 % of
    the raw value so a log plot never sees zero."""
    return max(mse_vs_reference - reference_variance, 0.01 * mse_vs_reference)


# --- scenes --------------------------------------------------------------------------

def find_scenes(shared_dir):
    """(name, path) of the repository's .blend scenes and the public ones; a
    note for a missing public folder."""
    scenes = [(f"repo/{p.stem}", p) for p in sorted((REPO / "blend_scenes").glob("*.blend"))]
    if shared_dir.is_dir():
        scenes += [(f"public/{p.stem}", p) for p in sorted(shared_dir.glob("*.blend"))]
    else:
        print(f"note: {shared_dir} not found; the public scenes are skipped", flush=True)
    return scenes


def settings_key(path, args):
    """Names a cached reference: the scene file's content and every setting
    that changes the image."""
    h = hashlib.sha1(Path(path).read_bytes())
    h.update(json.dumps(dict(res=args.res, bounces=args.max_bounces, spp=args.reference_spp,
                             seeds=REFERENCE_SEEDS), sort_keys=True).encode())
    return h.hexdigest()[:12]


def resolve_auto(spp, pattern):
    """What the Auto sampler renders in a final render at `spp`, by the
    native rule (native/sample/sampler_type.h) of this checkout's module."""
    sys.path.insert(0, str(REPO / "addon" / "coherent"))
    import _coherent
    r = _coherent.Renderer(_coherent.Scene(), width=1, height=1, spp=spp, sampler="auto", pattern=pattern)
    return r.settings["sampler"]


def configs(args, spp):
    """Render configurations at `spp` in loop order: Cycles first, then
    COHERENT per sampler and pattern: SPT, CPT and ICPT at --matrix-spps,
    Auto where the sampler it resolves to is not rendered anyway (elsewhere
    its row is a copy of that sampler's: same seed, same image)."""
    coherent = [("coherent", s, p) for s in args.samplers for p in args.patterns
                if (s != "auto" and spp in args.matrix_spps) or (s == "auto" and auto_twin(args, spp, p) is None)]
    return [("cycles", "-", "-")] + coherent


def auto_twin(args, spp, pattern):
    """The explicit sampler rendered at `spp` whose image Auto's equals, or None."""
    twin = resolve_auto(spp, pattern)
    return twin if twin in args.samplers and spp in args.matrix_spps else None


def add_auto_rows(args, rows):
    """Auto's rows where its twin was rendered instead (see configs)."""
    if "auto" not in args.samplers:
        return rows
    twins = [r for r in rows if r["engine"] == "coherent" and auto_twin(args, r["spp"], r["pattern"]) == r["sampler"]]
    return rows + [dict(r, sampler="auto") for r in twins]


# --- rendering -----------------------------------------------------------------------

def read_rgb(path):
    import OpenImageIO as oiio
    buf = oiio.ImageBuf(str(path))
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        raise OSError(f"cannot read {path}: {oiio.geterror()}")
    return np.asarray(px, dtype=np.float64)[:, :, :3]


def user_scripts(work):
    """A BLENDER_USER_SCRIPTS tree whose addons/coherent is this checkout's add-on."""
    addons = work / "blender_user" / "scripts" / "addons"
    addons.mkdir(parents=True, exist_ok=True)
    (work / "blender_user" / "config").mkdir(exist_ok=True)
    link = addons / "coherent"
    if link.is_symlink() or link.exists():
        link.unlink()
    link.symlink_to(REPO / "addon" / "coherent", target_is_directory=True)
    return addons.parent


def run_blender(args, scene_path, renders, on_render):
    """Renders `renders` in one Blender process; calls on_render(line dict)
    as each finishes. Returns what the worker said about its defaults."""
    job = dict(res=args.res, threads=args.threads, max_bounces=args.max_bounces, renders=renders)
    with tempfile.NamedTemporaryFile("w", suffix=".json", dir=args.work, delete=False) as f:
        json.dump(job, f)
    scripts = user_scripts(args.work)
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(scripts), BLENDER_USER_CONFIG=str(scripts.parent / "config"))
    env.pop("PYTHONPATH", None)
    cmd = [args.blender, "-b", "--factory-startup", "--python-exit-code", "1", "--addons", "coherent",
           str(scene_path), "--python", str(REPO / "bench" / "efficiency_render.py"), "--", f.name]
    info, tail = {}, []
    with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env) as p:
        for line in p.stdout:
            tail = (tail + [line])[-40:]
            if line.startswith("EFFBENCH_INFO "):
                info = json.loads(line.split(" ", 1)[1])
            elif line.startswith("EFFBENCH_RENDER "):
                on_render(json.loads(line.split(" ", 1)[1]))
    os.unlink(f.name)
    if p.returncode != 0:
        sys.exit(f"Blender failed on {scene_path} (exit {p.returncode}):\n{''.join(tail)}")
    return info


def render_list(args, stem, reference_needed):
    renders = []
    if reference_needed:
        for half, seed in zip("ab", REFERENCE_SEEDS):
            renders.append(dict(engine="CYCLES", spp=args.reference_spp // 2, seed=seed, sampler="-", pattern="-",
                                out=str(args.work / f"{stem}_ref_{half}.exr"), role="reference"))
    if not args.references_only:  # one-time costs (first Cycles session, caches) out of the timed renders
        for engine in ("CYCLES", "COHERENT"):
            renders.append(dict(engine=engine, spp=1, seed=0, sampler="auto", pattern=args.patterns[0],
                                out=str(args.work / "renders" / f"{stem}_warmup.exr"), role="warmup"))
    for rep in range(1, 0 if args.references_only else args.reps + 1):
        for spp in args.spps:
            for engine, sampler, pattern in configs(args, spp):
                out = args.work / "renders" / f"{stem}_{engine}_{sampler}_{pattern}_{spp}_{rep}.exr"
                renders.append(dict(engine=engine.upper(), spp=spp, seed=rep, sampler=sampler, pattern=pattern,
                                    out=str(out), rep=rep, role="measure"))
    return renders


def measure_scene(args, name, path, which):
    """Renders one scene; returns (rows, worker info). `which`: "scene i/n"
    for the progress lines."""
    stem = f"{name.replace('/', '-')}_{settings_key(path, args)}"
    halves = [args.work / f"{stem}_ref_{h}.exr" for h in "ab"]
    need_ref = not all(h.exists() for h in halves)
    (args.work / "renders").mkdir(parents=True, exist_ok=True)
    state = {"rows": []}
    if not need_ref:
        state["ref"] = reference_from_halves(read_rgb(halves[0]), read_rgb(halves[1]))
    renders = render_list(args, stem, need_ref)
    if not renders:
        return [], {}
    done = [0]

    def on_render(r):
        done[0] += 1
        if args.clock == "cpu":
            r["seconds"] = r["cpu_seconds"]
        progress = f"[{which}, render {done[0]}/{len(renders)}] {name} {r['engine'].lower()}"
        if r["role"] == "reference":
            print(f"{progress} reference half {r['spp']} spp: {r['seconds']:.2f} s", flush=True)
            if all(h.exists() for h in halves) and "ref" not in state:
                state["ref"] = reference_from_halves(read_rgb(halves[0]), read_rgb(halves[1]))
            return
        if r["role"] == "warmup":
            return
        ref, ref_var = state["ref"]
        raw = mse(read_rgb(r["out"]), ref)
        row = dict(scene=name, engine=r["engine"].lower(), sampler=r["sampler"], pattern=r["pattern"], spp=r["spp"],
                   rep=r["rep"], seconds=r["seconds"], mse_vs_reference=raw, reference_variance=ref_var,
                   mse=corrected_mse(raw, ref_var))
        state["rows"].append(row)
        print(f"{progress} {r['sampler']} {r['pattern']} {r['spp']} spp rep {r['rep']}: {r['seconds']:.2f} s, "
              f"rmse {math.sqrt(row['mse']):.5f}", flush=True)

    info = run_blender(args, path, renders, on_render)
    return add_auto_rows(args, state["rows"]), info


# --- CSV -----------------------------------------------------------------------------

def write_csv(path, rows):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=CSV_FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r[k] for k in CSV_FIELDS})


def read_csv(path):
    """Rows as written by write_csv, with numbers as numbers."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in ("spp", "rep"):
            r[k] = int(r[k])
        for k in ("seconds", "mse_vs_reference", "reference_variance", "mse"):
            r[k] = float(r[k])
    return rows


def save_results(args, csv_path, info_path, rows, info, scene_order):
    """Writes the CSV and the run's settings. With --append, the rows of
    scenes this run has not rendered, and the commands that made them, are
    read back from the files as they are now and kept."""
    done = {r["scene"] for r in rows}
    if args.append and csv_path.exists():
        rows = [r for r in read_csv(csv_path) if r["scene"] not in done] + rows
        if info_path.exists():
            earlier = json.loads(info_path.read_text()).get("commands", [])
            info["commands"] = earlier + [c for c in info["commands"] if c not in earlier]
    order = {n: i for i, n in enumerate(scene_order)}
    write_csv(csv_path, sorted(rows, key=lambda r: order.get(r["scene"], len(order))))
    info_path.write_text(json.dumps(info, indent=1) + "\n")


# --- main ----------------------------------------------------------------------------

def parse_args(argv):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--blender", default="blender")
    ap.add_argument("--shared", type=Path, default=REPO.parent / "shared" / "scenes",
                    help="folder of the public .blend scenes (skipped with a note when absent)")
    ap.add_argument("--scene", action="append", default=[], help="only scenes whose name contains this "
                                                                 "(repeatable), e.g. repo/cornell_box")
    ap.add_argument("--spps", type=int, nargs="+", default=[16, 64, 256, 1024])
    ap.add_argument("--matrix-spps", type=int, nargs="+", default=[16, 64, 256],
                    help="spp at which SPT, CPT and ICPT are rendered besides Auto (default: all but 1024)")
    ap.add_argument("--reference-spp", type=int, default=4096)
    ap.add_argument("--references-only", action="store_true", help="render the missing references and stop")
    ap.add_argument("--reps", type=int, default=1)
    ap.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                    help="seconds of a render: wall time (what a user waits), or the Blender process's CPU "
                         "time over all threads (steadier on a loaded machine; leaves out time threads wait)")
    ap.add_argument("--samplers", nargs="+", choices=SAMPLERS, default=SAMPLERS)
    ap.add_argument("--patterns", nargs="+", choices=PATTERNS, default=PATTERNS)
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--max-bounces", type=int, default=4, help="max, diffuse, glossy and transmission bounces")
    ap.add_argument("--work", type=Path, default=REPO / "build" / "efficiency_vs_cycles",
                    help="renders and cached references")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "results")
    ap.add_argument("--quick", action="store_true",
                    help="2 scenes, 16 and 64 spp, 512-spp reference; output under --work/quick")
    ap.add_argument("--report-only", action="store_true", help="redraw the md and png from the existing CSV")
    ap.add_argument("--append", action="store_true",
                    help="keep the existing CSV's rows of the scenes not rendered now (rerun one scene)")
    args = ap.parse_args(argv)
    if args.quick:
        args.spps, args.matrix_spps, args.reference_spp = [16, 64], [16, 64], 512
        args.scene = args.scene or ["repo/cornell_box", "public/stanford_bunny"]
        args.out = args.work / "quick"
    if args.reference_spp < 2 or args.reference_spp % 2:
        ap.error("--reference-spp must be even (it is rendered as two halves)")
    return args


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    args = parse_args(argv)
    args.work = args.work.resolve()
    args.work.mkdir(parents=True, exist_ok=True)
    args.out.mkdir(parents=True, exist_ok=True)
    csv_path = args.out / "efficiency_vs_cycles.csv"
    info_path = args.out / "efficiency_vs_cycles.json"
    command = "/usr/bin/python3 bench/efficiency_vs_cycles.py" + "".join(f" {a}" for a in argv)
    if not args.report_only:
        all_scenes = find_scenes(args.shared)
        scenes = [(n, p) for n, p in all_scenes if not args.scene or any(s in n for s in args.scene)]
        if not scenes:
            sys.exit("no scene matches --scene")
        rows = []
        for i, (name, path) in enumerate(scenes):
            scene_rows, worker = measure_scene(args, name, path, f"scene {i + 1}/{len(scenes)}")
            if args.references_only:
                continue
            rows += scene_rows
            info = dict(worker, commands=[command], res=args.res, threads=args.threads,
                        max_bounces=args.max_bounces, reference_spp=args.reference_spp, reps=args.reps,
                        clock=args.clock)
            # After every scene, so an interrupted run still has a report.
            save_results(args, csv_path, info_path, rows, info, [n for n, _ in all_scenes])
        if args.references_only:
            return
    efficiency_report.write(args.out, read_csv(csv_path), json.loads(info_path.read_text()))


if __name__ == "__main__":
    main()
