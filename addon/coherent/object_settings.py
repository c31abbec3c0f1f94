# SPDX-License-Identifier: Apache-2.0
"""Per-object settings the native scene reads besides geometry, looked up on
the Blender objects behind exported names."""

from __future__ import annotations

import bpy

# Cycles' default Shadow Terminator Geometry Offset (native kDefaultTerminatorOffset).
DEFAULT_TERMINATOR_OFFSET = 0.1


def blender_object(name):
    """The Blender object an exported object name stands for (an instance
    "parent/object" takes its object's); None if there is none."""
    objects = bpy.data.objects
    return objects.get(name) or objects.get(name.rsplit("/", 1)[-1])


def set_shadow_terminator(nscene):
    """Cycles' Object > Shading > Shadow Terminator > Geometry Offset (stored
    by the Cycles add-on), for the objects that change it from the default."""
    offsets = {}
    for name in nscene.object_names:
        ob = blender_object(name)
        settings = getattr(ob, "cycles", None) if ob is not None else None
        offset = getattr(settings, "shadow_terminator_geometry_offset", None)
        if offset is not None and abs(offset - DEFAULT_TERMINATOR_OFFSET) > 1e-7:
            offsets[name] = min(max(float(offset), 0.0), 1.0)
    if offsets:
        nscene.set_shadow_terminator(offsets)
