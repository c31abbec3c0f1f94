"""addon/coherent/shader_compiler.py without Blender: node graphs built from
plain stand-ins for bpy's nodes, sockets and links.

Checks what the compiler decides on its own: constant subgraphs fold (with
the native formulas) so a constant graph yields no program; node groups are
entered (nested), reroutes and muted nodes followed; a group that contains
itself and one nested too deep warn naming the node and fall back to the
default; unsupported nodes warn once per type; and the program it emits for a
varying graph passes the native validation and evaluates as the nodes say.
"""
import importlib.util

import pytest

from native_module import MODULE_DIR as ADDON, native

spec = importlib.util.spec_from_file_location("shader_compiler", ADDON / "shader_compiler.py")
sc = importlib.util.module_from_spec(spec)
spec.loader.exec_module(sc)

_ids = iter(range(1, 1 << 30))


class Socket:
    def __init__(self, node, name, kind="VALUE", default=0.0, identifier=None):
        self.node, self.name, self.type, self.default_value = node, name, kind, default
        self.identifier = identifier or name
        self.links = []

    @property
    def is_linked(self):
        return bool(self.links)


class Link:
    def __init__(self, from_socket, to_socket):
        self.from_socket, self.to_socket, self.from_node = from_socket, to_socket, from_socket.node
        self.is_muted, self.is_valid = False, True


class Sockets(list):
    def __getitem__(self, key):
        if isinstance(key, str):
            return next(s for s in self if s.name == key)
        return list.__getitem__(self, key)

    def get(self, key):
        return next((s for s in self if s.name == key), None)


class Node:
    def __init__(self, idname, name=None, inputs=(), outputs=(), **props):
        self.bl_idname, self.name, self.mute, self.internal_links = idname, name or idname, False, []
        self.inputs = Sockets(Socket(self, *spec) for spec in inputs)
        self.outputs = Sockets(Socket(self, *spec) for spec in outputs)
        self._pointer = next(_ids)
        self.__dict__.update(props)

    def as_pointer(self):
        return self._pointer


class Tree:
    def __init__(self, name, nodes):
        self.name, self.nodes = name, nodes


def link(from_socket, to_socket):
    new = Link(from_socket, to_socket)
    to_socket.links.append(new)
    from_socket.links.append(new)  # as in bpy, an output lists its links too


def math(op, a=0.0, b=0.0):
    return Node("ShaderNodeMath", inputs=[("A", "VALUE", a), ("B", "VALUE", b), ("C", "VALUE", 0.0)],
                outputs=[("Value",)], operation=op, use_clamp=False)


def uv_node():
    return Node("ShaderNodeTexCoord", outputs=[("UV", "VECTOR"), ("Generated", "VECTOR")])


def compiler(fold=native.fold_shader_constants):
    warnings = []
    builder = sc.ProgramBuilder(fold)
    return sc.GraphCompiler(builder, warnings.append, lambda image, node: 0, lambda name: 0), builder, warnings


def consumer(kind="VALUE"):
    return Socket(Node("ShaderNodeEmission"), "Strength", kind, 1.0)


def test_constant_subgraph_folds_with_native_formulas():
    gc, builder, warnings = compiler()
    a, b = math("POWER", 2.0, 0.5), math("ADD", 0.0, 1.0)
    link(a.outputs[0], b.inputs[0])
    target = consumer()
    link(b.outputs[0], target)
    value = gc.input_value(target)
    assert sc.is_constant(value) and value == pytest.approx(2.0 ** 0.5 + 1.0, rel=1e-6)
    assert builder.code == [] and builder.program() is None and warnings == []


def test_varying_graph_emits_a_valid_program():
    gc, builder, warnings = compiler()
    coord, sep, mul = uv_node(), Node("ShaderNodeSeparateXYZ", inputs=[("Vector", "VECTOR", (0, 0, 0))],
                                      outputs=[("X",), ("Y",), ("Z",)]), math("MULTIPLY", 0.0, 3.0)
    link(coord.outputs["UV"], sep.inputs[0])
    link(sep.outputs["Y"], mul.inputs[0])
    target = consumer()
    link(mul.outputs[0], target)
    value = gc.input_value(target)
    assert isinstance(value, sc.Reg) and value.width == 1
    assert [row[0] for row in builder.code] == [sc.OP["TEX_COORD"], sc.OP["MATH"]]
    assert builder.uses == {"uv"}
    builder.output("emission", 0, value)
    scene = native.Scene()
    scene.set_shading_inputs(uv_names=[""])
    scene.add_material("m", closures=[], program=builder.program())  # validated natively


def test_groups_reroutes_and_muted_nodes_are_followed():
    gc, builder, warnings = compiler()
    inner_in = Node("NodeGroupInput", outputs=[("x", "VALUE", 0.0, "Input_0")])
    inner_out = Node("NodeGroupOutput", inputs=[("y", "VALUE", 0.0, "Output_0")], is_active_output=True)
    double = math("MULTIPLY", 0.0, 2.0)
    link(inner_in.outputs[0], double.inputs[0])
    link(double.outputs[0], inner_out.inputs[0])
    group = Node("ShaderNodeGroup", inputs=[("x", "VALUE", 0.0, "Input_0")],
                 outputs=[("y", "VALUE", 0.0, "Output_0")], node_tree=Tree("double", [inner_in, double, inner_out]))
    reroute = Node("NodeReroute", inputs=[("In", "VALUE")], outputs=[("Out", "VALUE")])
    muted = math("SINE")
    muted.mute = True
    muted.internal_links = [Link(muted.inputs[0], muted.outputs[0])]
    muted.internal_links[0].to_socket = muted.outputs[0]
    link(math("ADD", 0.25, 0.5).outputs[0], reroute.inputs[0])
    link(reroute.outputs[0], muted.inputs[0])
    link(muted.outputs[0], group.inputs[0])
    target = consumer()
    link(group.outputs[0], target)
    assert gc.input_value(target) == pytest.approx(1.5)  # (0.25 + 0.5) * 2, the sine muted
    assert warnings == []


def test_self_containing_and_too_deep_groups_warn_with_the_node_name():
    gc, builder, warnings = compiler()
    out = Node("NodeGroupOutput", inputs=[("y", "VALUE", 0.0, "Output_0")], is_active_output=True)
    tree = Tree("loop", [out])
    inner = Node("ShaderNodeGroup", name="inner_ref", outputs=[("y", "VALUE", 0.0, "Output_0")], node_tree=tree)
    link(inner.outputs[0], out.inputs[0])
    tree.nodes.append(inner)
    top = Node("ShaderNodeGroup", name="top", outputs=[("y", "VALUE", 0.7, "Output_0")], node_tree=tree)
    target = consumer()
    link(top.outputs[0], target)
    value = gc.input_value(target)
    assert sc.is_constant(value)
    assert any("inner_ref" in w and "contains itself" in w for w in warnings), warnings


def test_unsupported_nodes_warn_once_per_type_and_use_the_default():
    gc, builder, warnings = compiler()
    targets = []
    for name in ("noise_a", "noise_b"):
        noise = Node("ShaderNodeTexPointDensity", name=name, outputs=[("Fac", "VALUE", 0.25)])
        target = consumer()
        link(noise.outputs[0], target)
        targets.append(gc.input_value(target))
    assert targets == [0.25, 0.25]
    assert len(warnings) == 1 and "ShaderNodeTexPointDensity" in warnings[0] and "noise_a" in warnings[0]


def test_colour_to_float_uses_luminance_and_float_to_colour_broadcasts():
    assert sc.convert_constant((1.0, 0.0, 0.0), 1) == pytest.approx(sc._LUMA[0])
    assert sc.convert_constant(0.5, 3) == (0.5, 0.5, 0.5)


# -- procedural textures ---------------------------------------------------------------


def _lookup3_final(a, b, c):
    """Bob Jenkins' lookup3 final() on 32-bit words, written from lookup3.c, independent of native/."""
    m = 0xFFFFFFFF
    rot = lambda x, k: ((x << k) | (x >> (32 - k))) & m  # noqa: E731
    c ^= b; c = (c - rot(b, 14)) & m
    a ^= c; a = (a - rot(c, 11)) & m
    b ^= a; b = (b - rot(a, 25)) & m
    c ^= b; c = (c - rot(b, 16)) & m
    a ^= c; a = (a - rot(c, 4)) & m
    b ^= a; b = (b - rot(a, 14)) & m
    c ^= b; c = (c - rot(b, 24)) & m
    return c


def _hash_float3_to_float(x, y, z):
    """Cycles' hash_float3_to_float: lookup3 hashword of the three float bit patterns, seed 13, as [0, 1]."""
    import struct
    import numpy as np
    kx, ky, kz = (struct.unpack("<I", struct.pack("<f", v))[0] for v in (x, y, z))
    a = b = c = (0xDEADBEEF + (3 << 2) + 13) & 0xFFFFFFFF
    c, b, a = (c + kz) & 0xFFFFFFFF, (b + ky) & 0xFFFFFFFF, (a + kx) & 0xFFFFFFFF
    return float(np.float32(_lookup3_final(a, b, c)) * (np.float32(1.0) / np.float32(0xFFFFFFFF)))


def white_noise(vector, dims="3D"):
    return Node("ShaderNodeTexWhiteNoise", inputs=[("Vector", "VECTOR", vector), ("W", "VALUE", 0.0)],
                outputs=[("Value",), ("Color", "RGBA")], noise_dimensions=dims)


def test_procedural_node_with_constant_inputs_folds_to_cycles_hash():
    gc, builder, warnings = compiler()
    target = consumer()
    link(white_noise((1.5, -2.0, 0.25)).outputs["Value"], target)
    value = gc.input_value(target)
    assert sc.is_constant(value) and builder.code == [] and warnings == []
    assert value == _hash_float3_to_float(1.5, -2.0, 0.25)


def test_procedural_nodes_emit_valid_programs():
    gc, builder, warnings = compiler()
    coord = uv_node()
    fac_color, color_fac = [("Fac",), ("Color", "RGBA")], [("Color", "RGBA"), ("Fac",)]
    kinds = {  # Blender's outputs, in its order, and the node's properties
        "ShaderNodeTexNoise": (fac_color, dict(noise_dimensions="4D")),
        "ShaderNodeTexVoronoi": ([("Distance",), ("Color", "RGBA"), ("Position", "VECTOR"), ("W",), ("Radius",)],
                                 dict(voronoi_dimensions="2D", feature="SMOOTH_F1", distance="MINKOWSKI")),
        "ShaderNodeTexMusgrave": ([("Fac",)], dict(musgrave_dimensions="3D", musgrave_type="HETERO_TERRAIN")),
        "ShaderNodeTexWave": (color_fac, dict(wave_type="RINGS", bands_direction="X", rings_direction="SPHERICAL",
                                              wave_profile="TRI")),
        "ShaderNodeTexGradient": (color_fac, dict(gradient_type="RADIAL")),
        "ShaderNodeTexMagic": (color_fac, dict(turbulence_depth=4)),
        "ShaderNodeTexBrick": (color_fac, dict(offset=0.5, offset_frequency=2, squash=1.0, squash_frequency=2)),
    }
    names = ["W", "Scale", "Detail", "Roughness", "Distortion", "Smoothness", "Exponent", "Randomness", "Dimension",
             "Lacunarity", "Offset", "Gain", "Detail Scale", "Detail Roughness", "Phase Offset", "Mortar Size",
             "Mortar Smooth", "Bias", "Brick Width", "Row Height"]
    inputs = [("Vector", "VECTOR", (0, 0, 0))] + [(n, "VALUE", 0.5) for n in names] + \
        [(n, "RGBA", (0.5, 0.5, 0.5)) for n in ("Color1", "Color2", "Mortar")]
    values = []
    for idname, (outputs, props) in kinds.items():
        tex = Node(idname, inputs=inputs, outputs=outputs, **props)
        link(coord.outputs["UV"], tex.inputs["Vector"])
        targets = [consumer(out.type) for out in tex.outputs]
        for out, target in zip(tex.outputs, targets):  # every output linked: one instruction computes them all
            link(out, target)
        values += [gc.input_value(target) for target in targets]
    assert warnings == [] and all(isinstance(v, sc.Reg) for v in values)
    procedural = [row for row in builder.code if sc.OP["TEX_WHITE_NOISE"] <= row[0] <= sc.OP["TEX_BRICK"]]
    assert len(procedural) == len(kinds)
    for v in values:
        builder.output("emission", 0, v)
    scene = native.Scene()
    scene.set_shading_inputs(uv_names=[""])
    scene.add_material("m", closures=[], program=builder.program())  # validated natively


def test_links_from_hidden_sockets_are_ignored_as_cycles_does():
    gc, builder, warnings = compiler()
    tex = white_noise((1.5, -2.0, 0.25))
    tex.outputs["Color"].enabled = False  # as Blender hides an output a mode does not have
    target = consumer()
    link(tex.outputs["Color"], target)
    assert gc.input_value(target) == 1.0 and builder.code == []  # the consumer's own default

# -- Colour adjustments, inputs and bump ----------------------------------------------


def map_range(kind, value, clamp=True):
    inputs = [("Value", "VALUE", value), ("From Min", "VALUE", 0.2), ("From Max", "VALUE", 0.6),
              ("To Min", "VALUE", 1.0), ("To Max", "VALUE", 3.0), ("Steps", "VALUE", 4.0)]
    inputs += [(name + "_FLOAT3", "VECTOR", (0.0, 0.0, 0.0)) for name in ("Vector", "From_Min", "From_Max", "To_Min",
                                                                          "To_Max", "Steps")]
    return Node("ShaderNodeMapRange", inputs=inputs, outputs=[("Result",), ("Vector", "VECTOR")],
                data_type="FLOAT", interpolation_type=kind, clamp=clamp)


@pytest.mark.parametrize("kind, value, expected", [("LINEAR", 0.4, 2.0), ("LINEAR", 0.9, 3.0),
                                                   ("STEPPED", 0.45, 1.0 + 2.0 * 3.0 / 4.0),
                                                   ("SMOOTHSTEP", 0.4, 2.0), ("SMOOTHERSTEP", 0.1, 1.0)])
def test_constant_map_range_folds_to_cycles_values(kind, value, expected):
    # Clamped to To Min .. To Max as Cycles' MapRangeNode::expand does; stepped: floor(0.625 * 5) / 4.
    gc, builder, warnings = compiler()
    target = consumer()
    link(map_range(kind, value).outputs[0], target)
    assert gc.input_value(target) == pytest.approx(expected, rel=1e-6)
    assert builder.code == [] and warnings == []


def test_bump_compiles_its_height_three_times_with_shifted_positions():
    gc, builder, warnings = compiler()
    geometry = Node("ShaderNodeNewGeometry", outputs=[("Position", "VECTOR"), ("Normal", "VECTOR")])
    sep = Node("ShaderNodeSeparateXYZ", inputs=[("Vector", "VECTOR", (0, 0, 0))], outputs=[("X",), ("Y",), ("Z",)])
    link(geometry.outputs["Position"], sep.inputs[0])
    bump = Node("ShaderNodeBump", inputs=[("Strength", "VALUE", 1.0), ("Distance", "VALUE", 1.0),
                                          ("Height", "VALUE", 0.0), ("Normal", "VECTOR", (0, 0, 0))],
                outputs=[("Normal", "VECTOR")], invert=False)
    link(sep.outputs["X"], bump.inputs["Height"])
    target = Socket(Node("ShaderNodeBsdfDiffuse"), "Normal", "VECTOR", (0, 0, 0))
    link(bump.outputs[0], target)
    value = gc.input_value(target)
    geometry_modes = [row[1] for row in builder.code if row[0] == sc.OP["GEOMETRY"]]
    position = sc.GEOMETRY_OUTPUTS.index("Position")
    assert sorted(geometry_modes) == sorted([sc.GEOMETRY_OUTPUTS.index("Normal")] +
                                            [position | axis << sc.BUMP_AXIS_SHIFT for axis in (0, 1, 2)])
    assert builder.code[-1][0] == sc.OP["BUMP"] and warnings == []
    builder.output("normal", 0, value)
    native.Scene().add_material("m", closures=[{}], program=builder.program())  # validated natively


def test_bump_without_a_height_passes_its_normal_through():
    gc, builder, warnings = compiler()
    bump = Node("ShaderNodeBump", inputs=[("Strength", "VALUE", 1.0), ("Distance", "VALUE", 1.0),
                                          ("Height", "VALUE", 0.0), ("Normal", "VECTOR", (0, 0, 0))],
                outputs=[("Normal", "VECTOR")], invert=False)
    target = Socket(Node("ShaderNodeBsdfDiffuse"), "Normal", "VECTOR", (0, 0, 0))
    link(bump.outputs[0], target)
    gc.input_value(target)
    assert [row[0] for row in builder.code] == [sc.OP["GEOMETRY"]]  # just the shading normal


def test_unsupported_geometry_and_attribute_outputs_warn_with_the_node_name():
    gc, builder, warnings = compiler()
    geometry = Node("ShaderNodeNewGeometry", name="geo", outputs=[("Pointiness",)])
    attribute = Node("ShaderNodeAttribute", name="attr", outputs=[("Fac",)], attribute_type="OBJECT",
                     attribute_name="x")
    assert gc.output_value(geometry, geometry.outputs[0]) == 0.5
    assert gc.output_value(attribute, attribute.outputs[0]) == 0.0
    assert any("'geo'" in w and "Pointiness" in w for w in warnings)
    assert any("'attr'" in w for w in warnings)
