"""The Python module (_coherent) without Blender: argument validation of
Renderer(...), Scene.add_mesh, add_material (closures) and add_light, and the
asynchronous start()/progress()/snapshot()/wait() path.

Every bad input must raise ValueError or TypeError whose message names the
argument. Only the exception type and the argument's name are asserted, not
the wording (the settings table words Renderer's messages).

The module is the one built for /usr/bin/python3 in addon/coherent/; it is
imported directly (the add-on package itself needs bpy).
"""

import re

import numpy as np
import pytest

from native_module import native

TRIANGLE = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32)
ONE_FACE = np.array([[0, 1, 2]])
NAN, INF = float("nan"), float("inf")


def small_scene():
    s = native.Scene()
    s.add_mesh("floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], np.float32),
               np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    s.world_color = (0.5, 0.5, 0.5)
    s.set_camera(position=(0.0, 0.0, 3.0), forward=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0))
    return s


def raises_naming(exc, arg):
    return pytest.raises(exc, match=re.escape(arg))


# --- Renderer(...) ---------------------------------------------------------------------------

BAD_RENDERER_VALUES = [
    # (keyword, value): a value of the right type outside what the renderer accepts
    ("sampler", "bogus"), ("sequences", "bogus"), ("integrator", "bogus"), ("traversal", "bogus"),
    ("assembly", "bogus"), ("reorder", "bogus"),
    ("packet", (4,)), ("packet", (4, 4, 4)), ("packet", (0, 4)), ("packet", (4, 17)),
    ("target_error", -0.1), ("target_error", NAN), ("target_error", INF),
    ("time_limit", -1.0), ("time_limit", NAN), ("time_limit", INF),
    ("adaptive_threshold", 0.0), ("adaptive_threshold", -0.1), ("adaptive_threshold", 1.5),
    ("adaptive_threshold", NAN), ("adaptive_min_samples", 1),
    ("width", 0), ("width", 1 << 17), ("height", 0), ("height", -3), ("spp", 0), ("spp", (1 << 24) + 1),
    ("threads", -1), ("threads", 5000), ("max_bounces", -1), ("max_bounces", 2000), ("diffuse_bounces", -1),
    ("glossy_bounces", -1), ("transmission_bounces", 1025), ("rr_min_bounces", -1), ("tile_size", 0),
    ("bvh_width", 3), ("wave_size", 0), ("ao_samples", 0), ("ao_distance", -1.0), ("ao_distance", NAN),
    ("ao_distance", 1e40),
    ("border", (0, 0, 9, 9)), ("border", (4, 0, 2, 8)), ("border", (1, 2, 3)),
]


def test_an_empty_border_renders_nothing():
    # Not an error: a farm's tile split may produce an empty tile.
    r = native.Renderer(small_scene(), width=8, height=8, spp=1, border=(3, 0, 3, 8))
    assert r.render()
    assert (r.film_width, r.film_height) == (0, 8)


@pytest.mark.parametrize("key,value", BAD_RENDERER_VALUES, ids=[f"{k}={v!r}" for k, v in BAD_RENDERER_VALUES])
def test_renderer_rejects_bad_value(key, value):
    with raises_naming(ValueError, key):
        native.Renderer(small_scene(), **{"width": 8, "height": 8, "spp": 1, key: value})


BAD_RENDERER_TYPES = [
    ("spp", "16"), ("width", 8.5), ("seed", -1), ("threads", "2"), ("target_error", "0.1"), ("time_limit", None),
    ("adaptive", "yes please"), ("adaptive_threshold", "0.01"), ("sampler", 3), ("heatmaps", "on"),
    ("packet", "ab"), ("packet", None), ("packet", 4), ("border", "abcd"), ("border", 7),
]


@pytest.mark.parametrize("key,value", BAD_RENDERER_TYPES, ids=[f"{k}={v!r}" for k, v in BAD_RENDERER_TYPES])
def test_renderer_rejects_wrong_type(key, value):
    with pytest.raises((TypeError, ValueError), match=re.escape(key)):
        native.Renderer(small_scene(), **{"width": 8, "height": 8, "spp": 1, key: value})


def test_renderer_needs_a_scene():
    with raises_naming(TypeError, "scene"):
        native.Renderer(None, width=8, height=8)


def test_renderer_accepts_the_edges_of_every_range():
    r = native.Renderer(small_scene(), width=1, height=1, spp=1, packet=(16, 1), adaptive_threshold=1.0,
                        adaptive_min_samples=2, target_error=0.0, time_limit=0.0, bvh_width=2, max_bounces=0,
                        border=(0, 0, 1, 1), ao_distance=0.0)
    assert r.render()


# --- Scene.add_mesh ------------------------------------------------------------------------------

BAD_MESHES = [
    # (argument named, exception, add_mesh keyword overrides)
    ("positions", ValueError, dict(positions=np.zeros((3, 2), np.float32))),
    ("positions", ValueError, dict(positions=np.zeros(9, np.float32))),
    ("positions", TypeError, dict(positions=np.array([["a", "b", "c"]] * 3))),
    ("positions", TypeError, dict(positions=None)),
    ("positions", TypeError, dict(positions=np.zeros((3, 3), complex))),
    ("indices", TypeError, dict(indices=np.array([[0.0, 1.0, 2.0]]))),
    ("indices", ValueError, dict(indices=np.array([[0, 1]]))),
    ("indices", TypeError, dict(indices=None)),
    ("matrix", ValueError, dict(matrix=np.eye(3))),
    ("matrix", ValueError, dict(matrix=np.full((4, 4), NAN))),
    ("matrix", ValueError, dict(matrix=np.diag([1.0, 1.0, INF, 1.0]))),
    ("matrix", TypeError, dict(matrix="identity")),
    ("matrix_close", ValueError, dict(matrix_close=np.full((4, 4), NAN))),
    ("normals", ValueError, dict(normals=np.zeros((2, 3, 3), np.float32))),
    ("normals", ValueError, dict(normals=np.zeros((1, 3), np.float32))),
    ("material_ids", ValueError, dict(material_ids=np.array([0, 0]))),
    ("material_ids", TypeError, dict(material_ids=np.array([0.5]))),
    ("material_slots", ValueError, dict(material_slots=[7])),
    ("material_slots", ValueError, dict(material_slots=[-1])),
    ("material_slots", TypeError, dict(material_slots=["white"])),
]


@pytest.mark.parametrize("arg,exc,overrides", BAD_MESHES, ids=[f"{a}-{i}" for i, (a, _, _) in enumerate(BAD_MESHES)])
def test_add_mesh_rejects_bad_input(arg, exc, overrides):
    s = native.Scene()
    kwargs = dict(positions=TRIANGLE, indices=ONE_FACE, matrix=np.eye(4))
    kwargs.update(overrides)
    with pytest.raises(exc, match=re.escape(arg)):
        s.add_mesh("mesh", **kwargs)


def test_add_mesh_drops_non_finite_and_out_of_range_triangles():
    # Broken geometry is dropped (and reported by the engine), not an error:
    # Blender scenes with a NaN vertex must still render.
    s = native.Scene()
    assert s.add_mesh("ok", TRIANGLE, ONE_FACE, np.eye(4)) == 1
    nan_vertex = TRIANGLE.copy()
    nan_vertex[0, 2] = NAN
    assert s.add_mesh("nan", nan_vertex, ONE_FACE, np.eye(4)) == 0
    assert s.add_mesh("oob", TRIANGLE, np.array([[0, 1, 3]]), np.eye(4)) == 0
    assert s.triangle_count == 1


# --- materials (closures) and lights ------------------------------------------------------------

BAD_MATERIALS = [
    ("closures[0]", TypeError, dict(closures=[1])),
    ("closures[0]", ValueError, dict(closures=[{"bogus": 1.0}])),
    ("closures[0]['ior']", ValueError, dict(closures=[{"ior": 0.0}])),
    ("closures[0]['ior']", ValueError, dict(closures=[{"ior": NAN}])),
    ("closures[0]['roughness']", ValueError, dict(closures=[{"roughness": NAN}])),
    ("closures[0]['base_color']", ValueError, dict(closures=[{"base_color": (1.0, 0.0)}])),
    ("closures[0]['base_color']", ValueError, dict(closures=[{"base_color": (NAN, 0.0, 0.0)}])),
    ("closures[0]['metallic']", TypeError, dict(closures=[{"metallic": "shiny"}])),
    ("closures[1]['specular']", TypeError, dict(closures=[{}, {"specular": None}])),
    ("closures", ValueError, dict(closures=[{}] * 64)),
    ("weights", ValueError, dict(closures=[{}, {}], weights=[1.0])),
    ("weights", ValueError, dict(closures=[{}], weights=[-1.0])),
    ("weights", ValueError, dict(closures=[{}], weights=[NAN])),
    ("weights", TypeError, dict(closures=[{}], weights=["half"])),
    ("emission", ValueError, dict(emission=(-1.0, 0.0, 0.0))),
    ("emission", ValueError, dict(emission=(NAN, 0.0, 0.0))),
    ("emission", ValueError, dict(emission=(1.0, 1.0))),
]


@pytest.mark.parametrize("arg,exc,kwargs", BAD_MATERIALS, ids=[f"{a}-{i}" for i, (a, _, _) in enumerate(BAD_MATERIALS)])
def test_add_material_rejects_bad_input(arg, exc, kwargs):
    with pytest.raises(exc, match=re.escape(arg)):
        native.Scene().add_material("m", **kwargs)


BAD_LIGHTS = [
    ("type", ValueError, dict(type="LASER")),
    ("shape", ValueError, dict(type="AREA", shape="TRIANGLE")),
    ("power", ValueError, dict(power=-1.0)),
    ("power", ValueError, dict(power=NAN)),
    ("power", TypeError, dict(power="bright")),
    ("color", ValueError, dict(color=(-1.0, 0.0, 0.0))),
    ("color", ValueError, dict(color=(1.0, 1.0))),
    ("position", ValueError, dict(position=(INF, 0.0, 0.0))),
    ("direction", ValueError, dict(direction=(0.0, 0.0, 0.0))),
    ("axis_u", ValueError, dict(type="AREA", axis_u=(0.0, 0.0, 0.0))),
    ("radius", ValueError, dict(radius=-0.5)),
    ("spot_size", ValueError, dict(type="SPOT", spot_size=NAN)),
    ("sun_angle", ValueError, dict(type="SUN", sun_angle=-1.0)),
    ("size_u", ValueError, dict(type="AREA", size_u=-1.0)),
    ("size_v", ValueError, dict(type="AREA", size_v=NAN)),
]


@pytest.mark.parametrize("arg,exc,kwargs", BAD_LIGHTS, ids=[f"{a}-{i}" for i, (a, _, _) in enumerate(BAD_LIGHTS)])
def test_add_light_rejects_bad_input(arg, exc, kwargs):
    kwargs = dict(kwargs)
    light_type = kwargs.pop("type", "POINT")
    with pytest.raises(exc, match=re.escape(arg)):
        native.Scene().add_light(light_type, **kwargs)


# --- the asynchronous path ---------------------------------------------------------------------

def test_start_wait_snapshot_and_progress():
    r = native.Renderer(small_scene(), width=16, height=8, spp=6, seed=3, threads=2)
    assert r.snapshot() == (0, None)  # nothing rendered yet
    r.start()
    assert r.wait() is True
    assert r.running is False
    p = r.progress()
    assert p["samples_done"] == 6 and p["samples_total"] == 6 and p["running"] is False and p["error"] == ""
    assert p["fraction"] == pytest.approx(1.0)
    samples, pixels = r.snapshot()
    assert samples == 6
    assert pixels.shape == (16 * 8, 4) and pixels.dtype == np.float32
    # The last snapshot is the finished film, row order included.
    np.testing.assert_array_equal(pixels, r.pass_pixels("Combined"))
    np.testing.assert_array_equal(r.snapshot(flip_y=False)[1], r.pass_pixels("Combined", flip_y=False))
    assert r.stats()["spp"] == 6


def test_async_render_matches_the_blocking_one():
    a = native.Renderer(small_scene(), width=12, height=12, spp=4, seed=9, threads=2)
    a.start()
    assert a.wait()
    b = native.Renderer(small_scene(), width=12, height=12, spp=4, seed=9, threads=1)
    assert b.render()
    np.testing.assert_array_equal(a.pass_pixels("Combined"), b.pass_pixels("Combined"))


def test_already_rendering_is_an_error_and_cancel_ends_start():
    # 2^20 passes: the render started below can only end by cancel(), so it
    # is certainly still running when the second start()/render() come.
    r = native.Renderer(small_scene(), width=32, height=32, spp=1 << 20, threads=2)
    r.start()
    try:
        with pytest.raises(RuntimeError, match="already rendering"):
            r.start()
        with pytest.raises(RuntimeError, match="already rendering"):
            r.render()
        with pytest.raises(RuntimeError, match="wait"):
            r.pass_pixels("Combined")  # the film is being written: snapshot() or wait() first
    finally:
        r.cancel()
        finished = r.wait()
    assert finished is False and r.cancelled
    assert r.running is False
    assert r.progress()["running"] is False
    assert r.stats()["spp"] < 1 << 20


def test_render_inside_its_own_progress_callback_is_an_error():
    r = native.Renderer(small_scene(), width=8, height=8, spp=2, threads=1)
    with pytest.raises(RuntimeError, match="already rendering"):
        r.render(lambda p: r.render())
    # The callback's exception cancelled the outer render.
    assert r.cancelled


# --- content_hash: the add-on's change detector for images held in Blender's memory ---------------

def test_content_hash_reads_any_contiguous_buffer_in_place_and_sees_one_changed_byte():
    import ctypes

    data = np.random.default_rng(3).integers(0, 256, 1 << 20, dtype=np.uint8)
    digest = native.content_hash(data)
    assert digest.startswith(f"{data.size} ")
    assert native.content_hash(data.tobytes()) == digest
    assert native.content_hash((ctypes.c_char * data.size).from_buffer(data)) == digest
    assert native.content_hash(data.view(np.float32)) == digest  # bytes, whatever the item type
    for index in (0, data.size // 2, data.size - 1):
        changed = data.copy()
        changed[index] ^= 1
        assert native.content_hash(changed) != digest, index
    # XXH3-64 of no bytes (seed 0), as the xxHash reference gives it.
    assert native.content_hash(b"") == "0 2d06800538d394c2"


def test_content_hash_refuses_a_strided_view():
    data = np.zeros(64, dtype=np.uint8)
    with pytest.raises((ValueError, BufferError)):
        native.content_hash(data[::2])
