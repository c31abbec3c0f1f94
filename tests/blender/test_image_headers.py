# What the add-on asks of a file image without making Blender decode it
# (addon/coherent/images.py, blender_format): reading Image.is_float or
# Image.channels decodes the whole file, and Blender frees decoded images
# again, so every render paid the decode (0.4 s for 40 MB of PNGs). For
# common file types the header settles both. The oracle is Blender itself:
# for every file below, the header's answer equals what Blender reports once
# it has loaded the image; and exporting a scene whose material samples a
# Non-Color PNG (handed to OpenImageIO by path) leaves the image undecoded.

import bpy
import pytest

from coherent import export, images, native_module

# (file name, Blender file format, colour mode, colour depth)
FILES = [
    ("rgba8.png", "PNG", "RGBA", "8"),
    ("grey8.png", "PNG", "BW", "8"),
    ("rgb16.png", "PNG", "RGB", "16"),
    ("grey16.png", "PNG", "BW", "16"),
    ("rgba16.tif", "TIFF", "RGBA", "16"),
    ("rgb8.jpg", "JPEG", "RGB", "8"),
    ("rgba_half.exr", "OPEN_EXR", "RGBA", "16"),
    ("rgb_float.exr", "OPEN_EXR", "RGB", "32"),
]


def save_image(path, file_format, mode, depth):
    settings = bpy.context.scene.render.image_settings
    settings.file_format = file_format
    settings.color_mode = mode
    if file_format != "JPEG":
        settings.color_depth = depth
    image = bpy.data.images.new("header_source", 16, 8, alpha=True, float_buffer=True)
    image.pixels.foreach_set([(i % 7) / 7.0 for i in range(16 * 8 * 4)])
    image.save_render(str(path))
    bpy.data.images.remove(image)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("headers")
    for name, file_format, mode, depth in FILES:
        save_image(folder / name, file_format, mode, depth)
    return folder


@pytest.mark.parametrize("name", [f[0] for f in FILES])
def test_header_gives_what_blender_reports_without_a_decode(files, name):
    image = bpy.data.images.load(str(files / name), check_existing=False)
    assert not image.has_data
    fmt = images.blender_format(image, native_module().image_file_format)
    assert not image.has_data, "reading the header decoded the image"
    # Blender's own answer (this decodes); a float image's channel count is left to Blender.
    assert fmt[0] == image.is_float and fmt[1] in (image.channels, None), (name, fmt)
    assert (fmt[1] is None) == image.is_float, (name, fmt)
    assert image.has_data
    bpy.data.images.remove(image)


def test_exporting_a_non_color_file_texture_leaves_it_undecoded(files):
    image = bpy.data.images.load(str(files / "rgba8.png"), check_existing=False)
    image.colorspace_settings.name = "Non-Color"  # not associated: handed to OpenImageIO by its path
    material = bpy.data.materials.new("header_material")
    material.use_nodes = True
    nodes = material.node_tree.nodes
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    material.node_tree.links.new(texture.outputs["Color"], nodes["Principled BSDF"].inputs["Roughness"])
    bpy.ops.mesh.primitive_plane_add()
    plane = bpy.context.active_object
    plane.data.materials.append(material)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    result = export.export_scene(native_module(), depsgraph, 8, 8, need_camera=False)
    assert result.scene.texture_stats()["images"] == 1
    assert not image.has_data, "the export made Blender decode the file"
    bpy.data.objects.remove(plane, do_unlink=True)
    bpy.data.materials.remove(material)
    bpy.data.images.remove(image)
