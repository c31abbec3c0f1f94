# SPDX-License-Identifier: Apache-2.0
"""Properties-editor panels for the Coherent engine.

Our own panels (sampling, quality cost, tracing, light paths, film,
performance, light, passes) are shown only when Coherent is the active
engine. Blender's generic panels (output, format, camera, material and world
node surfaces, ...) are made visible for Coherent by adding 'COHERENT' to
their COMPAT_ENGINES, the same mechanism Cycles uses; unregister() removes
exactly what register() added.
"""

from __future__ import annotations

import bpy

from . import operators, properties
from .quality_model import SAMPLERS, format_duration

ENGINE = "COHERENT"


class CoherentButtonsPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        # Without the native module there is no settings table, so no
        # settings to draw: the Sampling panel shows the load error instead.
        return context.engine in cls.COMPAT_ENGINES and properties.table_loaded()


# --- Render properties ----------------------------------------------------------


class RENDER_PT_coherent_sampling(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Sampling"
    bl_context = "render"

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        if not properties.table_loaded():
            layout.label(text="The Coherent native module did not load; see the console", icon="ERROR")
            return
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.coherent
        col = layout.column(align=True)
        col.prop(props, "samples", text="Render")
        col.prop(props, "preview_samples", text="Viewport")
        col = layout.column(align=True)
        col.prop(props, "target_error")
        col.prop(props, "time_limit")
        col.prop(props, "write_convergence")
        col = layout.column()
        row = col.row(align=True)
        row.prop(props, "seed")
        row.prop(props, "use_animated_seed", text="", icon="TIME")
        col = layout.column()
        col.prop(props, "sampler")
        col.prop(props, "pattern")
        sub = col.column()
        sub.active = props.pattern == "SOBOL"  # white noise halves are independent anyway
        sub.prop(props, "error_estimate")
        sub = col.column()
        sub.active = props.sampler != "SPT"  # CPT/ICPT share sequences per packet
        sub.prop(props, "packet_size")


class RENDER_PT_coherent_adaptive(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Adaptive Sampling"
    bl_context = "render"
    bl_parent_id = "RENDER_PT_coherent_sampling"

    def draw_header(self, context):
        self.layout.prop(context.scene.coherent, "use_adaptive_sampling", text="")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.coherent
        col = layout.column(align=True)
        col.active = props.use_adaptive_sampling
        col.prop(props, "adaptive_threshold", text="Noise Threshold")
        col.prop(props, "adaptive_min_samples", text="Min Samples")


class RENDER_PT_coherent_denoising(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Denoising"
    bl_context = "render"
    bl_parent_id = "RENDER_PT_coherent_sampling"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.coherent
        col = layout.column(heading="Denoise", align=True)
        col.prop(props, "use_denoising")
        col.prop(props, "use_preview_denoising")
        sub = layout.column()
        sub.active = props.use_denoising or props.use_preview_denoising
        sub.prop(props, "denoising_strength")
        sub = layout.column()
        sub.active = props.use_denoising
        sub.prop(props, "use_distribute_samples")


class RENDER_PT_coherent_quality_cost(CoherentButtonsPanel, bpy.types.Panel):
    """What reaching each error level costs, per sampler (operators.py estimates it)."""
    bl_label = "Quality Cost"
    bl_context = "render"
    bl_parent_id = "RENDER_PT_coherent_sampling"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        st = context.scene.coherent_quality
        col = layout.column(align=True)
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(st, "levels")
        col.prop(st, "pilot_seconds")
        col.prop(st, "pilot_max_pixels")
        if operators.quality_estimate_running():
            layout.operator(operators.COHERENT_OT_cancel_quality_cost.bl_idname, icon="CANCEL")
        else:
            layout.operator(operators.COHERENT_OT_estimate_quality_cost.bl_idname, icon="TIME")
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
                op = grid.operator(operators.COHERENT_OT_apply_quality_choice.bl_idname, depress=fastest,
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


class RENDER_PT_coherent_tracing(CoherentButtonsPanel, bpy.types.Panel):
    """Light transport and ray traversal: what is computed, and how rays are traced.

    Settings that do not apply to the current choice stay visible but
    inactive (greyed out), so the layout does not jump around.
    """
    bl_label = "Tracing"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.coherent

        col = layout.column()
        col.prop(props, "integrator")
        sub = col.column(align=True)
        sub.active = props.integrator == "AO"
        sub.prop(props, "ao_samples", text="AO Samples")
        sub.prop(props, "ao_distance", text="AO Distance")

        col = layout.column()
        col.prop(props, "traversal")
        packet = props.traversal in {"PACKET", "AUTO"}
        sub = col.column(align=True)
        sub.active = packet or props.sampler != "SPT"  # also the CPT/ICPT sequence blocks
        sub.prop(props, "packet_size")
        sub = col.column()
        sub.active = packet
        sub.prop(props, "assembly")
        sub = col.column()
        sub.active = props.traversal in {"AUTO", "SINGLE", "STREAM"}
        sub.row().prop(props, "bvh_width", expand=True)
        sub = col.column(align=True)
        sub.active = props.traversal == "WAVEFRONT"
        sub.prop(props, "reorder")
        sub.prop(props, "wave_size")
        sub = col.column()
        sub.active = props.traversal in {"AUTO", "PACKET", "STREAM", "WAVEFRONT"}
        sub.prop(props, "shader_batch")


class RENDER_PT_coherent_light_paths(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Light Paths"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        props = context.scene.coherent
        col = layout.column(heading="Max Bounces", align=True)
        col.prop(props, "max_bounces", text="Total")
        col.prop(props, "diffuse_bounces", text="Diffuse")
        col.prop(props, "glossy_bounces", text="Glossy")
        col.prop(props, "transmission_bounces", text="Transmission")
        col.prop(props, "transparent_max_bounces", text="Transparent")
        layout.prop(props, "rr_min_bounces")
        col = layout.column(heading="Clamping", align=True)
        col.prop(props, "clamp_direct", text="Direct Light")
        col.prop(props, "clamp_indirect", text="Indirect Light")


class RENDER_PT_coherent_film(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.render, "film_transparent", text="Transparent")


class RENDER_PT_coherent_performance(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        rd = context.scene.render
        props = context.scene.coherent
        col = layout.column(heading="Threads")
        col.prop(props, "threads", text="Coherent Threads")
        sub = col.column()
        sub.active = props.threads == 0
        sub.prop(rd, "threads_mode")
        sub2 = sub.column()
        sub2.enabled = rd.threads_mode == "FIXED"
        sub2.prop(rd, "threads")
        layout.prop(props, "tile_size")
        layout.prop(props, "report_interval")
        # Keeps meshes and BVH between final renders (persistent.py).
        layout.prop(rd, "use_persistent_data", text="Persistent Data")


# --- Light properties -----------------------------------------------------------


class DATA_PT_coherent_light(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Light"
    bl_context = "data"

    @classmethod
    def poll(cls, context):
        return context.light is not None and super().poll(context)

    def draw(self, context):
        layout = self.layout
        light = context.light
        layout.row().prop(light, "type", expand=True)
        layout.use_property_split = True
        layout.use_property_decorate = False

        col = layout.column()
        col.prop(light, "color")
        col.prop(light, "energy", text="Strength" if light.type == "SUN" else "Power")
        col.separator()
        if light.type in {"POINT", "SPOT"}:
            col.prop(light, "shadow_soft_size", text="Radius")
        elif light.type == "SUN":
            col.prop(light, "angle")
        elif light.type == "AREA":
            col.prop(light, "shape")
            sub = col.column(align=True)
            if light.shape in {"SQUARE", "DISK"}:
                sub.prop(light, "size")
            else:
                sub.prop(light, "size", text="Size X")
                sub.prop(light, "size_y", text="Y")
        if light.type == "SPOT":
            col.separator()
            col.prop(light, "spot_size", text="Spot Size")
            col.prop(light, "spot_blend", text="Blend", slider=True)
            col.prop(light, "show_cone")


# --- View layer properties --------------------------------------------------------


class VIEWLAYER_PT_coherent_passes(CoherentButtonsPanel, bpy.types.Panel):
    """Blender's own pass settings, laid out as Cycles' Passes panel."""
    bl_label = "Passes"
    bl_context = "view_layer"

    def draw(self, context):
        pass


class VIEWLAYER_PT_coherent_passes_data(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Data"
    bl_context = "view_layer"
    bl_parent_id = "VIEWLAYER_PT_coherent_passes"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        view_layer = context.view_layer
        col = layout.column(heading="Include", align=True)
        col.prop(view_layer, "use_pass_combined")
        col.prop(view_layer, "use_pass_z")
        col.prop(view_layer, "use_pass_mist")
        col.prop(view_layer, "use_pass_position")
        col.prop(view_layer, "use_pass_normal")
        col.prop(view_layer, "use_pass_vector")
        col.prop(view_layer, "use_pass_uv")
        col.prop(context.scene.coherent, "use_pass_error")
        # Cycles' own tick while its add-on is enabled (it defines the
        # property); this engine's scene-wide one otherwise. Either works.
        cycles = getattr(view_layer, "cycles", None)
        if cycles is not None and hasattr(cycles, "denoising_store_passes"):
            col.prop(cycles, "denoising_store_passes", text="Denoising Data")
        else:
            col.prop(context.scene.coherent, "use_pass_denoising_data")
        col = layout.column(heading="Indexes", align=True)
        col.prop(view_layer, "use_pass_object_index")
        col.prop(view_layer, "use_pass_material_index")
        col = layout.column(heading="Diagnostics", align=True)
        col.prop(context.scene.coherent, "use_pass_bvh_visits")
        col.prop(context.scene.coherent, "use_pass_simd_utilisation")


class VIEWLAYER_PT_coherent_passes_light(CoherentButtonsPanel, bpy.types.Panel):
    bl_label = "Light"
    bl_context = "view_layer"
    bl_parent_id = "VIEWLAYER_PT_coherent_passes"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        view_layer = context.view_layer
        for heading, lobe in (("Diffuse", "diffuse"), ("Glossy", "glossy"), ("Transmission", "transmission")):
            col = layout.column(heading=heading, align=True)
            col.prop(view_layer, f"use_pass_{lobe}_direct", text="Direct")
            col.prop(view_layer, f"use_pass_{lobe}_indirect", text="Indirect")
            col.prop(view_layer, f"use_pass_{lobe}_color", text="Color")
        col = layout.column(heading="Other", align=True)
        col.prop(view_layer, "use_pass_emit", text="Emission")
        col.prop(view_layer, "use_pass_environment")
        col.prop(view_layer, "use_pass_ambient_occlusion", text="Ambient Occlusion")


def _cryptomatte_panel():
    """Blender's own Cryptomatte panel (as Cycles shows it) under our Passes."""
    from bl_ui.properties_view_layer import ViewLayerCryptomattePanel

    class VIEWLAYER_PT_coherent_passes_crypto(CoherentButtonsPanel, ViewLayerCryptomattePanel, bpy.types.Panel):
        bl_label = "Cryptomatte"
        bl_context = "view_layer"
        bl_parent_id = "VIEWLAYER_PT_coherent_passes"

    return VIEWLAYER_PT_coherent_passes_crypto


# --- Object properties ------------------------------------------------------------


class OBJECT_PT_coherent_shadow_terminator(CoherentButtonsPanel, bpy.types.Panel):
    """Cycles' Geometry Offset (stored on the object by the Cycles add-on), which
    both engines read; Cycles' Shading Offset is not drawn: we do not use it."""
    bl_label = "Shadow Terminator"
    bl_context = "object"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        ob = context.object
        return (super().poll(context) and ob is not None and ob.type in {"MESH", "CURVE", "SURFACE", "META", "FONT"}
                and hasattr(ob, "cycles"))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(context.object.cycles, "shadow_terminator_geometry_offset", text="Geometry Offset")


classes = (
    RENDER_PT_coherent_sampling,
    RENDER_PT_coherent_adaptive,
    RENDER_PT_coherent_denoising,
    RENDER_PT_coherent_quality_cost,
    RENDER_PT_coherent_tracing,
    RENDER_PT_coherent_light_paths,
    RENDER_PT_coherent_film,
    RENDER_PT_coherent_performance,
    DATA_PT_coherent_light,
    OBJECT_PT_coherent_shadow_terminator,
    VIEWLAYER_PT_coherent_passes,
    VIEWLAYER_PT_coherent_passes_data,
    VIEWLAYER_PT_coherent_passes_light,
    _cryptomatte_panel(),
)


# --- Blender's own panels ---------------------------------------------------------

# Panels of Blender's generic ('BLENDER_RENDER') set that show settings we do
# not use or that our panels replace.
_EXCLUDED_PANELS = {
    "DATA_PT_area",           # in DATA_PT_coherent_light
    "DATA_PT_falloff_curve",  # legacy falloff, not supported
    "DATA_PT_light",          # replaced by DATA_PT_coherent_light
    "DATA_PT_preview",        # no preview renders
    "DATA_PT_spot",           # child of the EEVEE light panel; in DATA_PT_coherent_light
    "MATERIAL_PT_preview",
    "NODE_DATA_PT_light",
    "VIEWLAYER_PT_filter",
    "VIEWLAYER_PT_layer_passes",
}

# Panels of other engines that edit exactly what we read: the node-based
# material and world surfaces (so the Principled BSDF can be edited in the
# Properties editor) and the camera's depth of field.
_EXTRA_PANELS = {
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_WORLD_PT_surface",
    "DATA_PT_camera_dof",
    "DATA_PT_camera_dof_aperture",
}

_patched_panels = []  # panels whose COMPAT_ENGINES we extended


def _blender_panels():
    panels = []
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None or panel.__name__ in _EXCLUDED_PANELS:
            continue
        if "BLENDER_RENDER" in engines or panel.__name__ in _EXTRA_PANELS:
            panels.append(panel)
    return panels


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for panel in _blender_panels():
        if ENGINE not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE)
            _patched_panels.append(panel)


def unregister():
    while _patched_panels:
        _patched_panels.pop().COMPAT_ENGINES.discard(ENGINE)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
