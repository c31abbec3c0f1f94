# SPDX-License-Identifier: Apache-2.0
"""Blender images to native textures (Scene.add_image).

An image that Blender reads from a file on disk is handed over by path: the
native side decodes it with OpenImageIO, once while the file is unchanged,
and filters it from memory (beyond the texture memory limit, through
OpenImageIO's texture cache; native/shader/textures.h). One that
exists only inside Blender (packed, generated, painted) is handed over as
its pixels through numpy (Image.pixels.foreach_get, the only pixel access
Blender offers; it stores rows bottom-up, files top-down), turned back into
the bytes Blender holds when it is a byte image (Blender gives byte / 255 as
float32, so rint(value * 255) is exact). Decoding a packed PNG's bytes with
OpenImageIO instead gives the same bytes but was slower (0.32 s against
0.13 s for a 2048x2048 image) and saves no decoding: Blender decodes the
image anyway when the shader compiler asks Image.is_float.

Byte images stay bytes natively (4 bytes per RGBA pixel); the sRGB decoding
stays in the shader, after filtering, as Cycles does. In-memory images are
retained natively under a key (image name, then what changes with its
pixels: the packed bytes' hash, the generator's settings, or the pixels'
hash), so a later render of an unchanged image reuses the native copy and
its cached tiles instead of handing it over again.

Straight-alpha colour byte images are associated natively on the way in
(add_image(associate=True)), texel by texel, as Cycles does when it loads
them (BlenderImageLoader for packed and generated images, OIIOImageLoader
for files: c = c * a / 255 in integers, truncated), so filtering sees the
texels Cycles filters; the Image Texture node unassociates after filtering
when its Alpha output is used.
Float images need nothing: Blender holds float pixels associated already.
Data (Non-Color), Channel Packed and None images stay as stored.
"""

from __future__ import annotations

import os
import zlib

import numpy as np

from .shader_compiler import DATA_COLORSPACES


def _in_memory_only(image):
    return image.source != "FILE" or image.packed_file is not None or image.is_dirty


def _file_path(image):
    import bpy  # only here: the rest of the add-on's material code is bpy-free
    return bpy.path.native_pathsep(bpy.path.abspath(image.filepath_raw, library=image.library))


# Reading Image.is_float or Image.channels makes Blender decode a file image,
# and Blender frees decoded images again (after a Cycles render, for one):
# 0.4 s a render for 40 MB of PNGs (docs/results/textured_twin.md). For the
# file types below the header settles what the add-on needs, as Blender 3.4
# loads them (tests/blender/test_image_headers.py): a file of 8-bit values
# becomes a 4-channel byte image, a wider one a float image (whose channel
# count Blender decides on load: 4 for an RGB EXR or a grey 16-bit PNG).
_HEADER_TYPES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr", ".hdr")
_headers = {}  # (path, size, mtime) -> image_file_format() of the file


def blender_format(image, read_header=None):
    """(is_float, channels) as Blender reports them for `image`; from the file's header
    (`read_header`: _coherent.image_file_format) for an unedited file image of a type in
    _HEADER_TYPES, without decoding it, where channels is None for a float image; else from
    Blender."""
    if read_header is not None and not _in_memory_only(image):
        path = _file_path(image)
        if path.lower().endswith(_HEADER_TYPES):
            try:
                stat = os.stat(path)
            except OSError:
                stat = None
            if stat is not None:
                key = (path, stat.st_size, stat.st_mtime_ns)
                if key not in _headers:
                    _headers[key] = read_header(path)
                header = _headers[key]
                if header is not None:
                    return (True, None) if header["wide"] else (False, 4)
    return bool(image.is_float), int(image.channels)


def _associated_on_load(image, is_float, channels):
    """Whether Cycles associates this image's texels when it loads them: a straight byte colour image."""
    return (image.alpha_mode == "STRAIGHT" and not is_float and channels == 4
            and image.colorspace_settings.name not in DATA_COLORSPACES)


def _digest(data, content_hash=None):
    """A change detector for the successive versions of one image (keys also hold its identity): its length
    and a hash of its bytes, read in place. `content_hash` is _coherent.content_hash (XXH3-64 at memory
    speed, 10 GB/s here); without the native module, zlib's CRC-32 (2.5 GB/s)."""
    if content_hash is not None:
        return content_hash(data)
    return f"{len(memoryview(data).cast('B'))} {zlib.crc32(data):08x}"


# Blender's PackedFile in DNA_packedFile_types.h (unchanged since 2.5): {int size; int seek; void *data;}.
_PACKED_SIZE_OFFSET, _PACKED_DATA_OFFSET = 0, 8
_packed_view_ok = None  # None: not yet checked in this process; then whether packed_bytes' view is right


def packed_bytes(packed_file, content_hash=None):
    """The packed file's bytes where Blender holds them, as a ctypes array (no copy), or PackedFile.data.

    PackedFile.data copies every byte into a new Python bytes object, only for _version to hash it: with
    CRC-32, 15.5 ms per render for bench/textured_twin.py's 20.5 MB of packed PNGs, now 1.9 ms through this
    view and content_hash (medians of 15, docs/results/textured_twin.md). The view is trusted only when
    the struct's size field equals RNA's size, and after the first packed file of the process has hashed
    the same through it as through PackedFile.data (else the copy is used from then on, and a warning
    says why)."""
    global _packed_view_ok
    if _packed_view_ok is False:
        return packed_file.data
    import ctypes

    address = packed_file.as_pointer()
    size = ctypes.c_int.from_address(address + _PACKED_SIZE_OFFSET).value
    data = ctypes.c_void_p.from_address(address + _PACKED_DATA_OFFSET).value
    if size != packed_file.size or size <= 0 or not data:
        return packed_file.data
    view = (ctypes.c_char * size).from_address(data)
    if _packed_view_ok is None:
        copy = packed_file.data
        _packed_view_ok = _digest(view, content_hash) == _digest(copy, content_hash)
        if not _packed_view_ok:
            print("Coherent: packed images are read through PackedFile.data (a copy per render): "
                  "this Blender's PackedFile layout is not the one images.py expects")
            return copy
    return view


def _identity(image):
    library = image.library.filepath if getattr(image, "library", None) is not None else ""
    return f"{library}|{image.name}"


class ImageExporter:
    """Adds each bpy image once to a native scene and remembers its index."""

    def __init__(self, native_scene, read_header=None, content_hash=None):
        self.scene = native_scene
        self.read_header = read_header  # _coherent.image_file_format, None: ask Blender
        self.content_hash = content_hash  # _coherent.content_hash, None: zlib's CRC-32
        self._indices = {}

    def is_float(self, image):
        """Image.is_float, from the file's header where that avoids a decode (blender_format)."""
        return blender_format(image, self.read_header)[0]

    def index_of(self, image, material, node):
        key = image.original.as_pointer() if getattr(image, "original", None) is not None else image.as_pointer()
        index = self._indices.get(key)
        if index is None:
            label = f"Material '{material.name}', node '{node.name}', image '{image.name}'"
            index = self._add(image, label)
            self._indices[key] = index
        return index

    def _add(self, image, label):
        associate = _associated_on_load(image, *blender_format(image, self.read_header))
        path = None
        if not _in_memory_only(image):
            path = _file_path(image)
            # The native side decodes it (and associates it as Cycles would), once while the file is
            # unchanged: Blender's pixels of it cost a decode and a float per texel.
            return self.scene.add_image(label, path=path, associate=associate)
        version = _version(image, path, self.content_hash)
        if version is not None:
            key = f"{_identity(image)}\n{version}"
            index = self.scene.add_retained_image(label, key)
            if index is not None:
                return index
        pixels = image_pixels(image)
        associate = associate and pixels.dtype == np.uint8 and pixels.ndim == 3 and pixels.shape[2] == 4
        if version is None:  # no cheaper signal of a change than the pixels themselves
            key = (f"{_identity(image)}\npixels {pixels.shape} {pixels.dtype} {_digest(pixels, self.content_hash)}"
                   f"{' associated' if associate else ''}")
            index = self.scene.add_retained_image(label, key)
            if index is not None:
                return index
        return self.scene.add_image(label, pixels=pixels, key=key if pixels.size else "", associate=associate)


def _version(image, path=None, content_hash=None):
    """What fixes an unedited packed, generated or file image's pixels, read without them; None otherwise.
    (Blender converts float images to the scene's linear space on load, by their colour space.)"""
    if image.is_dirty:
        return None
    spaces = f"{image.colorspace_settings.name} {image.alpha_mode}"
    if path is not None:
        try:
            stat = os.stat(path)
        except OSError:
            return None
        return f"file {spaces} {path} {stat.st_size} {stat.st_mtime_ns}"
    if image.source == "FILE" and image.packed_file is not None:
        return f"packed {spaces} {_digest(packed_bytes(image.packed_file, content_hash), content_hash)}"
    if image.source == "GENERATED":
        return (f"generated {spaces} {image.generated_type} {tuple(image.generated_color)} "
                f"{image.generated_width}x{image.generated_height} float={image.use_generated_float}")
    return None


def image_pixels(image):
    """(H, W, C) pixels of a bpy image, first row at the top: uint8 for a byte image, else float32;
    (0, 0, 4) when it has none."""
    width, height = int(image.size[0]), int(image.size[1])  # reading the size loads the image
    channels = int(image.channels) if width and height else 4
    if width == 0 or height == 0 or channels == 0:
        return np.zeros((0, 0, 4), dtype=np.float32)
    pixels = np.empty(width * height * channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    pixels = pixels.reshape(height, width, channels)[::-1]
    if image.is_float:
        return np.ascontiguousarray(pixels)
    out = np.empty((height, width, channels), dtype=np.uint8)
    np.rint(np.multiply(pixels, 255.0, dtype=np.float32), out=out, casting="unsafe")
    return out
