"""Scene.add_prototype / add_instances through the Python module: argument
checks that name the argument, counts, and an instanced scene rendering as
the same triangles flattened with add_mesh, for every traversal."""


import numpy as np
import pytest

from native_module import native

# An octahedron: 6 vertices, 8 faces.
OCTA_P = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float32)
OCTA_I = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]])


def placements(count, seed=1):
    """Random rotations, scales in [0.3, 0.8] (every third mirrored) and
    translations over a 6 x 6 square: row-major object-to-world matrices."""
    rng = np.random.default_rng(seed)
    out = np.zeros((count, 4, 4), np.float32)
    for k in range(count):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        scale = rng.uniform(0.3, 0.8, 3) * ([-1, 1, 1] if k % 3 == 0 else 1)
        out[k, :3, :3] = q * scale
        out[k, :3, 3] = [rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(0.5, 1.5)]
        out[k, 3, 3] = 1.0
    return out


def base_scene():
    s = native.Scene()
    s.add_mesh("floor", np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], np.float32),
               np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    s.world_color = (0.6, 0.6, 0.6)
    s.set_camera(position=(0.0, -6.0, 6.0), forward=(0.0, 0.7071, -0.7071), up=(0.0, 0.7071, 0.7071))
    return s


def test_arguments_are_checked_and_named():
    s = base_scene()
    proto = s.add_prototype("octa", OCTA_P, OCTA_I)
    assert proto == 0
    with pytest.raises(ValueError, match="matrices"):
        s.add_instances(proto, np.eye(4))  # one matrix must still be (1, 4, 4)
    with pytest.raises(ValueError, match="prototype"):
        s.add_instances(3, placements(2))
    with pytest.raises(ValueError, match="material_slots"):
        s.add_instances(proto, placements(2), material_slots=[9])
    assert s.add_prototype("empty", OCTA_P, np.array([[0, 0, 0]])) == -1  # nothing usable
    assert "empty" in s.dropped_summary
    singular = placements(3)
    singular[1, :3, :3] = 0.0
    assert s.add_instances(proto, singular) == 2
    assert "non-invertible" in s.dropped_summary
    assert (s.prototype_count, s.instance_count, s.instanced_triangle_count) == (1, 2, 16)
    assert s.triangle_count == 2  # the floor only


@pytest.mark.parametrize("traversal", ["single", "packet", "stream", "wavefront"])
def test_instances_render_as_the_flattened_triangles(traversal):
    matrices = placements(40)
    instanced, flattened = base_scene(), base_scene()
    red = instanced.add_material("red", closures=[{"base_color": (0.8, 0.2, 0.1)}])
    assert flattened.add_material("red", closures=[{"base_color": (0.8, 0.2, 0.1)}]) == red
    proto = instanced.add_prototype("octa", OCTA_P, OCTA_I)
    assert instanced.add_instances(proto, matrices, material_slots=[red], name="octas") == 40
    for m in matrices:
        flattened.add_mesh("octa", OCTA_P, OCTA_I, m, material_slots=[red])
    assert flattened.triangle_count == instanced.triangle_count + instanced.instanced_triangle_count

    def render(scene):
        r = native.Renderer(scene, width=32, height=32, spp=8, traversal=traversal, sampler="cpt")
        r.render()
        return r.pass_pixels("Combined")[:, :3]

    a, b = render(instanced), render(flattened)
    # Memory: the 40 instances are counted, each a record of a few hundred
    # bytes (three 3x4 transforms and indices), not 8 triangles' worth of copies.
    r = native.Renderer(instanced, width=8, height=8, spp=1)
    r.render()
    memory = r.stats()["memory"]
    assert memory["instances"] == 40
    assert 100 <= memory["bytes_per_instance"] <= 400, memory
    assert memory["triangles"] < flattened.triangle_count, memory
    # The same samples meet the same surfaces: the images differ only where
    # rounding in the transform changes a path, far inside the noise.
    assert abs(a.mean() / b.mean() - 1.0) < 0.01, (a.mean(), b.mean())
    assert np.abs(a - b).mean() < 0.02 * b.mean()


def test_moving_instances_render_as_moving_flattened_triangles():
    opens = placements(30, seed=4)
    closes = opens.copy()
    closes[:, 0, 3] += 0.8  # every instance slides along x over the shutter
    instanced, flattened = base_scene(), base_scene()
    proto = instanced.add_prototype("octa", OCTA_P, OCTA_I)
    with pytest.raises(ValueError, match="matrices_close"):
        instanced.add_instances(proto, opens, matrices_close=closes[:3])
    assert instanced.add_instances(proto, opens, matrices_close=closes) == 30
    for a, b in zip(opens, closes):
        flattened.add_mesh("octa", OCTA_P, OCTA_I, a, matrix_close=b)
    assert "motion_blur" in instanced.features

    def render(scene, traversal):
        r = native.Renderer(scene, width=32, height=32, spp=16, traversal=traversal, sampler="cpt")
        r.render()
        return r.pass_pixels("Combined")[:, :3]

    flat = render(flattened, "single")
    for traversal in ("single", "stream"):
        a = render(instanced, traversal)
        assert abs(a.mean() / flat.mean() - 1.0) < 0.01, (traversal, a.mean(), flat.mean())
        assert np.abs(a - flat).mean() < 0.02 * flat.mean()
