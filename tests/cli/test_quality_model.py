"""The "what does quality cost" model (addon/coherent/quality_model.py) in plain Python.

quality_model.py does not import bpy, so it is loaded here straight from the
file, without Blender and without the add-on package (whose __init__ needs
bpy). Run: python3 -m pytest -q tests/cli/test_quality_model.py
"""
import importlib.util
import math
import random
import sys
from pathlib import Path

import numpy as np
import pytest

from seeds import seeded

REPO = Path(__file__).resolve().parents[2]


def _load_quality():
    path = REPO / "addon" / "coherent" / "quality_model.py"
    spec = importlib.util.spec_from_file_location("coherent_quality_model", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


q = _load_quality()


def exact_points(c=0.9, per_pass=0.01, overhead=0.0, passes=32):
    """The 1/sqrt(spp) law without noise; the first pass has no estimate, as in a real render."""
    pts = [(overhead + per_pass, 1, None)]
    pts += [(overhead + per_pass * n, n, c / math.sqrt(n)) for n in range(2, passes + 1)]
    return pts


def test_module_has_no_blender_part_without_bpy():
    # Loading it above ran without Blender; no Blender part may hide behind an optional import either.
    assert not hasattr(q, "bpy")
    assert not hasattr(q, "register")


def test_exact_data_recovers_the_model():
    fit = q.fit_convergence(exact_points(c=0.9, per_pass=0.01))
    assert fit.c == pytest.approx(0.9, rel=1e-12)
    assert fit.exponent == pytest.approx(-0.5, abs=1e-12)
    assert fit.seconds_per_pass == pytest.approx(0.01, rel=1e-9)
    assert fit.overhead == pytest.approx(0.0, abs=1e-9)
    assert fit.pilot_spp == 32 and fit.pilot_seconds == pytest.approx(0.32)
    # 31 points carry an estimate; the later half (16) is fitted.
    assert fit.points_used == 16
    # (0.9 / 0.05)^2 = 324 passes exactly, already even.
    assert fit.spp_for(0.05) == 324
    assert fit.seconds_for(0.05) == pytest.approx(3.24, rel=1e-9)
    assert fit.error_at_spp(324) == pytest.approx(0.05, rel=1e-12)


def test_overhead_and_time_per_pass_recovered():
    fit = q.fit_convergence(exact_points(c=0.5, per_pass=0.05, overhead=0.2))
    assert fit.seconds_per_pass == pytest.approx(0.05, rel=1e-9)
    assert fit.overhead == pytest.approx(0.2, rel=1e-9)
    assert fit.seconds_for_spp(100) == pytest.approx(0.2 + 5.0, rel=1e-9)


def test_pixel_scale_multiplies_pass_time_not_samples():
    one = q.fit_convergence(exact_points(c=0.7, per_pass=0.02))
    four = q.fit_convergence(exact_points(c=0.7, per_pass=0.02), pixel_scale=4.0)
    for level in (0.1, 0.03):
        assert four.spp_for(level) == one.spp_for(level)
        assert four.seconds_for(level) == pytest.approx(4.0 * one.seconds_for(level), rel=1e-9)


def test_spp_rounds_up_to_even_counts():
    # c chosen so (c / E)^2 lands below, on and above an even count.
    for n_exact, expected in ((7.2, 8), (8.0, 8), (8.01, 10), (0.3, 2), (1.0, 2)):
        fit = q.ConvergenceFit(c=math.sqrt(n_exact) * 0.1, exponent=-0.5, seconds_per_pass=1.0, overhead=0.0,
                               pixel_scale=1.0, points_used=2, pilot_spp=2, pilot_seconds=2.0)
        assert fit.spp_for(0.1) == expected, n_exact


def test_only_the_later_half_is_fitted():
    # Early passes with three times the error (e.g. an estimate still settling)
    # must not move the fit: they are in the discarded first half.
    pts = exact_points(c=0.9, passes=33)
    pts = [(s, n, None if e is None else (3.0 * e if n <= 16 else e)) for s, n, e in pts]
    fit = q.fit_convergence(pts)
    assert fit.c == pytest.approx(0.9, rel=1e-12)
    # With every point fitted, the early ones do move it.
    assert q.fit_convergence(pts, tail_fraction=1.0).c > 1.1


def test_free_exponent_matches_numpy_polyfit():
    rng = random.Random(3)
    pts = [(0.01 * n, n, 0.8 * n ** -0.45 * math.exp(rng.gauss(0, 0.1))) for n in range(2, 66)]
    fit = q.fit_convergence(pts)
    tail = pts[-fit.points_used:]
    slope, _ = np.polyfit(np.log([n for _, n, _ in tail]), np.log([e for _, _, e in tail]), 1)
    assert fit.exponent == pytest.approx(slope, rel=1e-9)
    # c with the exponent fixed at -1/2 is the geometric mean of e * sqrt(n).
    expected_c = math.exp(np.mean([math.log(e * math.sqrt(n)) for _, n, e in tail]))
    assert fit.c == pytest.approx(expected_c, rel=1e-12)


def test_noisy_data_stays_within_statistical_bounds():
    # Log-normal noise of 10 % on 63 estimates: log c is the mean of 32 of
    # them, standard deviation 0.1 / sqrt(32) = 0.018. Over 300 seeded trials
    # every estimate must stay within 5 sigma (chance of failing ~ 1e-4 in all),
    # and the predicted samples (proportional to c^2) within 10 sigma.
    sigma, c, worst = 0.1, 0.9, 0.0
    bound = 5 * sigma / math.sqrt(32)
    for seed in range(300):
        rng = random.Random(seeded(seed))
        pts = [(0.01 * n * (1 + 0.05 * rng.random()), n, c / math.sqrt(n) * math.exp(rng.gauss(0, sigma)))
               for n in range(2, 65)]
        fit = q.fit_convergence(pts)
        assert fit.points_used == 32
        err = abs(math.log(fit.c / c))
        worst = max(worst, err)
        assert err < bound, (seed, fit.c)
        assert abs(math.log(fit.spp_for(0.02) / (c / 0.02) ** 2)) < 2 * bound + 1e-3
        assert fit.seconds_per_pass > 0 and math.isfinite(fit.seconds_for(0.02))
    assert worst > 0.0  # the noise really reached the fit


def test_fewer_than_two_points_is_a_clear_error():
    with pytest.raises(q.ModelError, match="at least 2"):
        q.fit_convergence([])
    with pytest.raises(q.ModelError, match="at least 2"):
        q.fit_convergence([(0.1, 1, None), (0.2, 2, 0.5)])
    with pytest.raises(q.ModelError, match="at least 2"):
        q.fit_convergence([(0.1, 1, None), (0.2, 2, None), (0.3, 3, None)])


def test_zero_error_is_a_clear_error():
    pts = [(0.01 * n, n, 0.0) for n in range(2, 10)]
    with pytest.raises(q.ModelError, match="zero"):
        q.fit_convergence(pts)
    assert issubclass(q.ModelError, ValueError)


@pytest.mark.parametrize("bad", [
    [(0.1, 2, float("nan")), (0.2, 4, 0.3)],
    [(0.1, 2, -0.1), (0.2, 4, 0.3)],
    [(float("inf"), 2, 0.4), (0.2, 4, 0.3)],
    [(-1.0, 2, 0.4), (0.2, 4, 0.3)],
    [(0.1, 0, 0.4), (0.2, 4, 0.3)],
    [(0.1, 4, 0.4), (0.2, 4, 0.3)],
    [(0.1, 4)],
])
def test_invalid_points_are_rejected(bad):
    with pytest.raises(q.ModelError):
        q.fit_convergence(bad)


def test_invalid_arguments_are_rejected():
    pts = exact_points()
    for scale in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(q.ModelError, match="pixel_scale"):
            q.fit_convergence(pts, pixel_scale=scale)
    with pytest.raises(q.ModelError, match="tail_fraction"):
        q.fit_convergence(pts, tail_fraction=0.0)
    fit = q.fit_convergence(pts)
    for level in (0.0, -0.1, float("nan"), float("inf"), None):
        with pytest.raises(q.ModelError, match="error level"):
            fit.spp_for(level)
    with pytest.raises(q.ModelError, match="out of reach"):
        fit.spp_for(1e-12)


def test_points_are_ordered_by_spp():
    pts = exact_points(c=0.6)
    assert q.fit_convergence(list(reversed(pts))) == q.fit_convergence(pts)


def test_constant_timer_falls_back_to_mean_pass_time():
    # All passes reported at the same instant (a coarse timer): the slope is 0,
    # the mean time per pass is used instead of predicting zero seconds.
    pts = [(0.5, n, 0.9 / math.sqrt(n)) for n in range(2, 12)]
    fit = q.fit_convergence(pts)
    assert fit.seconds_per_pass == pytest.approx(0.5 / 11)
    assert fit.overhead == 0.0
    with pytest.raises(q.ModelError, match="no measurable time"):
        q.fit_convergence([(0.0, n, 0.9 / math.sqrt(n)) for n in range(2, 12)])


def test_predict_table_orders_levels_and_picks_the_fastest():
    fits = {
        "SPT": q.fit_convergence(exact_points(c=0.9, per_pass=0.010)),
        "CPT": q.fit_convergence(exact_points(c=0.9, per_pass=0.008)),   # same error, faster passes
        "ICPT": q.fit_convergence(exact_points(c=1.2, per_pass=0.008)),  # faster passes, more error
    }
    rows = q.predict_table(fits, levels=(0.2, 0.1, 0.05))
    assert [level for level, _, _ in rows] == [0.2, 0.1, 0.05]
    for level, cells, fastest in rows:
        assert fastest == "CPT"
        assert cells["CPT"].spp == cells["SPT"].spp < cells["ICPT"].spp
        assert all(p.seconds > 0 and math.isfinite(p.seconds) and p.error == level for p in cells.values())
    # A loose level costs less than a tight one, by 4x in samples per halving.
    for s in fits:
        assert rows[0][1][s].seconds < rows[1][1][s].seconds < rows[2][1][s].seconds
        assert rows[2][1][s].spp == pytest.approx(4 * rows[1][1][s].spp, abs=8)  # both rounded up to even
    with pytest.raises(q.ModelError):
        q.predict_table({}, levels=(0.1,))
    with pytest.raises(q.ModelError):
        q.predict_table(fits, levels=(0.1, 0.0))


def test_pilot_resolution():
    assert q.pilot_resolution(512, 512) == (512, 512, 1.0)  # the default pilots 512x512 at full size
    assert q.pilot_resolution(100, 80, max_pixels=10000) == (100, 80, 1.0)
    w, h, scale = q.pilot_resolution(512, 512, max_pixels=160 * 160)
    assert (w, h) == (160, 160) and scale == pytest.approx(512 * 512 / (160 * 160))
    w, h, scale = q.pilot_resolution(1920, 1080, max_pixels=160 * 160)
    assert abs(w / h - 1920 / 1080) < 0.02
    assert w * h <= 160 * 160 * 1.02
    assert scale == pytest.approx(1920 * 1080 / (w * h))
    assert q.pilot_resolution(10000, 1, max_pixels=100)[1] == 1  # never below one pixel
    with pytest.raises(q.ModelError):
        q.pilot_resolution(0, 10)


def test_format_duration():
    assert q.format_duration(0.4217) == "0.42 s"
    assert q.format_duration(4.26) == "4.3 s"
    assert q.format_duration(42.4) == "42 s"
    assert q.format_duration(185) == "3 min 05 s"
    assert q.format_duration(7560) == "2.1 h"
    assert q.format_duration(3 * 86400) == "3.0 days"
    assert q.format_duration(float("nan")) == "n/a"
    assert q.format_duration(-1) == "n/a"


# --- run_pilot's stopping logic, on a stand-in for the native Renderer ---------

class FakeRenderer:
    """Reports like the native Renderer: a report within each pass (same
    samples_done as before), then one at its end; pass n ends at n * dt."""

    def __init__(self, scene, **kwargs):
        self.kwargs = kwargs
        self.cancelled = False

    def cancel(self):
        self.cancelled = True

    def render(self, progress):
        dt = self.kwargs.pop("_dt", 0.1)
        for n in range(1, self.kwargs["spp"] + 1):
            within = dict(samples_done=n - 1, seconds=(n - 0.5) * dt, error_estimate=None)
            if not progress(within) or self.cancelled:
                return False
            end = dict(samples_done=n, seconds=n * dt, error_estimate=None if n < 2 else 0.8 / math.sqrt(n))
            if not progress(end) or self.cancelled:
                return False
        return True


class FakeNative:
    Renderer = FakeRenderer


def test_run_pilot_stops_at_budget_and_min_passes():
    made = []
    pts = q.run_pilot(FakeNative, None, 32, 24, "ICPT", {"threads": 1, "border": (0, 0, 1, 1)}, budget=1.0,
                      min_passes=4, on_renderer=lambda r: made.append(r))
    # Pass n ends at 0.1 n seconds: the budget is reached at pass 10.
    assert [n for _, n, _ in pts] == list(range(1, 11))
    assert pts[0][2] is None and pts[-1][2] == pytest.approx(0.8 / math.sqrt(10))
    r = made[0]
    assert made[1] is None  # handed back when done
    assert r.kwargs["sampler"] == "icpt" and r.kwargs["width"] == 32 and r.kwargs["height"] == 24
    assert r.kwargs["threads"] == 1 and "border" not in r.kwargs
    assert r.kwargs["target_error"] == 0.0 and r.kwargs["time_limit"] == 0.0
    fit = q.fit_convergence(pts)
    assert fit.c == pytest.approx(0.8, rel=1e-12)
    assert fit.seconds_per_pass == pytest.approx(0.1)


def test_run_pilot_takes_min_passes_past_the_budget():
    pts = q.run_pilot(FakeNative, None, 8, 8, "SPT", budget=0.05, min_passes=6)
    assert [n for _, n, _ in pts] == list(range(1, 7))


def test_run_pilot_cancel_raises():
    calls = []

    def cancelled():
        calls.append(1)
        return len(calls) > 5

    with pytest.raises(InterruptedError):
        q.run_pilot(FakeNative, None, 8, 8, "CPT", budget=10.0, cancelled=cancelled)
