# SPDX-License-Identifier: Apache-2.0
"""Cycles settings that make it a plain, unbiased path tracer comparable with ours.

Everything that would bias or smooth Cycles' estimate is off (adaptive
sampling, denoising, clamping, light threshold, glossy blur), caustics are on
and the pixel filter is a 1-pixel box, as in our film. Used by make_scenes.py
(written into the .blend files) and by tests/blender/render_for_agreement.py
(applied to any scene before comparing).
"""


def configure_cycles_reference(scene, samples):
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.use_animated_seed = False
    return c


def configure_comparison(scene, engine, samples, seed, limits):
    """Both engines as the per-scene agreement tests compare them: Cycles as
    above, COHERENT with the same samples, seed and bounce `limits` (a dict of
    the properties both engines name alike), independent pixels (SPT) and no
    clamping. `engine` is the one that renders next."""
    c = configure_cycles_reference(scene, samples)
    c.seed = seed
    for key, value in limits.items():
        setattr(c, key, value)
    if engine == "COHERENT":
        s = scene.coherent
        s.samples = samples
        s.seed = seed
        s.sampler = "SPT"
        s.clamp_direct = s.clamp_indirect = 0.0
        for key, value in limits.items():
            setattr(s, key, value)
