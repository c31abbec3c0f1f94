# SPDX-License-Identifier: Apache-2.0
"""Render settings stored in the .blend file: `scene.coherent`."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, IntVectorProperty, PointerProperty


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
        the viewport share: light paths, threads, tiles, film and sampler.

        Front ends add size, samples, seed and progressive_display (True in
        the viewport, which makes AUTO pick ICPT).
        """
        threads = self.threads
        if threads == 0 and scene.render.threads_mode == "FIXED":
            threads = scene.render.threads
        return dict(threads=threads, max_bounces=self.max_bounces, diffuse_bounces=self.diffuse_bounces,
                    glossy_bounces=self.glossy_bounces, transmission_bounces=self.transmission_bounces,
                    transparent=scene.render.film_transparent, tile_size=self.tile_size,
                    sampler=self.sampler.lower(), packet=(int(self.packet_size[0]), int(self.packet_size[1])))

    def seed_for_frame(self, frame):
        """The sampler seed for `frame`: constant unless use_animated_seed."""
        if not self.use_animated_seed:
            return self.seed
        # Cycles' hash_uint2(frame, seed) role: decorrelate consecutive frames.
        h = (self.seed * 0x9E3779B1 + (frame & 0xFFFFFFFF) * 0x85EBCA77) & 0xFFFFFFFFFFFFFFFF
        h ^= h >> 29
        return h


classes = (CoherentRenderSettings,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.coherent = PointerProperty(
        name="Coherent Render Settings", description="Coherent render settings", type=CoherentRenderSettings)


def unregister():
    if hasattr(bpy.types.Scene, "coherent"):
        del bpy.types.Scene.coherent
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
