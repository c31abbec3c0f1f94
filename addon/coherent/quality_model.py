# SPDX-License-Identifier: Apache-2.0
"""The model behind "what does quality cost": predicted render time to each error level, per sampler.

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

Plain Python: no bpy, and the native module only as an argument of
run_pilot, so the model is unit-tested (tests/cli/test_quality_model.py) and
used by bench/quality_prediction.py outside Blender. The Blender side lives
where Cycles keeps it: the settings in properties.py, the estimate operators
in operators.py, the Quality Cost panel in ui.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

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
        check_level(error)
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


def check_level(error):
    """Raises ModelError unless `error` is a usable error level: a finite number > 0."""
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
        check_level(level)
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
                  target_error=0.0, time_limit=0.0, progressive_display=False, adaptive=False,
                  error_estimate="exact")  # the model fits the error itself, not a bound
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
