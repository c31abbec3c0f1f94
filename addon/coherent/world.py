# SPDX-License-Identifier: Apache-2.0
"""Blender's World to the native scene's world.

Supported node trees (anything else warns once, naming the world and the
node, and falls back to the constant colour as before):

* World Output <- Background(Color, Strength): constant radiance Color x Strength.
* Background's Color <- Environment Texture (equirectangular), whose Vector is
  unlinked or comes from a Mapping node (rotation; type Point, Vector,
  Texture or Normal; no location) fed by Texture Coordinate > Generated or
  nothing. The native world is then Strength x map(R d), with the image's
  pixels handed over through numpy (float images are linear already; byte
  images in sRGB are linearised here, as Cycles does).
* Background's Color <- Sky Texture (Preetham, Hosek / Wilkie or Nishita), its
  Vector unlinked or from a Mapping node as above: the sky is precomputed
  natively as Cycles 3.4 does (_coherent.sky_texture) and the world is
  Strength x sky(R d), importance-sampled through a bake of the sky.
* No nodes: world.color.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import materials

_IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
_LINEAR_SPACES = {"Linear", "Non-Color", "Raw", "Linear ACES", "Linear ACEScg", "XYZ", "Filmic Log"}


@dataclass
class WorldSetup:
    color: tuple = (0.0, 0.0, 0.0)   # constant radiance, or the map's strength
    image: object = None             # bpy Image of an Environment Texture, or None
    rotation: tuple = _IDENTITY      # world direction -> map frame
    sky: dict = None                 # Sky Texture: keyword arguments of _coherent.sky_texture, or None
    key: tuple = field(default=())   # what the native world depends on (change detection)


def parse_world(world, warnings):
    """The WorldSetup of a Blender World (None: black)."""
    if world is None:
        return WorldSetup()
    if not world.use_nodes or world.node_tree is None:
        return _constant(materials._rgb(world.color))
    output = materials._active_output(world.node_tree, "ShaderNodeOutputWorld")
    source = materials._linked_source(output.inputs["Surface"]) if output is not None else None
    if source is None:
        return WorldSetup()
    node = source[0]
    if node.bl_idname != "ShaderNodeBackground":
        warnings.append(f"World '{world.name}': surface node '{node.name}' ({node.bl_idname}) is not supported, "
                        f"using the world colour")
        return _constant(materials._rgb(world.color))
    strength_socket = node.inputs["Strength"]
    linked = materials._linked_source(strength_socket)
    if linked is not None:
        warnings.append(f"World '{world.name}': Background 'Strength' is driven by node '{linked[0].name}' "
                        f"({linked[0].bl_idname}), which is not supported: using its default value")
    strength = max(float(strength_socket.default_value), 0.0)
    color_socket = node.inputs["Color"]
    linked = materials._linked_source(color_socket)
    if linked is not None:
        setup = _environment(world, linked[0], strength, warnings)
        if setup is not None:
            return setup
    return _constant(tuple(max(c * strength, 0.0) for c in materials._rgb(color_socket.default_value)))


def _constant(rgb):
    return WorldSetup(color=rgb, key=("color", rgb))


def _environment(world, node, strength, warnings):
    """WorldSetup for an Environment Texture feeding the Background colour; None (after a warning) otherwise."""
    where = f"World '{world.name}': node '{node.name}'"
    if node.bl_idname == "ShaderNodeTexSky":
        return _sky(world, node, strength, warnings)
    if node.bl_idname != "ShaderNodeTexEnvironment":
        warnings.append(f"{where} ({node.bl_idname}) drives the Background colour and is not supported: "
                        f"using the colour's default value")
        return None
    if node.projection != "EQUIRECTANGULAR":
        warnings.append(f"{where}: projection {node.projection} is not supported (only equirectangular): "
                        f"using the Background colour's default value")
        return None
    image = node.image
    if image is None or image.size[0] == 0 or image.size[1] == 0:
        name = "no image" if image is None else f"image '{image.name}' has no pixels (missing file?)"
        warnings.append(f"{where}: {name}: using the Background colour's default value")
        return None
    rotation = _vector_rotation(world, node, warnings)
    color = (strength, strength, strength)
    key = ("map", color, image.name, image.filepath, tuple(image.size), rotation)
    return WorldSetup(color=color, image=image, rotation=rotation, key=key)


_SKY_SETTINGS = ("turbidity", "ground_albedo", "sun_disc", "sun_size", "sun_intensity", "sun_elevation",
                 "sun_rotation", "altitude", "air_density", "dust_density", "ozone_density")


def sky_arguments(node):
    """Keyword arguments of _coherent.sky_texture for a Sky Texture node (Cycles' SkyTextureNode sync)."""
    args = {"sky_type": node.sky_type, "sun_direction": tuple(float(v) for v in node.sun_direction)}
    for name in _SKY_SETTINGS:
        value = getattr(node, name)
        args[name] = value if isinstance(value, bool) else float(value)
    return args


def _default_texture_mapping(mapping):
    return (not any(mapping.translation) and not any(mapping.rotation) and tuple(mapping.scale) == (1.0, 1.0, 1.0)
            and not mapping.use_min and not mapping.use_max
            and (mapping.mapping_x, mapping.mapping_y, mapping.mapping_z) == ("X", "Y", "Z"))


def _sky(world, node, strength, warnings):
    """WorldSetup for a Sky Texture feeding the Background colour."""
    if not _default_texture_mapping(node.texture_mapping):
        warnings.append(f"World '{world.name}': node '{node.name}': the texture's own mapping (Texture Mapping "
                        f"panel) is not supported: ignored (use a Mapping node)")
    # Blender disables the Vector input of a Nishita sky with its sun disc, and
    # Cycles ignores links into disabled sockets: the sky is then unrotated.
    rotation = _vector_rotation(world, node, warnings) if node.inputs["Vector"].enabled else _IDENTITY
    sky = sky_arguments(node)
    color = (strength, strength, strength)
    key = ("sky", color, tuple(sorted(sky.items())), rotation)
    return WorldSetup(color=color, rotation=rotation, sky=sky, key=key)


def _vector_rotation(world, env_node, warnings):
    """World-to-map rotation from the texture's Vector input (identity when unlinked)."""
    linked = materials._linked_source(env_node.inputs["Vector"])
    if linked is None:
        return _IDENTITY
    node, socket = linked
    where = f"World '{world.name}': node '{node.name}'"
    if node.bl_idname == "ShaderNodeTexCoord":
        if socket.name != "Generated":
            warnings.append(f"{where}: texture coordinate '{socket.name}' is not supported for the world "
                            f"(Generated is): using the view direction")
        return _IDENTITY
    if node.bl_idname != "ShaderNodeMapping":
        warnings.append(f"{where} ({node.bl_idname}) drives the texture's Vector and is not "
                        f"supported: using the view direction")
        return _IDENTITY
    inputs = node.inputs
    for name in ("Vector", "Location", "Rotation", "Scale"):
        src = materials._linked_source(inputs[name]) if name in inputs else None
        if src is not None and not (name == "Vector" and src[0].bl_idname == "ShaderNodeTexCoord"
                                    and src[1].name == "Generated"):
            warnings.append(f"{where}: Mapping input '{name}' driven by node '{src[0].name}' is not supported: "
                            f"using its default value")
    if "Location" in inputs and node.vector_type == "POINT" and any(abs(v) > 0 for v in inputs["Location"].default_value):
        warnings.append(f"{where}: a Mapping location does not apply to world directions here: ignored")
    scale = tuple(inputs["Scale"].default_value) if "Scale" in inputs else (1.0, 1.0, 1.0)
    if max(scale) - min(scale) > 1e-6 * max(abs(max(scale)), 1.0) or min(scale) <= 0.0:
        warnings.append(f"{where}: only a uniform positive Mapping scale is supported: scale ignored")
    r = _euler_xyz(inputs["Rotation"].default_value if "Rotation" in inputs else (0.0, 0.0, 0.0))
    if node.vector_type == "TEXTURE":
        r = r.T  # Texture mapping applies the inverse rotation
    return tuple(tuple(float(v) for v in row) for row in r)


def _euler_xyz(angles):
    """Blender's XYZ Euler rotation matrix (R = Rz Ry Rx), as the Mapping node applies it."""
    x, y, z = (float(a) for a in angles)
    cx, sx, cy, sy, cz, sz = math.cos(x), math.sin(x), math.cos(y), math.sin(y), math.cos(z), math.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def image_pixels(image):
    """Linear RGB(A) float32 pixels of `image`, shape (height, width, channels), rows bottom to top."""
    width, height = image.size
    channels = image.channels
    pixels = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(height, width, channels)
    space = image.colorspace_settings.name
    if not image.is_float and space not in _LINEAR_SPACES:
        rgb = pixels[..., :3]
        pixels[..., :3] = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    return pixels


def export_world(world, scene, warnings):
    """Sets the native scene's world from a Blender World; returns the WorldSetup."""
    setup = parse_world(world, warnings)
    if setup.sky is not None:
        from . import native_module
        scene.set_world_sky(native_module().sky_texture(**setup.sky), np.array(setup.rotation, dtype=np.float32))
    elif setup.image is not None:
        replaced = scene.set_world_map(image_pixels(setup.image), np.array(setup.rotation, dtype=np.float32))
        if replaced:
            warnings.append(f"World '{world.name}': image '{setup.image.name}' has {replaced} non-finite or "
                            f"negative values, rendered as 0")
    else:
        scene.clear_world_map()
    scene.world_color = setup.color
    return setup
