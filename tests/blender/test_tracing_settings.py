# The add-on's tracing settings (scene.coherent: integrator, traversal,
# packet assembly, BVH width, reordering, wave size, AO, adaptive sampling),
# the "Tracing" and "Adaptive Sampling" panels, the heatmap passes, and the
# Info report after a render.
#
# In-process tests check properties, renderer_kwargs and the panels; the
# headless renders (subprocess Blender, as a user runs them) check that the
# settings reach the render and the passes reach the file. Tests named
# test_renderer_honours_* check what the renderer must do with a setting.

import re

import bpy
import numpy as np
import pytest

import blender_helpers as bh

SMALL = bh.python_expr("scene.render.resolution_percentage = 12",  # 512 -> 61 px
                       "scene.coherent.samples = 4")

# Enum property -> the native names its items must map to.
ENUMS = {
    "integrator": ["pt", "drt", "wrt", "rcs", "ao"],
    "traversal": ["auto", "single", "packet", "stream", "wavefront"],
    "assembly": ["types", "runs"],
    "reorder": ["none", "static1d", "static3d", "hash32", "hash192", "csd32"],
}


@pytest.fixture
def props(coherent_addon):
    settings = bpy.context.scene.coherent
    names = ["integrator", "traversal", "assembly", "bvh_width", "reorder", "wave_size", "ao_samples",
             "ao_distance", "use_adaptive_sampling", "adaptive_threshold", "adaptive_min_samples",
             "use_pass_bvh_visits", "use_pass_simd_utilisation", "sampler"]
    saved = {n: getattr(settings, n) for n in names}
    yield settings
    for n, v in saved.items():
        setattr(settings, n, v)


def tiny_native_scene(native):
    scene = native.Scene()
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    scene.add_mesh("Quad", quad, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    return scene


# --- properties and renderer_kwargs ------------------------------------------------------------

def test_defaults_match_the_native_defaults(props):
    kwargs = props.renderer_kwargs(bpy.context.scene)
    assert kwargs["integrator"] == "pt" and kwargs["traversal"] == "auto"
    assert kwargs["assembly"] == "types" and kwargs["bvh_width"] == 8 and kwargs["reorder"] == "none"
    assert kwargs["wave_size"] == 65536 and kwargs["ao_samples"] == 16 and kwargs["ao_distance"] == 0.0
    assert kwargs["heatmaps"] is False and kwargs["adaptive"] is False
    assert kwargs["adaptive_threshold"] == pytest.approx(0.01) and kwargs["adaptive_min_samples"] == 16


@pytest.mark.parametrize("name", sorted(ENUMS))
def test_enum_items_are_the_native_names(props, name):
    identifiers = [item.identifier for item in props.bl_rna.properties[name].enum_items]
    assert [i.lower() for i in identifiers] == ENUMS[name]


def test_bvh_width_items(props):
    assert [i.identifier for i in props.bl_rna.properties["bvh_width"].enum_items] == ["2", "4", "8"]


@pytest.mark.parametrize("name,native_values", sorted(ENUMS.items()) + [("bvh_width", [2, 4, 8])])
def test_every_enum_item_reaches_the_native_renderer(coherent_addon, props, name, native_values):
    """renderer_kwargs maps each item to arguments the native Renderer accepts and keeps."""
    native = coherent_addon.native_module()
    scene = bpy.context.scene
    for item, expected in zip(props.bl_rna.properties[name].enum_items, native_values):
        setattr(props, name, item.identifier)
        kwargs = props.renderer_kwargs(scene)
        assert kwargs[name] == expected
        r = native.Renderer(tiny_native_scene(native), width=4, height=4, spp=1, **kwargs)
        if name == "traversal" and expected == "auto":
            # Auto resolves by the (resolved) sampler: packets with CPT, single rays otherwise.
            assert r.settings[name] == ("packet" if r.settings["sampler"] == "cpt" else "single"), kwargs
        else:
            assert r.settings[name] == expected


def test_numeric_settings_reach_the_native_renderer(coherent_addon, props):
    native = coherent_addon.native_module()
    scene = bpy.context.scene
    props.wave_size, props.ao_samples, props.ao_distance = 4096, 5, 0.25
    props.use_adaptive_sampling, props.adaptive_threshold, props.adaptive_min_samples = True, 0.05, 6
    kwargs = props.renderer_kwargs(scene)
    assert (kwargs["wave_size"], kwargs["ao_samples"]) == (4096, 5)
    assert kwargs["ao_distance"] == pytest.approx(0.25)
    assert kwargs["adaptive"] is True and kwargs["adaptive_min_samples"] == 6
    assert kwargs["adaptive_threshold"] == pytest.approx(0.05)
    s = native.Renderer(tiny_native_scene(native), width=4, height=4, spp=1, **kwargs).settings
    assert (s["wave_size"], s["ao_samples"]) == (4096, 5) and s["ao_distance"] == pytest.approx(0.25)


@pytest.mark.parametrize("bvh, simd", [(False, False), (True, False), (False, True), (True, True)])
def test_heatmaps_follow_the_pass_toggles(props, bvh, simd):
    props.use_pass_bvh_visits, props.use_pass_simd_utilisation = bvh, simd
    assert props.renderer_kwargs(bpy.context.scene)["heatmaps"] == (bvh or simd)


def test_numeric_limits(props):
    props.wave_size = 0
    assert props.wave_size >= 1
    props.ao_samples = 0
    assert props.ao_samples >= 1
    props.ao_distance = -3.0
    assert props.ao_distance >= 0.0
    props.adaptive_threshold = 0.0
    assert props.adaptive_threshold > 0.0  # the native side rejects 0
    props.adaptive_min_samples = 0
    assert props.adaptive_min_samples >= 2


# --- panels ----------------------------------------------------------------------------------

class FakeLayout:
    """Stands in for a panel's UILayout and records, per prop(), whether it
    is shown active (its own and every enclosing layout's `active`)."""

    def __init__(self, log, parent=None):
        self.log, self.parent = log, parent
        self.active = self.enabled = True
        self.use_property_split = self.use_property_decorate = False

    def shown_active(self):
        return self.active and (self.parent is None or self.parent.shown_active())

    def column(self, **_):
        return FakeLayout(self.log, self)

    row = column

    def separator(self, **_):
        pass

    def label(self, **_):
        pass

    def prop(self, data, name, **_):
        assert hasattr(data, name), f"the panel draws a missing property {name!r}"
        self.log.append((name, self.shown_active()))


def draw_panel(panel_class, context_scene):
    """{property name: shown active} of what panel_class.draw() shows."""
    log = []
    fake_self = type("Panel", (), {"layout": FakeLayout(log)})()

    class Context:
        scene = context_scene
        view_layer = bpy.context.view_layer
        engine = bh.ENGINE_ID

    panel_class.draw(fake_self, Context())
    return dict(log)


def test_tracing_panel_shows_what_applies(coherent_addon, props):
    from coherent import ui
    scene = bpy.context.scene
    props.integrator, props.traversal = "PT", "SINGLE"
    shown = draw_panel(ui.RENDER_PT_coherent_tracing, scene)
    for name in ["integrator", "traversal", "packet_size", "assembly", "bvh_width", "reorder", "wave_size",
                 "ao_samples", "ao_distance"]:
        assert name in shown, name
    assert shown["bvh_width"] and not shown["assembly"] and not shown["reorder"] and not shown["ao_samples"]

    props.integrator, props.traversal = "AO", "PACKET"
    shown = draw_panel(ui.RENDER_PT_coherent_tracing, scene)
    assert shown["ao_samples"] and shown["ao_distance"] and shown["assembly"] and shown["packet_size"]
    assert not shown["bvh_width"] and not shown["wave_size"]

    props.traversal = "WAVEFRONT"
    shown = draw_panel(ui.RENDER_PT_coherent_tracing, scene)
    assert shown["reorder"] and shown["wave_size"] and not shown["assembly"]


def test_adaptive_panel(coherent_addon, props):
    from coherent import ui
    assert ui.RENDER_PT_coherent_adaptive.bl_parent_id == "RENDER_PT_coherent_sampling"
    props.use_adaptive_sampling = False
    shown = draw_panel(ui.RENDER_PT_coherent_adaptive, bpy.context.scene)
    assert shown == {"adaptive_threshold": False, "adaptive_min_samples": False}
    props.use_adaptive_sampling = True
    shown = draw_panel(ui.RENDER_PT_coherent_adaptive, bpy.context.scene)
    assert shown == {"adaptive_threshold": True, "adaptive_min_samples": True}


def test_passes_panel_has_the_heatmap_toggles(coherent_addon):
    from coherent import ui
    shown = draw_panel(ui.VIEWLAYER_PT_coherent_passes_data, bpy.context.scene)
    assert shown["use_pass_bvh_visits"] and shown["use_pass_simd_utilisation"] and shown["use_pass_error"]


def test_panels_are_registered(coherent_addon):
    for name in ["RENDER_PT_coherent_tracing", "RENDER_PT_coherent_adaptive"]:
        assert getattr(bpy.types, name, None) is not None, name


def test_tracing_summary_names_packets_and_simd(coherent_addon):
    from coherent import engine
    settings = dict(integrator="drt", traversal="packet", packet=(8, 4), assembly="runs", bvh_width=8,
                    reorder="none", wave_size=65536)
    text = engine.tracing_summary(settings, {"simd_utilisation": {"box": 0.75, "triangle": 0.5}})
    assert text == ("Coherent: distribution ray tracing, packets 8x4 (runs), "
                    "SIMD utilisation: boxes 75.0 %, triangles 50.0 %")
    settings.update(integrator="pt", traversal="single")
    text = engine.tracing_summary(settings, {"simd_utilisation": {"box": None, "triangle": None}})
    assert text == "Coherent: path tracing, single rays, BVH width 8"


# --- headless renders --------------------------------------------------------------------------

def test_heatmap_passes_in_multilayer_exr(blender, blend_scenes, tmp_path):
    settings = bh.python_expr("scene.coherent.use_pass_bvh_visits = True",
                              "scene.coherent.use_pass_simd_utilisation = True",
                              "scene.coherent.traversal = 'PACKET'",
                              "scene.view_layers[0].use_pass_z = True")
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "OPEN_EXR_MULTILAYER",
                     "-o", tmp_path / "heat_####", "--python-expr", SMALL, "--python-expr", settings, "-f", "1")
    assert result.returncode == 0, result.describe()
    ch = bh.read_image_channels(tmp_path / "heat_0001.exr")
    visits = bh.find_channels(ch, "BVH Visits", "X")[..., 0]
    simd = bh.find_channels(ch, "SIMD Utilisation", "X")[..., 0]
    depth = bh.find_channels(ch, "Depth", "Z")[..., 0]
    assert visits.shape == simd.shape == (61, 61)
    assert np.isfinite(visits).all() and np.isfinite(simd).all()
    assert (visits >= 0).all() and (simd >= 0).all() and (simd <= 1).all()
    # The Info report names the traversal and, for packets, the SIMD utilisation.
    m = re.search(r"Info: Coherent: path tracing, packets 4x4 \(ray types\), SIMD utilisation: "
                  r"boxes ([\d.]+) %, triangles ([\d.]+) %", result.stdout)
    assert m, result.describe()
    assert 0.0 < float(m.group(1)) <= 100.0 and 0.0 < float(m.group(2)) <= 100.0
    # Where geometry is, its camera rays visited the BVH, in packets that used some lanes.
    geometry = depth < 1e9
    assert geometry.mean() > 0.5
    assert (visits[geometry] >= 1).all()
    assert (simd[geometry] > 0).all()


def test_bvh_visits_pass_warns_with_streams(blender, blend_scenes, tmp_path):
    # Streams count visits per node queue, not per pixel: the pass is zero,
    # and the render says why instead of leaving a silent black pass.
    settings = bh.python_expr("scene.coherent.use_pass_bvh_visits = True", "scene.coherent.traversal = 'STREAM'")
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "OPEN_EXR_MULTILAYER",
                     "-o", tmp_path / "stream_####", "--python-expr", SMALL, "--python-expr", settings, "-f", "1")
    assert result.returncode == 0, result.describe()
    assert "the BVH Visits pass is zero: stream traversal does not count visits per pixel" in result.output
    visits = bh.find_channels(bh.read_image_channels(tmp_path / "stream_0001.exr"), "BVH Visits", "X")[..., 0]
    assert (visits == 0).all()


# SPT traces single rays; Auto's CPT would time single rays against packets
# and report whichever was faster.
SINGLE_RAYS = bh.python_expr("scene.coherent.sampler = 'SPT'")


def test_heatmap_passes_off_by_default(blender, blend_scenes, tmp_path):
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "OPEN_EXR_MULTILAYER",
                     "-o", tmp_path / "plain_####", "--python-expr", SMALL, "--python-expr", SINGLE_RAYS, "-f", "1")
    assert result.returncode == 0, result.describe()
    names = {n.split(".")[-2] for n in bh.read_image_channels(tmp_path / "plain_0001.exr") if "." in n}
    assert "BVH Visits" not in names and "SIMD Utilisation" not in names
    # Single rays: the report names the integrator and BVH width, no SIMD utilisation.
    assert "Info: Coherent: path tracing, single rays, BVH width 8" in result.stdout, result.describe()
    assert "SIMD utilisation" not in result.stdout


def test_renderer_honours_ambient_occlusion(blender, blend_scenes, tmp_path):
    settings = bh.python_expr("scene.coherent.integrator = 'AO'", "scene.coherent.ao_samples = 4")
    result = blender(blend_scenes / "cornell_box.blend", "-E", bh.ENGINE_ID, "-F", "OPEN_EXR",
                     "-o", tmp_path / "ao_####", "--python-expr", SMALL, "--python-expr", settings,
                     "--python-expr", SINGLE_RAYS, "-f", "1")
    assert result.returncode == 0, result.describe()
    assert "Info: Coherent: ambient occlusion, single rays" in result.stdout, result.describe()
    ch = bh.read_image_channels(tmp_path / "ao_0001.exr")
    rgb = np.stack([ch["R"], ch["G"], ch["B"]], axis=-1)
    assert np.isfinite(rgb).all()
    assert (rgb >= 0).all() and (rgb <= 1).all()
    assert np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 1], rgb[..., 2])
    assert 0.3 < rgb.mean() < 1.0
