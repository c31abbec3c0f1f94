# SPDX-License-Identifier: Apache-2.0
"""Settings stored in the .blend file: `scene.coherent` (render settings) and
`scene.coherent_quality` (the Quality Cost estimate's settings and table)."""

from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, IntVectorProperty, PointerProperty, StringProperty)

from .quality_model import (DEFAULT_LEVELS, DEFAULT_MIN_PASSES, DEFAULT_PILOT_MAX_PIXELS, DEFAULT_PILOT_SECONDS,
                            SAMPLERS)


class CoherentRenderSettings(bpy.types.PropertyGroup):
    samples: IntProperty(
        name="Samples", description="Samples per pixel for final renders",
        default=64, min=1, max=1 << 24, soft_max=4096)
    preview_samples: IntProperty(
        name="Viewport Samples", description="Samples per pixel for viewport renders",
        default=16, min=1, max=1 << 24, soft_max=1024)
    # Stopping rules for final renders; whichever of Samples, Target Error
    # and Time Limit comes first ends the render.
    target_error: FloatProperty(
        name="Target Error", description="Stop the final render once its estimated relative RMSE (from the "
                                         "even and odd sample passes, no reference needed) is at most this; "
                                         "0 = off",
        default=0.0, min=0.0, max=10.0, soft_max=0.2, step=0.1, precision=3, subtype="FACTOR")
    time_limit: FloatProperty(
        name="Time Limit", description="Stop the final render after the sample pass that ends past this many "
                                       "seconds; 0 = off",
        default=0.0, min=0.0, soft_max=3600.0, unit="TIME_ABSOLUTE", subtype="TIME_ABSOLUTE")
    write_convergence: BoolProperty(
        name="Write Convergence", description="After a final render, write <output path>_convergence.csv "
                                              "(seconds, samples and estimated error of every sample pass) next "
                                              "to the render output, to see what accuracy costs in time "
                                              "(plot it with `coherent plot`)",
        default=False)
    use_pass_error: BoolProperty(
        name="Error", description="Write an 'Error' pass: per pixel, the estimated RMS error of the rendered "
                                  "radiance (from the even and odd sample passes)",
        default=False)

    seed: IntProperty(
        name="Seed", description="Seed of the sample sequences; renders with equal seeds are identical",
        default=0, min=0)
    use_animated_seed: BoolProperty(
        name="Animated Seed", description="Combine the seed with the frame number so noise changes per frame",
        default=False)

    # Random sequences (Sadeghi et al. 2009, "Coherent Path Tracing").
    sampler: EnumProperty(
        name="Sampler", description="How the random numbers of paths are shared between pixels",
        items=(
            ("SPT", "SPT", "Standard path tracing: an independent random sequence per pixel and sample"),
            ("CPT", "CPT", "Coherent path tracing: one sequence per sample shared by every pixel; coherent "
                           "secondary rays, structured noise that vanishes at high sample counts"),
            ("ICPT", "ICPT", "Interleaved coherent path tracing: packet blocks split into randomised "
                             "Latin-hypercube subsets that share sequences; hides CPT's structured noise"),
            ("AUTO", "Auto", "ICPT in the viewport and for final renders below 256 samples, CPT above"),
        ),
        default="AUTO")
    packet_size: IntVectorProperty(
        name="Packet Size", description="Ray packet size in pixels (width, height); ICPT uses square blocks "
                                        "of the shorter side",
        size=2, default=(4, 4), min=1, max=16)

    # Adaptive sampling (final renders and the viewport).
    use_adaptive_sampling: BoolProperty(
        name="Adaptive Sampling", description="Stop sampling a pixel once its estimated relative error, and its "
                                              "3x3 neighbours', is below the noise threshold",
        default=False)
    adaptive_threshold: FloatProperty(
        name="Noise Threshold", description="Relative per-pixel error (estimated from the even and odd sample "
                                            "passes) at which a pixel stops taking samples",
        default=0.01, min=0.0001, max=1.0, soft_max=0.1, step=0.1, precision=4)
    adaptive_min_samples: IntProperty(
        name="Min Samples", description="Samples every pixel takes before adaptive sampling may stop it "
                                        "(rounded up to an even number)",
        default=16, min=2, max=1 << 24, soft_max=4096)

    # Light transport and tracing (native/render/render_modes.h). Enum
    # identifiers are the native names in upper case: renderer_kwargs lowers them.
    integrator: EnumProperty(
        name="Integrator", description="Which light transport is computed",
        items=(
            ("PT", "Path Tracing", "Full global illumination: path tracing with next-event estimation and "
                                   "multiple importance sampling"),
            ("DRT", "Distribution", "Distribution ray tracing: soft shadows from area lights, glossy "
                                    "reflection and refraction, depth of field; no diffuse interreflection"),
            ("WRT", "Whitted", "Whitted ray tracing: direct light, paths continue through mirrors and "
                               "glass only"),
            ("RCS", "Ray Casting", "Ray casting with shadows: direct light at the first hit only"),
            ("AO", "Ambient Occlusion", "Fraction of cosine-distributed rays from the first hit that escape "
                                        "within the AO distance (white = unoccluded)"),
        ),
        default="PT")
    traversal: EnumProperty(
        name="Traversal", description="How rays are traced through the BVH; every mode finds the same hits",
        items=(
            ("AUTO", "Auto", "Packets with the CPT sampler (where they pay, measured), single rays otherwise"),
            ("SINGLE", "Single Rays", "One ray at a time over a BVH of the chosen width"),
            ("PACKET", "Packets", "SIMD packets of the rays of Packet Size pixels, secondary rays assembled "
                                  "by Assembly"),
            ("STREAM", "Streams", "Breadth-first ray streams with per-node ray queues over the wide BVH"),
            ("WAVEFRONT", "Wavefront", "Staged pipeline (generate, extend, reorder, shade, shadow) over waves "
                                       "of paths, reordered by Reorder"),
        ),
        default="AUTO")
    assembly: EnumProperty(
        name="Assembly", description="Packet traversal: how secondary rays are grouped into packets",
        items=(
            ("TYPES", "Ray Types", "One packet per ray type (shadow, diffuse, glossy, reflection, refraction)"),
            ("RUNS", "Runs", "Consecutive rays of the same type in pixel order form a packet"),
        ),
        default="TYPES")
    bvh_width: EnumProperty(
        name="BVH Width", description="Branching factor of the BVH for single-ray and stream traversal",
        items=(("2", "2", "Binary BVH"), ("4", "4", "4-wide BVH"), ("8", "8", "8-wide BVH")),
        default="8")
    reorder: EnumProperty(
        name="Reorder", description="Wavefront traversal: how rays are sorted for coherence before tracing",
        items=(
            ("NONE", "None", "Trace rays in the order paths produced them"),
            ("STATIC1D", "Static 1D", "Pixel order along a Morton curve"),
            ("STATIC3D", "Static 3D", "Morton order of the ray origins"),
            ("HASH32", "Hash 32", "32-bit keys of origin and direction bits, radix sorted"),
            ("HASH192", "Hash 192", "192-bit keys of origin and direction bits, radix sorted"),
            ("CSD32", "CSD 32", "Compress-sort-decompress of 32-bit keys"),
        ),
        default="NONE")
    wave_size: IntProperty(
        name="Wave Size", description="Wavefront traversal: paths in flight per wave (bounds memory)",
        default=1 << 16, min=1, max=1 << 24, soft_min=1024, soft_max=1 << 20)
    ao_samples: IntProperty(
        name="AO Samples", description="Ambient occlusion: occlusion rays per camera sample",
        default=16, min=1, max=4096, soft_max=256)
    ao_distance: FloatProperty(
        name="AO Distance", description="Ambient occlusion: length of occlusion rays; 0 = a tenth of the "
                                        "scene's bounding-box diagonal",
        default=0.0, min=0.0, soft_max=100.0, subtype="DISTANCE", unit="LENGTH")

    # Diagnostic heatmap passes (view layer panel).
    use_pass_bvh_visits: BoolProperty(
        name="BVH Visits", description="Write a 'BVH Visits' pass: BVH node visits per camera sample, all "
                                       "rays of the sample's path (where traversal is expensive)",
        default=False)
    use_pass_simd_utilisation: BoolProperty(
        name="SIMD Utilisation", description="Write a 'SIMD Utilisation' pass: the mean fraction, 0..1, of "
                                             "SIMD lanes holding an active ray in the packets that traced the "
                                             "pixel (where coherence is lost); 1 for single rays",
        default=False)

    max_bounces: IntProperty(
        name="Total", description="Maximum number of bounces of any kind",
        default=12, min=0, max=1024)
    diffuse_bounces: IntProperty(
        name="Diffuse", description="Maximum number of diffuse reflection bounces",
        default=4, min=0, max=1024)
    glossy_bounces: IntProperty(
        name="Glossy", description="Maximum number of glossy reflection bounces",
        default=4, min=0, max=1024)
    transmission_bounces: IntProperty(
        name="Transmission", description="Maximum number of transmission (refraction) bounces",
        default=12, min=0, max=1024)

    threads: IntProperty(
        name="Threads", description="Render threads; 0 uses Blender's Performance > Threads setting "
                                    "(all cores when set to Auto-Detect)",
        default=0, min=0, max=1024)
    tile_size: IntProperty(
        name="Tile Size", description="Edge length in pixels of the image tiles threads work on",
        default=32, min=4, max=1024)

    def renderer_kwargs(self, scene):
        """Keyword arguments of _coherent.Renderer that the final render and
        the viewport share: light paths, threads, tiles, film, sampler,
        adaptive sampling, integrator and traversal, and whether the heatmap
        passes are filled.

        Front ends add size, samples, seed and progressive_display (True in
        the viewport, which makes AUTO pick ICPT); the viewport turns
        heatmaps off (it shows Combined only).
        """
        threads = self.threads
        if threads == 0 and scene.render.threads_mode == "FIXED":
            threads = scene.render.threads
        return dict(threads=threads, max_bounces=self.max_bounces, diffuse_bounces=self.diffuse_bounces,
                    glossy_bounces=self.glossy_bounces, transmission_bounces=self.transmission_bounces,
                    transparent=scene.render.film_transparent, tile_size=self.tile_size,
                    sampler=self.sampler.lower(), packet=(int(self.packet_size[0]), int(self.packet_size[1])),
                    adaptive=self.use_adaptive_sampling, adaptive_threshold=self.adaptive_threshold,
                    adaptive_min_samples=self.adaptive_min_samples,
                    integrator=self.integrator.lower(), traversal=self.traversal.lower(),
                    assembly=self.assembly.lower(), bvh_width=int(self.bvh_width), reorder=self.reorder.lower(),
                    wave_size=self.wave_size, ao_samples=self.ao_samples, ao_distance=self.ao_distance,
                    heatmaps=self.use_pass_bvh_visits or self.use_pass_simd_utilisation)

    def seed_for_frame(self, frame):
        """The sampler seed for `frame`: constant unless use_animated_seed."""
        if not self.use_animated_seed:
            return self.seed
        # Cycles' hash_uint2(frame, seed) role: decorrelate consecutive frames.
        h = (self.seed * 0x9E3779B1 + (frame & 0xFFFFFFFF) * 0x85EBCA77) & 0xFFFFFFFFFFFFFFFF
        h ^= h >> 29
        return h


# --- Quality Cost (quality_model.py, operators.py) --------------------------------

QUALITY_SAMPLER_ITEMS = tuple((s, s, "") for s in SAMPLERS)


class CoherentQualityRow(bpy.types.PropertyGroup):
    """One error level of the table: predicted spp and seconds per sampler (SAMPLERS order)."""
    error: FloatProperty(name="Error", subtype="FACTOR", precision=3)
    spp: IntVectorProperty(name="Samples", size=len(SAMPLERS))
    seconds: FloatVectorProperty(name="Seconds", size=len(SAMPLERS))
    fastest: EnumProperty(name="Fastest", items=QUALITY_SAMPLER_ITEMS)


class CoherentQualityFitInfo(bpy.types.PropertyGroup):
    """A pilot's fit, for display and scripting."""
    sampler: EnumProperty(name="Sampler", items=QUALITY_SAMPLER_ITEMS)
    c: FloatProperty(name="Error at 1 spp")
    exponent: FloatProperty(name="Fitted Exponent")
    seconds_per_pass: FloatProperty(name="Seconds per Pass (film resolution)")
    pilot_spp: IntProperty(name="Pilot Passes")
    pilot_seconds: FloatProperty(name="Pilot Seconds")


class CoherentQualitySettings(bpy.types.PropertyGroup):
    """`scene.coherent_quality`: what to estimate, and the latest estimate's table."""
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


classes = (CoherentRenderSettings, CoherentQualityRow, CoherentQualityFitInfo, CoherentQualitySettings)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.coherent = PointerProperty(
        name="Coherent Render Settings", description="Coherent render settings", type=CoherentRenderSettings)
    bpy.types.Scene.coherent_quality = PointerProperty(type=CoherentQualitySettings, name="Coherent Quality Cost")


def unregister():
    if hasattr(bpy.types.Scene, "coherent_quality"):
        del bpy.types.Scene.coherent_quality
    if hasattr(bpy.types.Scene, "coherent"):
        del bpy.types.Scene.coherent
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
