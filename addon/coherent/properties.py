# SPDX-License-Identifier: Apache-2.0
"""Settings stored in the .blend file: `scene.coherent` (render settings) and
`scene.coherent_quality` (the Quality Cost estimate's settings and table)."""

from __future__ import annotations

import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       IntProperty, IntVectorProperty, PointerProperty, StringProperty)

from .quality_model import (DEFAULT_LEVELS, DEFAULT_MIN_PASSES, DEFAULT_PILOT_MAX_PIXELS, DEFAULT_PILOT_SECONDS,
                            SAMPLERS)


# Blender property -> (settings-table row, overrides). The row gives the
# property's type, enum items, range, default and tooltip (the native
# module's settings_table(), read at registration); an override is only
# where Blender's conventions differ: two sample counts, Blender's own
# defaults for a final render, units. Table rows not listed here are not
# Blender properties: width, height and transparent come from Blender's own
# render settings, heatmaps from the passes below, progressive_display and
# force_all_features from the front end.
TABLE_PROPERTIES = {
    "samples": ("spp", dict(description="Samples per pixel for final renders", default=64)),
    "preview_samples": ("spp", dict(name="Viewport Samples", description="Samples per pixel for viewport renders",
                                    default=16, soft_max=1024)),
    "target_error": ("target_error", dict(step=0.1, precision=3, subtype="FACTOR")),
    "time_limit": ("time_limit", dict(unit="TIME_ABSOLUTE", subtype="TIME_ABSOLUTE")),
    "seed": ("seed", {}),
    "sampler": ("sampler", dict(default="AUTO")),
    "pattern": ("pattern", {}),
    "error_estimate": ("error_estimate", {}),
    "packet_size": ("packet", {}),
    "use_adaptive_sampling": ("adaptive", {}),
    "adaptive_threshold": ("adaptive_threshold", dict(step=0.1, precision=4)),
    "adaptive_min_samples": ("adaptive_min_samples", {}),
    "integrator": ("integrator", {}),
    "traversal": ("traversal", {}),
    "assembly": ("assembly", {}),
    "shader_batch": ("shader_batch", {}),
    "bvh_width": ("bvh_width", {}),
    "reorder": ("reorder", {}),
    "wave_size": ("wave_size", dict(soft_min=1024)),
    "ao_samples": ("ao_samples", {}),
    "ao_distance": ("ao_distance", dict(subtype="DISTANCE", unit="LENGTH")),
    "max_bounces": ("max_bounces", {}),
    "diffuse_bounces": ("diffuse_bounces", {}),
    "glossy_bounces": ("glossy_bounces", {}),
    "transmission_bounces": ("transmission_bounces", {}),
    "transparent_max_bounces": ("transparent_max_bounces", {}),
    "rr_min_bounces": ("rr_min_bounces", {}),
    "clamp_direct": ("clamp_direct", {}),
    "clamp_indirect": ("clamp_indirect", {}),
    "uniform_light_selection": ("uniform_light_selection", {}),
    "threads": ("threads", dict(description="Render threads; 0 uses Blender's Performance > Threads setting "
                                            "(all cores when set to Auto-Detect)")),
    "tile_size": ("tile_size", {}),
    "report_interval": ("report_interval", dict(unit="TIME_ABSOLUTE", subtype="TIME_ABSOLUTE")),
    # Denoising, as Cycles' Sampling > Denoise: Render and Viewport.
    "use_denoising": ("denoise", dict(name="Render", description="Denoise final renders with the native "
                                                                 "feature-guided, cross-validated filter; the "
                                                                 "noisy image stays in the 'Noisy Image' pass")),
    "use_preview_denoising": ("denoise", dict(name="Viewport", description="Denoise the viewport's image at "
                                                                          "2, 4, 8, ... samples and when done")),
    "denoising_strength": ("denoise_strength", dict(name="Strength")),
    "use_distribute_samples": ("distribute_samples", {}),
    "use_pass_denoising_data": ("denoising_data", {}),
}
# Set by renderer_kwargs' callers: samples, seed and denoising differ between
# final render and viewport, and the stopping rules apply to final renders only.
FRONT_END_ROWS = {"spp", "seed", "target_error", "time_limit", "denoise"}

INT32_MAX = (1 << 31) - 1


def _tooltip(text):
    return text[:1].upper() + text[1:]


def _int32(v):
    return int(max(-INT32_MAX - 1, min(INT32_MAX, v)))


def table_property(row, **overrides):
    """A bpy property built from one settings-table row (see _coherent.settings_table())."""
    kind = row["type"]
    args = dict(name=row["label"], description=_tooltip(row["help"]))
    if kind == "bool":
        args.update(default=row["default"])
        return BoolProperty(**{**args, **overrides})
    if kind == "choice" or (kind == "int" and row["allowed"]):
        # Enum identifiers are the native names upper-cased (saved .blend files
        # store identifiers); native_value() lowers them again.
        if kind == "choice":
            items = tuple((n.upper(), label, _tooltip(h)) for n, label, h, hidden in row["choices"] if not hidden)
        else:
            items = tuple((str(v), str(v), f"{row['label']} {v}") for v in row["allowed"])
        args.update(items=items, default=str(row["default"]).upper())
        return EnumProperty(**{**args, **overrides})
    if kind in ("int", "seed"):
        args.update(default=_int32(row["default"]), min=_int32(row["min"]) if kind == "int" else 0,
                    max=_int32(row["max"]) if kind == "int" else INT32_MAX)
        if kind == "int":
            args.update(soft_max=_int32(row["soft_max"]))
        return IntProperty(**{**args, **overrides})
    if kind == "real":
        args.update(default=row["default"], min=row["min"], max=row["max"], soft_max=row["soft_max"])
        return FloatProperty(**{**args, **overrides})
    if kind == "size":
        args.update(size=2, default=tuple(row["default"]), min=_int32(row["min"]), max=_int32(row["max"]))
        return IntVectorProperty(**{**args, **overrides})
    raise ValueError(f"settings table row {row['name']!r}: unknown type {kind!r}")


def native_value(row, value):
    """A Blender property value as Renderer(...) takes it."""
    if row["type"] == "choice":
        return value.lower()
    if row["type"] == "int" and row["allowed"]:
        return int(value)
    if row["type"] == "size":
        return tuple(int(v) for v in value)
    return value


_table = {}  # row name -> row, filled at registration from the native module


class CoherentRenderSettings(bpy.types.PropertyGroup):
    # Properties of the add-on's own (no settings-table row). The table's
    # rows are added in register(), from TABLE_PROPERTIES.
    write_convergence: BoolProperty(
        name="Write Convergence", description="After a final render, write <output path>_convergence.csv "
                                              "(seconds, samples and estimated error after every batch of sample passes) next "
                                              "to the render output, to see what accuracy costs in time "
                                              "(plot it with `coherent plot`)",
        default=False)
    use_pass_error: BoolProperty(
        name="Error", description="Write an 'Error' pass: per pixel, the estimated RMS error of the rendered "
                                  "radiance (from the even and odd sample passes)",
        default=False)
    use_animated_seed: BoolProperty(
        name="Animated Seed", description="Combine the seed with the frame number so noise changes per frame",
        default=False)
    # Diagnostic heatmap passes (view layer panel); either fills both.
    use_pass_bvh_visits: BoolProperty(
        name="BVH Visits", description="Write a 'BVH Visits' pass: BVH node visits per camera sample, all "
                                       "rays of the sample's path (where traversal is expensive)",
        default=False)
    use_pass_simd_utilisation: BoolProperty(
        name="SIMD Utilisation", description="Write a 'SIMD Utilisation' pass: the mean fraction, 0..1, of "
                                             "SIMD lanes holding an active ray in the packets that traced the "
                                             "pixel (where coherence is lost); 1 for single rays",
        default=False)

    def renderer_kwargs(self, scene):
        """Keyword arguments of _coherent.Renderer that the final render and
        the viewport share: light paths, threads, tiles, film, sampler,
        adaptive sampling, integrator and traversal, and whether the heatmap
        passes are filled.

        Front ends add size, samples, seed and progressive_display (True in
        the viewport, which makes AUTO pick ICPT); the viewport turns
        heatmaps off (it shows Combined only).
        """
        kwargs = {}
        for prop, (name, _) in TABLE_PROPERTIES.items():
            if name not in FRONT_END_ROWS:
                kwargs[name] = native_value(_table[name], getattr(self, prop))
        if kwargs["threads"] == 0 and scene.render.threads_mode == "FIXED":
            kwargs["threads"] = scene.render.threads
        kwargs["transparent"] = scene.render.film_transparent
        kwargs["heatmaps"] = self.use_pass_bvh_visits or self.use_pass_simd_utilisation
        # The Error pass and the convergence record show the estimate as the
        # error itself: they get the unbiased one.
        if self.use_pass_error or self.write_convergence:
            kwargs["error_estimate"] = "exact"
        return kwargs

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


def table_loaded():
    """Whether the settings table was read (the native module loaded at registration)."""
    return bool(_table)


def register():
    # The table comes from the native module; without it the engine still
    # registers (rendering then reports the module's load error) and the
    # panels show that error instead of settings.
    from . import native_module
    try:
        rows = native_module().settings_table()
    except ImportError:
        rows = []
    _table.clear()
    _table.update((row["name"], row) for row in rows)
    if _table:
        for prop, (name, overrides) in TABLE_PROPERTIES.items():
            CoherentRenderSettings.__annotations__[prop] = table_property(_table[name], **overrides)
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
