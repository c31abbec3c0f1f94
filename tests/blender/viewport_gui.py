# Uses a Rendered 3D viewport the way a person does, in a real Blender
# window (run under Xvfb by test_viewport.py):
#
#   xvfb-run blender --factory-startup --addons coherent cornell_box.blend \
#       --python viewport_gui.py -- OUT_DIR
#
# A timer drives a state machine (Blender must keep running its event loop
# for the viewport to draw): switch the largest 3D View to camera view and
# Rendered shading, wait for the first frame and for all samples, capture the
# region's pixels (Blender's screenshot operator, overlays off), render the
# same camera with F12, move an object, capture again,
# close and reopen the Rendered view twice while watching threads and
# memory, and finally quit Blender while a render is running. Everything
# measured goes to OUT_DIR/result.json; the pixels to .npy / .png files.
# The assertions live in test_viewport.py.

import json
import os
import sys
import time
import traceback
from pathlib import Path

import bpy
import gpu
import numpy as np
from bpy_extras import view3d_utils

OUT = Path(sys.argv[sys.argv.index("--") + 1])
OUT.mkdir(parents=True, exist_ok=True)
ENGINE = "COHERENT"
PREVIEW_SAMPLES = int(os.environ.get("COHERENT_VP_SAMPLES", "16"))
MOVE_X = 0.35          # how far the tall box moves (metres)
TICK = 0.02            # a hang is caught by test_viewport.py's subprocess timeout

scene = bpy.context.scene
result = {"events": []}


def log(msg):
    print(f"viewport_gui: {msg}", flush=True)
    result["events"].append(msg)


def find_view3d():
    best = None
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D" and (best is None or area.width * area.height > best[1].width * best[1].height):
                best = (window, area)
    return best


def window_region(area):
    return next(r for r in area.regions if r.type == "WINDOW")


def coherent_viewport():
    return sys.modules["coherent"].viewport


def live_session():
    sessions = coherent_viewport().sessions()
    return sessions[0] if sessions else None


def thread_count():
    """Live threads of this process. A joined thread can still be listed in
    /proc/self/task for a moment after pthread_join returned (the kernel
    releases the task after waking the joiner), in state Z or X: not counted."""
    live = 0
    for tid in os.listdir("/proc/self/task"):
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue  # gone while we looked
        live += state not in ("Z", "X")
    return live


def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def screenshot(window, area, name):
    """The 3D View's window region as on screen (Blender's own screenshot), RGB, bottom row first.

    Saved as OUT/name.png (whole window) and OUT/name.npy (the region).
    """
    path = OUT / f"{name}.png"
    with bpy.context.temp_override(window=window, area=area):
        bpy.ops.screen.screenshot(filepath=str(path), check_existing=False)
    image = bpy.data.images.load(str(path))
    try:
        width, height = image.size
        pixels = np.empty(width * height * 4, dtype=np.float32)
        image.pixels.foreach_get(pixels)
    finally:
        bpy.data.images.remove(image)
    pixels = pixels.reshape(height, width, 4)[..., :3]
    region = window_region(area)
    x0, y0 = region.x - window.x, region.y - window.y  # region origin in window pixels
    crop = pixels[y0:y0 + region.height, x0:x0 + region.width]
    np.save(OUT / f"{name}.npy", crop)
    return crop


def rendering_done():
    session = live_session()
    return session is not None and session.final_seconds is not None


def wait_ticks(n):
    for _ in range(n):
        yield


def project(area, points):
    region = window_region(area)
    rv3d = area.spaces.active.region_3d
    out = [view3d_utils.location_3d_to_region_2d(region, rv3d, p) for p in points]
    return [(float(p.x), float(p.y)) for p in out if p is not None]


def camera_frame_rect(area):
    cam = scene.camera
    corners = [cam.matrix_world @ c for c in cam.data.view_frame(scene=scene)]
    xy = np.array(project(area, corners))
    return [float(xy[:, 0].min()), float(xy[:, 1].min()), float(xy[:, 0].max()), float(xy[:, 1].max())]


def object_rect(area, ob):
    from mathutils import Vector
    xy = np.array(project(area, [ob.matrix_world @ Vector(c) for c in ob.bound_box]))
    return [float(xy[:, 0].min()), float(xy[:, 1].min()), float(xy[:, 0].max()), float(xy[:, 1].max())]


# -- the script, as a generator: each `yield` waits one timer tick -------------------------

def wait_until(what, condition):
    """Waits (timer ticks) for an event; no time limit here: the log names the wait a hang is in."""
    log(f"waiting for {what}")
    start = time.perf_counter()
    while not condition():
        yield
    log(f"{what} after {time.perf_counter() - start:.2f} s")


def run():
    window, area = find_view3d()
    space = area.spaces.active
    region = window_region(area)
    scene.render.engine = ENGINE
    scene.coherent.preview_samples = PREVIEW_SAMPLES
    scene.render.preview_pixel_size = "2"
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.show_region_toolbar = False
    space.show_region_ui = False
    space.show_region_header = False  # it overlaps the region's top rows
    space.show_region_tool_header = False
    space.region_3d.view_perspective = "CAMERA"
    with bpy.context.temp_override(window=window, area=area, region=region):
        bpy.ops.view3d.view_center_camera()
    yield
    result["region"] = [region.width, region.height]
    result["threads_before"] = thread_count()
    result["rss_before"] = rss_mb()

    # 1. Rendered shading: first frame, then all samples.
    t_switch = time.perf_counter()
    space.shading.type = "RENDERED"
    yield from wait_until("first frame", lambda: live_session() is not None
                          and live_session().first_frame_at is not None)
    session = live_session()
    result["first_frame_ms"] = (session.first_frame_at - t_switch) * 1e3
    result["threads_rendering"] = thread_count()
    yield from wait_until("all samples (1)", rendering_done)
    yield from wait_ticks(5)  # the final frame reaches the screen
    result["all_samples_s"] = session.final_seconds
    result["camera_rect"] = camera_frame_rect(area)
    tall = bpy.data.objects["TallBox"]
    result["box_rect_before"] = object_rect(area, tall)
    screenshot(window, area, "shot1")
    result["counters_1"] = dict(session.counters)
    result["extracted_1"] = session.mesh_cache.extracted

    # 2. The same camera rendered with F12 (final render), saved as the
    # viewer sees it (view transform applied, like the viewport).
    rect = result["camera_rect"]
    scene.render.resolution_x = 128
    scene.render.resolution_y = max(1, round(128 * (rect[3] - rect[1]) / (rect[2] - rect[0])))
    scene.render.resolution_percentage = 100
    scene.coherent.samples = 64
    bpy.ops.render.render()
    bpy.data.images["Render Result"].save_render(str(OUT / "final.png"))
    result["threads_after_final_render"] = thread_count()
    log("final render saved")
    yield

    # 3. Move an object: a restart, then all samples again.
    session = live_session()
    version_before = session.scene_version
    t_edit = time.perf_counter()
    tall.location.x += MOVE_X
    yield from wait_until("restart after the move", lambda: session.scene_version != version_before
                          and session.first_frame_at is not None and session.first_frame_at > t_edit)
    result["restart_ms"] = (session.first_frame_at - t_edit) * 1e3
    yield from wait_until("all samples (2)", rendering_done)
    yield from wait_ticks(5)
    result["box_rect_after"] = object_rect(area, tall)
    screenshot(window, area, "shot2")
    result["counters_2"] = dict(session.counters)
    result["extracted_2"] = session.mesh_cache.extracted
    result["triangles"] = session.scene.triangle_count
    session = None

    # 4. Close and reopen the Rendered view: the render thread must go, memory must not grow.
    for cycle in range(3):
        space.shading.type = "SOLID"
        # A freed session has joined its render thread: Session.free() -> stop()
        # -> Renderer.wait(), or the native Renderer's destructor, which cancels
        # and joins. So the count read right after is final, no polling.
        yield from wait_until(f"session freed ({cycle})", lambda: not coherent_viewport().sessions())
        result.setdefault("threads_after_close", []).append(thread_count())
        result.setdefault("rss_after_close", []).append(rss_mb())
        if cycle == 2:
            break
        space.shading.type = "RENDERED"
        # Closed again while still refining: the harder case for stopping.
        yield from wait_until(f"full-resolution stage (cycle {cycle})", lambda: live_session() is not None
                              and live_session().renderer is not None
                              and live_session().stage + 1 == len(live_session().stages)
                              and live_session().renderer.running)
        result.setdefault("threads_rendering_cycle", []).append(thread_count())
    log(f"threads {result['threads_before']} -> {result['threads_after_close']}, "
        f"rss {result['rss_before']:.0f} -> {[round(r) for r in result['rss_after_close']]} MB")

    # 5. Quit while a render runs: Blender must stop it and exit cleanly.
    space.shading.type = "RENDERED"
    scene.coherent.preview_samples = 4096
    yield from wait_until("render running before quit", lambda: live_session() is not None
                          and live_session().renderer is not None and live_session().renderer.running)
    result["ok"] = True


def main():
    steps = run()

    def tick():
        try:
            next(steps)
            return TICK
        except StopIteration:
            pass
        except Exception:  # noqa: BLE001 - reported in result.json, then quit
            result["error"] = traceback.format_exc()
            log(result["error"])
        with open(OUT / "result.json", "w") as f:
            json.dump(result, f, indent=1)
        bpy.ops.wm.quit_blender()
        return None

    bpy.app.timers.register(tick, first_interval=0.5)


main()
