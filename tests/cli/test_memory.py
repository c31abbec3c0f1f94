"""Large scenes in memory (render/memory_budget.h), through the CLI and the
Python module: the JSON report and stats() carry the render's sizes (scene,
BVH and film bytes, bytes per triangle, the process's peak RSS), and a
render over its memory limit (COHERENT_MEMORY_LIMIT, a budget for the whole
render) fails before building, with an error naming the sizes: exit status 1
from the CLI, MemoryError from the module, after which the module still
renders.
"""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from test_cli import oiio_pixels, write_gltf

REPO = Path(__file__).resolve().parents[2]
GRID = 120  # vertices per side: 2 * 119^2 = 28,322 triangles
TRIANGLES = 2 * (GRID - 1) ** 2


def grid_arrays():
    xs = np.linspace(-1.0, 1.0, GRID, dtype=np.float32)
    x, y = np.meshgrid(xs, xs)
    positions = np.stack([x.ravel(), y.ravel(), np.zeros(GRID * GRID, np.float32)], axis=1)
    i = (np.arange(GRID - 1)[:, None] * GRID + np.arange(GRID - 1)[None, :]).ravel()
    indices = np.concatenate([np.stack([i, i + 1, i + GRID], 1), np.stack([i + 1, i + GRID + 1, i + GRID], 1)])
    return positions, indices


@pytest.fixture(scope="module")
def grid_gltf(tmp_path_factory):
    positions, indices = grid_arrays()
    # A camera 3 units above the grid, looking down -z (glTF cameras look down their -z).
    camera = {"camera": 0, "translation": [0.0, 0.0, 3.0]}
    path = write_gltf(tmp_path_factory.mktemp("grid") / "grid.gltf", positions.ravel().tolist(),
                      indices.ravel().tolist(), extra_nodes=[camera])
    doc = json.loads(path.read_text())
    doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}}]
    path.write_text(json.dumps(doc))
    return path


def render_cli(cli, scene, out, env=None):
    return subprocess.run([cli, "render", str(scene), "-o", str(out), "--res", "32", "32", "--spp", "2", "--json"],
                          capture_output=True, text=True, timeout=300, env=env)


def test_json_report_has_the_render_memory(cli, grid_gltf, tmp_path):
    r = render_cli(cli, grid_gltf, tmp_path / "grid.exr")
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    m = report["memory"]
    assert m["triangles"] == report["triangles"] == TRIANGLES
    # The scene holds at least its 3 world-space vertices per triangle (36
    # bytes); the finished BVH measures 72-86 bytes per triangle on the
    # repository's scenes (memory_budget.cpp).
    assert m["scene_bytes"] >= 36 * TRIANGLES
    assert 40 * TRIANGLES <= m["bvh_bytes"] <= 200 * TRIANGLES
    assert m["bytes_per_triangle"] == pytest.approx((m["scene_bytes"] + m["bvh_bytes"]) / TRIANGLES)
    assert 100 <= m["bytes_per_triangle"] <= 500
    assert m["bvh_bytes_per_triangle"] == pytest.approx(m["bvh_bytes"] / TRIANGLES)
    assert m["film_bytes"] >= 32 * 32 * 4 * 4  # at least RGBA float per pixel
    assert m["estimate_bytes"] >= m["scene_bytes"] + m["bvh_bytes"] + m["film_bytes"]
    assert m["limit_bytes"] > 0  # MemAvailable is known on Linux
    # The process held the scene and the BVH at once, and a 28k-triangle
    # render needs nowhere near 4 GiB.
    assert m["scene_bytes"] + m["bvh_bytes"] <= m["peak_rss_bytes"] < 4 << 30


def test_a_render_over_the_memory_limit_fails_before_rendering(cli, grid_gltf, tmp_path):
    out = tmp_path / "never.exr"
    r = render_cli(cli, grid_gltf, out, env=dict(os.environ, COHERENT_MEMORY_LIMIT="2M"))
    assert r.returncode == 1, r.stdout + r.stderr
    assert r.stdout == ""
    message = r.stderr.strip()
    assert len(message.splitlines()) == 1, message
    for part in ("not enough memory", f"{TRIANGLES} triangles", "COHERENT_MEMORY_LIMIT=2M", "2.0 MiB"):
        assert part in message, message
    assert not out.exists()


def test_a_malformed_memory_limit_is_named(cli, grid_gltf, tmp_path):
    r = render_cli(cli, grid_gltf, tmp_path / "never.exr", env=dict(os.environ, COHERENT_MEMORY_LIMIT="lots"))
    assert r.returncode == 1
    assert "COHERENT_MEMORY_LIMIT: 'lots' is not a memory size" in r.stderr, r.stderr


# --- the Python module ---------------------------------------------------------------------------

@pytest.fixture
def native():
    sys.path.insert(0, str(REPO / "addon" / "coherent"))
    import _coherent
    return _coherent


def grid_scene(native):
    positions, indices = grid_arrays()
    s = native.Scene()
    s.add_mesh("grid", positions, indices, np.eye(4))
    s.set_camera(position=(0.0, 0.0, 3.0), forward=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0))
    s.world_color = (0.5, 0.5, 0.5)
    return s


def test_module_raises_memory_error_naming_the_sizes_and_still_renders(native, monkeypatch):
    scene = grid_scene(native)
    monkeypatch.setenv("COHERENT_MEMORY_LIMIT", "1M")
    with pytest.raises(MemoryError) as error:
        native.Renderer(scene, width=16, height=16, spp=1)
    message = str(error.value)
    for part in ("not enough memory", f"{TRIANGLES} triangles", "COHERENT_MEMORY_LIMIT=1M", "1.0 MiB"):
        assert part in message, message
    monkeypatch.delenv("COHERENT_MEMORY_LIMIT")
    renderer = native.Renderer(scene, width=16, height=16, spp=1)  # the scene is still usable
    assert renderer.render()
    m = renderer.stats()["memory"]
    assert m["triangles"] == TRIANGLES and m["bvh_bytes"] == renderer.bvh_stats()["bytes"]
    assert 100 <= m["bytes_per_triangle"] <= 500
    assert m["peak_rss_bytes"] >= m["scene_bytes"] + m["bvh_bytes"]


def test_gltf_mesh_placed_by_several_nodes_is_stored_once(cli, tmp_path):
    # Three nodes placing one glTF mesh become one prototype and three
    # instances (its triangles and BVH stored once); three copies of the mesh
    # are three world-space meshes. The images agree up to the rounding of
    # hits through a transform.
    positions, indices = grid_arrays()
    camera = {"camera": 0, "translation": [0.0, 0.0, 6.0]}
    places = [{"translation": [x, 0.0, 0.0]} for x in (-2.2, 0.0, 2.2)]
    reports, images = {}, {}
    for kind in ("shared", "copies"):
        path = write_gltf(tmp_path / f"{kind}.gltf", positions.ravel().tolist(), indices.ravel().tolist())
        doc = json.loads(path.read_text())
        doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.01}}]
        if kind == "copies":
            doc["meshes"] = doc["meshes"] * 3
        doc["nodes"] = [{**place, "mesh": 0 if kind == "shared" else k} for k, place in enumerate(places)] + [camera]
        doc["scenes"] = [{"nodes": [0, 1, 2, 3]}]
        path.write_text(json.dumps(doc))
        r = render_cli(cli, path, tmp_path / f"{kind}.exr")
        assert r.returncode == 0, r.stderr
        reports[kind] = json.loads(r.stdout)["memory"]
        pixels = oiio_pixels(tmp_path / f"{kind}.exr")
        images[kind] = np.array([pixels[key][:3] for key in sorted(pixels)])
    assert reports["shared"]["instances"] == 3 and reports["copies"]["instances"] == 0
    # One copy of the grid's vertices instead of three.
    assert reports["shared"]["scene_bytes"] < 0.5 * reports["copies"]["scene_bytes"]
    shared, copies = images["shared"], images["copies"]
    assert shared.std() > 0.01, "the grids must be visible"
    close = np.abs(shared - copies) <= 1e-4 * np.maximum(1.0, np.abs(copies))
    assert close.mean() > 0.99, f"{100 * (1 - close.mean()):.2f} % of values differ"
