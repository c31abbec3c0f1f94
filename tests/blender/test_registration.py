# The add-on registers and unregisters cleanly, repeatedly, in a live Blender.

import bpy
import pytest

from blender_helpers import ENGINE_ID

SETTINGS = ("samples", "max_bounces", "diffuse_bounces", "glossy_bounces",
            "transmission_bounces", "seed", "threads")


def registered_engines():
    return [c for c in bpy.types.RenderEngine.__subclasses__()
            if getattr(c, "bl_idname", None) == ENGINE_ID and c.is_registered]


def engine_selectable(scene):
    """Whether 'COHERENT' is accepted as render engine (RNA rejects unknown ids)."""
    previous = scene.render.engine
    try:
        scene.render.engine = ENGINE_ID
    except TypeError:
        return False
    scene.render.engine = previous
    return True


def test_bl_info(coherent_addon):
    info = coherent_addon.bl_info
    assert info["name"]
    assert info["category"] == "Render"
    assert tuple(info["blender"]) <= bpy.app.version
    assert all(isinstance(v, int) for v in info["version"])


def test_engine_is_registered(coherent_addon):
    engines = registered_engines()
    assert len(engines) == 1, engines
    assert engine_selectable(bpy.context.scene)


def test_register_unregister_twice(coherent_addon):
    scene = bpy.context.scene
    for _ in range(2):
        coherent_addon.unregister()
        assert registered_engines() == []
        assert not hasattr(bpy.types.Scene, "coherent")
        assert not engine_selectable(scene)
        coherent_addon.register()
        assert len(registered_engines()) == 1
        assert hasattr(bpy.types.Scene, "coherent")
        assert engine_selectable(scene)
    # Settings still work after re-registration.
    scene.coherent.samples = 7
    assert scene.coherent.samples == 7


@pytest.mark.parametrize("name", SETTINGS)
def test_scene_settings_exist(coherent_addon, name):
    settings = bpy.context.scene.coherent
    assert hasattr(settings, name), f"scene.coherent has no property {name!r}"
    value = getattr(settings, name)
    assert isinstance(value, int), (name, value)
    prop = settings.bl_rna.properties[name]
    # A value inside the declared range round-trips.
    target = max(prop.hard_min, min(prop.hard_max, value + 1))
    setattr(settings, name, target)
    assert getattr(settings, name) == target
    setattr(settings, name, value)


def test_bounce_settings_reject_negative(coherent_addon):
    settings = bpy.context.scene.coherent
    for name in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces"):
        setattr(settings, name, -5)  # RNA clamps to the hard minimum
        assert getattr(settings, name) >= 0, name
    settings.samples = 0
    assert settings.samples >= 1
