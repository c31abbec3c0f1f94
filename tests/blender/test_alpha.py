# Transparent, Translucent and Holdout closures and Principled Alpha from an
# image texture (native/render/transparency.h) against Cycles, on the scene
# alpha_scene.py builds: an alpha-clipped quad in front of a coloured wall
# and its cut-out sun shadow, a translucent leaf lit from behind, a tinted
# transparent pane (Mix Shader), a holdout sphere.
#
# The criterion: per-channel means within 2 %, every 16x16 block's
# mean within 8 % (plus a small absolute floor for blocks that are black in
# both), and the alpha channel alike (the holdout's hole).

from pathlib import Path

import numpy as np

import blender_helpers as bh

SCRIPT = Path(__file__).with_name("alpha_scene.py")
SIZE = 96
SAMPLES = 128
SEED = 5
BLOCK = 16
MEAN_TOLERANCE = 0.02
BLOCK_TOLERANCE = 0.08
BLOCK_FLOOR = 0.004  # absolute: blocks near black in both engines
ALPHA_BLOCK_TOLERANCE = 0.02

_RENDERS = {}  # engine -> renders, shared by the tests of one session


def read_rgba(path):
    channels = bh.read_image_channels(path)
    rgba = np.stack([channels[n] for n in sorted(channels, key=lambda n: "RGBA".index(n.split(".")[-1]))], axis=-1)
    assert np.isfinite(rgba).all()
    return rgba.astype(np.float64)


def render(blender, engine, tmp_path):
    """(main scene RGBA, deterministic nodes scene RGBA, log) of one engine, rendered once per session."""
    if engine not in _RENDERS:
        out = tmp_path / engine.lower()
        result = blender("--python", SCRIPT, "--", engine, out, SAMPLES, SIZE, SEED, timeout=400)
        assert result.returncode == 0, result.describe()
        main, nodes = read_rgba(Path(str(out) + ".exr")), read_rgba(Path(str(out) + "_nodes.exr"))
        assert main.shape == (SIZE, SIZE, 4) and nodes.shape == (32, 32, 4)
        _RENDERS[engine] = (main, nodes, result.stdout + result.stderr)
    return _RENDERS[engine]


def block_means(img):
    h, w = img.shape[:2]
    return img[:h // BLOCK * BLOCK, :w // BLOCK * BLOCK].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, -1).mean(axis=(1, 3))


def test_alpha_scene_matches_cycles(blender, tmp_path):
    ours, _, log = render(blender, bh.ENGINE_ID, tmp_path)
    cycles, _, _ = render(blender, "CYCLES", tmp_path)
    assert "not supported" not in log and "unsupported" not in log, log

    mean_ours, mean_cycles = ours[..., :3].mean(axis=(0, 1)), cycles[..., :3].mean(axis=(0, 1))
    ratio = mean_ours / mean_cycles
    bo, bc = block_means(ours), block_means(cycles)
    rel = np.abs(bo[..., :3] - bc[..., :3]) / np.maximum(bc[..., :3], 1e-9)
    ok = np.abs(bo[..., :3] - bc[..., :3]) <= BLOCK_TOLERANCE * bc[..., :3] + BLOCK_FLOOR
    alpha_diff = np.abs(bo[..., 3] - bc[..., 3])
    text = (f"alpha scene {SIZE}^2 px, {SAMPLES} spp: mean ratio ours/cycles {np.round(ratio, 4)}, "
            f"worst block {rel.max():.3f} relative, alpha means {ours[..., 3].mean():.4f} vs "
            f"{cycles[..., 3].mean():.4f}, worst alpha block {alpha_diff.max():.4f}")
    print(text)
    assert np.all(np.abs(ratio - 1.0) <= MEAN_TOLERANCE), text
    assert ok.all(), f"{int((~ok).sum())} block channels beyond 8 %: {text}"
    # The holdout's hole: alpha below 1 somewhere, and the same alpha per block.
    assert cycles[..., 3].min() < 0.5 and ours[..., 3].min() < 0.5, text
    assert alpha_diff.max() <= ALPHA_BLOCK_TOLERANCE, text


def test_principled_alpha_and_shader_nodes_convert(coherent_addon):
    """Principled Alpha becomes Cycles' Mix of a white Transparent BSDF (1 - alpha) and the
    Principled BSDF with its emission (alpha); Transparent, Translucent and Holdout nodes
    become closures of their kinds."""
    import bpy
    from coherent.materials import MaterialConverter

    class Recorder:
        def __init__(self):
            self.materials = []

        def add_material(self, name, closures, weights, emission, program=None):
            self.materials.append((closures, weights, emission, program))
            return len(self.materials)

    mat = bpy.data.materials.new("HalfAlpha")
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Alpha"].default_value = 0.25
    bsdf.inputs["Emission"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Emission Strength"].default_value = 2.0
    warnings = []
    rec = Recorder()
    MaterialConverter(rec, warnings).index_of(mat)
    closures, weights, emission, program = rec.materials[0]
    assert not warnings, warnings
    kinds = [c.get("kind", "principled") for c in closures]
    assert sorted(zip(kinds, weights)) == [("principled", 0.25), ("transparent", 0.75)]
    assert emission == (0.5, 0.5, 0.5) and program is None

    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    out = next(n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    for idname, kind in (("ShaderNodeBsdfTransparent", "transparent"), ("ShaderNodeBsdfTranslucent", "translucent"),
                         ("ShaderNodeHoldout", "holdout")):
        node = nodes.new(idname)
        links.new(node.outputs[0], out.inputs["Surface"])
        rec = Recorder()
        MaterialConverter(rec, warnings).index_of(mat)
        assert [c["kind"] for c in rec.materials[0][0]] == [kind], (idname, rec.materials[0])
    assert not warnings, warnings
    bpy.data.materials.remove(mat)


def test_transparent_and_holdout_nodes_match_cycles_exactly(blender, tmp_path):
    """Deterministic at 1 sample per pixel: an emitter seen through a Transparent BSDF
    shows colour x emission; a 50/50 Mix of Holdout and Emission halves the colour and
    the alpha. Cycles must agree pixel for pixel (float rounding)."""
    _, ours, _ = render(blender, bh.ENGINE_ID, tmp_path)
    _, cycles, _ = render(blender, "CYCLES", tmp_path)
    left, right = ours[:, :16], ours[:, 16:]
    np.testing.assert_allclose(left[..., :3], np.broadcast_to([0.2, 0.3, 0.225], left[..., :3].shape), atol=1e-5)
    np.testing.assert_allclose(right, np.broadcast_to([0.2, 0.4, 0.1, 0.5], right.shape), atol=1e-5)
    np.testing.assert_allclose(ours, cycles, atol=1e-5)
