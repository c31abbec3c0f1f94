# Latency of the interactive viewport (addon/coherent/viewport.py), measured
# in a real Blender window under Xvfb (Mesa software OpenGL) exactly as a user
# sees it: from the action to the first frame drawn on screen.
#
#   python3 bench/viewport_latency.py            # Cornell box and Sponza -> docs/results/viewport_latency.md
#
# Without bpy this file is the driver: it starts one windowed Blender per
# scene with itself as the --python script. Inside Blender it switches the
# largest 3D View to camera view and Rendered shading at full viewport
# resolution (pixel size 1) and records:
#   first frame      Rendered switched on -> first image drawn (export + BVH + coarse stage)
#   N samples        Rendered switched on -> all Viewport samples drawn
#   restart latency  edit -> first image of the edited scene drawn, for an
#                    orbit (view rotation), a transform, a material colour and
#                    a light's power
# Each edit is repeated REPEATS times; the median is reported.

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    import bpy
except ImportError:
    bpy = None

REPO = Path(__file__).resolve().parents[1]
SCENES = {
    "Cornell box": REPO / "blend_scenes" / "cornell_box.blend",
    "Sponza": REPO.parent / "shared" / "scenes" / "crytek_sponza.blend",
}
SAMPLES = 16
REPEATS = 5
TIMEOUT = 300.0


# ---------------------------------------------------------------------- inside Blender

def _blender_main(out_path):
    import numpy as np
    from mathutils import Quaternion

    scene = bpy.context.scene
    result = {"restart_ms": {}}

    def viewport():
        return sys.modules["coherent"].viewport

    def session():
        s = viewport().sessions()
        return s[0] if s else None

    def wait(condition):
        start = time.perf_counter()
        while not condition():
            if time.perf_counter() - start > TIMEOUT:
                raise TimeoutError("timed out")
            yield

    def run():
        window, area = max(((w, a) for w in bpy.context.window_manager.windows for a in w.screen.areas
                            if a.type == "VIEW_3D"), key=lambda wa: wa[1].width * wa[1].height)
        space = area.spaces.active
        region = next(r for r in area.regions if r.type == "WINDOW")
        scene.render.engine = "COHERENT"
        scene.coherent.preview_samples = SAMPLES
        scene.render.preview_pixel_size = "1"
        space.overlay.show_overlays = False
        space.region_3d.view_perspective = "CAMERA"
        with bpy.context.temp_override(window=window, area=area, region=region):
            bpy.ops.view3d.view_center_camera()
        yield
        result["region"] = [region.width, region.height]

        t0 = time.perf_counter()
        space.shading.type = "RENDERED"
        yield from wait(lambda: session() is not None and session().first_frame_at is not None)
        s = session()
        result["first_frame_ms"] = (s.first_frame_at - t0) * 1e3
        result["first_stage"] = list(s.stages[0])
        yield from wait(lambda: s.final_seconds is not None)
        result["all_samples_s"] = s.restart_time - t0 + s.final_seconds
        result["triangles"] = s.scene.triangle_count
        result["stages"] = [list(st) for st in s.stages]
        result["bvh_seconds_initial"] = s.bvh_seconds

        meshes = [o for o in scene.objects if o.type == "MESH"]
        mover = max(meshes, key=lambda o: len(o.data.polygons))  # the largest mesh: the worst case
        material = next((m for o in meshes for m in [o.active_material]
                         if m is not None and m.use_nodes and any(n.type in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE")
                                                                 for n in m.node_tree.nodes)), None)
        light = next((o for o in scene.objects if o.type == "LIGHT"), None)

        def orbit():
            space.region_3d.view_perspective = "PERSP"
            space.region_3d.view_rotation = Quaternion((0, 0, 1), 0.02) @ space.region_3d.view_rotation

        def move():
            mover.location.x += 0.01

        def recolor():
            node = next(n for n in material.node_tree.nodes if n.type in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE"))
            socket = node.inputs["Color" if node.type == "BSDF_DIFFUSE" else "Base Color"]
            c = socket.default_value
            socket.default_value = (c[0] * 0.9, c[1], c[2], 1.0)

        def relight():
            light.data.energy *= 1.05

        edits = [("orbit", orbit), ("transform", move)]
        if material is not None:
            edits.append(("material", recolor))
        if light is not None:
            edits.append(("light", relight))
        for name, edit in edits:
            times = []
            for _ in range(REPEATS):
                s = session()
                restarts = s.counters["restarts"]
                t_edit = time.perf_counter()
                edit()
                yield from wait(lambda: s.counters["restarts"] > restarts and s.first_frame_at is not None
                                and s.first_frame_at > t_edit)
                times.append((s.first_frame_at - t_edit) * 1e3)
                yield from wait(lambda: s.stage > 0 or len(s.stages) == 1)  # let it refine a little
            result["restart_ms"][name] = statistics.median(times)
            if name == "transform":
                result["bvh_seconds"] = session().bvh_seconds  # the transform's BVH refit (copy + refit)
        result["counters"] = dict(session().counters)

    steps = run()

    def tick():
        try:
            next(steps)
            return 0.005
        except StopIteration:
            pass
        except Exception as e:  # noqa: BLE001 - reported, then quit
            import traceback
            result["error"] = traceback.format_exc()
        with open(out_path, "w") as f:
            json.dump(result, f, indent=1)
        bpy.ops.wm.quit_blender()
        return None

    bpy.app.timers.register(tick, first_interval=0.5)


# ---------------------------------------------------------------------- driver

def _run_scene(blend, tmp):
    scripts = Path(tmp) / "scripts"
    (scripts / "addons").mkdir(parents=True, exist_ok=True)
    link = scripts / "addons" / "coherent"
    if not link.exists():
        link.symlink_to(REPO / "addon" / "coherent", target_is_directory=True)
    (Path(tmp) / "config").mkdir(exist_ok=True)
    out = Path(tmp) / f"{blend.stem}.json"
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(scripts), BLENDER_USER_CONFIG=str(Path(tmp) / "config"),
               TMPDIR=str(tmp))
    cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", "blender", "--factory-startup", "--addons", "coherent",
           str(blend), "--python", __file__, "--", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=900)
    if not out.is_file():
        sys.exit(f"no result for {blend}:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return json.loads(out.read_text())


def main():
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, blend in SCENES.items():
            r = _run_scene(blend, tmp)
            if "error" in r:
                sys.exit(f"{name}: {r['error']}")
            rows[name] = r
            print(name, json.dumps(r))
    lines = [
        "# Viewport latency",
        "",
        "Measured by `python3 bench/viewport_latency.py` in a real Blender 3.4 window under Xvfb",
        "(Mesa llvmpipe OpenGL, which also draws the image on the CPU), on the 2-core development",
        f"machine; full viewport resolution (pixel size 1), Viewport samples = {SAMPLES}, camera view.",
        "Times run from the action to the first frame of its result drawn on screen; restart",
        f"latencies are medians of {REPEATS} edits. Sampler: the Sampling panel's (default Auto,",
        "which is ICPT in the viewport).",
        "",
        "| | " + " | ".join(rows) + " |",
        "|---|" + "---|" * len(rows),
        "| triangles | " + " | ".join(f"{r['triangles']:,}" for r in rows.values()) + " |",
        "| viewport (pixels) | " + " | ".join(f"{r['region'][0]}x{r['region'][1]}" for r in rows.values()) + " |",
        "| first stage (divisor, spp) | " + " | ".join(f"1/{r['first_stage'][0]}, {r['first_stage'][1]}"
                                                      for r in rows.values()) + " |",
        "| first frame after switching to Rendered (ms) | " + " | ".join(f"{r['first_frame_ms']:.0f}"
                                                                        for r in rows.values()) + " |",
        f"| all {SAMPLES} samples at full resolution (s) | " + " | ".join(f"{r['all_samples_s']:.1f}"
                                                                      for r in rows.values()) + " |",
    ]
    for edit in ("orbit", "transform", "material", "light"):
        lines.append(f"| restart after {edit} (ms) | " + " | ".join(
            f"{r['restart_ms'][edit]:.0f}" if edit in r["restart_ms"] else "-" for r in rows.values()) + " |")
    lines.append("| BVH build, first (spatial splits) (s) | " + " | ".join(
        f"{r['bvh_seconds_initial']:.3f}" for r in rows.values()) + " |")
    lines.append("| BVH refit after a transform (copy + refit) (s) | " + " | ".join(
        f"{r['bvh_seconds']:.3f}" for r in rows.values()) + " |")
    lines += [
        "",
        "Orbit, material and light restarts reuse the BVH (the native Scene keeps it; only the camera,",
        "a material or the lights change in place). A transform re-exports the native scene from the",
        "session's cached mesh arrays (no mesh is re-extracted from Blender, so the triangles keep",
        "their order) and refits a copy of the previous BVH to the moved triangles",
        "(`Scene.refit_bvh_from`, `Bvh::refit`: boxes recomputed bottom-up, same topology and 8-wide",
        "collapse), which is what the transform row measures on the scene's largest mesh. Adding or",
        "deleting objects or editing a mesh still rebuilds the BVH (binned SAH, no spatial splits).",
        "",
        "Before the refit, the same benchmark measured the transform restart at 242 ms on Sponza",
        "(0.219 s of it the binned-SAH rebuild) and 38 ms on the Cornell box; compare the transform",
        "row above. The refit keeps the topology of the first (spatial-split) build, so the hits stay",
        "exact but a tree whose objects moved far from where they were built traces slower; the",
        "viewport rebuilds it only when the set of objects or a mesh changes.",
        "",
        "Reading the numbers: the first frame of Sponza is dominated by exporting 262k triangles from",
        "383 objects (~0.3 s) and building the BVH with spatial splits (row above); the coarse first",
        "stage itself renders in tens of milliseconds. A transform on Sponza now costs the re-export",
        "from cached arrays (~50 ms) plus the refit. Machine shared with other engineers' builds: the",
        "seconds-scale rows are noisy (an earlier run under load measured 3.3 s / 1.6 s for Sponza).",
        "",
        "Raw results:",
        "",
        "```json",
        json.dumps(rows, indent=1),
        "```",
        "",
    ]
    out = REPO / "docs" / "results" / "viewport_latency.md"
    out.write_text("\n".join(lines))
    print(f"wrote {out}")


if __name__ == "__main__":
    if bpy is not None:
        _blender_main(sys.argv[sys.argv.index("--") + 1])
    else:
        main()
