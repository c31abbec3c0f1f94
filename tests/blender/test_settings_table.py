# The one settings table (native/render/setting_table.h) as the Python module
# and the Blender add-on see it: Renderer(...) takes exactly its names, with
# one validation naming the setting; the Blender properties' types, enum
# items, ranges and tooltips are the table's. Runs in Blender's Python.

import bpy
import numpy as np
import pytest


@pytest.fixture
def native(coherent_addon):
    return coherent_addon.native_module()


@pytest.fixture
def table(native):
    return {row["name"]: row for row in native.settings_table()}


@pytest.fixture
def props(coherent_addon):
    return bpy.context.scene.coherent


def quad_scene(native):
    scene = native.Scene()
    quad = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    scene.add_mesh("Quad", quad, np.array([[0, 1, 2], [0, 2, 3]]), np.eye(4))
    return scene


# --- the table itself ----------------------------------------------------------------------------

def test_rows_are_complete_and_defaults_are_in_range(native, table):
    assert len(table) == len(native.settings_table()), "names are unique"
    for name, row in table.items():
        assert row["type"] in {"bool", "int", "seed", "real", "choice", "size"}, name
        assert row["label"] and row["help"] and row["group"], name
        assert row["cli_name"].startswith("--"), name
        if row["type"] in {"int", "real"}:
            assert row["min"] <= row["default"] <= row["max"], name
            assert row["min"] <= row["soft_max"] <= row["max"], name
        if row["type"] == "choice":
            names = [c[0] for c in row["choices"]]
            assert row["default"] in names and len(set(names)) == len(names), name


def test_every_default_is_accepted_by_the_renderer(native, table):
    defaults = {name: row["default"] for name, row in table.items()}
    defaults.update(width=8, height=8, spp=1, threads=1)  # keep it quick; still table values
    r = native.Renderer(quad_scene(native), **defaults)
    assert r.render()
    settings = r.settings
    assert set(table) <= set(settings)


# --- one validation, naming the setting -------------------------------------------------------

def out_of_range(row):
    if row["type"] == "int":
        return int(row["max"]) + 1 if not row["allowed"] else 3
    if row["type"] == "real":
        return row["max"] * 2 + 1
    if row["type"] == "choice":
        return "no-such-" + row["name"]
    if row["type"] == "size":
        return (int(row["max"]) + 1, 1)
    return None


def wrong_type(row):
    return {"bool": 1, "int": "4", "seed": 1.5, "real": "x", "choice": 3, "size": 4}[row["type"]]


def test_out_of_range_values_raise_value_error_naming_the_setting(native, table):
    checked = 0
    for name, row in table.items():
        bad = out_of_range(row)
        if bad is None:
            continue
        with pytest.raises(ValueError, match=name):
            native.Renderer(quad_scene(native), **{name: bad})
        checked += 1
    assert checked >= 25


def test_wrong_types_raise_type_error_naming_the_setting(native, table):
    for name, row in table.items():
        with pytest.raises(TypeError, match=name):
            native.Renderer(quad_scene(native), **{name: wrong_type(row)})


def test_unknown_names_and_cross_setting_rules(native):
    with pytest.raises(TypeError, match="unknown setting 'spp_max'"):
        native.Renderer(quad_scene(native), spp_max=4)
    with pytest.raises(ValueError, match="width x height"):
        native.Renderer(quad_scene(native), width=65536, height=65536)
    with pytest.raises(ValueError, match="border"):
        native.Renderer(quad_scene(native), width=8, height=8, border=(0, 0, 9, 8))
    with pytest.raises(ValueError, match="seed"):
        native.Renderer(quad_scene(native), seed=-1)
    r = native.Renderer(quad_scene(native), width=8, height=8, seed=(1 << 64) - 1)
    assert r.settings["seed"] == (1 << 64) - 1


def test_a_settings_dict_and_keywords_combine(native):
    r = native.Renderer(quad_scene(native), {"width": 8, "height": 6, "spp": 3, "integrator": "ao"}, spp=2)
    s = r.settings
    assert (s["width"], s["height"], s["spp"], s["integrator"]) == (8, 6, 2, "ao")
    with pytest.raises(TypeError, match="settings"):
        native.Renderer(quad_scene(native), [("spp", 2)])


# --- the Blender properties come from the table ------------------------------------------------

def test_blender_properties_follow_the_table(coherent_addon, props, table):
    from coherent import properties
    int32 = (1 << 31) - 1
    for prop, (name, overrides) in properties.TABLE_PROPERTIES.items():
        row, rna = table[name], props.bl_rna.properties[prop]
        if "description" not in overrides:
            assert rna.description.lower() == row["help"].lower(), prop
        if row["type"] == "choice":
            items = [i.identifier for i in rna.enum_items]
            assert items == [c[0].upper() for c in row["choices"] if not c[3]], prop
        elif row["type"] == "int" and row["allowed"]:
            assert [int(i.identifier) for i in rna.enum_items] == row["allowed"], prop
        elif row["type"] == "real":  # float32 in Blender
            assert rna.hard_min == pytest.approx(row["min"], rel=1e-6), prop
            assert rna.hard_max == pytest.approx(row["max"], rel=1e-6), prop
        elif row["type"] in {"int", "size"}:  # int32 in Blender
            assert (rna.hard_min, rna.hard_max) == (max(row["min"], -int32 - 1), min(row["max"], int32)), prop


@pytest.fixture
def edited_props(props):
    """scene.coherent, restored to its values after the test."""
    saved = {p.identifier: getattr(props, p.identifier) for p in props.bl_rna.properties
             if p.identifier != "rna_type" and not p.is_readonly}
    saved = {k: (tuple(v) if hasattr(v, "__len__") and not isinstance(v, str) else v) for k, v in saved.items()}
    yield props
    for k, v in saved.items():
        setattr(props, k, v)


def test_renderer_kwargs_are_table_names_the_renderer_accepts(coherent_addon, native, edited_props, table):
    props = edited_props
    kwargs = props.renderer_kwargs(bpy.context.scene)
    assert set(kwargs) <= set(table)
    props.integrator = "AO"
    props.bvh_width = "4"
    props.packet_size = (2, 8)
    props.clamp_direct = 3.0
    kwargs = props.renderer_kwargs(bpy.context.scene)
    r = native.Renderer(quad_scene(native), width=8, height=8, spp=1, **kwargs)
    s = r.settings
    assert (s["integrator"], s["bvh_width"], s["packet"], s["clamp_direct"]) == ("ao", 4, (2, 8), 3.0)
