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
* Mix Shader: weights (1 - fac, fac); Add Shader: both branches at full weight.

Only constant inputs are supported. A linked input (texture, math, ...) falls
back to the socket's default value, and an unsupported shader node becomes a
Lambert closure with the node's Color input; both produce one warning per
material and node type so the user knows the render differs from Cycles.
No per-vertex or per-pixel work happens here.
"""

from __future__ import annotations

import math

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
    """Accumulates (weight, closure) pairs and emission for one material."""

    def __init__(self):
        self.closures = []  # list of (weight, dict)
        self.emission = [0.0, 0.0, 0.0]

    def add_closure(self, weight, closure):
        if weight > _MIN_WEIGHT:
            self.closures.append((weight, closure))

    def add_emission(self, weight, rgb):
        for i in range(3):
            self.emission[i] += weight * max(rgb[i], 0.0)


class MaterialConverter:
    """Converts bpy materials once each and keeps their native indices."""

    def __init__(self, native_scene, warnings):
        self.scene = native_scene
        self.warnings = warnings  # list of str shared with the exporter
        self._cache = {}  # original material pointer -> native index
        self._warned = set()

    # -- public -------------------------------------------------------------

    def index_of(self, material):
        """Native material index for a bpy material (None -> default material 0)."""
        if material is None:
            return 0
        key = material.original.as_pointer() if material.original is not None else material.as_pointer()
        index = self._cache.get(key)
        if index is None:
            closures, weights, emission = self.convert(material)
            index = self.scene.add_material(material.name, closures=closures, weights=weights, emission=emission)
            self._cache[key] = index
        return index

    def native_indices(self):
        """{original material pointer: native index} of every material converted so far (a copy)."""
        return dict(self._cache)

    def convert(self, material):
        """(closures, weights, emission) for add_material."""
        flat = _Flattened()
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
        return [c for _, c in closures], [w for w, _ in closures], tuple(flat.emission)

    # -- node walking ---------------------------------------------------------

    def _warn(self, material, text):
        key = (material.name, text)
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(f"Material '{material.name}': {text}")

    def _shader_socket(self, material, socket, weight, flat, depth):
        """Adds what flows into a SHADER input socket, scaled by `weight`."""
        if weight <= _MIN_WEIGHT:
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
            if self._value(material, node, "Roughness") > 0.0:
                self._warn(material, "Diffuse BSDF roughness (Oren-Nayar) is not supported, using Lambert")
            flat.add_closure(weight, self._diffuse(color))
        elif kind in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic"):
            if kind == "ShaderNodeBsdfAnisotropic" and abs(self._value(material, node, "Anisotropy")) > 0.0:
                self._warn(material, "anisotropy is not supported, using isotropic Glossy")
            roughness = 0.0 if getattr(node, "distribution", "") == "SHARP" else self._value(material, node, "Roughness")
            flat.add_closure(weight, dict(_DEFAULT_CLOSURE, base_color=self._color(material, node, "Color"),
                                          metallic=1.0, roughness=roughness))
        elif kind in ("ShaderNodeBsdfGlass", "ShaderNodeBsdfRefraction"):
            if kind == "ShaderNodeBsdfRefraction":
                self._warn(material, "Refraction BSDF approximated by Glass BSDF (adds reflection)")
            roughness = 0.0 if getattr(node, "distribution", "") == "SHARP" else self._value(material, node, "Roughness")
            ior = self._value(material, node, "IOR")
            flat.add_closure(weight, dict(_DEFAULT_CLOSURE, base_color=self._color(material, node, "Color"),
                                          roughness=roughness, transmission=1.0, ior=max(ior, 1e-3),
                                          specular=_specular_from_ior(max(ior, 1e-3))))
        elif kind == "ShaderNodeEmission":
            color = self._color(material, node, "Color")
            strength = self._value(material, node, "Strength")
            flat.add_emission(weight, tuple(c * strength for c in color))
        elif kind == "ShaderNodeMixShader":
            fac = min(max(self._value(material, node, "Fac"), 0.0), 1.0)
            self._shader_socket(material, node.inputs[1], weight * (1.0 - fac), flat, depth + 1)
            self._shader_socket(material, node.inputs[2], weight * fac, flat, depth + 1)
        elif kind == "ShaderNodeAddShader":
            self._shader_socket(material, node.inputs[0], weight, flat, depth + 1)
            self._shader_socket(material, node.inputs[1], weight, flat, depth + 1)
        else:
            # Nearest supported BSDF: Lambert with the node's colour if it has one.
            self._warn(material, f"unsupported shader node {kind} ('{node.name}') rendered as diffuse")
            color = self._color(material, node, "Color") if "Color" in node.inputs else (0.8, 0.8, 0.8)
            flat.add_closure(weight, self._diffuse(color))

    def _principled(self, material, node, weight, flat):
        ior = max(self._value(material, node, "IOR"), 1e-3)
        closure = {
            "base_color": self._color(material, node, "Base Color"),
            "metallic": self._value(material, node, "Metallic"),
            "roughness": self._value(material, node, "Roughness"),
            "specular": self._value(material, node, "Specular"),
            "transmission": self._value(material, node, "Transmission"),
            "ior": ior,
            "principled_diffuse": True,
        }
        ignored = [name for name, unused in (
            ("Subsurface", 0.0), ("Sheen", 0.0), ("Clearcoat", 0.0), ("Anisotropic", 0.0), ("Specular Tint", 0.0),
        ) if name in node.inputs and self._value(material, node, name, check_link=False) > unused]
        if "Alpha" in node.inputs and self._value(material, node, "Alpha", check_link=False) < 1.0:
            ignored.append("Alpha")
        for name in ("Normal", "Clearcoat Normal", "Tangent"):
            if name in node.inputs and _linked_source(node.inputs[name]) is not None:
                ignored.append(f"{name} (linked)")
        if ignored:
            self._warn(material, "Principled BSDF inputs not supported (ignored): " + ", ".join(ignored))
        flat.add_closure(weight, closure)
        emission = self._color(material, node, "Emission")
        strength = self._value(material, node, "Emission Strength")
        if strength != 0.0 and any(c > 0.0 for c in emission):
            flat.add_emission(weight, tuple(c * strength for c in emission))

    @staticmethod
    def _diffuse(color):
        return dict(_DEFAULT_CLOSURE, base_color=color, specular=0.0, metallic=0.0, roughness=1.0)

    # -- inputs -----------------------------------------------------------------

    def _input(self, material, node, name, check_link=True):
        socket = node.inputs[name]
        if check_link:
            source = _linked_source(socket)
            if source is not None:
                self._warn(material, f"input '{name}' of {node.bl_idname} is driven by {source[0].bl_idname}, "
                                     f"which is not supported: using its default value")
        return socket.default_value

    def _value(self, material, node, name, check_link=True):
        value = float(self._input(material, node, name, check_link))
        return value if math.isfinite(value) else 0.0

    def _color(self, material, node, name):
        value = _rgb(self._input(material, node, name))
        return tuple(v if math.isfinite(v) else 0.0 for v in value)


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
