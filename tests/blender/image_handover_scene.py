# Run by test_image_handover.py in a subprocess Blender:
#
#   blender -b --addons coherent --python image_handover_scene.py -- OUT_DIR
#
# The node_scenes.py set-up (an orthographic camera sees an emitting plane,
# 1 sample per pixel, UVs snapped to pixel centres) with its Emission colour
# from an Image Texture (linear filtering, sRGB) of a 13x11 byte RGBA image
# held three ways: packed into the .blend (a PNG), read from a PNG file, and
# generated then painted through Image.pixels. Alpha mode Channel Packed: the
# colour is filtered as stored (a reader that associated the PNG's alpha
# would darken it). Each is rendered by Cycles, then twice by COHERENT:
# OUT_DIR/<case>_<engine>[_again].exr. "HANDOVER_RENDER <case> <n>" precedes
# each of COHERENT's renders, so its "Coherent: finished ..." line (images
# reused) can be matched to it.
#
# Then an image packed from an uncompressed TGA is rendered by COHERENT
# (OUT_DIR/repacked_before_coherent.exr), and repacked (Image > Reload) after
# another TGA of the same length (other texels) was saved over that file:
# rendered by Cycles, then twice by COHERENT (HANDOVER_RENDER repacked 0 / 1),
# whose first render must see the new bytes although length and name are
# unchanged: OUT_DIR/repacked_<engine>[_again].exr.
#
# Then the image with alpha mode Straight, packed, file-backed and as a
# generated float image (colour space Linear), with Linear and Closest
# filtering, its Alpha output unused or driving the Emission strength:
# Cycles associates byte texels when it loads them (c * a / 255 in
# integers; Blender's float pixels are associated already) and unassociates
# after filtering only when Alpha is used. Rendered once by each engine:
# OUT_DIR/straight_<source>_<interp>_<alpha>_<engine>.exr.

import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import node_scenes  # noqa: E402

WIDTH, HEIGHT = 13, 11


def pattern(seed=11):
    """RGBA float pixels, rows bottom-up as Image.pixels takes them: byte values exactly."""
    rng = np.random.default_rng(seed)
    bytes_ = rng.integers(0, 256, size=(HEIGHT, WIDTH, 4))
    bytes_[..., 3] = np.maximum(bytes_[..., 3], 40)
    return (bytes_ / 255.0).astype(np.float32)


def painted_image(name, seed=11):
    image = bpy.data.images.new(name, WIDTH, HEIGHT, alpha=True, float_buffer=False)
    image.colorspace_settings.name = "sRGB"  # before the pixels: changing it regenerates the image
    image.pixels.foreach_set(pattern(seed).ravel())
    return image


def tga_bytes(out_dir, seed):
    """An uncompressed TGA of pattern(seed): its length depends only on the image's size."""
    image = painted_image(f"tga_{seed}", seed)
    path = os.path.join(out_dir, f"pattern_{seed}.tga")
    image.filepath_raw = path
    image.file_format = "TARGA_RAW"
    image.save()
    with open(path, "rb") as f:
        return path, f.read()


def render_repacked(scene, material, out_dir):
    path, _ = tga_bytes(out_dir, 11)
    _, other = tga_bytes(out_dir, 12)
    image = bpy.data.images.load(path, check_existing=False)
    image.name = "repacked"
    image.pack()
    assert len(image.packed_file.data) == len(other), "the two TGAs must have the same length"
    image.alpha_mode = "CHANNEL_PACKED"
    image_tree(material, image)
    scene.render.engine = "COHERENT"
    render(scene, out_dir, "repacked_before_coherent")
    # Blender's Reload re-packs a packed image from its file: the user saved other texels over it.
    with open(path, "wb") as f:
        f.write(other)
    image.reload()
    assert image.packed_file.data == other
    # The add-on hashes a packed file where Blender holds it (images.packed_bytes), not a copy.
    from coherent import images as coherent_images
    view = coherent_images.packed_bytes(image.packed_file)
    print(f"PACKED_VIEW {type(view).__name__} {bytes(view) == other}", flush=True)
    scene.render.engine = "CYCLES"
    render(scene, out_dir, "repacked_cycles")
    scene.render.engine = "COHERENT"
    for n, suffix in enumerate(("", "_again")):
        print(f"HANDOVER_RENDER repacked {n}", flush=True)
        render(scene, out_dir, f"repacked_coherent{suffix}")


def make_images(out_dir):
    """{case: image}: packed PNG, file-backed PNG, generated and painted."""
    saved = painted_image("saved")
    path = os.path.join(out_dir, "handover.png")
    saved.filepath_raw = path
    saved.file_format = "PNG"
    saved.save()
    packed = bpy.data.images.load(path, check_existing=False)
    packed.name = "packed"
    packed.pack()
    file_backed = bpy.data.images.load(path, check_existing=False)
    file_backed.name = "file"
    images = {"packed": packed, "file": file_backed, "generated": painted_image("generated")}
    for image in images.values():
        image.alpha_mode = "CHANNEL_PACKED"
    return images


def render(scene, out_dir, name):
    scene.render.filepath = os.path.join(out_dir, f"{name}.exr")
    bpy.ops.render.render(write_still=True)


def image_tree(material, image, interpolation="Linear", alpha_used=False):
    nt, emission = node_scenes.fresh_tree(material)
    tex = node_scenes.node(nt, "ShaderNodeTexImage", interpolation=interpolation, extension="REPEAT")
    tex.image = image
    mapping = node_scenes.node(nt, "ShaderNodeMapping", vector_type="POINT")
    mapping.inputs["Scale"].default_value = (1.3, 1.3, 1.0)
    nt.links.new(node_scenes.pixel_uv(nt), mapping.inputs[0])
    nt.links.new(mapping.outputs[0], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], emission.inputs["Color"])
    if alpha_used:
        nt.links.new(tex.outputs["Alpha"], emission.inputs["Strength"])


def render_straight_cases(scene, material, out_dir):
    path = os.path.join(out_dir, "handover.png")
    packed = bpy.data.images.load(path, check_existing=False)
    packed.name = "straight_packed"
    packed.pack()
    file_backed = bpy.data.images.load(path, check_existing=False)
    file_backed.name = "straight_file"
    # Float pixels Blender holds associated already; scene-linear "Linear" is colour, not data.
    float_image = bpy.data.images.new("straight_float", WIDTH, HEIGHT, alpha=True, float_buffer=True)
    float_image.colorspace_settings.name = "Linear"
    float_image.pixels.foreach_set(pattern().ravel())
    for source, image in (("packed", packed), ("file", file_backed), ("float", float_image)):
        image.alpha_mode = "STRAIGHT"
        for interpolation in ("Linear", "Closest"):
            for alpha in ("unused", "used"):
                image_tree(material, image, interpolation, alpha == "used")
                case = f"straight_{source}_{interpolation.lower()}_{alpha}"
                for engine in ("CYCLES", "COHERENT"):
                    scene.render.engine = engine
                    render(scene, out_dir, f"{case}_{engine.lower()}")


def main():
    out_dir = sys.argv[sys.argv.index("--") + 1]
    scene, plane, material = node_scenes.setup_scene()
    for case, image in make_images(out_dir).items():
        image_tree(material, image)
        scene.render.engine = "CYCLES"
        render(scene, out_dir, f"{case}_cycles")
        scene.render.engine = "COHERENT"
        for n, suffix in enumerate(("", "_again")):
            print(f"HANDOVER_RENDER {case} {n}", flush=True)
            render(scene, out_dir, f"{case}_coherent{suffix}")
    render_repacked(scene, material, out_dir)
    render_straight_cases(scene, material, out_dir)


if __name__ == "__main__":
    main()
