# The Python module's tracing options: Renderer(integrator=..., traversal=...,
# assembly=..., bvh_width=..., reorder=..., wave_size=..., ao_samples=...,
# ao_distance=..., heatmaps=...), its `settings` and per-bounce stats(), and
# the 'BVH Visits' / 'SIMD Utilisation' passes. Runs in Blender's Python
# (the module is built for it) on a small scene made with the module itself.
#
# Tests named test_renderer_honours_* check what the renderer must do with
# a setting (not just accept it).

import math

import numpy as np
import pytest

SIZE = 24


@pytest.fixture
def native(coherent_addon):
    return coherent_addon.native_module()


def ground_and_box(native):
    """A large floor (z = 0) with a unit cube on it, seen from above at an
    angle so that every pixel sees geometry; lit by a white world."""
    scene = native.Scene()
    floor = np.array([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], np.float32)
    scene.add_mesh("Floor", floor, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    v = np.array([[x, y, z] for z in (0, 1) for y in (-0.5, 0.5) for x in (-0.5, 0.5)], np.float32)
    faces = np.array([[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], [0, 1, 5], [0, 5, 4],
                      [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]])
    scene.add_mesh("Box", v, faces, np.eye(4))
    eye = np.array([0.0, -3.0, 3.0])
    forward = -eye / np.linalg.norm(eye)
    up = np.cross(np.cross(forward, [0, 0, 1]), forward)
    scene.set_camera(position=tuple(eye), forward=tuple(forward), up=tuple(up / np.linalg.norm(up)))
    scene.world_color = (1.0, 1.0, 1.0)
    return scene


def render(native, scene=None, **kwargs):
    args = dict(width=SIZE, height=SIZE, spp=2, seed=5, threads=2)
    args.update(kwargs)
    r = native.Renderer(scene if scene is not None else ground_and_box(native), **args)
    assert r.render()
    return r


# --- arguments -------------------------------------------------------------------------------

def test_defaults(native):
    r = native.Renderer(ground_and_box(native), width=8, height=8, spp=1)
    s = r.settings
    assert (s["integrator"], s["traversal"], s["assembly"], s["bvh_width"], s["reorder"]) == \
        ("pt", "single", "types", 8, "none")
    assert s["wave_size"] == 65536 and s["ao_samples"] == 16 and s["ao_distance"] == 0.0
    assert s["heatmaps"] is False
    assert s["packet"] == (4, 4)


def test_auto_traversal_resolves_by_sampler(native):
    # Packets where they pay (CPT), single rays otherwise; the settings
    # report what was resolved.
    scene = ground_and_box(native)
    for sampler, expected in (("cpt", "packet"), ("spt", "single"), ("icpt", "single")):
        r = native.Renderer(scene, width=8, height=8, spp=1, sampler=sampler, traversal="auto")
        assert r.settings["traversal"] == expected, sampler


ACCEPTED = [
    *[("integrator", v, v) for v in ["pt", "drt", "wrt", "rcs", "ao"]],
    *[("traversal", v, v) for v in ["single", "packet", "stream", "wavefront"]],
    ("traversal", "wide", "single"),
    ("assembly", "types", "types"), ("assembly", "runs", "runs"),
    *[("bvh_width", w, w) for w in (2, 4, 8)],
    *[("reorder", v, v) for v in ["none", "static1d", "static3d", "hash32", "hash192", "csd32"]],
    ("wave_size", 1000, 1000), ("ao_samples", 3, 3), ("ao_distance", 0.5, 0.5), ("heatmaps", True, True),
]


@pytest.mark.parametrize("name,value,expected", ACCEPTED, ids=[f"{n}={v}" for n, v, _ in ACCEPTED])
def test_accepted_values_reach_settings(native, name, value, expected):
    extra = {"traversal": "wavefront"} if name == "reorder" else {}
    r = native.Renderer(ground_and_box(native), width=8, height=8, spp=1, **{name: value}, **extra)
    assert r.settings[name] == expected
    assert r.render()


BAD = [("integrator", "path"), ("integrator", "PT"), ("traversal", "simd"), ("assembly", "rays"),
       ("bvh_width", 3), ("bvh_width", 16), ("reorder", "hash64"), ("wave_size", 0), ("wave_size", -1),
       ("ao_samples", 0), ("ao_distance", -1.0), ("ao_distance", math.nan), ("ao_distance", math.inf),
       ("ao_distance", 1e300)]


@pytest.mark.parametrize("name,value", BAD, ids=[f"{n}={v}" for n, v in BAD])
def test_bad_values_raise_value_error_naming_the_argument(native, name, value):
    with pytest.raises(ValueError, match=name):
        native.Renderer(ground_and_box(native), width=8, height=8, spp=1, **{name: value})


@pytest.mark.parametrize("name,value", [("integrator", 1), ("bvh_width", "8"), ("heatmaps", "yes")])
def test_wrong_types_raise_type_error(native, name, value):
    with pytest.raises(TypeError):
        native.Renderer(ground_and_box(native), width=8, height=8, spp=1, **{name: value})


def test_unknown_pass_lists_the_heatmaps(native):
    r = render(native, spp=1)
    with pytest.raises(ValueError, match="BVH Visits"):
        r.pass_pixels("Heat")


# --- statistics ------------------------------------------------------------------------------

def finite_ratio(value, lo=0.0, hi=math.inf):
    return value is None or (math.isfinite(value) and lo <= value <= hi)


@pytest.mark.parametrize("traversal", ["single", "packet", "stream", "wavefront"])
def test_stats_carry_per_bounce_work(native, traversal):
    stats = render(native, traversal=traversal).stats()
    for key in ["bounces", "simd_utilisation", "rays_per_second", "trace_seconds", "sort_seconds"]:
        assert key in stats, key
    assert stats["rays_per_second"] == pytest.approx(stats["mrays_per_s"] * 1e6)
    assert stats["trace_seconds"] >= 0 and stats["sort_seconds"] >= 0
    assert finite_ratio(stats["simd_utilisation"]["box"], 0, 1)
    assert finite_ratio(stats["simd_utilisation"]["triangle"], 0, 1)
    for i, b in enumerate(stats["bounces"]):
        assert b["bounce"] == i and b["and_deeper"] == (i == 7)
        assert b["box_lanes_active"] <= b["box_lanes"] and b["triangle_lanes_active"] <= b["triangle_lanes"]
        for key in ["node_visits_per_ray", "box_tests_per_ray", "triangle_tests_per_ray"]:
            assert finite_ratio(b[key]), (key, b)
        for key in ["simd_box_utilisation", "simd_triangle_utilisation"]:
            assert finite_ratio(b[key], 0, 1), (key, b)


@pytest.mark.parametrize("traversal", ["single", "packet", "stream", "wavefront"])
def test_renderer_honours_per_bounce_counts(native, traversal):
    stats = render(native, traversal=traversal).stats()
    bounces = stats["bounces"]
    assert bounces, "no per-bounce statistics"
    assert sum(b["rays"] for b in bounces) == stats["total_rays"]
    assert bounces[0]["rays"] >= SIZE * SIZE * 2  # camera rays (and their shadow rays)
    if traversal == "packet":
        assert 0.0 < stats["simd_utilisation"]["box"] <= 1.0
    if traversal == "single":
        assert stats["simd_utilisation"] == {"box": None, "triangle": None}


# --- heatmap passes --------------------------------------------------------------------------

@pytest.mark.parametrize("traversal", ["single", "packet"])
def test_heatmap_passes_have_the_film_shape_and_are_finite(native, traversal):
    r = render(native, traversal=traversal, heatmaps=True)
    for name in ["BVH Visits", "SIMD Utilisation"]:
        p = r.pass_pixels(name)
        assert p.shape == (SIZE * SIZE, 1) and p.dtype == np.float32
        assert np.isfinite(p).all() and (p >= 0).all()


def test_heatmap_passes_are_zero_when_off(native):
    r = render(native)
    assert not r.pass_pixels("BVH Visits").any()
    assert not r.pass_pixels("SIMD Utilisation").any()


@pytest.mark.parametrize("traversal", ["single", "packet"])
def test_renderer_honours_heatmaps(native, traversal):
    r = render(native, traversal=traversal, heatmaps=True)
    visits = r.pass_pixels("BVH Visits")[:, 0]
    simd = r.pass_pixels("SIMD Utilisation")[:, 0]
    assert (visits >= 1).all()  # every pixel sees the floor: its camera ray enters the BVH
    assert ((simd > 0) & (simd <= 1)).all()
    if traversal == "single":
        assert (simd == 1).all()  # single rays waste no lane (film.h)
    # Flipped like every other pass (flip_y=True: bottom row first).
    top_first = r.pass_pixels("BVH Visits", flip_y=False)[:, 0].reshape(SIZE, SIZE)
    assert np.array_equal(top_first[::-1].reshape(-1), visits)


def test_renderer_honours_ambient_occlusion(native):
    r = render(native, integrator="ao", ao_samples=8, ao_distance=0.5, spp=4)
    rgba = r.pass_pixels("Combined").reshape(SIZE, SIZE, 4)
    rgb = rgba[..., :3]
    assert np.isfinite(rgb).all()
    assert (rgb >= 0).all() and (rgb <= 1).all()
    assert np.array_equal(rgb[..., 0], rgb[..., 1]) and np.array_equal(rgb[..., 1], rgb[..., 2])  # grey
    # The open floor more than 0.5 from the cube is unoccluded; near the
    # cube's base up to half the hemisphere is blocked.
    assert rgb.max() == pytest.approx(1.0)
    assert rgb.min() < 0.9
    assert (rgb[..., 0] == 1.0).mean() > 0.3
