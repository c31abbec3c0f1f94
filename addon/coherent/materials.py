# SPDX-License-Identifier: Apache-2.0
"""Blender materials to COHERENT materials.

The native material is a weighted sum of at most four Principled-style
closures plus an emission colour (native/scene/material.h). This module walks
the shader node tree from the active Material Output's Surface socket and
flattens Mix/Add shader nodes into that form:

* Principled BSDF: Base Color, Metallic, Specular, Roughness, IOR, Transmission,
  Emission x Emission Strength.
* Diffuse BSDF: a Principled closure without specular layer.
* Glossy / Anisotropic BSDF: a metal closure whose F0 is the node colour.
* Glass / Refraction BSDF: a fully transmissive closure.
* Emission: adds colour x strength to the emission; contributes no closure.
* Transparent / Translucent BSDF: closures of kind 'transparent' / 'translucent'
  with the node colour; Holdout: a 'holdout' closure (native/render/transparency.h).
* Principled Alpha < 1 (or linked): as Cycles expands it, a Mix Shader of a white
  Transparent BSDF (weight 1 - alpha) and the Principled BSDF with its emission
  (weight alpha).
* Mix Shader: weights (1 - fac, fac); Add Shader: both branches at full weight.

A linked input (texture, maths, node group, ...) is compiled into the
material's shader program (shader_compiler.py), which the renderer runs per
shading point; a subgraph of constants folds to a constant, so a material
whose inputs are all constant has no program and costs what it always did.
An unsupported shader node becomes a Lambert closure with the node's Color
input, and unsupported texture/maths nodes use their socket default; each
produces one warning per material and node type.
No per-vertex or per-pixel work happens here.
"""

from __future__ import annotations

import math

from . import shader_compiler
from .shader_compiler import Reg, is_constant

# Default closure: Principled BSDF defaults (Blender 3.4).
_DEFAULT_CLOSURE = {
    "base_color": (0.8, 0.8, 0.8),
    "metallic": 0.0,
    "roughness": 0.5,
    "specular": 0.5,
    "transmission": 0.0,
    "ior": 1.45,
}

MAX_CLOSURES = 4
# Closure weights below this are dropped: they cannot change the image.
_MIN_WEIGHT = 1e-6


def _rgb(value):
    return (float(value[0]), float(value[1]), float(value[2]))


def _specular_from_ior(ior):
    """Principled 'Specular' whose F0 (0.08 * specular) matches a dielectric of this IOR."""
    f0 = ((ior - 1.0) / (ior + 1.0)) ** 2
    return min(max(f0 / 0.08, 0.0), 1.0)


class _Flattened:
    """Accumulates (weight, closure) pairs and emission for one material.

    Weights, closure values and emission colours are constants or, where a
    node graph drives them, registers of `builder`'s program.
    """

    def __init__(self, builder):
        self.builder = builder
        self.closures = []  # list of (weight, dict)
        self.emission = [0.0, 0.0, 0.0]
        self.emission_reg = None  # the program's share of the emission, if any

    def add_closure(self, weight, closure):
        if not is_constant(weight) or weight > _MIN_WEIGHT:
            self.closures.append((weight, closure))

    def add_emission(self, weight, rgb):
        if is_constant(weight) and is_constant(rgb):
            for i in range(3):
                self.emission[i] += weight * max(rgb[i], 0.0)
            return
        b = self.builder
        term = b.emit("VECTOR_MATH", shader_compiler.VECTOR_MATH_OPS.index("SCALE"),
                      [(rgb, 3), ((0.0, 0.0, 0.0), 3), ((0.0, 0.0, 0.0), 3), (weight, 1)], (3, 1))[0]
        if self.emission_reg is not None:
            term = b.emit("VECTOR_MATH", shader_compiler.VECTOR_MATH_OPS.index("ADD"),
                          [(self.emission_reg, 3), (term, 3), ((0.0, 0.0, 0.0), 3), (0.0, 1)], (3, 1))[0]
        self.emission_reg = term


def _product(builder, a, b):
    if is_constant(a) and is_constant(b):
        return a * b
    return builder.emit("MATH", shader_compiler.MATH_OPS.index("MULTIPLY"), [(a, 1), (b, 1), (0.0, 1)], (1,))[0]


def _unit_clamped(builder, x):
    if is_constant(x):
        return min(max(x, 0.0), 1.0)
    return builder.emit("MATH", shader_compiler.MATH_OPS.index("ADD") | shader_compiler.CLAMP_BIT,
                        [(x, 1), (0.0, 1), (0.0, 1)], (1,))[0]


def _one_minus(builder, x):
    if is_constant(x):
        return 1.0 - x
    return builder.emit("MATH", shader_compiler.MATH_OPS.index("SUBTRACT"), [(1.0, 1), (x, 1), (0.0, 1)], (1,))[0]


class MaterialConverter:
    """Converts bpy materials once each and keeps their native indices."""

    def __init__(self, native_scene, warnings, fold=None, images=None):
        self.scene = native_scene
        self.warnings = warnings  # list of str shared with the exporter
        self._cache = {}  # original material pointer -> native index
        self._converted = {}  # original material pointer -> add_material arguments (prepare())
        self._warned = set()
        self.fold = fold  # _coherent.fold_shader_constants: folds constant subgraphs natively
        self.images = images  # ImageExporter (images.py), None: no image textures
        # What the compiled programs read (Scene.set_shading_inputs).
        self.uv_names = []
        self.color_names = []  # colour attributes the programs read ("" = the render colour attribute)
        self.tangent_uv = None  # UV map name the normal maps' tangents follow
        self.uses = set()

    # -- public -------------------------------------------------------------

    def index_of(self, material):
        """Native material index for a bpy material (None -> default material 0)."""
        if material is None:
            return 0
        key = material.original.as_pointer() if material.original is not None else material.as_pointer()
        index = self._cache.get(key)
        if index is None:
            args = self._converted.get(key)
            if args is None:
                args = self.convert(material)
            closures, weights, emission, program = args
            extra = {"program": program} if program is not None else {}
            index = self.scene.add_material(material.name, closures=closures, weights=weights, emission=emission,
                                            **extra)
            self._cache[key] = index
        return index

    def fresh(self, warnings):
        """A converter for re-converting edited materials of the same scene (viewport edits)."""
        other = MaterialConverter(self.scene, warnings, self.fold, self.images)
        other.uv_names = self.uv_names
        other.color_names = self.color_names
        other.tangent_uv = self.tangent_uv
        return other

    def prepare(self, materials):
        """Converts these materials before any mesh is added and declares what their programs read."""
        for material in materials:
            key = material.original.as_pointer() if material.original is not None else material.as_pointer()
            if key not in self._converted:
                self._converted[key] = self.convert(material)
        try:
            self.scene.set_shading_inputs(uv_names=list(self.uv_names), tangents="tangents" in self.uses,
                                          objects="objects" in self.uses, color_names=list(self.color_names))
        except ValueError:  # meshes already added (a re-export into a live scene): keep what they carry
            pass

    def uv_index(self, name):
        """Scene UV layer index of a UV map name ("" = the active render UV map)."""
        if name not in self.uv_names:
            self.uv_names.append(name)
        return self.uv_names.index(name)

    def color_index(self, name):
        """Scene colour attribute index of an attribute name."""
        if name not in self.color_names:
            self.color_names.append(name)
        return self.color_names.index(name)

    def native_indices(self):
        """{original material pointer: native index} of every material converted so far (a copy)."""
        return dict(self._cache)

    def convert(self, material):
        """(closures, weights, emission, program) for add_material; program is None for constant materials."""
        builder = shader_compiler.ProgramBuilder(self.fold)
        self._graph = shader_compiler.GraphCompiler(
            builder, lambda text: self._warn(material, text),
            (lambda image, node: self.images.index_of(image, material, node)) if self.images else
            (lambda image, node: self._no_images(material, node)), self._uv_index_for(builder), self.color_index,
            image_is_float=self.images.is_float if self.images else None)
        self._builder = builder
        flat = _Flattened(builder)
        if material.use_nodes and material.node_tree is not None:
            output = _active_output(material.node_tree, "ShaderNodeOutputMaterial")
            if output is None:
                self._warn(material, "no Material Output node: rendered black")
            else:
                self._shader_socket(material, output.inputs["Surface"], 1.0, flat, depth=0)
        else:
            # Cycles renders node-less materials as a Diffuse BSDF of the
            # viewport colour; do the same so both engines agree.
            flat.add_closure(1.0, self._diffuse(_rgb(material.diffuse_color)))

        closures = flat.closures
        if len(closures) > MAX_CLOSURES:
            closures = sorted(closures, key=lambda wc: wc[0], reverse=True)
            dropped = sum(w for w, _ in closures[MAX_CLOSURES:])
            self._warn(material, f"more than {MAX_CLOSURES} BSDFs: kept the {MAX_CLOSURES} strongest "
                                 f"(dropped total weight {dropped:.3g})")
            closures = closures[:MAX_CLOSURES]
        return self._finish(builder, closures, flat)

    def _finish(self, builder, closures, flat):
        """Constants for add_material, and the program binding every driven value."""
        out_closures, out_weights = [], []
        for i, (weight, closure) in enumerate(closures):
            if not is_constant(weight):
                builder.output("weight", i, weight)
                weight = 1.0
            constant = {}
            for key, value in closure.items():
                if key == "normal":
                    builder.output("normal", i, value)
                elif not is_constant(value):
                    builder.output(key, i, value)
                    constant[key] = _DEFAULT_CLOSURE[key]
                else:
                    constant[key] = value
            out_closures.append(constant)
            out_weights.append(weight)
        emission = tuple(flat.emission)
        if flat.emission_reg is not None:
            total = builder.emit("VECTOR_MATH", shader_compiler.VECTOR_MATH_OPS.index("ADD"),
                                 [(flat.emission_reg, 3), (emission, 3), ((0.0, 0.0, 0.0), 3), (0.0, 1)], (3, 1))[0]
            builder.output("emission", 0, total)
            emission = (0.0, 0.0, 0.0)  # textured emitters are reached by BSDF sampling, not light sampling
        program = builder.program()
        if program is not None:
            self.uses |= builder.uses
        return out_closures, out_weights, emission, program

    def _uv_index_for(self, builder):
        def uv_index(name):
            if self.tangent_uv is None and "tangents" in builder.uses:
                self.tangent_uv = name
            return self.uv_index(name)
        return uv_index

    def _no_images(self, material, node):
        self._warn(material, f"image textures are not available here ('{node.name}'): rendered magenta")
        return 0

    # -- node walking ---------------------------------------------------------

    def _warn(self, material, text):
        key = (material.name, text)
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(f"Material '{material.name}': {text}")

    def _shader_socket(self, material, socket, weight, flat, depth):
        """Adds what flows into a SHADER input socket, scaled by `weight` (a constant or a register)."""
        if is_constant(weight) and weight <= _MIN_WEIGHT:
            return
        source = _linked_source(socket)
        if source is None:
            return  # unconnected shader input: no closure (black), as in Cycles
        node, _out = source
        if depth > 64:
            self._warn(material, "shader node tree nested too deeply, truncated")
            return
        self._shader_node(material, node, weight, flat, depth)

    def _shader_node(self, material, node, weight, flat, depth):
        kind = node.bl_idname
        if kind == "ShaderNodeBsdfPrincipled":
            self._principled(material, node, weight, flat)
        elif kind == "ShaderNodeBsdfDiffuse":
            color = self._color(material, node, "Color")
            if self._value(material, node, "Roughness", check_link=False) > 0.0:
                self._warn(material, "Diffuse BSDF roughness (Oren-Nayar) is not supported, using Lambert")
            flat.add_closure(weight, self._with_normal(node, self._diffuse(color)))
        elif kind in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"):
            if kind == "ShaderNodeBsdfAnisotropic" and abs(self._value(material, node, "Anisotropy", check_link=False)) > 0.0:
                self._warn(material, "anisotropy is not supported, using isotropic Glossy")
            roughness = 0.0 if getattr(node, "distribution", "") == "SHARP" else self._value(material, node, "Roughness")
            flat.add_closure(weight, self._with_normal(node, dict(
                _DEFAULT_CLOSURE, base_color=self._color(material, node, "Color"), metallic=1.0, roughness=roughness)))
        elif kind in ("ShaderNodeBsdfGlass", "ShaderNodeBsdfRefraction"):
            if kind == "ShaderNodeBsdfRefraction":
                self._warn(material, "Refraction BSDF approximated by Glass BSDF (adds reflection)")
            roughness = 0.0 if getattr(node, "distribution", "") == "SHARP" else self._value(material, node, "Roughness")
            ior = self._constant_value(material, node, "IOR")
            flat.add_closure(weight, self._with_normal(node, dict(
                _DEFAULT_CLOSURE, base_color=self._color(material, node, "Color"), roughness=roughness,
                transmission=1.0, ior=max(ior, 1e-3), specular=_specular_from_ior(max(ior, 1e-3)))))
        elif kind in ("ShaderNodeBsdfTransparent", "ShaderNodeBsdfTranslucent"):
            closure = dict(kind="transparent" if kind == "ShaderNodeBsdfTransparent" else "translucent",
                           base_color=self._color(material, node, "Color"))
            if kind == "ShaderNodeBsdfTranslucent":
                self._with_normal(node, closure)
            flat.add_closure(weight, closure)
        elif kind == "ShaderNodeHoldout":
            flat.add_closure(weight, dict(kind="holdout"))
        elif kind == "ShaderNodeEmission":
            color = self._color(material, node, "Color")
            strength = self._value(material, node, "Strength")
            self._add_emission(flat, weight, color, strength)
        elif kind == "ShaderNodeMixShader":
            b = self._builder
            fac = _unit_clamped(b, self._value(material, node, "Fac"))
            self._shader_socket(material, node.inputs[1], _product(b, weight, _one_minus(b, fac)), flat, depth + 1)
            self._shader_socket(material, node.inputs[2], _product(b, weight, fac), flat, depth + 1)
        elif kind == "ShaderNodeAddShader":
            self._shader_socket(material, node.inputs[0], weight, flat, depth + 1)
            self._shader_socket(material, node.inputs[1], weight, flat, depth + 1)
        else:
            # Nearest supported BSDF: Lambert with the node's colour if it has one.
            self._warn(material, f"unsupported shader node {kind} ('{node.name}') rendered as diffuse")
            color = self._color(material, node, "Color") if "Color" in node.inputs else (0.8, 0.8, 0.8)
            flat.add_closure(weight, self._diffuse(color))

    def _principled(self, material, node, weight, flat):
        ior = max(self._constant_value(material, node, "IOR"), 1e-3)
        closure = {
            "base_color": self._color(material, node, "Base Color"),
            "metallic": self._value(material, node, "Metallic"),
            "roughness": self._value(material, node, "Roughness"),
            "specular": self._value(material, node, "Specular"),
            "transmission": self._value(material, node, "Transmission"),
            "ior": ior,
            "principled_diffuse": True,
        }
        self._with_normal(node, closure)
        ignored = [name for name, unused in (
            ("Subsurface", 0.0), ("Sheen", 0.0), ("Clearcoat", 0.0), ("Anisotropic", 0.0), ("Specular Tint", 0.0),
        ) if name in node.inputs and self._value(material, node, name, check_link=False) > unused]
        for name in ("Clearcoat Normal", "Tangent"):
            if name in node.inputs and _linked_source(node.inputs[name]) is not None:
                ignored.append(f"{name} (linked)")
        if ignored:
            self._warn(material, "Principled BSDF inputs not supported (ignored): " + ", ".join(ignored))
        weight = self._principled_alpha(material, node, weight, flat)
        flat.add_closure(weight, closure)
        emission = self._color(material, node, "Emission")
        strength = self._value(material, node, "Emission Strength")
        self._add_emission(flat, weight, emission, strength)

    def _principled_alpha(self, material, node, weight, flat):
        """Cycles' expansion of Alpha: a white Transparent BSDF at weight (1 - alpha); returns the
        weight left for the Principled BSDF and its emission."""
        if "Alpha" not in node.inputs:
            return weight
        alpha = self._value(material, node, "Alpha")
        if is_constant(alpha) and alpha >= 1.0:
            return weight
        b = self._builder
        alpha = _unit_clamped(b, alpha)
        flat.add_closure(_product(b, weight, _one_minus(b, alpha)), dict(kind="transparent", base_color=(1.0, 1.0, 1.0)))
        return _product(b, weight, alpha)

    def _add_emission(self, flat, weight, color, strength):
        if is_constant(color) and is_constant(strength):
            if strength != 0.0 and any(c > 0.0 for c in color):
                flat.add_emission(weight, tuple(c * strength for c in color))
            return
        b = self._builder
        scaled = b.emit("VECTOR_MATH", shader_compiler.VECTOR_MATH_OPS.index("SCALE"),
                        [(color, 3), ((0.0, 0.0, 0.0), 3), ((0.0, 0.0, 0.0), 3), (strength, 1)], (3, 1))[0]
        flat.add_emission(weight, scaled)

    def _with_normal(self, node, closure):
        """Adds a linked Normal input (Normal Map, ...) to the closure; returns it."""
        normal = node.inputs.get("Normal")
        if normal is not None and _linked_source(normal) is not None:
            closure["normal"] = self._graph.input_value(normal, 3)
        return closure

    @staticmethod
    def _diffuse(color):
        return dict(_DEFAULT_CLOSURE, base_color=color, specular=0.0, metallic=0.0, roughness=1.0)

    # -- inputs -----------------------------------------------------------------

    def _linked(self, node, name):
        """The compiled value of a linked input (a constant if its graph folds), or None if unlinked."""
        socket = node.inputs[name]
        if _linked_source(socket) is None:
            return None
        self._graph.consumer = f"input '{name}' of {node.bl_idname}"
        return self._graph.input_value(socket)

    def _value(self, material, node, name, check_link=True):
        linked = self._linked(node, name) if check_link else None
        if linked is not None:
            return _finite(linked) if is_constant(linked) else linked
        value = float(node.inputs[name].default_value)
        return value if math.isfinite(value) else 0.0

    def _constant_value(self, material, node, name):
        """An input that must be constant: a driven one warns and uses its default."""
        value = self._value(material, node, name)
        if is_constant(value):
            return value
        self._warn(material, f"a texture-driven '{name}' of {node.bl_idname} is not supported: using its default")
        return self._value(material, node, name, check_link=False)

    def _color(self, material, node, name):
        linked = self._linked(node, name)
        if linked is not None:
            if not is_constant(linked):
                return linked
            value = linked if isinstance(linked, tuple) else (linked,) * 3
        else:
            value = _rgb(node.inputs[name].default_value)
        return tuple(v if math.isfinite(v) else 0.0 for v in value)


def _finite(value):
    value = float(value) if not isinstance(value, tuple) else float(sum(value) / 3.0)
    return value if math.isfinite(value) else 0.0


def _linked_source(socket):
    """(node, output socket) feeding `socket`, following reroutes and muted nodes; None if unlinked."""
    seen = 0
    while socket.is_linked and seen < 256:
        seen += 1
        link = next((l for l in socket.links if not l.is_muted and l.is_valid), None)
        if link is None:
            return None
        node = link.from_node
        if node.bl_idname == "NodeReroute":
            socket = node.inputs[0]
            continue
        if node.mute:
            # A muted node passes its first matching input through (internal links).
            passthrough = next((il.from_socket for il in node.internal_links if il.to_socket == link.from_socket), None)
            if passthrough is None:
                return None
            socket = passthrough
            continue
        return node, link.from_socket
    return None


def _active_output(node_tree, idname):
    """The output node Cycles would use: active, targeting ALL or CYCLES."""
    outputs = [n for n in node_tree.nodes if n.bl_idname == idname]
    for wanted in (("ALL", "CYCLES"), ("ALL", "CYCLES", "EEVEE")):
        for n in outputs:
            if n.is_active_output and getattr(n, "target", "ALL") in wanted:
                return n
        for n in outputs:
            if getattr(n, "target", "ALL") in wanted:
                return n
    return None


def world_color(world, warnings):
    """The native scene's world_color for a World: constant radiance, or an HDRI's strength (world.py)."""
    from .world import parse_world
    return parse_world(world, warnings).color
