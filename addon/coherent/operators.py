# SPDX-License-Identifier: Apache-2.0
"""Operators: the Quality Cost estimate (pilot renders, quality_model.py's fit)
and applying a choice from its table.

An estimate is prepared on the main thread (_PilotJob: the export reads the
depsgraph) and its pilots render either there (execute: scripts, background
mode) or on a worker thread (invoke: a modal operator whose timer reports
progress, Esc or the Cancel button stop it). Results are written into
scene.coherent_quality (properties.py) on the main thread; ui.py draws them.
"""

from __future__ import annotations

import atexit
import threading
import time

import bpy
from bpy.props import EnumProperty, IntProperty

from . import engine, export
from .properties import QUALITY_SAMPLER_ITEMS
from .quality_model import (SAMPLERS, ModelError, check_level, fit_convergence, format_duration, pilot_resolution,
                            predict_table, run_pilot)


def _film_size(scene):
    width, height = engine.render_size(scene.render)
    border = engine.border_pixels(scene.render, width, height)
    film = (border[2] - border[0], border[3] - border[1]) if border else (width, height)
    return width, height, film


class _PilotJob:
    """Everything an estimate needs, prepared on the main thread (export
    reads the depsgraph); run() only touches the native scene, so it may
    run on a worker thread."""

    def __init__(self, context):
        from . import native_module  # deferred: the package imports this module first

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
            check_level(level)
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
    sampler: EnumProperty(name="Sampler", items=QUALITY_SAMPLER_ITEMS)

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


def quality_estimate_running():
    """Whether an interactive estimate is running (the panel then offers Cancel)."""
    return _active_job is not None


classes = (COHERENT_OT_estimate_quality_cost, COHERENT_OT_cancel_quality_cost, COHERENT_OT_apply_quality_choice)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    _stop_active_job()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
