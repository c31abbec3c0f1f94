"""The add-on's native module (_coherent) for the tests that use it without
Blender (the add-on package itself needs bpy, the module does not). A
module that is not built is a failure that says so, never a skip."""
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
MODULE_DIR = REPO / "addon" / "coherent"

if not sorted(MODULE_DIR.glob("_coherent*.so")):
    pytest.fail(f"the native module _coherent*.so is not built in {MODULE_DIR}; build the CMake target _coherent",
                pytrace=False)
sys.path.insert(0, str(MODULE_DIR))
import _coherent as native  # noqa: E402,F401
