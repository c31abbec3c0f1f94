# SPDX-License-Identifier: Apache-2.0
"""What does quality cost: predicted render time to each error level, per sampler.

A short pilot render per sampler (SPT, CPT, ICPT) records, after every sample
pass, (seconds, spp, error_estimate), where the estimate is the film's
reference-free relative RMSE from its even and odd half buffers (the same
number the Target Error stopping rule uses). From these points:

- error(spp) = c * spp^(-1/2), the Monte Carlo rate, with c fitted in log
  space on the later half of the points (the first passes carry the most
  noise in the estimate itself). The exponent is also fitted freely and
  reported: far from -0.5 means the pilot was too short to trust.
- seconds(spp) = overhead + spp * seconds_per_pass, a least-squares line over
  the same points.

Error is modelled against samples, not time, on purpose: the pass count is
exact while time on a shared machine is noisy, and keeping the two apart lets
a pilot at a reduced resolution predict a larger render: the time per pass is
multiplied by (film pixels / pilot pixels) and the spp is carried over. That
assumes the relative RMSE does not depend on the resolution; it does somewhat
(a bigger pixel also averages the image's own variation within it), so a
scaled-down pilot over-predicts the samples (see DEFAULT_PILOT_MAX_PIXELS).

The Blender pilots use the scene's seed, so their passes are exactly the
first passes of the final render the table predicts.

Prediction for a level E: spp = (c / E)^2 rounded up to an even count (the
stopping rule only checks even pass counts), seconds = seconds(spp).

The first part of this file is plain Python (no bpy, no native module) so it
can be unit-tested and used by bench/quality_prediction.py; the Blender
operator, properties and panel follow, defined only when bpy is importable.
"""

from __future__ import annotations

import atexit
import math
import threading
import time
from dataclasses import dataclass

try:
    import bpy
except ImportError:  # plain Python: the model functions only
    bpy = None

SAMPLERS = ("SPT", "CPT", "ICPT")
DEFAULT_LEVELS = (0.10, 0.05, 0.02, 0.01)
# Pilot defaults: seconds of rendering per sampler, the least number of passes
# whatever the budget (a fit needs several points with an estimate, which
# starts at pass 2), and the pixel count above which the pilot is scaled down.
DEFAULT_PILOT_SECONDS = 1.0
DEFAULT_MIN_PASSES = 8
DEFAULT_MAX_PASSES = 1 << 16
# Scaling the pilot down is not free: a bigger pixel footprint adds the
# image's own variation within a pixel (edges, gradients) to the per-sample
# variance, so a scaled-down pilot over-predicts the samples needed. Measured
# in docs/results/quality_prediction.md: about 1.3x at half the width and
# height, 2-3x at a quarter. Hence a generous default: frames up to 512x512
# are piloted at full size.
DEFAULT_PILOT_MAX_PIXELS = 512 * 512


class ModelError(ValueError):
    """The pilot data cannot support a prediction (too few points, zero error, ...)."""


# --- the model (pure Python) -----------------------------------------------------


@dataclass(frozen=True)
class ConvergenceFit:
    """error(spp) = c * spp^-0.5 and seconds(spp) = overhead + spp * seconds_per_pass (pilot scale)."""

    c: float                 # relative RMSE at 1 spp under the 1/sqrt(spp) law
    exponent: float          # freely fitted exponent of error ~ spp^exponent (diagnostic; ideal -0.5)
    seconds_per_pass: float  # at the pilot resolution
    overhead: float          # seconds at spp = 0 (>= 0; not scaled with pixels)
    pixel_scale: float       # film pixels / pilot pixels; time per pass is multiplied by it
    points_used: int         # pilot points in the fit (the later half)
    pilot_spp: int           # passes the pilot took
    pilot_seconds: float     # pilot render seconds

    def spp_for(self, error):
        """Predicted passes for the estimate to reach `error`: an even count >= 2."""
        _check_level(error)
        n = (self.c / error) ** 2
        if not math.isfinite(n) or n > 1e15:
            raise ModelError(f"error level {error:g} is out of reach (predicted {n:.3g} samples)")
        return max(2, 2 * math.ceil(n / 2.0 - 1e-9))

    def seconds_for_spp(self, spp):
        """Predicted render seconds (film resolution) for `spp` passes."""
        return self.overhead + spp * self.seconds_per_pass * self.pixel_scale

    def seconds_for(self, error):
        """Predicted render seconds (film resolution) to reach `error`."""
        return self.seconds_for_spp(self.spp_for(error))

    def error_at_spp(self, spp):
        return self.c / math.sqrt(spp)


def _check_level(error):
    if not (isinstance(error, (int, float)) and math.isfinite(error) and error > 0.0):
        raise ModelError(f"error level must be a finite number > 0, got {error!r}")


def clean_points(points):
    """The pilot points that carry an estimate, validated, ordered by spp.

    `points`: iterable of (seconds, spp, error_estimate); rows whose estimate
    is None (before the 2nd pass) are skipped. Raises ModelError for negative
    or non-finite values, and a repeated spp.
    """
    rows = []
    for row in points:
        if len(row) != 3:
            raise ModelError(f"a pilot point is (seconds, spp, error_estimate), got {row!r}")
        seconds, spp, error = row
        if error is None:
            continue
        seconds, spp, error = float(seconds), int(spp), float(error)
        if not (math.isfinite(seconds) and seconds >= 0.0):
            raise ModelError(f"pilot point at {spp} spp has invalid seconds {seconds!r}")
        if spp < 1:
            raise ModelError(f"pilot point has invalid spp {spp}")
        if not (math.isfinite(error) and error >= 0.0):
            raise ModelError(f"pilot point at {spp} spp has invalid error estimate {error!r}")
        rows.append((seconds, spp, error))
    rows.sort(key=lambda r: r[1])
    for a, b in zip(rows, rows[1:]):
        if a[1] == b[1]:
            raise ModelError(f"two pilot points at {a[1]} spp")
    return rows


def _line_fit(xs, ys):
    """Least-squares (intercept, slope) of y = a + b x; xs must not all be equal."""
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    sxy = sum((x - mx) * (y - my) for x, y in zip(xs, ys))
    b = sxy / sxx
    return my - b * mx, b


def fit_convergence(points, pixel_scale=1.0, tail_fraction=0.5):
    """Fits the model to pilot points (seconds, spp, error_estimate).

    Uses the later `tail_fraction` of the points that have an estimate (at
    least 2). Raises ModelError with a readable reason when there are fewer
    than 2 such points, when the estimate is zero (a noise-free image: empty
    or unlit scene, nothing to predict), or when the inputs are invalid.
    """
    if not (math.isfinite(pixel_scale) and pixel_scale > 0.0):
        raise ModelError(f"pixel_scale must be a finite number > 0, got {pixel_scale!r}")
    if not (0.0 < tail_fraction <= 1.0):
        raise ModelError(f"tail_fraction must be in (0, 1], got {tail_fraction!r}")
    rows = clean_points(points)
    if len(rows) < 2:
        raise ModelError(f"need at least 2 pilot passes with an error estimate, got {len(rows)} "
                         f"(the estimate exists from the 2nd pass on: lengthen the pilot)")
    if any(e == 0.0 for _, _, e in rows):
        raise ModelError("the error estimate is zero: the image is noise-free (an empty or unlit scene?), "
                         "so there is no error level to reach")
    k = max(2, math.ceil(len(rows) * tail_fraction))
    tail = rows[-k:]
    log_n = [math.log(n) for _, n, _ in tail]
    log_e = [math.log(e) for _, _, e in tail]
    # With the exponent fixed at -1/2, log c = mean(log e + log n / 2): the
    # least-squares solution in log space.
    log_c = sum(le + 0.5 * ln for le, ln in zip(log_e, log_n)) / k
    _, exponent = _line_fit(log_n, log_e)
    overhead, per_pass = _line_fit([float(n) for _, n, _ in tail], [s for s, _, _ in tail])
    last_seconds, last_spp = rows[-1][0], rows[-1][1]
    if not (per_pass > 0.0):
        # Timer noise on a very short pilot: fall back to the mean pass time.
        per_pass, overhead = last_seconds / last_spp, 0.0
    if not (per_pass > 0.0):
        raise ModelError("the pilot took no measurable time; cannot predict render time")
    return ConvergenceFit(c=math.exp(log_c), exponent=exponent, seconds_per_pass=per_pass,
                          overhead=max(0.0, overhead), pixel_scale=float(pixel_scale), points_used=k,
                          pilot_spp=last_spp, pilot_seconds=last_seconds)


@dataclass(frozen=True)
class Prediction:
    sampler: str
    error: float    # the error level (relative RMSE)
    spp: int
    seconds: float  # render seconds at the film resolution (no export or BVH build)


def predict_table(fits, levels=DEFAULT_LEVELS):
    """Rows of predictions: [(level, {sampler: Prediction}, fastest sampler)], in `levels` order.

    `fits`: {sampler: ConvergenceFit}. Levels must be finite and > 0.
    """
    if not fits:
        raise ModelError("no pilot fits to predict from")
    rows = []
    for level in levels:
        _check_level(level)
        cells = {s: Prediction(s, level, f.spp_for(level), f.seconds_for(level)) for s, f in fits.items()}
        fastest = min(cells.values(), key=lambda p: (p.seconds, p.spp)).sampler
        rows.append((level, cells, fastest))
    return rows


def pilot_resolution(width, height, max_pixels=DEFAULT_PILOT_MAX_PIXELS):
    """(pilot_width, pilot_height, pixel_scale): the frame scaled down (same
    aspect, to the nearest pixel) to at most ~max_pixels, and the ratio of the
    frame's pixels to the pilot's."""
    if width < 1 or height < 1:
        raise ModelError(f"invalid resolution {width}x{height}")
    if max_pixels < 1:
        raise ModelError(f"max_pixels must be >= 1, got {max_pixels}")
    if width * height <= max_pixels:
        return width, height, 1.0
    s = math.sqrt(max_pixels / (width * height))
    pw, ph = max(1, round(width * s)), max(1, round(height * s))
    return pw, ph, (width * height) / (pw * ph)


def format_duration(seconds):
    """Short human duration: '0.42 s', '12 s', '3 min 05 s', '2.1 h', '3.4 days'."""
    if seconds is None or not math.isfinite(seconds) or seconds < 0.0:
        return "n/a"
    if seconds < 10.0:
        return f"{seconds:.2f} s" if seconds < 1.0 else f"{seconds:.1f} s"
    if seconds < 60.0:
        return f"{seconds:.0f} s"
    if seconds < 3600.0:
        m, s = divmod(int(round(seconds)), 60)
        return f"{m} min {s:02d} s"
    if seconds < 86400.0:
        return f"{seconds / 3600.0:.1f} h"
    return f"{seconds / 86400.0:.1f} days"


def run_pilot(native, nscene, width, height, sampler, renderer_kwargs=None, budget=DEFAULT_PILOT_SECONDS,
              min_passes=DEFAULT_MIN_PASSES, max_passes=DEFAULT_MAX_PASSES, seed=0, cancelled=lambda: False,
              on_pass=None, on_renderer=None):
    """Renders `nscene` with `sampler` until `budget` seconds and `min_passes`
    passes are both reached (or `max_passes`); returns the per-pass points
    [(seconds, spp, error_estimate)] (estimate None for the 1st pass).

    Needs the native module but not bpy. `cancelled()` is polled after every
    progress report; on_pass(spp, seconds) is called after every pass;
    on_renderer(renderer or None) hands out the live renderer so another
    thread can cancel() it. Raises InterruptedError when cancelled.
    """
    kwargs = dict(renderer_kwargs or {})
    kwargs.update(width=width, height=height, spp=max_passes, seed=seed, sampler=sampler.lower(),
                  target_error=0.0, time_limit=0.0, progressive_display=False, adaptive=False)
    kwargs.pop("border", None)
    renderer = native.Renderer(nscene, **kwargs)
    points = []
    last = [0]
    stopped_by_us = [False]

    def progress(p):
        if cancelled():
            return False
        done = p["samples_done"]
        if done == last[0]:  # a report within a pass
            return True
        last[0] = done
        points.append((p["seconds"], done, p["error_estimate"]))
        if on_pass is not None:
            on_pass(done, p["seconds"])
        if p["seconds"] >= budget and done >= min_passes:
            stopped_by_us[0] = True
            return False
        return True

    if on_renderer is not None:
        on_renderer(renderer)
    try:
        finished = renderer.render(progress)
    finally:
        if on_renderer is not None:
            on_renderer(None)
    if not finished and not stopped_by_us[0]:
        raise InterruptedError("pilot render cancelled")
    return points


# --- Blender ---------------------------------------------------------------------

if bpy is not None:
    from bpy.props import (CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                           IntProperty, IntVectorProperty, PointerProperty, StringProperty)

    _SAMPLER_ITEMS = tuple((s, s, "") for s in SAMPLERS)

    class CoherentQualityRow(bpy.types.PropertyGroup):
        """One error level of the table: predicted spp and seconds per sampler (SAMPLERS order)."""
        error: FloatProperty(name="Error", subtype="FACTOR", precision=3)
        spp: IntVectorProperty(name="Samples", size=len(SAMPLERS))
        seconds: FloatVectorProperty(name="Seconds", size=len(SAMPLERS))
        fastest: EnumProperty(name="Fastest", items=_SAMPLER_ITEMS)

    class CoherentQualityFitInfo(bpy.types.PropertyGroup):
        """A pilot's fit, for display and scripting."""
        sampler: EnumProperty(name="Sampler", items=_SAMPLER_ITEMS)
        c: FloatProperty(name="Error at 1 spp")
        exponent: FloatProperty(name="Fitted Exponent")
        seconds_per_pass: FloatProperty(name="Seconds per Pass (film resolution)")
        pilot_spp: IntProperty(name="Pilot Passes")
        pilot_seconds: FloatProperty(name="Pilot Seconds")

    class CoherentQualitySettings(bpy.types.PropertyGroup):
        levels: FloatVectorProperty(
            name="Error Levels", description="Relative RMSE levels to predict the render time for",
            size=len(DEFAULT_LEVELS), default=DEFAULT_LEVELS, min=1e-4, max=10.0, precision=3)
        pilot_seconds: FloatProperty(
            name="Pilot Time", description="Seconds of pilot rendering per sampler (at least "
                                           f"{DEFAULT_MIN_PASSES} passes are taken whatever this says)",
            default=DEFAULT_PILOT_SECONDS, min=0.05, max=60.0, unit="TIME_ABSOLUTE", subtype="TIME_ABSOLUTE")
        pilot_max_pixels: IntProperty(
            name="Pilot Pixels", description="Pilots render larger frames scaled down to about this many pixels "
                                             "and scale the time per pass back up by the pixel count; a "
                                             "scaled-down pilot over-predicts the samples needed (about 1.3x at "
                                             "half the width and height)",
            default=DEFAULT_PILOT_MAX_PIXELS, min=64, max=1 << 24)
        rows: CollectionProperty(type=CoherentQualityRow)
        fits: CollectionProperty(type=CoherentQualityFitInfo)
        film_size: IntVectorProperty(name="Film Size", size=2)
        pilot_size: IntVectorProperty(name="Pilot Size", size=2)
        status: StringProperty(name="Status")

    def _film_size(scene):
        from .engine import border_pixels, render_size  # deferred: engine imports bpy-heavy modules
        width, height = render_size(scene.render)
        border = border_pixels(scene.render, width, height)
        film = (border[2] - border[0], border[3] - border[1]) if border else (width, height)
        return width, height, film

    class _PilotJob:
        """Everything an estimate needs, prepared on the main thread (export
        reads the depsgraph); run() only touches the native scene, so it may
        run on a worker thread."""

        def __init__(self, context):
            from . import export, native_module

            scene = context.scene
            self.native = native_module()
            # Looked up by name when results are stored: a bpy reference kept
            # across the modal run could dangle after an undo step.
            self.scene_name = scene.name
            settings = scene.coherent_quality
            width, height, film = _film_size(scene)
            self.film = film
            self.pilot_w, self.pilot_h, _ = pilot_resolution(width, height, settings.pilot_max_pixels)
            # Film pixels over pilot pixels: the pilot renders the whole frame
            # scaled down, the final render only the border's film.
            self.pixel_scale = (film[0] * film[1]) / (self.pilot_w * self.pilot_h)
            self.levels = tuple(float(v) for v in settings.levels)
            for level in self.levels:
                _check_level(level)
            self.budget = float(settings.pilot_seconds)
            depsgraph = context.evaluated_depsgraph_get()
            exported = export.export_scene(self.native, depsgraph, self.pilot_w, self.pilot_h)
            self.warnings = list(exported.warnings)
            self.nscene = exported.scene
            if self.nscene.triangle_count == 0:
                raise ModelError("the scene has no geometry to render, so there is no error to predict")
            props = scene.coherent
            self.kwargs = props.renderer_kwargs(scene)
            # The final render's seed: the pilot's passes are its first passes.
            self.seed = props.seed_for_frame(scene.frame_current)
            # Pilots run without adaptive sampling (run_pilot turns it off):
            # the model predicts when the whole image reaches the error level.
            self.adaptive = bool(self.kwargs.get("adaptive", False))
            self.points = {}
            self.fits = {}
            self.current = ""      # sampler being piloted
            self.fraction = 0.0    # of the whole estimate, for the progress bar
            self.thread_id = None
            # perf_counter() stamps: when cancel was first asked for, when run() returned.
            self.cancel_requested_at = None
            self.ended_at = None
            self._cancel = threading.Event()
            self._renderer = None
            self._lock = threading.Lock()

        def cancel(self):
            if not self._cancel.is_set():
                self.cancel_requested_at = time.perf_counter()
            self._cancel.set()
            with self._lock:
                if self._renderer is not None:
                    self._renderer.cancel()

        def _set_renderer(self, r):
            with self._lock:
                self._renderer = r
                if r is not None and self._cancel.is_set():
                    r.cancel()

        def run(self):
            """The three pilots and the fits; raises ModelError or InterruptedError."""
            self.thread_id = threading.get_ident()  # which thread rendered (tests: not Blender's main one)
            try:
                self._run_pilots()
            finally:
                self.ended_at = time.perf_counter()

        def _run_pilots(self):
            for i, sampler in enumerate(SAMPLERS):
                self.current = sampler

                def on_pass(spp, seconds, i=i):
                    self.fraction = (i + min(1.0, seconds / self.budget)) / len(SAMPLERS)

                pts = run_pilot(self.native, self.nscene, self.pilot_w, self.pilot_h, sampler, self.kwargs,
                                budget=self.budget, seed=self.seed, cancelled=self._cancel.is_set,
                                on_pass=on_pass, on_renderer=self._set_renderer)
                self.points[sampler] = pts
                try:
                    self.fits[sampler] = fit_convergence(pts, pixel_scale=self.pixel_scale)
                except ModelError as e:
                    raise ModelError(f"{sampler} pilot: {e}") from None
            self.fraction = 1.0

        def settings(self):
            """The scene's coherent_quality, or None if the scene is gone (main thread only)."""
            scene = bpy.data.scenes.get(self.scene_name)
            return scene.coherent_quality if scene is not None else None

        def store(self):
            """Writes the table into scene.coherent_quality (main thread only)."""
            st = self.settings()
            if st is None:
                raise ModelError(f"scene '{self.scene_name}' no longer exists")
            rows = predict_table(self.fits, self.levels)
            st.rows.clear()
            for level, cells, fastest in rows:
                row = st.rows.add()
                row.error = level
                row.spp = [cells[s].spp for s in SAMPLERS]
                row.seconds = [cells[s].seconds for s in SAMPLERS]
                row.fastest = fastest
            st.fits.clear()
            for s in SAMPLERS:
                f, info = self.fits[s], st.fits.add()
                info.sampler = s
                info.c = f.c
                info.exponent = f.exponent
                info.seconds_per_pass = f.seconds_per_pass * f.pixel_scale
                info.pilot_spp = f.pilot_spp
                info.pilot_seconds = f.pilot_seconds
            st.film_size = self.film
            st.pilot_size = (self.pilot_w, self.pilot_h)
            st.status = (f"Pilots at {self.pilot_w}x{self.pilot_h}, times for {self.film[0]}x{self.film[1]} "
                         f"(render only, no export or BVH build)")
            if self.pixel_scale > 1.0:
                st.status += "; scaled-down pilots predict high"
            if self.adaptive:
                st.status += "; predicted without Adaptive Sampling"

    # The estimate running interactively, for the Cancel button; at most one
    # (the operator's poll refuses a second). Module state rather than a scene
    # property: a saved file must never claim an estimate is running.
    _active_job = None
    _active_thread = None

    def _stop_active_job():
        """Cancels and joins the interactive estimate's thread, if any (prompt:
        cancelling a render takes well under a second). Used when the add-on
        is unregistered and at interpreter exit, so no pilot thread calls into
        a Python that is shutting down."""
        global _active_job, _active_thread
        job, thread = _active_job, _active_thread
        _active_job = _active_thread = None
        if job is not None:
            job.cancel()
        if thread is not None and thread.is_alive():
            thread.join()

    atexit.register(_stop_active_job)

    class COHERENT_OT_estimate_quality_cost(bpy.types.Operator):
        """Render a short pilot per sampler and predict the time to reach each error level"""
        bl_idname = "coherent.estimate_quality_cost"
        bl_label = "Estimate Quality Cost"
        bl_options = {"REGISTER"}

        _job = None
        _thread = None
        _timer = None
        _error = None

        @classmethod
        def poll(cls, context):
            return context.scene is not None and _active_job is None

        def _prepare(self, context):
            try:
                return _PilotJob(context)
            except (ModelError, ImportError, RuntimeError) as e:  # ExportError is a RuntimeError
                self.report({"ERROR"}, f"Coherent: {e}")
                return None

        def _finish(self, context, job, error):
            global _active_job, _active_thread
            if _active_job is job:
                _active_job = _active_thread = None
            for w in job.warnings:
                self.report({"WARNING"}, w)
            if error is None:
                try:
                    job.store()
                except ModelError as e:
                    error = e
            st = job.settings()
            if isinstance(error, InterruptedError):
                message = "quality estimate cancelled"
                if st is not None:
                    st.status = "Estimate cancelled"
                self.report({"WARNING"}, "Coherent: " + message)
                return {"CANCELLED"}
            if error is not None:
                if st is not None:
                    st.status = f"Estimate failed: {error}"
                self.report({"ERROR"}, f"Coherent: {error}")
                return {"CANCELLED"}
            self.report({"INFO"}, "Coherent: " + st.status)
            return {"FINISHED"}

        # Blocking (scripts, background mode, tests): freezes the UI for the pilot budget only.
        def execute(self, context):
            job = self._prepare(context)
            if job is None:
                return {"CANCELLED"}
            wm = context.window_manager
            wm.progress_begin(0.0, 1.0)
            error = None
            try:
                job.run()
            except (ModelError, InterruptedError, RuntimeError) as e:
                error = e
            finally:
                wm.progress_end()
            return self._finish(context, job, error)

        # Interactive: pilots on a worker thread, a timer reports progress, Esc cancels.
        def invoke(self, context, event):
            job = self._prepare(context)
            if job is None:
                return {"CANCELLED"}
            global _active_job, _active_thread
            self._job, self._error = job, None
            _active_job = job
            context.scene.coherent_quality.status = "Estimating..."

            def work():
                try:
                    job.run()
                except BaseException as e:  # noqa: BLE001 - handed to the main thread
                    self._error = e

            self._thread = threading.Thread(target=work, name="coherent-quality-pilot", daemon=True)
            _active_thread = self._thread
            self._thread.start()
            wm = context.window_manager
            wm.progress_begin(0.0, 1.0)
            self._timer = wm.event_timer_add(0.1, window=context.window)
            wm.modal_handler_add(self)
            return {"RUNNING_MODAL"}

        def modal(self, context, event):
            job = self._job
            if event.type == "ESC":
                job.cancel()
                return {"RUNNING_MODAL"}  # the thread ends promptly; finish on the next timer tick
            if event.type != "TIMER":
                return {"PASS_THROUGH"}
            wm = context.window_manager
            wm.progress_update(job.fraction)
            st = job.settings()
            if st is not None:
                st.status = f"Estimating: {job.current} pilot ({job.fraction:.0%}), Esc cancels"
            for area in context.screen.areas if context.screen else ():
                if area.type == "PROPERTIES":
                    area.tag_redraw()
            if self._thread.is_alive():
                return {"RUNNING_MODAL"}
            self._thread.join()
            wm.event_timer_remove(self._timer)
            wm.progress_end()
            result = self._finish(context, job, self._error)
            for area in context.screen.areas if context.screen else ():
                area.tag_redraw()
            return result

        def cancel(self, context):
            # Blender ends the modal operator (file load, window closed): stop the thread.
            global _active_job, _active_thread
            if self._job is not None:
                self._job.cancel()
                if _active_job is self._job:
                    _active_job = _active_thread = None
            if self._thread is not None:
                self._thread.join()
            if self._timer is not None:
                context.window_manager.event_timer_remove(self._timer)
                context.window_manager.progress_end()

    class COHERENT_OT_cancel_quality_cost(bpy.types.Operator):
        """Stop the running quality estimate (as Esc does)"""
        bl_idname = "coherent.cancel_quality_cost"
        bl_label = "Cancel Estimate"

        @classmethod
        def poll(cls, context):
            return _active_job is not None

        def execute(self, context):
            _active_job.cancel()
            return {"FINISHED"}

    class COHERENT_OT_apply_quality_choice(bpy.types.Operator):
        """Use this sampler and stop the final render at this error level (raises Samples so that the \
Target Error decides)"""
        bl_idname = "coherent.apply_quality_choice"
        bl_label = "Apply Quality Choice"
        bl_options = {"REGISTER", "UNDO"}

        row: IntProperty(name="Row", min=0)
        sampler: EnumProperty(name="Sampler", items=_SAMPLER_ITEMS)

        def execute(self, context):
            scene = context.scene
            rows = scene.coherent_quality.rows
            if self.row >= len(rows):
                self.report({"ERROR"}, "Coherent: no such row in the quality table; estimate first")
                return {"CANCELLED"}
            row = rows[self.row]
            i = SAMPLERS.index(self.sampler)
            props = scene.coherent
            props.sampler = self.sampler
            props.target_error = row.error
            # Headroom over the prediction: the error estimate is noisy and
            # the samples limit must not end the render before the target.
            needed = min(2 * row.spp[i], 1 << 24)
            if props.samples < needed:
                props.samples = needed
            if 0.0 < props.time_limit < row.seconds[i]:
                self.report({"WARNING"}, f"Coherent: the Time Limit ({format_duration(props.time_limit)}) "
                                         f"is shorter than the predicted {format_duration(row.seconds[i])}")
            self.report({"INFO"}, f"Coherent: sampler {self.sampler}, target error {row.error:.1%}, "
                                  f"samples {props.samples}")
            return {"FINISHED"}

    class RENDER_PT_coherent_quality_cost(bpy.types.Panel):
        bl_label = "Quality Cost"
        bl_space_type = "PROPERTIES"
        bl_region_type = "WINDOW"
        bl_context = "render"
        bl_parent_id = "RENDER_PT_coherent_sampling"
        bl_options = {"DEFAULT_CLOSED"}
        COMPAT_ENGINES = {"COHERENT"}

        @classmethod
        def poll(cls, context):
            return context.engine in cls.COMPAT_ENGINES

        def draw(self, context):
            layout = self.layout
            st = context.scene.coherent_quality
            col = layout.column(align=True)
            col.use_property_split = True
            col.use_property_decorate = False
            col.prop(st, "levels")
            col.prop(st, "pilot_seconds")
            col.prop(st, "pilot_max_pixels")
            if _active_job is not None:
                layout.operator(COHERENT_OT_cancel_quality_cost.bl_idname, icon="CANCEL")
            else:
                layout.operator(COHERENT_OT_estimate_quality_cost.bl_idname, icon="TIME")
            if st.status:
                layout.label(text=st.status)
            if not st.rows:
                return
            grid = layout.grid_flow(row_major=True, columns=len(SAMPLERS) + 1, even_columns=True, align=True)
            grid.label(text="Error")
            for s in SAMPLERS:
                grid.label(text=s)
            for r, row in enumerate(st.rows):
                grid.label(text=f"{row.error:.1%}")
                for i, s in enumerate(SAMPLERS):
                    fastest = s == row.fastest
                    op = grid.operator(COHERENT_OT_apply_quality_choice.bl_idname, depress=fastest,
                                       icon="CHECKMARK" if fastest else "NONE",
                                       text=f"{format_duration(row.seconds[i])} · {row.spp[i]} spp")
                    op.row = r
                    op.sampler = s
            layout.label(text="Click a cell to use its sampler and error level.", icon="INFO")
            sub = layout.column(align=True)
            sub.scale_y = 0.8
            for f in st.fits:
                sub.label(text=f"{f.sampler}: {f.pilot_spp} passes in {f.pilot_seconds:.2f} s, "
                               f"{format_duration(f.seconds_per_pass)} per pass, fitted exponent {f.exponent:.2f}")

    classes = (CoherentQualityRow, CoherentQualityFitInfo, CoherentQualitySettings,
               COHERENT_OT_estimate_quality_cost, COHERENT_OT_cancel_quality_cost, COHERENT_OT_apply_quality_choice,
               RENDER_PT_coherent_quality_cost)

    def register():
        for cls in classes:
            bpy.utils.register_class(cls)
        bpy.types.Scene.coherent_quality = PointerProperty(type=CoherentQualitySettings,
                                                           name="Coherent Quality Cost")

    def unregister():
        _stop_active_job()
        if hasattr(bpy.types.Scene, "coherent_quality"):
            del bpy.types.Scene.coherent_quality
        for cls in reversed(classes):
            bpy.utils.unregister_class(cls)
