# SPDX-License-Identifier: Apache-2.0
"""Coherent: a CPU ray tracer for Blender built on coherent ray traversal.

Package layout (imitating Cycles' add-on): engine.py holds the RenderEngine,
properties.py the settings stored in the .blend, operators.py the operators,
ui.py the panels. export.py and materials.py (with motion.py) turn the
depsgraph into a native scene; viewport.py runs the Rendered viewport from
viewport_sync.py (depsgraph updates into the native scene),
viewport_render.py (the progressive restarts) and viewport_draw.py (the GPU
texture). quality_model.py is the Quality Cost model, plain Python. The
native module `_coherent` (built by CMake into this folder) does all heavy
work.
"""

bl_info = {
    "name": "Coherent",
    "author": "COHERENT authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Render Engine",
    "description": "CPU path tracer with packet, stream and wavefront ray traversal",
    "warning": "",
    "doc_url": "",
    "category": "Render",
}

# Support 'reload' (F3 > Reload Scripts): re-import submodules in dependency order.
if "bpy" in locals():
    import importlib

    for _name in ("quality_model", "materials", "motion", "export", "scene_reuse", "viewport_sync", "persistent", "viewport_render",
                  "viewport_draw", "viewport", "properties", "engine", "operators", "ui"):
        if _name in locals():
            importlib.reload(locals()[_name])

import os
import sys

import bpy

from . import engine, export, materials, operators, properties, quality_model, ui, viewport

_native = None
_native_error = None
_registered = False


def native_module():
    """The compiled `_coherent` module; raises ImportError with build instructions if missing."""
    global _native, _native_error
    if _native is not None:
        return _native
    try:
        from . import _coherent
    except ImportError as e:
        here = os.path.dirname(os.path.abspath(__file__))
        _native_error = (
            f"Coherent: the native module '_coherent' could not be loaded from {here} ({e}). "
            f"Build it with: cmake -S <repo> -B <repo>/build -DCMAKE_BUILD_TYPE=Release && "
            f"cmake --build <repo>/build --target _coherent "
            f"(it must be built for Python {sys.version_info.major}.{sys.version_info.minor}, Blender's Python)."
        )
        raise ImportError(_native_error) from None
    _native = _coherent
    _native_error = None
    return _native


def register():
    """Registers properties, the engine and panels. Calling it twice is harmless."""
    global _registered
    if _registered:
        return
    properties.register()
    bpy.utils.register_class(engine.CoherentRenderEngine)
    operators.register()
    ui.register()
    _registered = True
    try:
        native_module()
    except ImportError as e:
        # Registration still succeeds so the engine shows up; rendering then
        # fails with the same message instead of a traceback.
        print(str(e), file=sys.stderr)


def unregister():
    """Undoes register(). Calling it twice (or before register) is harmless."""
    global _registered
    if not _registered:
        return
    ui.unregister()
    operators.unregister()  # stops a running estimate before its settings go
    bpy.utils.unregister_class(engine.CoherentRenderEngine)
    properties.unregister()
    _registered = False
