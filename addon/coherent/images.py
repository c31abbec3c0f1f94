# SPDX-License-Identifier: Apache-2.0
"""Blender images to native textures (Scene.add_image).

An image that Blender reads from a file on disk is handed over by path, so
OpenImageIO's texture cache loads, tiles and MIP-maps it itself. One that
exists only inside Blender (packed into the .blend, generated, or painted and
not saved) is handed over as its float pixel buffer through numpy
(Image.pixels.foreach_get; Blender stores rows bottom-up, files top-down).
"""

from __future__ import annotations

import numpy as np


def _in_memory_only(image):
    return image.source != "FILE" or image.packed_file is not None or image.is_dirty


class ImageExporter:
    """Adds each bpy image once to a native scene and remembers its index."""

    def __init__(self, native_scene):
        self.scene = native_scene
        self._indices = {}

    def index_of(self, image, material, node):
        key = image.original.as_pointer() if getattr(image, "original", None) is not None else image.as_pointer()
        index = self._indices.get(key)
        if index is None:
            label = f"Material '{material.name}', node '{node.name}', image '{image.name}'"
            index = self._add(image, label)
            self._indices[key] = index
        return index

    def _add(self, image, label):
        if not _in_memory_only(image):
            import bpy  # only here: the rest of the add-on's material code is bpy-free
            path = bpy.path.abspath(image.filepath_raw, library=image.library)
            return self.scene.add_image(label, path=bpy.path.native_pathsep(path))
        return self.scene.add_image(label, pixels=image_pixels(image))


def image_pixels(image):
    """Float (H, W, C) pixels of a bpy image, first row at the top; (0, 0, 4) when it has none."""
    width, height = int(image.size[0]), int(image.size[1])  # reading the size loads the image
    channels = int(image.channels) if width and height else 4
    if width == 0 or height == 0 or channels == 0:
        return np.zeros((0, 0, 4), dtype=np.float32)
    pixels = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    return np.ascontiguousarray(pixels.reshape(height, width, channels)[::-1])
