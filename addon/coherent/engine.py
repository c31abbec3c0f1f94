# SPDX-License-Identifier: Apache-2.0
"""The Coherent RenderEngine: final renders with progressive display and passes.

A render runs in Blender's render thread: export the depsgraph (export.py),
build the native Renderer (BVH), then render pass by pass. The native render
releases the GIL and calls back into Python after every batch of sample passes
(about every quarter second, the report_interval setting) and during long
ones; the callback reports progress and statistics, shows the image refining
(at most every PREVIEW_INTERVAL seconds) and polls test_break() to cancel
promptly.

Errors never produce a silent blank image: they are reported with
report({'ERROR'}) (a command-line render then exits non-zero and writes no
file) and error_set() (shown in the Image Editor).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
import traceback

import bpy
import numpy as np

from . import export, motion, object_settings, persistent, viewport

# Seconds between progressive updates of the displayed image.
PREVIEW_INTERVAL = 0.5

# Native pass name -> (Blender channel ids, Blender pass type) for register_pass.
_PASSES = {
    "Combined": ("RGBA", "COLOR"),
    "Depth": ("Z", "VALUE"),
    "Normal": ("XYZ", "VECTOR"),
    "Error": ("X", "VALUE"),
    # Diagnostic heatmaps (scene.coherent.use_pass_bvh_visits / use_pass_simd_utilisation).
    "BVH Visits": ("X", "VALUE"),
    "SIMD Utilisation": ("X", "VALUE"),
    # Denoising (Cycles' names): the feature buffers, and Combined as rendered.
    "Denoising Albedo": ("RGB", "COLOR"),
    "Denoising Normal": ("XYZ", "VECTOR"),
    "Denoising Depth": ("Z", "VALUE"),
    "Noisy Image": ("RGBA", "COLOR"),
}

# Cycles' passes: (ViewLayer property, pass name, channel ids, pass type), in
# the order Cycles registers them. Ticked ones are accumulated natively
# (Renderer(passes=...)); the others cost nothing.
VIEW_LAYER_PASSES = (
    ("use_pass_mist", "Mist", "Z", "VALUE"),
    ("use_pass_position", "Position", "XYZ", "VECTOR"),
    ("use_pass_vector", "Vector", "XYZW", "VECTOR"),
    ("use_pass_uv", "UV", "UVA", "VECTOR"),
    ("use_pass_object_index", "IndexOB", "X", "VALUE"),
    ("use_pass_material_index", "IndexMA", "X", "VALUE"),
    ("use_pass_diffuse_direct", "DiffDir", "RGB", "COLOR"),
    ("use_pass_diffuse_indirect", "DiffInd", "RGB", "COLOR"),
    ("use_pass_diffuse_color", "DiffCol", "RGB", "COLOR"),
    ("use_pass_glossy_direct", "GlossDir", "RGB", "COLOR"),
    ("use_pass_glossy_indirect", "GlossInd", "RGB", "COLOR"),
    ("use_pass_glossy_color", "GlossCol", "RGB", "COLOR"),
    ("use_pass_transmission_direct", "TransDir", "RGB", "COLOR"),
    ("use_pass_transmission_indirect", "TransInd", "RGB", "COLOR"),
    ("use_pass_transmission_color", "TransCol", "RGB", "COLOR"),
    ("use_pass_emit", "Emit", "RGB", "COLOR"),
    ("use_pass_environment", "Env", "RGB", "COLOR"),
    ("use_pass_ambient_occlusion", "AO", "RGB", "COLOR"),
)
_PASSES.update({name: (chan_id, kind) for _, name, chan_id, kind in VIEW_LAYER_PASSES})

# Blender's World > Mist falloff as Cycles' exponent.
_MIST_FALLOFF = {"QUADRATIC": 2.0, "LINEAR": 1.0, "INVERSE_QUADRATIC": 0.5}


def stores_denoising_data(scene, view_layer):
    """Whether the Denoising Albedo, Normal and Depth passes are written: Cycles'
    View Layer tick (Passes > Data > Denoising Data,
    view_layer.cycles.denoising_store_passes, there while the Cycles add-on
    is enabled), or this engine's scene-wide setting of the same name, which
    earlier files may have ticked; either one turns them on."""
    cycles = getattr(view_layer, "cycles", None)
    return bool(getattr(cycles, "denoising_store_passes", False)) or scene.coherent.use_pass_denoising_data


def enabled_passes(view_layer):
    """Names of the Cycles passes ticked in `view_layer`."""
    return [name for prop, name, _, _ in VIEW_LAYER_PASSES if getattr(view_layer, prop, False)]


# Cryptomatte: (ViewLayer property, native type, pass name prefix), as Cycles names them.
CRYPTOMATTE = (("use_pass_cryptomatte_object", "object", "CryptoObject"),
               ("use_pass_cryptomatte_material", "material", "CryptoMaterial"),
               ("use_pass_cryptomatte_asset", "asset", "CryptoAsset"))


def cryptomatte_types(view_layer):
    """The Cryptomatte types ticked in `view_layer`, native names."""
    return [kind for prop, kind, _ in CRYPTOMATTE if getattr(view_layer, prop, False)]


def cryptomatte_pass_names(view_layer, prefix):
    """CryptoObject00, CryptoObject01, ...: a pass per two levels (Cycles)."""
    return [f"{prefix}{i:02d}" for i in range((min(16, view_layer.pass_cryptomatte_depth) + 1) // 2)]


def _crypto_names(nscene):
    """Per exported object, the names Cryptomatte hashes: the object's own
    (an instance "parent/object" is its object) and its asset, the top-level
    parent, as Cycles names them."""
    objects = bpy.data.objects
    names, assets = [], []
    for name in nscene.object_names:
        own = name.rsplit("/", 1)[-1]
        names.append(own)
        ob = objects.get(own)
        while ob is not None and ob.parent is not None:
            ob = ob.parent
        assets.append(ob.name if ob is not None else own)
    return names, assets


def stamp_cryptomatte(result, nscene, view_layer, native):
    """Cycles' Cryptomatte metadata (blender/session.cpp add_cryptomatte_layer):
    per type, cryptomatte/<first 7 hex digits of the layer name's hash>/
    name, hash, conversion and manifest."""
    objects, assets = _crypto_names(nscene)
    materials = [nscene.material(i)["name"] for i in range(nscene.material_count)]
    for kind, names in (("object", objects), ("material", materials), ("asset", assets)):
        if kind not in cryptomatte_types(view_layer):
            continue
        layer = f"{view_layer.name}.Crypto{kind.capitalize()}"
        key = f"cryptomatte/{native.Scene.cryptomatte_hash(layer):08x}"[:len("cryptomatte/") + 7]
        result.stamp_data_add_field(f"{key}/name", layer)
        result.stamp_data_add_field(f"{key}/hash", "MurmurHash3_32")
        result.stamp_data_add_field(f"{key}/conversion", "uint32_to_float32")
        result.stamp_data_add_field(f"{key}/manifest", native.Scene.cryptomatte_manifest(names))


def set_data_pass_inputs(nscene, bscene):
    """What the data passes read: pass_index of objects (by exported name;
    an instance "parent/object" takes its object's) and materials (by name),
    and the World's mist and AO distance. Per object and material, never per
    vertex."""
    object_index = {}
    for name in nscene.object_names:
        ob = object_settings.blender_object(name)
        if ob is not None and ob.pass_index:
            object_index[name] = float(ob.pass_index)
    material_index = []
    for i in range(nscene.material_count):
        mat = bpy.data.materials.get(nscene.material(i)["name"]) if i else None
        material_index.append(float(mat.pass_index) if mat is not None else 0.0)
    world = bscene.world
    kwargs = {}
    if world is not None:
        mist = world.mist_settings
        kwargs = dict(mist_start=mist.start, mist_depth=mist.depth,
                      mist_falloff=_MIST_FALLOFF.get(mist.falloff, 2.0), ao_distance=world.light_settings.distance)
    crypto_objects, crypto_assets = _crypto_names(nscene)
    nscene.set_data_passes(object_pass_index=object_index, material_pass_index=material_index,
                           crypto_object_names=crypto_objects, crypto_asset_names=crypto_assets, **kwargs)

# Integrator and traversal as the Info report names them.
_INTEGRATOR_NAMES = {"pt": "path tracing", "drt": "distribution ray tracing", "wrt": "Whitted ray tracing",
                     "rcs": "ray casting", "ao": "ambient occlusion"}
_TRAVERSAL_NAMES = {"single": "single rays", "packet": "packets", "stream": "ray streams",
                    "wavefront": "wavefront"}


def _format_percent(value):
    return "n/a" if value is None else f"{100.0 * value:.1f} %"


def tracing_summary(settings, stats):
    """One line naming the integrator and traversal of a render and, when
    packets were traced, their SIMD utilisation, e.g.
    "Coherent: path tracing, packets 4x4 (ray types), SIMD utilisation: boxes 91.2 %, triangles 63.0 %".

    `settings` is Renderer.settings, `stats` Renderer.stats().
    """
    integrator = _INTEGRATOR_NAMES.get(settings["integrator"], settings["integrator"])
    traversal = settings["traversal"]
    text = f"Coherent: {integrator}, {_TRAVERSAL_NAMES.get(traversal, traversal)}"
    if traversal == "packet":
        w, h = settings["packet"]
        text += f" {w}x{h} ({'ray types' if settings['assembly'] == 'types' else 'runs'})"
    elif traversal in ("single", "stream"):
        text += f", BVH width {settings['bvh_width']}"
    elif traversal == "wavefront":
        text += f" (reorder {settings['reorder']}, waves of {settings['wave_size']:,})"
    simd = stats.get("simd_utilisation") or {}
    if simd.get("box") is not None or simd.get("triangle") is not None:
        text += (f", SIMD utilisation: boxes {_format_percent(simd.get('box'))}, "
                 f"triangles {_format_percent(simd.get('triangle'))}")
    return text


def _format_bytes(size):
    for unit in ("B", "KiB", "MiB", "GiB"):
        if size < 1024.0 or unit == "GiB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024.0


def memory_summary(memory):
    """One line with what the render held, e.g. "Coherent: memory: peak 412.3 MiB,
    871,306 triangles at 224 bytes each (BVH 71.4 MiB, scene 114.3 MiB), film 224.0 KiB".

    `memory` is Renderer.stats()["memory"]; the peak is the whole process's
    (Blender's own memory included).
    """
    peak = memory.get("peak_rss_bytes")
    text = f"Coherent: memory: peak {_format_bytes(peak) if peak else 'n/a'}, {memory['triangles']:,} triangles"
    if memory.get("bytes_per_triangle") is not None:
        text += f" at {memory['bytes_per_triangle']:.0f} bytes each"
    if memory.get("instances"):
        text += f", {memory['instances']:,} instances at {memory['bytes_per_instance']:.0f} bytes each"
    return (text + f" (BVH {_format_bytes(memory['bvh_bytes'])}, scene {_format_bytes(memory['scene_bytes'])}), "
                   f"film {_format_bytes(memory['film_bytes'])}")


def _format_time(seconds):
    seconds = max(0.0, seconds)
    minutes, secs = divmod(int(round(seconds)), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes:02d}:{secs:02d}"


def _texture_summary(scene):
    """', N images (K reused), X MB in-memory pixels, Y MB texture cache' when the scene has image
    textures, else ''. Reused: in-memory images held from an earlier render, not handed over again."""
    textures = scene.texture_stats()
    if not textures["images"]:
        return ""
    return (f", {textures['images']} images ({textures['reused']} reused), "
            f"{textures['buffer_bytes'] / 2**20:.1f} MB in-memory pixels, "
            f"{textures['memory_bytes'] / 2**20:.1f} MB texture cache")


def _format_error(estimate):
    """The relative RMSE estimate as a percentage, or "n/a" before 2 passes
    and when not estimated (Sampling > Error Estimate: Auto)."""
    return "n/a" if estimate is None else f"{100.0 * estimate:.1f} %"


def _format_prediction(native, seconds, error, target):
    """Formats " → 1.0 % in ~00:42": time left to the target error, or "" without one.

    The native predicted_seconds_to_error assumes the error keeps falling as
    1/sqrt(samples), i.e. as 1/sqrt(time).
    """
    if error is None or target <= 0.0:
        return ""
    total = native.predicted_seconds_to_error(seconds, error, target)
    if total < 0.0:
        return ""
    return f" → {_format_error(target)} in ~{_format_time(total - seconds)}"


def convergence_path(scene):
    """Where write_convergence puts the CSV: `<render output path>_convergence.csv`.

    The output path is this frame's, without its extension; without an output
    path, the blend file's directory (or the temp dir for an unsaved file).
    """
    render = scene.render
    if render.filepath.strip():
        base = os.path.splitext(bpy.path.abspath(render.frame_path(frame=scene.frame_current)))[0]
    else:
        directory = os.path.dirname(bpy.data.filepath) if bpy.data.filepath else tempfile.gettempdir()
        stem = bpy.path.display_name_from_filepath(bpy.data.filepath) if bpy.data.filepath else "untitled"
        base = os.path.join(directory, f"{stem}_{scene.frame_current:04d}")
    return base + "_convergence.csv"


def write_convergence_csv(path, rows):
    """Writes (seconds, spp, error_estimate) rows as `coherent render --convergence` does."""
    directory = os.path.dirname(path)
    if directory:
        os.makedirs(directory, exist_ok=True)
    with open(path, "w", encoding="ascii", newline="") as f:
        f.write("seconds,spp,error_estimate\n")
        for seconds, spp, error in rows:
            f.write(f"{seconds:.6f},{spp},{error!r}\n")


def render_size(render):
    """Full-frame size in pixels after Resolution %, as Blender computes it."""
    return (render.resolution_x * render.resolution_percentage // 100,
            render.resolution_y * render.resolution_percentage // 100)


def border_pixels(render, width, height):
    """Render border as (x0, y0, x1, y1) pixels with y = 0 at the TOP row, or None.

    Blender truncates border * size to integers with y measured from the
    bottom (render_init_from_main); the native renderer measures y from the top.
    """
    if not render.use_border:
        return None
    x0, x1 = int(render.border_min_x * width), int(render.border_max_x * width)
    yb0, yb1 = int(render.border_min_y * height), int(render.border_max_y * height)
    if (x0, yb0, x1, yb1) == (0, 0, width, height):
        return None
    if x1 <= x0 or yb1 <= yb0:
        raise RuntimeError("the render border is empty")
    return (x0, height - yb1, x1, height - yb0)


class CoherentRenderEngine(bpy.types.RenderEngine):
    bl_idname = "COHERENT"
    bl_label = "Coherent"
    bl_use_postprocess = True
    # Use Blender's shader nodes (Principled BSDF, ...) as the material UI.
    bl_use_shading_nodes_custom = False
    # Material Preview shading in the viewport uses EEVEE.
    bl_use_eevee_viewport = True
    bl_use_preview = False

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._renderer = None
        self._viewport = None
        self._persistent = None  # PersistentScene while render.use_persistent_data is on

    def __del__(self):
        # Blender may destroy an instance whose __init__ never ran.
        renderer = getattr(self, "_renderer", None)
        if renderer is not None:
            renderer.cancel()
        session = getattr(self, "_viewport", None)
        if session is not None:
            session.free()
        kept = getattr(self, "_persistent", None)
        if kept is not None:
            kept.free()

    # -- viewport ("Rendered" shading) -------------------------------------------

    def view_update(self, context, depsgraph):
        if getattr(self, "_viewport", None) is None:
            self._viewport = viewport.ViewportSession()
        self._viewport.update(self, context, depsgraph)

    def view_draw(self, context, depsgraph):
        session = getattr(self, "_viewport", None)
        if session is None:
            return
        try:
            session.draw(self, context, depsgraph)
        except Exception as e:  # noqa: BLE001 - never let a draw callback spam tracebacks
            session.error = f"Coherent: {type(e).__name__}: {e}"
            traceback.print_exc()
            self.update_stats("", session.error)

    # -- passes -----------------------------------------------------------------

    def update_render_passes(self, scene=None, renderlayer=None):
        self.register_pass(scene, renderlayer, "Combined", 4, "RGBA", "COLOR")
        if renderlayer.use_pass_z:
            self.register_pass(scene, renderlayer, "Depth", 1, "Z", "VALUE")
        if renderlayer.use_pass_normal:
            self.register_pass(scene, renderlayer, "Normal", 3, "XYZ", "VECTOR")
        # Scene-wide, not per view layer: the estimate belongs to the render.
        if scene is not None and scene.coherent.use_pass_error:
            self.register_pass(scene, renderlayer, "Error", 1, "X", "VALUE")
        # Heatmaps, scene-wide like Error: they describe how the render traced.
        if scene is not None and scene.coherent.use_pass_bvh_visits:
            self.register_pass(scene, renderlayer, "BVH Visits", 1, "X", "VALUE")
        if scene is not None and scene.coherent.use_pass_simd_utilisation:
            self.register_pass(scene, renderlayer, "SIMD Utilisation", 1, "X", "VALUE")
        # Denoising: Combined is denoised; the noisy image and, on request,
        # the features the denoiser used stay available.
        if scene is not None and stores_denoising_data(scene, renderlayer):
            self.register_pass(scene, renderlayer, "Denoising Albedo", 3, "RGB", "COLOR")
            self.register_pass(scene, renderlayer, "Denoising Normal", 3, "XYZ", "VECTOR")
            self.register_pass(scene, renderlayer, "Denoising Depth", 1, "Z", "VALUE")
        if scene is not None and scene.coherent.use_denoising:
            self.register_pass(scene, renderlayer, "Noisy Image", 4, "RGBA", "COLOR")
        for prop, name, chan_id, kind in VIEW_LAYER_PASSES:
            if getattr(renderlayer, prop, False):
                self.register_pass(scene, renderlayer, name, len(chan_id), chan_id, kind)
        for prop, _, prefix in CRYPTOMATTE:
            if getattr(renderlayer, prop, False):
                for name in cryptomatte_pass_names(renderlayer, prefix):
                    self.register_pass(scene, renderlayer, name, 4, "rgba", "COLOR")  # lower case, as Cycles

    # -- final render -------------------------------------------------------------

    def render(self, depsgraph):
        if self.is_preview:
            return
        try:
            self._render(depsgraph)
        except Exception as e:  # noqa: BLE001 - every failure must reach the user
            self._fail(e)

    def _fail(self, error):
        # MemoryError: the native renderer's check before building (or a
        # failed allocation) says what did not fit; Blender keeps working.
        if isinstance(error, (ImportError, export.ExportError, MemoryError)):
            # A MemoryError from Python itself (e.g. numpy in the export) has no message.
            message = str(error) or "out of memory (MemoryError)"
        else:
            traceback.print_exc()
            message = f"{type(error).__name__}: {error}"
        if not message.startswith("Coherent"):
            message = "Coherent: " + message
        print(message, file=sys.stderr)
        self.error_set(message)
        self.report({"ERROR"}, message)

    def _warn(self, message):
        print(f"Coherent warning: {message}", file=sys.stderr)
        self.report({"WARNING"}, message)

    def _render(self, depsgraph):
        from . import native_module  # deferred: the package imports this module first

        native = native_module()
        scene = depsgraph.scene
        render = scene.render
        props = scene.coherent

        width, height = render_size(render)
        if self.resolution_x > 0 and self.resolution_y > 0:
            width, height = self.resolution_x, self.resolution_y
        border = border_pixels(render, width, height)

        moving, frame_motion, cameras = self._evaluate_motion(depsgraph)
        self.update_stats("", "Exporting scene")
        exported = self._export(native, depsgraph, width, height, moving, frame_motion)
        for warning in exported.warnings:
            self._warn(warning)
        if self.test_break():
            return
        nscene = exported.scene

        self.update_stats("", f"Building BVH ({nscene.triangle_count:,} triangles)")
        if nscene.instance_count:
            print(f"Coherent: {nscene.instance_count:,} instances of {nscene.prototype_count} shared meshes "
                  f"({nscene.instanced_triangle_count:,} triangles as instanced) beside "
                  f"{nscene.triangle_count:,} world-space triangles")
        view_layer = depsgraph.view_layer
        passes, cryptomatte = enabled_passes(view_layer), cryptomatte_types(view_layer)
        if passes or cryptomatte:
            set_data_pass_inputs(nscene, scene)
        object_settings.set_shadow_terminator(nscene)
        if cameras is not None:
            nscene.set_camera_frames(*cameras)
        kwargs = props.renderer_kwargs(scene)
        kwargs["denoising_data"] = stores_denoising_data(scene, view_layer)
        build_start = time.perf_counter()
        renderer = native.Renderer(
            nscene, width=width, height=height, spp=props.samples,
            seed=props.seed_for_frame(scene.frame_current), border=border,
            progressive_display=False, target_error=props.target_error, time_limit=props.time_limit,
            denoise=props.use_denoising, passes=passes, cryptomatte=cryptomatte,
            cryptomatte_levels=min(16, view_layer.pass_cryptomatte_depth), **kwargs)
        build_seconds = time.perf_counter() - build_start
        self._renderer = renderer
        reuse = self._persistent.report if self._persistent is not None else None
        if reuse is not None and reuse.refit_seconds is not None:
            build_seconds += reuse.refit_seconds

        # Blender's result covers the border only (cropped or not: it pastes
        # an uncropped border into the full frame itself).
        result = self.begin_result(0, 0, renderer.film_width, renderer.film_height,
                                   layer=depsgraph.view_layer.name)
        try:
            if (result.resolution_x, result.resolution_y) != (renderer.film_width, renderer.film_height):
                raise RuntimeError(f"render result is {result.resolution_x}x{result.resolution_y} pixels, "
                                   f"expected {renderer.film_width}x{renderer.film_height}")
            convergence = []  # (seconds, spp, error) per completed pass with an estimate
            finished = renderer.render(self._progress_callback(renderer, result, native, props.target_error,
                                                               convergence))
            self._write_passes(result, renderer, names=None)
        finally:
            self.end_result(result)
            self._renderer = None
        if cryptomatte:
            # On the engine's whole result (a begin_result() one does not keep metadata), as Cycles does.
            stamp_cryptomatte(self.get_result(), nscene, view_layer, native)

        stats = renderer.stats()
        state = "finished" if finished else "cancelled"
        print(f"Coherent: {state} {width}x{height}, {stats['spp']} spp, "
              f"{nscene.triangle_count:,} triangles: "
              f"export {exported.seconds:.2f} s, BVH {build_seconds:.2f} s, render {stats['seconds']:.2f} s, "
              f"{stats['mrays_per_s']:.1f} Mrays/s{_texture_summary(nscene)}")
        # What the accuracy cost: the final estimate, time and samples.
        error = _format_error(stats["error_estimate"])
        if stats["error_estimate"] is None and stats["spp"] >= 2:
            error = "not estimated (Sampling > Error Estimate: Auto saves its noise)"
        summary = (f"Coherent: error {error} after {stats['spp']} samples "
                   f"in {stats['seconds']:.2f} s")
        print(summary)
        self.report({"INFO"}, summary)
        if reuse is not None:
            kept = reuse.summary(build_seconds)
            print(kept)
            self.report({"INFO"}, kept)
        memory = memory_summary(stats["memory"])
        print(memory)
        self.report({"INFO"}, memory)
        if stats["denoised_error_estimate"] is not None:
            denoised = (f"Coherent: denoised in {stats['denoise_seconds']:.2f} s, estimated error "
                        f"{_format_error(stats['error_estimate'])} -> {_format_error(stats['denoised_error_estimate'])}")
            print(denoised)
            self.report({"INFO"}, denoised)
        tracing = tracing_summary(renderer.settings, stats)
        print(tracing)
        self.report({"INFO"}, tracing)
        if props.use_pass_bvh_visits and not renderer.settings["counts_path_visits"]:
            self._warn(f"the BVH Visits pass is zero: {renderer.settings['traversal']} traversal does not count "
                       f"visits per pixel")
        if stats.get("nonfinite_samples"):
            self._warn(f"{stats['nonfinite_samples']} samples were NaN/Inf and discarded")
        if finished and props.write_convergence:
            path = convergence_path(scene)
            try:
                write_convergence_csv(path, convergence)
            except OSError as e:
                self._warn(f"could not write the convergence record {path}: {e.strerror or e}")
            else:
                message = f"Coherent: convergence record ({len(convergence)} passes) written to {path}"
                print(message)
                self.report({"INFO"}, message)

    def _evaluate_motion(self, depsgraph):
        """(shutter motion, frame motion, camera frames) of motion.py: what
        motion blur and the Vector pass need, each only when turned on."""
        scene = depsgraph.scene
        moving, frame_motion, cameras = {}, {}, None
        if scene.render.use_motion_blur:
            self.update_stats("", "Motion blur: evaluating the shutter")
            moving = motion.shutter_matrices(self, depsgraph, export.MOTION_TYPES)
        if depsgraph.view_layer.use_pass_vector:
            self.update_stats("", "Vector pass: evaluating the previous and next frames")
            frame_motion, cameras = motion.frame_matrices(self, depsgraph, export.MOTION_TYPES,
                                                          self.camera_override or scene.camera)
        return moving, frame_motion, cameras

    def _export(self, native, depsgraph, width, height, moving, frame_motion):
        """Exports the depsgraph; with persistent data, through the kept PersistentScene."""
        scene = depsgraph.scene
        if not scene.render.use_persistent_data:
            if self._persistent is not None:
                self._persistent.free()
                self._persistent = None
            return export.export_scene(native, depsgraph, width, height, camera_override=self.camera_override,
                                       cancelled=self.test_break, motion=moving, frame_motion=frame_motion)
        if self._persistent is None:
            self._persistent = persistent.PersistentScene()
        # What the kept scene and BVH are valid for: another scene or view
        # layer, or settings that shape the BVH (its width), start afresh.
        identity = (scene.original.as_pointer(), depsgraph.view_layer.name,
                    repr(sorted(scene.coherent.renderer_kwargs(scene).items())))
        return self._persistent.export(native, depsgraph, width, height, identity,
                                       camera_override=self.camera_override, cancelled=self.test_break,
                                       motion=moving, frame_motion=frame_motion)

    def _progress_callback(self, renderer, result, native, target_error, convergence):
        """The per-pass callback; appends (seconds, spp, error) to `convergence`
        for every completed pass that has an error estimate."""
        last_preview = [time.monotonic()]
        last_done = [0]

        def progress(p):
            done, total, seconds = p["samples_done"], p["samples_total"], p["seconds"]
            if p["denoise_fraction"] is not None:  # after the last pass
                self.update_stats("", f"Sample {done}/{total} | Denoising {100.0 * p['denoise_fraction']:.0f} %")
                return not self.test_break()
            fraction = p["fraction"]
            self.update_progress(fraction)
            remaining = seconds * (1.0 - fraction) / fraction if fraction > 0.0 else 0.0
            error = p["error_estimate"]
            error_text = ""
            if error is not None:
                prediction = _format_prediction(native, seconds, error, target_error)
                error_text = f" | Error {_format_error(error)}{prediction}"
            self.update_stats("", f"Sample {done}/{total}{error_text} | {p['mrays_per_s']:.1f} Mrays/s | "
                                  f"Time {_format_time(seconds)} | Remaining {_format_time(remaining)}")
            # The film may only be read in the report that ends a pass (the
            # first one with a new samples_done): progress reports within a
            # pass run while worker threads are still adding samples.
            pass_ended = done != last_done[0]
            last_done[0] = done
            if pass_ended and error is not None:
                convergence.append((seconds, done, error))
            now = time.monotonic()
            if pass_ended and done < total and now - last_preview[0] >= PREVIEW_INTERVAL:
                self._write_passes(result, renderer, names=("Combined",))
                self.update_result(result)
                last_preview[0] = time.monotonic()
            return not self.test_break()

        return progress

    @staticmethod
    def _write_passes(result, renderer, names):
        for layer in result.layers:
            for render_pass in layer.passes:
                known = render_pass.name in _PASSES or render_pass.name.startswith("Crypto")
                if not known or (names is not None and render_pass.name not in names):
                    continue
                pixels = renderer.pass_pixels(render_pass.name)
                if pixels.shape[1] != render_pass.channels:
                    continue
                # (pixels, channels) float32 in one call: no per-pixel Python.
                render_pass.rect.foreach_set(pixels)
