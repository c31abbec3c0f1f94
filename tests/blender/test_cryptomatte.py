# Cryptomatte in Blender (View Layer > Passes > Cryptomatte): our engine and
# Cycles render glass_scene.blend with object, material and asset
# Cryptomatte at 4 levels (pass_renders.py "crypto"): the manifests in the
# EXR metadata give every name the same hash, and inside objects both
# engines put the same id at rank 0 with full coverage. The compositor's
# Cryptomatte node, run headless on our render ("matte"), isolates one
# object's pixels.

import json

import numpy as np
import pytest

import blender_helpers as bh
from test_passes import interior, render

def exr_metadata(path):
    import OpenImageIO as oiio
    spec = oiio.ImageInput.open(str(path)).spec()
    return {a.name: a.value for a in spec.extra_attribs}


def manifests(metadata):
    """{layer name: {object name: hash hex}} from Cryptomatte metadata."""
    out = {}
    for key, value in metadata.items():
        if key.startswith("cryptomatte/") and key.endswith("/name"):
            base = key[:-len("name")]
            assert metadata[base + "hash"] == "MurmurHash3_32"
            assert metadata[base + "conversion"] == "uint32_to_float32"
            out[value] = json.loads(metadata[base + "manifest"])
    return out


@pytest.fixture(scope="module")
def crypto(user_scripts, tmp_path_factory):
    out = tmp_path_factory.mktemp("crypto")
    renders = render(user_scripts, bh.BLEND_SCENES / "glass_scene.blend", out, "crypto", 4, 25)
    return out, renders


def test_cryptomatte_manifest_hashes_equal_cycles(crypto):
    out, _ = crypto
    ours, theirs = manifests(exr_metadata(out / "coherent.exr")), manifests(exr_metadata(out / "cycles.exr"))
    assert set(ours) == {"ViewLayer.CryptoObject", "ViewLayer.CryptoMaterial", "ViewLayer.CryptoAsset"}
    assert set(ours) == set(theirs)
    expected = {"ViewLayer.CryptoObject": {"Floor", "Backdrop", "GlassSphere", "MetalSphere"},
                "ViewLayer.CryptoAsset": {"Floor", "Backdrop", "GlassSphere", "MetalSphere"},
                "ViewLayer.CryptoMaterial": {"Floor", "Backdrop", "Glass", "Metal"}}
    for layer, names in expected.items():
        # Cycles also lists its default shaders; every name both list has one hash.
        assert names <= set(ours[layer]) & set(theirs[layer]), (layer, ours[layer], theirs[layer])
        for name in set(ours[layer]) & set(theirs[layer]):
            assert ours[layer][name] == theirs[layer][name], (layer, name)


def test_cryptomatte_ids_and_coverage_match_cycles_inside_objects(crypto):
    _, renders = crypto
    ours, theirs = renders["coherent"], renders["cycles"]
    inside = interior(bh.find_channels(theirs, "IndexOB", "X")[..., 0])
    for layer in ("CryptoObject00", "CryptoMaterial00", "CryptoAsset00"):
        a, b = bh.find_channels(ours, layer, "rgba"), bh.find_channels(theirs, layer, "rgba")
        # Rank 0: the same id, covering the whole pixel; nothing at rank 1.
        assert (a[..., 0][inside] == b[..., 0][inside]).all(), layer
        assert np.allclose(a[..., 1][inside], 1.0) and np.allclose(b[..., 1][inside], 1.0), layer
        assert (a[..., 3][inside] == 0).all(), layer
    # At object edges coverage splits between ids and sums to 1 where the
    # pixel saw only objects (no world in this view).
    a = bh.find_channels(ours, "CryptoObject00", "rgba")
    a1 = bh.find_channels(ours, "CryptoObject01", "rgba")
    total = a[..., 1] + a[..., 3] + a1[..., 1] + a1[..., 3]
    assert np.allclose(total[~inside], 1.0, atol=1e-6)
    assert (a[..., 3][~inside] > 0).any()


def test_compositor_cryptomatte_node_isolates_one_object(user_scripts, tmp_path):
    result = bh.run_blender([bh.BLEND_SCENES / "glass_scene.blend", "--python",
                             bh.REPO_ROOT / "tests" / "blender" / "pass_renders.py", "--", tmp_path, 25, 4, "matte",
                             "COHERENT"], user_scripts, timeout=300)
    assert result.returncode == 0, result.describe()
    matte = bh.read_image_channels(tmp_path / "coherent.exr")["R"]
    index_channels = bh.read_image_channels(tmp_path / "index0001.exr")
    index = next(iter(index_channels.values()))
    metal = float(result.stdout.split("METAL_SPHERE_INDEX")[1].split()[0])
    inside = interior(index)
    assert ((index == metal) & inside).sum() > 100
    # Inside objects: the matte is 1 exactly on MetalSphere and 0 elsewhere.
    assert np.allclose(matte[inside & (index == metal)], 1.0, atol=1e-4)
    assert np.allclose(matte[inside & (index != metal)], 0.0, atol=1e-4)
