"""Fixtures shared by the CLI tests.

The scene the tests render is generated here by tests/fixtures/make_gltf.py,
so the suite needs nothing beside the clone (the public scenes in
../shared/scenes are for benchmarks and the `shared` CTest label).
"""
import importlib.util
import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli():
    path = os.environ.get("COHERENT_CLI")
    if not path:
        pytest.fail("COHERENT_CLI must name the built coherent executable (ctest sets it)")
    assert Path(path).is_file(), path
    return path


@pytest.fixture(scope="session")
def cornell(tmp_path_factory):
    """The generated Cornell box (.glb): diffuse walls, a metal block, a glass
    sphere, an emissive ceiling quad, a point light and a camera."""
    spec = importlib.util.spec_from_file_location("make_gltf", REPO / "tests" / "fixtures" / "make_gltf.py")
    make_gltf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_gltf)
    path = tmp_path_factory.mktemp("fixtures") / "cornell_box.glb"
    make_gltf.cornell_box(path)
    return path
