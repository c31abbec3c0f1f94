"""glTF base colour textures in the CLI (native/io/gltf_textures.cpp).

A quad seen head-on by an orthographic camera carries a 2x2 texture (red,
green / blue, white, top row first) on its TEXCOORD_0, sampled NEAREST. Lit
by the uniform white world the loader adds to a scene without lights, each
quarter of the image must show its texel's colour: this checks that the
texture is read (embedded in the .glb, or a .png beside a .gltf), that UVs
follow glTF's top-left origin, and that a missing image renders Cycles'
magenta with a warning instead of failing.
"""
import base64
import json
import struct
import subprocess
import zlib

import pytest

TEXELS = [[(255, 0, 0), (0, 255, 0)], [(0, 0, 255), (255, 255, 255)]]  # rows top to bottom
EXPECTED = {"top_left": 0, "top_right": 1, "bottom_left": 2}  # dominant channel of each quarter


def png_bytes(rows):
    raw = b"".join(b"\x00" + bytes(c for px in row for c in px) for row in rows)
    chunk = lambda kind, data: (struct.pack(">I", len(data)) + kind + data +  # noqa: E731
                                struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    header = struct.pack(">IIBBBBB", len(rows[0]), len(rows), 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def quad_document(image):
    positions = [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0]
    uvs = [0, 1, 1, 1, 1, 0, 0, 0]  # glTF: v = 0 at the top of the image
    normals = [0, 0, 1] * 4
    indices = [0, 1, 2, 0, 2, 3]
    blob = struct.pack("<12f", *positions) + struct.pack("<8f", *uvs) + struct.pack("<12f", *normals) + \
        struct.pack("<6H", *indices)
    views = [(0, 48), (48, 32), (80, 48), (128, 12)]
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in views],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "NORMAL": 2}, "indices": 3,
                                    "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0,
                                                "roughnessFactor": 1.0}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"magFilter": 9728, "minFilter": 9728}],
        "images": [image],
        "cameras": [{"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 10}}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 2]}],
        "scenes": [{"nodes": [0, 1]}], "scene": 0,
    }
    return doc, blob


def write_glb(path, doc, blob):
    doc["buffers"][0]["byteLength"] = len(blob)
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    blob += b"\x00" * (-len(blob) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(blob), b"BIN\x00") + blob
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body)


def embedded_glb(path):
    doc, blob = quad_document({"bufferView": 4, "mimeType": "image/png"})
    image = png_bytes(TEXELS)
    blob += b"\x00" * (-len(blob) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(image)})
    write_glb(path, doc, blob + image)


def gltf_beside(path, image_name, write_image=True):
    doc, blob = quad_document({"uri": image_name})
    doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    path.write_text(json.dumps(doc))
    if write_image:
        (path.parent / image_name).write_bytes(png_bytes(TEXELS))


def quarters(cli, scene, tmp_path):
    out = tmp_path / "out.exr"
    result = subprocess.run([cli, "render", scene, "-o", out, "--res", "16", "16", "--spp", "16"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    import OpenImageIO as oiio
    pixels = oiio.ImageBuf(str(out)).get_pixels(oiio.FLOAT)[..., :3]
    q = {"top_left": pixels[2:6, 2:6], "top_right": pixels[2:6, 10:14], "bottom_left": pixels[10:14, 2:6],
         "bottom_right": pixels[10:14, 10:14]}
    return {k: v.mean(axis=(0, 1)) for k, v in q.items()}, result.stderr


@pytest.mark.parametrize("kind", ["glb_embedded", "gltf_file_beside"])
def test_base_color_texture_on_uvs(cli, tmp_path, kind):
    if kind == "glb_embedded":
        scene = tmp_path / "quad.glb"
        embedded_glb(scene)
    else:
        scene = tmp_path / "quad.gltf"
        gltf_beside(scene, "texels%20one.png".replace("%20", " "))
    means, log = quarters(cli, scene, tmp_path)
    for quarter, channel in EXPECTED.items():
        rgb = means[quarter]
        others = [rgb[k] for k in range(3) if k != channel]
        assert rgb[channel] > 0.2 and max(others) < 0.1 * rgb[channel], (quarter, rgb, log)
    white = means["bottom_right"]
    assert min(white) > 0.5 and max(white) - min(white) < 0.05 * max(white), white


def test_missing_image_renders_magenta_with_a_warning(cli, tmp_path):
    scene = tmp_path / "quad.gltf"
    gltf_beside(scene, "missing.png", write_image=False)
    means, log = quarters(cli, scene, tmp_path)
    assert "missing.png" in log and "magenta" in log, log
    for rgb in means.values():
        assert rgb[1] < 0.05 * rgb[0] and abs(rgb[0] - rgb[2]) < 0.05 * rgb[0], means


def test_emissive_and_metallic_roughness_textures(cli, tmp_path):
    """The texture as emission (factor 1) on a black surface that also has a metallic-roughness
    texture: with no other light the camera sees exactly the decoded texels, and a material with
    several textured outputs loads as one program. (What the metallic-roughness texture does to
    reflection is not checked here.)"""
    scene = tmp_path / "emissive.glb"
    doc, blob = quad_document({"bufferView": 4, "mimeType": "image/png"})
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0,
                                                  "roughnessFactor": 1.0, "metallicRoughnessTexture": {"index": 0}},
                         "emissiveTexture": {"index": 0}, "emissiveFactor": [1.0, 1.0, 1.0]}]
    image = png_bytes(TEXELS)
    blob += b"\x00" * (-len(blob) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(image)})
    write_glb(scene, doc, blob + image)
    means, log = quarters(cli, scene, tmp_path)
    expected = {"top_left": (1, 0, 0), "top_right": (0, 1, 0), "bottom_left": (0, 0, 1), "bottom_right": (1, 1, 1)}
    for quarter, rgb in expected.items():
        assert means[quarter] == pytest.approx(rgb, abs=1e-5), (quarter, means[quarter], log)


@pytest.mark.parametrize("transform, expected", [
    # Half a texture to the right: each quarter shows its horizontal neighbour (repeat wraps).
    ({"offset": [0.5, 0.0]}, {"top_left": (0, 1, 0), "top_right": (1, 0, 0), "bottom_left": (1, 1, 1),
                              "bottom_right": (0, 0, 1)}),
    # A quarter turn: u' = -v, v' = u in glTF's UV space (the extension's column-major matrices).
    ({"rotation": 1.5707963}, {"top_left": (0, 1, 0), "top_right": (1, 1, 1), "bottom_left": (1, 0, 0),
                               "bottom_right": (0, 0, 1)}),
])
def test_khr_texture_transform(cli, tmp_path, transform, expected):
    scene = tmp_path / "transformed.glb"
    doc, blob = quad_document({"bufferView": 4, "mimeType": "image/png"})
    doc["extensionsUsed"] = ["KHR_texture_transform"]
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1]}, "emissiveFactor": [1, 1, 1],
                         "emissiveTexture": {"index": 0, "extensions": {"KHR_texture_transform": transform}}}]
    image = png_bytes(TEXELS)
    blob += b"\x00" * (-len(blob) % 4)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(image)})
    write_glb(scene, doc, blob + image)
    means, log = quarters(cli, scene, tmp_path)
    for quarter, rgb in expected.items():
        assert means[quarter] == pytest.approx(rgb, abs=1e-5), (quarter, means, log)
