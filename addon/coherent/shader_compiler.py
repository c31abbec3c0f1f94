# SPDX-License-Identifier: Apache-2.0
"""Shader node graphs to native shader programs (native/shader/program.h).

materials.py walks the shader (closure) nodes of a material; wherever a
closure input is linked to a texture or maths node, it asks this module for
the input's value. The compiler follows the link backwards through reroutes,
muted nodes and (nested) node groups, emits one instruction per node into a
linear program over float registers, and returns either a constant (when the
whole subgraph is constant: it is folded with the native formulas, so a
material without textures stays a constant material) or a register.

The module only reads node attributes (bl_idname, inputs, outputs, links,
properties), so its tests can drive it with plain Python stand-ins.

Values: a Python float, a 3-tuple of floats (constants), or a `Reg`.
"""

from __future__ import annotations

# Instruction opcodes: ShaderOp in native/shader/program.h, in order.
OPS = ("MATH", "VECTOR_MATH", "MIX_COLOR", "MIX_FLOAT", "MIX_VECTOR", "MAPPING", "COLOR_RAMP", "INVERT",
       "RGB_TO_BW", "COMBINE", "CHECKER", "IMAGE_TEXTURE", "TEX_COORD", "NORMAL_MAP", "CLAMP",
       # Procedural textures (the block at the end of this file)
       "TEX_WHITE_NOISE", "TEX_NOISE", "TEX_VORONOI", "TEX_MUSGRAVE", "TEX_WAVE", "TEX_GRADIENT", "TEX_MAGIC",
       "TEX_BRICK")
# Colour adjustments, inputs and bump
OPS += ("CURVES", "FLOAT_CURVE", "HUE_SAT_VAL", "GAMMA", "BRIGHT_CONTRAST", "MAP_RANGE", "VECTOR_MAP_RANGE_FACTOR",
        "VECTOR_MAP_RANGE_APPLY", "COLOR_CONVERT", "FRESNEL", "GEOMETRY", "LIGHT_PATH", "ATTRIBUTE",
        "BUMP_TEX_COORD", "BUMP")
OPS += ("SKY_TEXTURE",)  # Sky
OP = {name: i for i, name in enumerate(OPS)}
# Closure fields a program drives: ShaderField in program.h, in order.
FIELDS = ("base_color", "metallic", "roughness", "specular", "transmission", "ior", "weight", "emission", "normal")
FIELD = {name: i for i, name in enumerate(FIELDS)}
VEC3_FIELDS = {"base_color", "emission", "normal"}

# Blender enum identifiers in the order of their native enums (node_math.h, node_color.h).
MATH_OPS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "SINE", "COSINE", "TANGENT", "ARCSINE", "ARCCOSINE",
            "ARCTANGENT", "POWER", "LOGARITHM", "MINIMUM", "MAXIMUM", "ROUND", "LESS_THAN", "GREATER_THAN",
            "MODULO", "ABSOLUTE", "ARCTAN2", "FLOOR", "CEIL", "FRACT", "SQRT", "INVERSE_SQRT", "SIGN", "EXPONENT",
            "RADIANS", "DEGREES", "SINH", "COSH", "TANH", "TRUNC", "SNAP", "WRAP", "COMPARE", "MULTIPLY_ADD",
            "PINGPONG", "SMOOTH_MIN", "SMOOTH_MAX")
VECTOR_MATH_OPS = ("ADD", "SUBTRACT", "MULTIPLY", "DIVIDE", "CROSS_PRODUCT", "PROJECT", "REFLECT", "DOT_PRODUCT",
                   "DISTANCE", "LENGTH", "SCALE", "NORMALIZE", "SNAP", "FLOOR", "CEIL", "MODULO", "FRACTION",
                   "ABSOLUTE", "MINIMUM", "MAXIMUM", "WRAP", "SINE", "COSINE", "TANGENT", "REFRACT", "FACEFORWARD",
                   "MULTIPLY_ADD")
BLEND_TYPES = ("MIX", "ADD", "MULTIPLY", "SUBTRACT", "SCREEN", "DIVIDE", "DIFFERENCE", "DARKEN", "LIGHTEN",
               "OVERLAY", "DODGE", "BURN", "HUE", "SATURATION", "VALUE", "COLOR", "SOFT_LIGHT", "LINEAR_LIGHT")
MAPPING_TYPES = ("POINT", "TEXTURE", "VECTOR", "NORMAL")
TEX_COORDS = {"UV": 0, "Generated": 1, "Object": 2, "Normal": 3}
NORMAL_MAP_SPACES = {"TANGENT": 0, "OBJECT": 1, "WORLD": 2}
IMAGE_INTERPOLATION = {"Linear": 0, "Closest": 1, "Cubic": 2, "Smart": 2}
IMAGE_EXTENSION = {"REPEAT": 0, "EXTEND": 1, "CLIP": 2}
IMAGE_SRGB, IMAGE_UNASSOCIATE, IMAGE_IGNORE_ALPHA = 0x10, 0x20, 0x80  # program.h's ImageFlags
CLAMP_BIT = 0x100          # Math clamp / Mix clamp factor
CLAMP_RESULT_BIT = 0x200   # Mix (colour) clamp result
NON_UNIFORM_BIT = 0x400    # Mix (vector) per-component factor
RAMP_TABLE_SIZE = 256
MAX_GROUP_DEPTH = 16
# Ops that read geometry or images: never folded.
_VARYING_OPS = {OP["TEX_COORD"], OP["IMAGE_TEXTURE"], OP["NORMAL_MAP"], OP["FRESNEL"], OP["GEOMETRY"],
                OP["LIGHT_PATH"], OP["ATTRIBUTE"], OP["BUMP_TEX_COORD"], OP["BUMP"]}
# Cycles' luma of Blender 3.4's scene linear space (RGB to BW, colour -> float conversion).
_LUMA = (0.212671, 0.71516, 0.072169)


class Reg:
    """A register holding a float (width 1) or a vec3 (width 3)."""

    __slots__ = ("index", "width")

    def __init__(self, index, width):
        self.index = index
        self.width = width

    def component(self, k):
        return Reg(self.index + k, 1)

    def __repr__(self):
        return f"Reg({self.index}, {self.width})"


def is_constant(value):
    return not isinstance(value, Reg)


def _width_of(socket_type):
    return 3 if socket_type in ("RGBA", "VECTOR") else 1


class ProgramBuilder:
    """Registers, instructions and outputs of one program; folds constant instructions.

    `fold(program_dict) -> registers` runs instructions natively
    (_coherent.fold_shader_constants); without it nothing is folded.
    """

    def __init__(self, fold=None):
        self.constants = []
        self.code = []
        self.data = []
        self.outputs = []
        self.uses = set()  # "uv", "tangents", "objects"
        self._fold = fold
        self._const_regs = {}
        self._const_indices = set()

    # -- registers ------------------------------------------------------------

    def register(self, value, width):
        """A register holding `value` converted to `width` (constants are shared)."""
        if isinstance(value, Reg):
            return self.convert(value, width)
        value = convert_constant(value, width)
        key = (width, value)
        reg = self._const_regs.get(key)
        if reg is None:
            reg = Reg(len(self.constants), width)
            self.constants.extend([value] if width == 1 else list(value))
            self._const_regs[key] = reg
            self._const_indices.add(reg.index)
        return reg

    def convert(self, reg, width, as_color=True):
        if reg.width == width:
            return reg
        if width == 3:  # float -> (f, f, f)
            return self.emit("COMBINE", 0, [(reg, 1), (reg, 1), (reg, 1)], (3,))[0]
        if as_color:  # colour -> luma, as Cycles converts
            return self.emit("RGB_TO_BW", 0, [(reg, 3)], (1,))[0]
        return self.emit("VECTOR_MATH", VECTOR_MATH_OPS.index("DOT_PRODUCT"),
                         [(reg, 3), ((1 / 3, 1 / 3, 1 / 3), 3), (0.0, 3), (0.0, 1)], (3, 1))[1]

    def _new(self, width):
        reg = Reg(len(self.constants), width)
        self.constants.extend([0.0] * width)
        return reg

    # -- instructions -----------------------------------------------------------

    def emit(self, op, mode, inputs, out_widths, data=0):
        """Appends an instruction; returns its outputs (constants where it folded)."""
        ins = [self.register(v, w) if v is not None else None for v, w in inputs]
        outs = [self._new(w) for w in out_widths]
        row = [OP[op], mode, -1, -1, -1, -1, -1, -1, data]
        for k, reg in enumerate(outs):
            row[2 + k] = reg.index
        for k, reg in enumerate(ins):
            row[4 + k] = reg.index if reg is not None else -1
        self.code.append(row)
        if self._fold is not None and OP[op] not in _VARYING_OPS and all(
                i is None or self._is_constant_reg(i) for i in ins):
            return self._fold_last(outs)
        return outs

    def _is_constant_reg(self, reg):
        return reg.index in self._const_indices

    def _fold_last(self, outs):
        row = self.code.pop()
        registers = self._fold({"code": [row], "constants": self.constants, "data": self.data})
        values = []
        for reg in outs:
            v = registers[reg.index:reg.index + reg.width]
            values.append(float(v[0]) if reg.width == 1 else tuple(float(x) for x in v))
        return values

    def output(self, field, closure, value):
        self.outputs.append((FIELD[field], closure, self.register(value, 3 if field in VEC3_FIELDS else 1).index))

    def program(self):
        """The dict Scene.add_material(program=...) takes; None when nothing varies."""
        if not self.outputs:
            return None
        return {"code": self.code, "constants": self.constants, "data": self.data, "outputs": self.outputs}


def convert_constant(value, width):
    if width == 1:
        if isinstance(value, tuple):
            return float(sum(c * w for c, w in zip(value, _LUMA)))
        return float(value)
    if isinstance(value, tuple):
        return tuple(float(c) for c in value[:3])
    return (float(value),) * 3


def socket_default(socket):
    """A socket's own value as a compiler constant."""
    value = getattr(socket, "default_value", 0.0)
    if _width_of(socket.type) == 3:
        return tuple(float(value[k]) for k in range(3))
    try:
        return float(value)
    except TypeError:
        return 0.0


# -- the node graph ---------------------------------------------------------------


class GraphCompiler:
    """Compiles what feeds input sockets of one material's node tree.

    warn(text): one warning line (the caller prefixes the material name).
    image_index(image, node) -> scene image index: registers an image.
    uv_index(name) -> UV layer index ("" = the active render UV map).
    color_index(name) -> colour attribute index ("" = the render colour attribute); None: not exported.
    image_is_float(image) -> Image.is_float without a decode where possible; None: read Image.is_float.
    """

    def __init__(self, builder, warn, image_index, uv_index, color_index=None, image_is_float=None):
        self.b = builder
        self.warn = warn
        self.image_index = image_index
        self.image_is_float = image_is_float
        self.uv_index = uv_index
        self.color_index = color_index
        self._cache = {}          # (group path, node pointer, output name, bump axis) -> value
        self._warned_types = set()
        self._warned_links = set()  # pointers of invalid links already reported
        self._group_path = ()     # the group nodes we are inside, outermost first
        self.consumer = ""        # which closure input is being compiled, for warnings
        self.bump_axis = 0        # compiling a Bump height at offset 1 (dx) or 2 (dy): position reads shift

    # -- sockets and links ------------------------------------------------------------

    def input_value(self, socket, width=None):
        """The value flowing into an input socket (its default when unlinked)."""
        width = width or _width_of(socket.type)
        linked = self._follow(socket)
        if linked is None:
            return convert_constant(socket_default(socket), width)
        node, out = linked
        value = self.output_value(node, out)
        if isinstance(value, Reg):
            return self.b.convert(value, width, as_color=out.type == "RGBA")
        return convert_constant(value, width)

    def _follow(self, socket):
        """(node, output socket) feeding `socket` across reroutes, muted nodes and group boundaries."""
        for _ in range(256):
            link = next((l for l in socket.links if _link_used(l)), None) if socket.is_linked else None
            if link is None:
                self._warn_invalid_links(socket)
                return None
            node = link.from_node
            if node.bl_idname == "NodeReroute":
                socket = node.inputs[0]
            elif node.mute:
                socket = next((il.from_socket for il in node.internal_links if il.to_socket == link.from_socket), None)
                if socket is None:
                    return None
            elif node.bl_idname == "NodeGroupInput":
                if not self._group_path:
                    return None
                group = self._group_path[-1]
                outer = _by_identifier(group.inputs, link.from_socket.identifier)
                if outer is None:
                    return None
                # The group node's input lives one level up.
                self._group_path = self._group_path[:-1]
                try:
                    return self._resolved_outside(outer, group)
                finally:
                    self._group_path = self._group_path + (group,)
            else:
                return node, link.from_socket
        return None

    def _warn_invalid_links(self, socket):
        # Blender marks a link invalid when it closes a cycle (or joins sockets
        # it cannot convert); Cycles drops it silently, we say so once.
        for link in socket.links if socket.is_linked else ():
            if not link.is_valid and link.as_pointer() not in self._warned_links:
                self._warned_links.add(link.as_pointer())
                self.warn(f"link from node '{link.from_node.name}' to node '{link.to_node.name}' is invalid "
                          f"(a cycle, or sockets that cannot connect): ignored, using the input's default value")

    def _resolved_outside(self, socket, group):
        # Evaluate the outer socket in the outer context now, and hand back a
        # constant pseudo node so the caller's context stays unchanged.
        return _Resolved(self.input_value(socket)), _RESOLVED_OUTPUT

    # -- nodes ----------------------------------------------------------------------------

    def output_value(self, node, out):
        if isinstance(node, _Resolved):
            return node.value
        key = (tuple(g.as_pointer() for g in self._group_path), node.as_pointer(), out.identifier, self.bump_axis)
        if key not in self._cache:
            self._cache[key] = self._compile_node(node, out)
        return self._cache[key]

    def _compile_node(self, node, out):
        handler = _HANDLERS.get(node.bl_idname)
        if handler is None:
            if node.bl_idname not in self._warned_types:
                self._warned_types.add(node.bl_idname)
                feeding = f" (feeding {self.consumer})" if self.consumer else ""
                self.warn(f"node {node.bl_idname} ('{node.name}'){feeding} is not supported: "
                          f"using its output's default value")
            return socket_default(out) if hasattr(out, "default_value") else 0.0
        return handler(self, node, out)

    def group(self, node, out):
        tree = node.node_tree
        if tree is None:
            return socket_default(out)
        if len(self._group_path) >= MAX_GROUP_DEPTH:
            self.warn(f"node group '{node.name}' nested deeper than {MAX_GROUP_DEPTH}: using the default value")
            return socket_default(out)
        if any(g.node_tree == tree for g in self._group_path):
            self.warn(f"node group '{node.name}' ({tree.name}) contains itself: using the default value")
            return socket_default(out)
        output = next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput" and n.is_active_output), None) or \
            next((n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"), None)
        inner = _by_identifier(output.inputs, out.identifier) if output is not None else None
        if inner is None:
            return socket_default(out)
        self._group_path = self._group_path + (node,)
        try:
            return self.input_value(inner, _width_of(out.type))
        finally:
            self._group_path = self._group_path[:-1]


def _link_used(link):
    """Cycles skips muted and invalid links, and links from or to a socket the node hides (unavailable)."""
    return not link.is_muted and link.is_valid and getattr(link.from_socket, "enabled", True) and \
        getattr(link.to_socket, "enabled", True)


def _by_identifier(sockets, identifier):
    return next((s for s in sockets if s.identifier == identifier), None)


class _Resolved:
    """A value computed outside the current node group, standing in for a node."""

    def __init__(self, value):
        self.value = value


class _ResolvedOutput:
    type = "RGBA"
    identifier = "resolved"


_RESOLVED_OUTPUT = _ResolvedOutput()


# -- node handlers: (compiler, node, output socket) -> value --------------------------


def _inp(gc, node, key, width=None):
    return gc.input_value(node.inputs[key], width)


def _value_node(gc, node, out):
    return float(node.outputs[0].default_value)


def _rgb_node(gc, node, out):
    return tuple(float(c) for c in node.outputs[0].default_value[:3])


def _math(gc, node, out):
    mode = MATH_OPS.index(node.operation) | (CLAMP_BIT if node.use_clamp else 0)
    ins = [(_inp(gc, node, k, 1), 1) for k in range(3)]
    return gc.b.emit("MATH", mode, ins, (1,))[0]


def _vector_math(gc, node, out):
    vec, value = gc.b.emit("VECTOR_MATH", VECTOR_MATH_OPS.index(node.operation),
                           [(_inp(gc, node, 0, 3), 3), (_inp(gc, node, 1, 3), 3), (_inp(gc, node, 2, 3), 3),
                            (_inp(gc, node, "Scale", 1), 1)], (3, 1))
    return value if out.identifier == "Value" else vec


def _mix_rgb(gc, node, out):
    # Legacy MixRGB: Cycles uses the factor as is and clamps only the result.
    mode = BLEND_TYPES.index(node.blend_type) | (CLAMP_RESULT_BIT if node.use_clamp else 0)
    return gc.b.emit("MIX_COLOR", mode, [(_inp(gc, node, "Fac", 1), 1), (_inp(gc, node, "Color1", 3), 3),
                                         (_inp(gc, node, "Color2", 3), 3)], (3,))[0]


def _mix(gc, node, out):
    """Blender 3.4's Mix node: inputs 0/1 factor (float/vector), 2-3 floats, 4-5 vectors, 6-7 colours."""
    clamp_factor = CLAMP_BIT if node.clamp_factor else 0
    kind = node.data_type
    if kind == "FLOAT":
        return gc.b.emit("MIX_FLOAT", clamp_factor, [(_inp(gc, node, 0, 1), 1), (_inp(gc, node, 2, 1), 1),
                                                     (_inp(gc, node, 3, 1), 1)], (1,))[0]
    if kind == "VECTOR":
        non_uniform = node.factor_mode == "NON_UNIFORM"
        fac = (_inp(gc, node, 1, 3), 3) if non_uniform else (_inp(gc, node, 0, 1), 1)
        mode = clamp_factor | (NON_UNIFORM_BIT if non_uniform else 0)
        return gc.b.emit("MIX_VECTOR", mode, [fac, (_inp(gc, node, 4, 3), 3), (_inp(gc, node, 5, 3), 3)], (3,))[0]
    mode = BLEND_TYPES.index(node.blend_type) | clamp_factor | (CLAMP_RESULT_BIT if node.clamp_result else 0)
    return gc.b.emit("MIX_COLOR", mode, [(_inp(gc, node, 0, 1), 1), (_inp(gc, node, 6, 3), 3),
                                         (_inp(gc, node, 7, 3), 3)], (3,))[0]


def _mapping(gc, node, out):
    kind = MAPPING_TYPES.index(node.vector_type)
    ins = [(_inp(gc, node, "Vector", 3), 3)]
    for name in ("Location", "Rotation", "Scale"):
        socket = node.inputs.get(name) if hasattr(node.inputs, "get") else None
        ins.append((gc.input_value(socket, 3) if socket is not None else (0.0, 0.0, 0.0), 3))
    return gc.b.emit("MAPPING", kind, ins, (3,))[0]


def _color_ramp(gc, node, out):
    ramp = node.color_ramp
    offset = len(gc.b.data)
    for i in range(RAMP_TABLE_SIZE):
        gc.b.data.extend(float(c) for c in ramp.evaluate(i / (RAMP_TABLE_SIZE - 1)))
    interpolate = 1 if ramp.interpolation != "CONSTANT" else 0
    color, alpha = gc.b.emit("COLOR_RAMP", interpolate, [(_inp(gc, node, "Fac", 1), 1)], (3, 1), data=offset)
    return alpha if out.identifier == "Alpha" else color


def _invert(gc, node, out):
    return gc.b.emit("INVERT", 0, [(_inp(gc, node, "Fac", 1), 1), (_inp(gc, node, "Color", 3), 3)], (3,))[0]


def _rgb_to_bw(gc, node, out):
    return gc.b.emit("RGB_TO_BW", 0, [(_inp(gc, node, 0, 3), 3)], (1,))[0]


def _separate(gc, node, out):
    value = _inp(gc, node, 0, 3)
    if getattr(node, "mode", "RGB") != "RGB":
        value = _color_convert(gc, "RGB_TO_" + node.mode, value)
    k = [o.identifier for o in node.outputs].index(out.identifier)
    return value.component(k) if isinstance(value, Reg) else value[k]


def _combine(gc, node, out):
    parts = [_inp(gc, node, k, 1) for k in range(3)]
    if all(is_constant(p) for p in parts):
        value = tuple(parts)
    else:
        value = gc.b.emit("COMBINE", 0, [(p, 1) for p in parts], (3,))[0]
    if getattr(node, "mode", "RGB") != "RGB":
        value = _color_convert(gc, node.mode + "_TO_RGB", value)
    return value


def _clamp(gc, node, out):
    mode = 1 if node.clamp_type == "RANGE" else 0
    return gc.b.emit("CLAMP", mode, [(_inp(gc, node, k, 1), 1) for k in range(3)], (1,))[0]


def _tex_coord(gc, node, out):
    kind = TEX_COORDS.get(out.identifier)
    if kind is None or (out.identifier == "Object" and getattr(node, "object", None) is not None):
        gc.warn(f"Texture Coordinate output '{out.identifier}' ('{node.name}') is not supported: using UV")
        kind = 0
    return _coordinate(gc, kind, "")


def _coordinate(gc, kind, uv_name):
    data = 0
    if kind == TEX_COORDS["UV"]:
        data = gc.uv_index(uv_name)
        gc.b.uses.add("uv")
    else:
        gc.b.uses.add("objects")
    if gc.bump_axis:
        return gc.b.emit("BUMP_TEX_COORD", kind | gc.bump_axis << BUMP_AXIS_SHIFT, [], (3,), data=data)[0]
    return gc.b.emit("TEX_COORD", kind, [], (3,), data=data)[0]


def _uv_map(gc, node, out):
    return _coordinate(gc, TEX_COORDS["UV"], node.uv_map)


def _texture_vector(gc, node, default_kind):
    """A texture node's Vector input; unlinked, Cycles uses UVs (images) or generated coordinates."""
    socket = node.inputs["Vector"]
    if gc._follow(socket) is None:
        return _coordinate(gc, default_kind, "")
    return gc.input_value(socket, 3)


def _checker(gc, node, out):
    vector = _texture_vector(gc, node, TEX_COORDS["Generated"])
    color, fac = gc.b.emit("CHECKER", 0, [(vector, 3), (_inp(gc, node, "Color1", 3), 3),
                                          (_inp(gc, node, "Color2", 3), 3), (_inp(gc, node, "Scale", 1), 1)], (3, 1))
    return fac if out.identifier == "Fac" else color


# Colour spaces whose values Cycles leaves alone, no alpha association: those Blender 3.4's OCIO
# configuration marks isdata (ColorSpaceManager::colorspace_is_data). Linear, XYZ, Filmic Log are colour.
DATA_COLORSPACES = ("Non-Color", "Raw")


def image_flags(node, image, alpha_linked, is_float=None):
    """ImageTexture mode bits for an Image Texture node (Cycles' image flags). Straight colour texels
    are associated when handed over (images.py), as Cycles associates them on load, so both Straight
    and Premultiplied images are unassociated after filtering when Alpha is used (NODE_IMAGE_ALPHA_UNASSOCIATE).
    is_float: the image's Image.is_float when known without asking Blender (images.blender_format)."""
    flags = IMAGE_INTERPOLATION.get(node.interpolation, 0)
    flags |= IMAGE_EXTENSION.get(node.extension, 0) << 2
    colorspace = image.colorspace_settings.name if image is not None else "sRGB"
    is_data = colorspace in DATA_COLORSPACES
    if is_float is None:
        is_float = getattr(image, "is_float", False)
    if colorspace == "sRGB" and not is_float:
        flags |= IMAGE_SRGB
    alpha_mode = getattr(image, "alpha_mode", "STRAIGHT")
    if alpha_mode == "NONE":
        flags |= IMAGE_IGNORE_ALPHA
    elif not is_data and alpha_mode in ("STRAIGHT", "PREMUL") and alpha_linked:
        flags |= IMAGE_UNASSOCIATE
    return flags


def _image(gc, node, out):
    image = node.image
    if image is None:
        gc.warn(f"Image Texture '{node.name}' has no image: rendered magenta")
        return (1.0, 0.0, 1.0) if out.identifier == "Color" else 1.0
    if getattr(node, "projection", "FLAT") != "FLAT":
        gc.warn(f"Image Texture '{node.name}': projection {node.projection} is not supported, using FLAT")
    index = gc.image_index(image, node)
    vector = _texture_vector(gc, node, TEX_COORDS["UV"])
    alpha_linked = node.outputs["Alpha"].is_linked
    is_float = gc.image_is_float(image) if gc.image_is_float is not None else None
    color, alpha = gc.b.emit("IMAGE_TEXTURE", image_flags(node, image, alpha_linked, is_float), [(vector, 3)], (3, 1),
                             data=index)
    return alpha if out.identifier == "Alpha" else color


def _normal_map(gc, node, out):
    space = NORMAL_MAP_SPACES.get(node.space)
    if space is None:
        gc.warn(f"Normal Map space {node.space} ('{node.name}') is not supported: using tangent space")
        space = 0
    gc.b.uses.add("tangents" if space == 0 else "objects")
    data = gc.uv_index(node.uv_map) if space == 0 else 0
    return gc.b.emit("NORMAL_MAP", space, [(_inp(gc, node, "Strength", 1), 1), (_inp(gc, node, "Color", 3), 3)],
                     (3,), data=data)[0]


def _sky_texture(gc, node, out):
    """Sky Texture: precomputed natively as for the world (world.sky_arguments), its table in the program's data."""
    from . import native_module
    from .world import _default_texture_mapping, sky_arguments
    if not _default_texture_mapping(node.texture_mapping):
        gc.warn(f"Sky Texture '{node.name}': the texture's own mapping is not supported: ignored")
    offset = len(gc.b.data)
    gc.b.data.extend(native_module().sky_texture(**sky_arguments(node)).tolist())
    # A disabled Vector input (Nishita with its sun disc) ignores its link, as in Cycles.
    vector = (_texture_vector(gc, node, TEX_COORDS["Generated"]) if node.inputs["Vector"].enabled
              else _coordinate(gc, TEX_COORDS["Generated"], ""))
    return gc.b.emit("SKY_TEXTURE", 0, [(vector, 3)], (3,), data=offset)[0]


def _group(gc, node, out):
    return gc.group(node, out)


_HANDLERS = {
    "ShaderNodeValue": _value_node,
    "ShaderNodeRGB": _rgb_node,
    "ShaderNodeMath": _math,
    "ShaderNodeVectorMath": _vector_math,
    "ShaderNodeMixRGB": _mix_rgb,
    "ShaderNodeMix": _mix,
    "ShaderNodeMapping": _mapping,
    "ShaderNodeValToRGB": _color_ramp,
    "ShaderNodeInvert": _invert,
    "ShaderNodeRGBToBW": _rgb_to_bw,
    "ShaderNodeSeparateRGB": _separate,
    "ShaderNodeSeparateXYZ": _separate,
    "ShaderNodeSeparateColor": _separate,
    "ShaderNodeCombineRGB": _combine,
    "ShaderNodeCombineXYZ": _combine,
    "ShaderNodeCombineColor": _combine,
    "ShaderNodeClamp": _clamp,
    "ShaderNodeTexCoord": _tex_coord,
    "ShaderNodeUVMap": _uv_map,
    "ShaderNodeTexChecker": _checker,
    "ShaderNodeTexImage": _image,
    "ShaderNodeNormalMap": _normal_map,
    "ShaderNodeTexSky": _sky_texture,
    "ShaderNodeGroup": _group,
}


# -- procedural textures ----------------------------------------------------------------
#
# White Noise, Noise, Voronoi, Musgrave, Wave, Gradient, Magic and Brick
# compile to one instruction each, evaluated natively with Blender 3.4
# Cycles' hash and noise functions (native/shader/node_procedural.h). These
# nodes have more sockets than an instruction has register slots, so each
# instruction addresses its registers through a list it appends to the
# program's data: inputs in the order of node_procedural.h's layouts, then
# outputs (only the linked ones are computed, the others are marked unused).
# A node whose inputs are all constant folds like any other.

NO_REGISTER = 0xFFFF
DIMENSIONS = {"1D": 1, "2D": 2, "3D": 3, "4D": 4}
VORONOI_FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")
VORONOI_METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
MUSGRAVE_TYPES = ("MULTIFRACTAL", "FBM", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN")
WAVE_TYPES = ("BANDS", "RINGS")
WAVE_BANDS = ("X", "Y", "Z", "DIAGONAL")
WAVE_RINGS = ("X", "Y", "Z", "SPHERICAL")
WAVE_PROFILES = ("SIN", "SAW", "TRI")
GRADIENT_TYPES = ("LINEAR", "QUADRATIC", "EASING", "DIAGONAL", "RADIAL", "QUADRATIC_SPHERE", "SPHERICAL")


def _emit_listed(b, op, mode, inputs, out_widths, wanted):
    """Appends a procedural instruction computing outputs `wanted` (indices); returns their values
    (registers, or constants where it folded).

    inputs: (value, width) in layout order; out_widths: the widths of all the op's outputs.
    """
    in_regs = [b.register(v, w) for v, w in inputs]
    outs = {k: b._new(out_widths[k]) for k in wanted}
    offset = len(b.data)
    b.data.extend(float(r.index) for r in in_regs)
    b.data.extend(float(outs[k].index if k in outs else NO_REGISTER) for k in range(len(out_widths)))
    b.code.append([OP[op], mode, -1, -1, -1, -1, -1, -1, offset])
    if b._fold is not None and all(b._is_constant_reg(r) for r in in_regs):
        return b._fold_last([outs[k] for k in wanted])
    return [outs[k] for k in wanted]


def _procedural(gc, node, out, op, mode, inputs, out_widths):
    """One instruction for every linked output of `node` (plus `out`); the others' values are cached."""
    ids = [o.identifier for o in node.outputs]
    wanted = [k for k, o in enumerate(node.outputs) if o.identifier == out.identifier or o.is_linked]
    values = _emit_listed(gc.b, op, mode, inputs, out_widths, wanted)
    group = tuple(g.as_pointer() for g in gc._group_path)
    for k, value in zip(wanted, values):
        gc._cache.setdefault((group, node.as_pointer(), ids[k], gc.bump_axis), value)  # output_value's key
    return values[wanted.index(ids.index(out.identifier))]


def _floats(gc, node, names):
    return [(_inp(gc, node, name, 1), 1) for name in names]


def _vector(gc, node):
    return (_texture_vector(gc, node, TEX_COORDS["Generated"]), 3)


def _white_noise(gc, node, out):
    # Cycles' White Noise reads its Vector socket as is (zero when unlinked), not texture coordinates.
    inputs = [(_inp(gc, node, "Vector", 3), 3), (_inp(gc, node, "W", 1), 1)]
    return _procedural(gc, node, out, "TEX_WHITE_NOISE", DIMENSIONS[node.noise_dimensions], inputs, (1, 3))


def _noise(gc, node, out):
    inputs = [_vector(gc, node)] + _floats(gc, node, ("W", "Scale", "Detail", "Roughness", "Distortion"))
    return _procedural(gc, node, out, "TEX_NOISE", DIMENSIONS[node.noise_dimensions], inputs, (1, 3))


def _voronoi(gc, node, out):
    mode = DIMENSIONS[node.voronoi_dimensions] | VORONOI_FEATURES.index(node.feature) << 4 | \
        VORONOI_METRICS.index(node.distance) << 8
    inputs = [_vector(gc, node)] + _floats(gc, node, ("W", "Scale", "Smoothness", "Exponent", "Randomness"))
    return _procedural(gc, node, out, "TEX_VORONOI", mode, inputs, (1, 3, 3, 1, 1))


def _musgrave(gc, node, out):
    mode = DIMENSIONS[node.musgrave_dimensions] | MUSGRAVE_TYPES.index(node.musgrave_type) << 4
    inputs = [_vector(gc, node)] + _floats(gc, node, ("W", "Scale", "Detail", "Dimension", "Lacunarity", "Offset",
                                                     "Gain"))
    return _procedural(gc, node, out, "TEX_MUSGRAVE", mode, inputs, (1,))


def _wave(gc, node, out):
    mode = WAVE_TYPES.index(node.wave_type) | WAVE_BANDS.index(node.bands_direction) << 2 | \
        WAVE_RINGS.index(node.rings_direction) << 4 | WAVE_PROFILES.index(node.wave_profile) << 6
    inputs = [_vector(gc, node)] + _floats(gc, node, ("Scale", "Distortion", "Detail", "Detail Scale",
                                                     "Detail Roughness", "Phase Offset"))
    return _procedural(gc, node, out, "TEX_WAVE", mode, inputs, (3, 1))


def _gradient(gc, node, out):
    mode = GRADIENT_TYPES.index(node.gradient_type)
    return _procedural(gc, node, out, "TEX_GRADIENT", mode, [_vector(gc, node)], (3, 1))


def _magic(gc, node, out):
    depth = max(0, min(10, int(node.turbulence_depth)))
    inputs = [_vector(gc, node)] + _floats(gc, node, ("Scale", "Distortion"))
    return _procedural(gc, node, out, "TEX_MAGIC", depth, inputs, (3, 1))


def _brick(gc, node, out):
    mode = max(0, min(255, int(node.offset_frequency))) | max(0, min(255, int(node.squash_frequency))) << 8
    inputs = [_vector(gc, node)] + [(_inp(gc, node, name, 3), 3) for name in ("Color1", "Color2", "Mortar")]
    inputs += _floats(gc, node, ("Scale", "Mortar Size", "Mortar Smooth", "Bias", "Brick Width", "Row Height"))
    inputs += [(float(node.offset), 1), (float(node.squash), 1)]
    return _procedural(gc, node, out, "TEX_BRICK", mode, inputs, (3, 1))


_HANDLERS.update({
    "ShaderNodeTexWhiteNoise": _white_noise,
    "ShaderNodeTexNoise": _noise,
    "ShaderNodeTexVoronoi": _voronoi,
    "ShaderNodeTexMusgrave": _musgrave,
    "ShaderNodeTexWave": _wave,
    "ShaderNodeTexGradient": _gradient,
    "ShaderNodeTexMagic": _magic,
    "ShaderNodeTexBrick": _brick,
})


# -- Colour adjustments, inputs and bump ----------------------------------------------
# Each as Cycles 3.4 compiles it (intern/cycles/scene/shader_nodes.cpp,
# blender/shader.cpp); the formulas are native/shader/node_adjust.h.

CURVE_TABLE_SIZE = 256
BUMP_AXIS_SHIFT = 8
MAP_RANGE_TYPES = ("LINEAR", "STEPPED", "SMOOTHSTEP", "SMOOTHERSTEP")
COLOR_CONVERSIONS = ("RGB_TO_HSV", "HSV_TO_RGB", "RGB_TO_HSL", "HSL_TO_RGB")
FRESNEL_KINDS = {"Fresnel": 0, "Layer Fresnel": 1, "Layer Facing": 2}
GEOMETRY_OUTPUTS = ("Position", "Normal", "Tangent", "True Normal", "Incoming", "Parametric", "Backfacing")
LIGHT_PATH_OUTPUTS = ("Is Camera Ray", "Is Shadow Ray", "Is Diffuse Ray", "Is Glossy Ray", "Is Singular Ray",
                      "Is Reflection Ray", "Is Transmission Ray", "Ray Length", "Ray Depth", "Diffuse Depth",
                      "Glossy Depth", "Transparent Depth", "Transmission Depth")


def _curve_range(mapping, count):
    """Cycles' curvemapping_minmax: the x span of the first `count` curves' end points."""
    lo = min(float(mapping.curves[k].points[0].location[0]) for k in range(count))
    hi = max(float(mapping.curves[k].points[-1].location[0]) for k in range(count))
    return lo, hi


def _curve_table(gc, mapping, count, rgb_curve=False):
    """A curve table in the program's data (Cycles' curvemapping_*_to_array): offset."""
    mapping.update()
    lo, hi = _curve_range(mapping, 4 if rgb_curve else count)
    offset = len(gc.b.data)
    gc.b.data.extend((lo, hi))
    curves = [mapping.curves[k] for k in range(count)]
    for i in range(CURVE_TABLE_SIZE):
        t = lo + i / (CURVE_TABLE_SIZE - 1) * (hi - lo)
        if rgb_curve:  # the combined curve first, then each channel's
            t = mapping.evaluate(mapping.curves[3], t)
        row = [float(mapping.evaluate(c, t)) for c in curves]
        gc.b.data.extend(row + [0.0] if count == 3 else row)
    return offset, 1 if mapping.extend == "EXTRAPOLATED" else 0


def _rgb_curves(gc, node, out):
    vector = node.bl_idname == "ShaderNodeVectorCurve"
    offset, extrapolate = _curve_table(gc, node.mapping, 3, rgb_curve=not vector)
    value = _inp(gc, node, "Vector" if vector else "Color", 3)
    return gc.b.emit("CURVES", extrapolate, [(_inp(gc, node, "Fac", 1), 1), (value, 3)], (3,), data=offset)[0]


def _float_curve(gc, node, out):
    offset, extrapolate = _curve_table(gc, node.mapping, 1)
    return gc.b.emit("FLOAT_CURVE", extrapolate, [(_inp(gc, node, "Factor", 1), 1), (_inp(gc, node, "Value", 1), 1)],
                     (1,), data=offset)[0]


def _packed(gc, parts):
    """Three floats as one vec3 operand (constant when they all are)."""
    if all(is_constant(p) for p in parts):
        return tuple(float(p) for p in parts)
    return gc.b.emit("COMBINE", 0, [(p, 1) for p in parts], (3,))[0]


def _hue_saturation(gc, node, out):
    hsv = _packed(gc, [_inp(gc, node, name, 1) for name in ("Hue", "Saturation", "Value")])
    return gc.b.emit("HUE_SAT_VAL", 0, [(_inp(gc, node, "Fac", 1), 1), (_inp(gc, node, "Color", 3), 3), (hsv, 3)],
                     (3,))[0]


def _gamma(gc, node, out):
    return gc.b.emit("GAMMA", 0, [(_inp(gc, node, "Color", 3), 3), (_inp(gc, node, "Gamma", 1), 1)], (3,))[0]


def _bright_contrast(gc, node, out):
    return gc.b.emit("BRIGHT_CONTRAST", 0, [(_inp(gc, node, "Color", 3), 3), (_inp(gc, node, "Bright", 1), 1),
                                            (_inp(gc, node, "Contrast", 1), 1)], (3,))[0]


def _map_range(gc, node, out):
    """Inputs 0-5: float value, from min/max, to min/max, steps; 6-11 the same as vectors."""
    kind = MAP_RANGE_TYPES.index(node.interpolation_type)
    if node.data_type == "FLOAT_VECTOR":
        v = [_inp(gc, node, k, 3) for k in range(6, 12)]
        factor = gc.b.emit("VECTOR_MAP_RANGE_FACTOR", kind, [(v[0], 3), (v[1], 3), (v[2], 3), (v[5], 3)], (3,))[0]
        clamp = CLAMP_BIT if node.clamp and kind < 2 else 0
        return gc.b.emit("VECTOR_MAP_RANGE_APPLY", clamp, [(factor, 3), (v[3], 3), (v[4], 3)], (3,))[0]
    v = [_inp(gc, node, k, 1) for k in range(6)]
    result = gc.b.emit("MAP_RANGE", kind, [(v[0], 1), (v[1], 1), (v[2], 1), (_packed(gc, v[3:6]), 3)], (1,))[0]
    if node.clamp:  # MapRangeNode::expand: a Clamp node over To Min .. To Max
        result = gc.b.emit("CLAMP", 1, [(result, 1), (v[3], 1), (v[4], 1)], (1,))[0]
    return result


def _color_convert(gc, conversion, value):
    return gc.b.emit("COLOR_CONVERT", COLOR_CONVERSIONS.index(conversion), [(value, 3)], (3,))[0]


def _separate_hsv(gc, node, out):
    hsv = _color_convert(gc, "RGB_TO_HSV", _inp(gc, node, "Color", 3))
    k = [o.identifier for o in node.outputs].index(out.identifier)
    return hsv.component(k) if isinstance(hsv, Reg) else hsv[k]


def _combine_hsv(gc, node, out):
    return _color_convert(gc, "HSV_TO_RGB", _packed(gc, [_inp(gc, node, k, 1) for k in range(3)]))


def _geometry_output(gc, name):
    kind = GEOMETRY_OUTPUTS.index(name)
    if name == "Tangent":
        gc.b.uses.add("objects")  # around the generated coordinates' axis, in object space
    return gc.b.emit("GEOMETRY", kind | gc.bump_axis << BUMP_AXIS_SHIFT, [], (1 if name == "Backfacing" else 3,))[0]


def _normal_input(gc, node):
    """A Normal input: the shading normal unless linked (Cycles' LINK_NORMAL)."""
    socket = node.inputs["Normal"]
    if gc._follow(socket) is None:
        return _geometry_output(gc, "Normal")
    return gc.input_value(socket, 3)


def _fresnel(gc, node, out):
    if node.bl_idname == "ShaderNodeFresnel":
        kind, x = FRESNEL_KINDS["Fresnel"], _inp(gc, node, "IOR", 1)
    else:
        kind = FRESNEL_KINDS["Layer Fresnel" if out.identifier == "Fresnel" else "Layer Facing"]
        x = _inp(gc, node, "Blend", 1)
    return gc.b.emit("FRESNEL", kind, [(x, 1), (_normal_input(gc, node), 3)], (1,))[0]


# The attributes the exporter computes for Geometry > Pointiness (per vertex)
# and Random Per Island (per triangle) (geometry_attributes.py; a leading dot
# as Blender's internal names).
POINTINESS_ATTRIBUTE = ".coherent_pointiness"
RANDOM_PER_ISLAND_ATTRIBUTE = ".coherent_random_per_island"


def _geometry(gc, node, out):
    name = out.identifier
    if name in GEOMETRY_OUTPUTS:
        return _geometry_output(gc, name)
    attribute = {"Pointiness": POINTINESS_ATTRIBUTE, "Random Per Island": RANDOM_PER_ISLAND_ATTRIBUTE}.get(name)
    if attribute is not None and gc.color_index is not None:
        gc.b.uses.add("colors")
        grey, _ = gc.b.emit("ATTRIBUTE", gc.bump_axis, [], (3, 1), data=gc.color_index(attribute))
        return gc.b.convert(grey, 1, as_color=False)
    fallback = 0.5 if name == "Pointiness" else 0.0
    gc.warn(f"Geometry output '{name}' ('{node.name}') is not supported: using {fallback}")
    return fallback


def _light_path(gc, node, out):
    if out.identifier not in LIGHT_PATH_OUTPUTS:
        gc.warn(f"Light Path output '{out.identifier}' ('{node.name}') is not supported: using 0")
        return 0.0
    return gc.b.emit("LIGHT_PATH", LIGHT_PATH_OUTPUTS.index(out.identifier), [], (1,))[0]


def _attribute(gc, node, out):
    """Attribute (geometry type) and Color Attribute nodes: a mesh attribute as per-corner RGBA."""
    if node.bl_idname == "ShaderNodeVertexColor":
        name = node.layer_name
    elif getattr(node, "attribute_type", "GEOMETRY") == "GEOMETRY":
        name = node.attribute_name
    else:
        name = None
    if name is None or gc.color_index is None:
        gc.warn(f"attribute node '{node.name}' reads an object or instancer attribute, which is not supported: "
                f"using 0")
        return 0.0
    gc.b.uses.add("colors")
    color, alpha = gc.b.emit("ATTRIBUTE", gc.bump_axis, [], (3, 1), data=gc.color_index(name))
    if out.identifier == "Alpha":
        return alpha
    if out.identifier == "Fac":  # Cycles: the average of the channels
        return gc.b.convert(color, 1, as_color=False)
    return color


def _bump(gc, node, out):
    """Cycles' Bump: the height compiled three times, at the point and one ray footprint along dx and dy."""
    normal = _normal_input(gc, node)
    height = node.inputs["Height"]
    if gc._follow(height) is None:
        return normal  # BumpNode::constant_fold: nothing to perturb
    if gc.bump_axis:
        gc.warn(f"Bump '{node.name}' inside another Bump's height: using its normal input")
        return normal
    heights = []
    for axis in (0, 1, 2):
        gc.bump_axis = axis
        try:
            heights.append(gc.input_value(height, 1))
        finally:
            gc.bump_axis = 0
    return gc.b.emit("BUMP", 1 if node.invert else 0, [(_inp(gc, node, "Strength", 1), 1),
                                                      (_inp(gc, node, "Distance", 1), 1), (normal, 3),
                                                      (_packed(gc, heights), 3)], (3,))[0]


_HANDLERS.update({
    "ShaderNodeBump": _bump,
    "ShaderNodeAttribute": _attribute,
    "ShaderNodeVertexColor": _attribute,
    "ShaderNodeRGBCurve": _rgb_curves,
    "ShaderNodeVectorCurve": _rgb_curves,
    "ShaderNodeFloatCurve": _float_curve,
    "ShaderNodeHueSaturation": _hue_saturation,
    "ShaderNodeGamma": _gamma,
    "ShaderNodeBrightContrast": _bright_contrast,
    "ShaderNodeMapRange": _map_range,
    "ShaderNodeSeparateHSV": _separate_hsv,
    "ShaderNodeCombineHSV": _combine_hsv,
    "ShaderNodeFresnel": _fresnel,
    "ShaderNodeLayerWeight": _fresnel,
    "ShaderNodeNewGeometry": _geometry,
    "ShaderNodeLightPath": _light_path,
})
