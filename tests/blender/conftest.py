# Fixtures for the Blender-side tests (run inside Blender through
# run_pytest.py; see there for how the add-on directory reaches sys.path).

import sys

import pytest

import blender_helpers as bh

if str(bh.ADDON_DIR) not in sys.path:
    sys.path.insert(0, str(bh.ADDON_DIR))


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "shared: reads the public scenes in ../shared/scenes; runs only in the CTest entry "
        "blender-shared (label `shared`), which every other entry deselects with -m 'not shared'")


def addon_is_registered():
    import bpy
    return hasattr(bpy.types.Scene, "coherent")


@pytest.fixture(scope="session")
def repo_root():
    return bh.REPO_ROOT


@pytest.fixture(scope="session")
def blend_scenes():
    return bh.BLEND_SCENES


@pytest.fixture(scope="session")
def shared_scenes():
    """../shared/scenes; only tests marked `shared` use it, and they run only
    where it exists (.ci/run), so its absence is a failure, not a skip."""
    if not bh.SHARED_SCENES.is_dir():
        pytest.fail(f"{bh.SHARED_SCENES} does not exist; tests marked `shared` need the public scenes")
    return bh.SHARED_SCENES


@pytest.fixture(scope="session")
def native_built():
    if not bh.native_module_paths():
        pytest.fail(f"the native module _coherent*.so is not built in {bh.ADDON_PACKAGE}; "
                    "build the CMake target _coherent first")
    return bh.native_module_paths()[0]


@pytest.fixture
def coherent_addon(native_built):
    """The add-on package, registered in this Blender (registered once and
    kept registered; tests that unregister it must register it again)."""
    import coherent
    if not addon_is_registered():
        coherent.register()
    return coherent


@pytest.fixture(scope="session")
def user_scripts(tmp_path_factory, native_built):
    """A BLENDER_USER_SCRIPTS dir whose addons/coherent links to the working tree."""
    return bh.make_user_scripts(tmp_path_factory.mktemp("blender_user"))


@pytest.fixture
def blender(user_scripts):
    """Runs a subprocess `blender -b --factory-startup --addons coherent ...`."""
    def run(*args, timeout=300, addons=True, cwd=None):
        return bh.run_blender(args, user_scripts, timeout=timeout, addons=addons, cwd=cwd)
    return run
