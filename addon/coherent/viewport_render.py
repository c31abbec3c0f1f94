# SPDX-License-Identifier: Apache-2.0
"""Progressive restarts of the Rendered viewport's render.

After any change the image is rendered in stages, a coarse one first (at
most FIRST_STAGE_PIXELS pixels, 1 sample: it shows within tens of
milliseconds), then twice the resolution per stage, then the full viewport
resolution with the Viewport sample count (the Auto sampler is ICPT here:
each pass spreads its error evenly over the image, the paper's answer for
intermediate results). Each stage is one native Renderer running on its own
thread (Renderer.start()) over the scene sync's native scene; it never
touches Python.
"""

from __future__ import annotations

import math
import sys
import time

# Pixels of the first, coarse stage of a restarted render.
FIRST_STAGE_PIXELS = 16384


def progressive_stages(width, height, samples):
    """[(divisor, samples)] of a restart: coarse 1-sample stages, then the full resolution."""
    divisor = 1
    while math.ceil(width / divisor) * math.ceil(height / divisor) > FIRST_STAGE_PIXELS:
        divisor *= 2
    stages = []
    while divisor > 1:
        stages.append((divisor, 1))
        divisor //= 2
    stages.append((1, samples))
    return stages


class ProgressiveRender:
    """The running restart of one viewport: its stages and the current stage's Renderer."""

    def __init__(self, counters):
        self.renderer = None
        self.view_key = None         # what the running restart was started with
        self.stages = []
        self.stage = 0
        self.width, self.height = 1, 1
        self.counters = counters     # shared with the session (tests and benchmarks read them)
        # Timings, for tests and bench/viewport_latency.py.
        self.restart_time = None       # perf_counter() of the latest restart
        self.first_frame_seconds = None  # restart -> its first drawn frame
        self.final_seconds = None      # restart -> all samples drawn
        self.first_frame_at = None     # perf_counter() when the latest restart's first frame was drawn

    @property
    def final_stage(self):
        return self.stage + 1 == len(self.stages)

    def stop(self):
        """Cancels and joins the render thread (returns within a fraction of a pass)."""
        self._drop_renderer()
        self.view_key = None

    def restart(self, sync, scene, camera, width, height, view_key):
        """Starts over for a new view or scene: the first, coarsest stage."""
        self.stop()
        sync.scene.set_camera(**camera)
        self.view_key = view_key
        self.width, self.height = width, height
        self.stages = progressive_stages(width, height, scene.coherent.preview_samples)
        self.stage = 0
        self.restart_time = time.perf_counter()
        self.first_frame_seconds = None
        self.first_frame_at = None
        self.final_seconds = None
        self.counters["restarts"] += 1
        self._start_stage(sync, scene)

    def stage_finished(self):
        """Whether the current stage rendered all its samples and a finer one follows."""
        return self.renderer is not None and not self.renderer.running and not self.final_stage

    def next_stage(self, sync, scene):
        self.stage += 1
        self._start_stage(sync, scene)

    def note_first_frame(self):
        """The restart's first image was drawn."""
        if self.restart_time is not None:
            self.first_frame_at = time.perf_counter()
            self.first_frame_seconds = self.first_frame_at - self.restart_time

    def note_all_samples_drawn(self):
        if self.final_seconds is None and self.restart_time is not None:
            self.final_seconds = time.perf_counter() - self.restart_time

    def _start_stage(self, sync, scene):
        from . import native_module  # deferred: the package imports this module first

        native = native_module()
        self._drop_renderer()  # a finished stage's (keeps view_key: same restart)
        props = scene.coherent
        divisor, samples = self.stages[self.stage]
        kwargs = props.renderer_kwargs(scene)
        kwargs.update(width=max(1, math.ceil(self.width / divisor)), height=max(1, math.ceil(self.height / divisor)),
                      spp=samples, seed=props.seed, progressive_display=True,
                      # The viewport draws Combined only: no counters or feature passes to pay for,
                      # unless it is denoised.
                      heatmaps=False, denoising_data=False, denoise=props.use_preview_denoising)
        sync.ensure_bvh()
        self.renderer = native.Renderer(sync.scene, **kwargs)
        self.renderer.start()

    def _drop_renderer(self):
        renderer, self.renderer = self.renderer, None
        if renderer is None:
            return
        renderer.cancel()
        try:
            renderer.wait()
        except RuntimeError as e:  # a native error in the render: already reported in draw()
            print(f"Coherent: {e}", file=sys.stderr)
