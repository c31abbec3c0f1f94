"""Denoising through the Python module (_coherent), as the add-on uses it:
final renders (render() with a progress callback) and the viewport's
asynchronous path (start()/snapshot()/wait()). Imported as in test_module_api.py."""
import numpy as np

from test_module_api import native, small_scene

SIZE = dict(width=24, height=20)


def test_render_reports_denoising_and_keeps_the_noisy_image():
    # Denoising renders with paired scrambles (error_estimate exact): so must
    # the plain render whose image it keeps.
    plain = native.Renderer(small_scene(), spp=8, seed=5, error_estimate="exact", **SIZE)
    plain.render(None)
    reports = []
    # Uniform samples, as the plain render's (Distribute Samples would spread
    # the same number differently; tests/native/test_sample_distribution.cpp).
    r = native.Renderer(small_scene(), spp=8, seed=5, denoise=True, distribute_samples=False, **SIZE)
    assert r.render(lambda p: reports.append(p) or True)
    # Passes report no denoising; the denoiser reports after the last pass,
    # ending at 1, with samples_done unchanged.
    assert all(p["denoise_fraction"] is None for p in reports if p["samples_done"] < 8)
    fractions = [p["denoise_fraction"] for p in reports if p["denoise_fraction"] is not None]
    assert fractions and fractions[-1] == 1.0
    assert all(p["samples_done"] == 8 for p in reports if p["denoise_fraction"] is not None)
    np.testing.assert_array_equal(r.pass_pixels("Noisy Image"), plain.pass_pixels("Combined"))
    assert not np.array_equal(r.pass_pixels("Combined"), plain.pass_pixels("Combined"))
    stats, plain_stats = r.stats(), plain.stats()
    # (This world-lit floor is nearly noise-free: only the estimate's presence
    # is asserted here; tests/cli/test_denoise.py compares it with the truth.)
    assert stats["denoised_error_estimate"] >= 0.0 and stats["denoise_seconds"] > 0.0
    assert plain_stats["denoised_error_estimate"] is None and plain_stats["denoise_seconds"] == 0.0
    for name in ("Denoising Albedo", "Denoising Normal"):
        assert r.pass_pixels(name).shape == (24 * 20, 3)
        assert np.isfinite(r.pass_pixels(name)).all()
    # Without denoising the feature passes cost nothing and read as zero.
    assert not plain.pass_pixels("Denoising Albedo").any()


def test_viewport_snapshot_is_the_denoised_image():
    r = native.Renderer(small_scene(), spp=6, seed=5, denoise=True, progressive_display=True, **SIZE)
    r.start()
    assert r.wait()
    samples, pixels = r.snapshot(True)
    assert samples == 6
    np.testing.assert_array_equal(pixels, r.pass_pixels("Combined"))
    assert not np.array_equal(pixels, r.pass_pixels("Noisy Image"))


def test_viewport_snapshot_without_denoising_is_the_noisy_image():
    r = native.Renderer(small_scene(), spp=6, seed=5, progressive_display=True, **SIZE)
    r.start()
    assert r.wait()
    _, pixels = r.snapshot(True)
    np.testing.assert_array_equal(pixels, r.pass_pixels("Noisy Image"))
