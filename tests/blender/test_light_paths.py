# COHERENT against Cycles on the small scenes light_path_scenes.py builds:
#
# - Point light of radius r (Cycles 3.4: a disc of radius r facing the
#   shading point, radiance P / (4 pi) / (pi r^2), hit by BSDF rays) seen in
#   a smooth glass and a mirror sphere, the camera zoomed onto its
#   reflection so the highlight covers ~90 pixels. Compared: the image mean
#   (all of it is light from the point light, the world is black) and the
#   sum over the highlight (pixels above 10 % of either image's maximum),
#   within 4 %. Measured at 256 spp, two seeds each: mirror 0.9995-1.0003,
#   glass 0.999-1.020 (its highlight also holds light refracted through the
#   sphere, which only BSDF sampling finds: that is the spread). A
#   wrong disc radiance, radius or Fresnel moves these by far more.
#   At a 50 mm view the same reflections cover a fraction of a pixel, and a
#   few hundred samples per pixel give either engine a few hits there: that
#   noise, not a bias, is what earlier glass-scene comparisons of a handful
#   of highlight pixels showed (at 4096 spp the 1x totals agree too).
# - Light Path > Is Shadow Ray: with transparent shadows the surface shader
#   runs for shadow rays and reads 1 there, as in Cycles. A quad that is
#   diffuse to camera rays and transparent to shadow rays is seen and casts
#   no shadow; the reverse one is unseen and casts one. Direct light from a
#   sharp sun, black world: the image is deterministic up to pixel coverage
#   at edges, so 8x8 blocks must agree within 2 % (plus a floor for black).
# - Geometry > Pointiness (addon/coherent/geometry_attributes.py, Cycles'
#   attr_create_pointiness): a lifted grid split along a seam, seen from
#   above with Emission = Pointiness, must match per pixel within 5e-4. The
#   values span 0.42-0.58; what remains is where in its pixel each sample
#   fell (measured at most 1.4e-4 at 64 spp). Skipping the welding of the
#   seam's duplicate vertices moves those vertices by up to 0.007.
# - Shadow terminator (native/render/shadow_terminator.h): low-poly,
#   smooth-shaded wavy sheets under a grazing sun, direct light only, one
#   with Cycles' Geometry Offset at 0 and one at 0.1 (or both at 0). Cycles'
#   two renders differ in 9 of 64 8x8 blocks by up to 0.048 (the crests'
#   faceted shadows); ours must match each within the Is Shadow Ray
#   tolerance (measured: at most 0.0015), so ignoring the offset, or
#   refusing light below the flat triangle where the smooth normal accepts
#   it, fails.
# - Geometry > Random Per Island (native/scene/mesh_islands.h): 16 separate
#   grids in one mesh; constant per island, so every pixel whose 3x3
#   neighbourhood is one island in Cycles' image must match within float
#   rounding (1e-6): the hash of Cycles' own union-find representative.

from pathlib import Path

import numpy as np
import pytest

import blender_helpers as bh

SCRIPT = Path(__file__).with_name("light_path_scenes.py")
SIZE = 64
SAMPLES = 256
SEEDS = (3, 4)
CASES = ("shadow", "glass", "mirror", "pointiness", "islands", "terminator", "terminator_off")
HIGHLIGHT_TOLERANCE = 0.04
BLOCK = 8
BLOCK_TOLERANCE = 0.02
BLOCK_FLOOR = 0.003

_RENDERS = {}


def render(blender, engine, tmp_path):
    """{case: RGB image averaged over SEEDS} of one engine, rendered once per session."""
    if engine not in _RENDERS:
        images = {case: [] for case in CASES}
        for seed in SEEDS:
            out = tmp_path / f"{engine.lower()}_{seed}"
            result = blender("--python", SCRIPT, "--", engine, out, SAMPLES, SIZE, seed, *CASES, timeout=300)
            assert result.returncode == 0, result.describe()
            assert "not supported" not in result.output, result.output
            for case in CASES:
                channels = bh.read_image_channels(Path(f"{out}_{case}.exr"))
                rgb = np.stack([channels[k] for k in ("R", "G", "B")], axis=-1).astype(np.float64)
                assert rgb.shape == (SIZE, SIZE, 3) and np.isfinite(rgb).all()
                images[case].append(rgb)
        _RENDERS[engine] = {case: np.mean(imgs, axis=0) for case, imgs in images.items()}
    return _RENDERS[engine]


@pytest.mark.parametrize("case", ["glass", "mirror"])
def test_point_light_reflection_matches_cycles(blender, tmp_path, case):
    ours, cycles = render(blender, bh.ENGINE_ID, tmp_path)[case], render(blender, "CYCLES", tmp_path)[case]
    lum_o, lum_c = ours.mean(axis=-1), cycles.mean(axis=-1)
    highlight = (lum_o > 0.1 * lum_o.max()) | (lum_c > 0.1 * lum_c.max())
    image_ratio = lum_o.mean() / lum_c.mean()
    highlight_ratio = lum_o[highlight].sum() / lum_c[highlight].sum()
    text = (f"{case} sphere, point light r = 0.25: image mean ours/cycles {image_ratio:.4f}, highlight "
            f"({int(highlight.sum())} px) {highlight_ratio:.4f}")
    print(text)
    assert 20 <= highlight.sum() <= SIZE * SIZE // 4, f"the zoomed view misses the highlight: {text}"
    assert abs(image_ratio - 1.0) <= HIGHLIGHT_TOLERANCE, text
    assert abs(highlight_ratio - 1.0) <= HIGHLIGHT_TOLERANCE, text


def block_means(img):
    h, w = img.shape[:2]
    return img.reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, -1).mean(axis=(1, 3))


def test_is_shadow_ray_matches_cycles(blender, tmp_path):
    ours, cycles = render(blender, bh.ENGINE_ID, tmp_path)["shadow"], render(blender, "CYCLES", tmp_path)["shadow"]
    bo, bc = block_means(ours), block_means(cycles)
    bad = np.abs(bo - bc) > BLOCK_TOLERANCE * bc + BLOCK_FLOOR
    text = (f"Is Shadow Ray scene: means ours {np.round(ours.mean(axis=(0, 1)), 4)}, cycles "
            f"{np.round(cycles.mean(axis=(0, 1)), 4)}, worst block difference {np.abs(bo - bc).max():.4f}")
    print(text)
    assert not bad.any(), f"{int(bad.sum())} block channels differ: {text}"
    # The scene shows what it tests: a lit floor, a shadow (the unseen quad's)
    # and the seen quad's green.
    lum = cycles.mean(axis=-1)
    assert (lum > 0.2).mean() > 0.5 and (lum < 0.01).any()
    assert (cycles[..., 1] > 2.0 * cycles[..., 0] + 0.05).any()


def test_shadow_terminator_offset_matches_cycles(blender, tmp_path):
    ours = render(blender, bh.ENGINE_ID, tmp_path)
    cycles = render(blender, "CYCLES", tmp_path)
    shown = np.abs(block_means(cycles["terminator"]) - block_means(cycles["terminator_off"]))
    assert shown.max() > 0.02, f"the offset changes Cycles' image too little to test: {shown.max():.4f}"
    for case in ("terminator", "terminator_off"):
        bo, bc = block_means(ours[case]), block_means(cycles[case])
        bad = np.abs(bo - bc) > BLOCK_TOLERANCE * bc + BLOCK_FLOOR
        text = (f"{case}: means ours {ours[case].mean():.5f}, cycles {cycles[case].mean():.5f}, worst block "
                f"difference {np.abs(bo - bc).max():.4f} (the offset moves Cycles' blocks by up to {shown.max():.4f})")
        print(text)
        assert not bad.any(), f"{int(bad.sum())} block channels differ: {text}"


def test_pointiness_matches_cycles(blender, tmp_path):
    ours = render(blender, bh.ENGINE_ID, tmp_path)["pointiness"].mean(axis=-1)
    cycles = render(blender, "CYCLES", tmp_path)["pointiness"].mean(axis=-1)
    diff = np.abs(ours - cycles)
    text = (f"pointiness: cycles {cycles.min():.4f}..{cycles.max():.4f}, largest difference {diff.max():.6f} "
            f"at {np.unravel_index(diff.argmax(), diff.shape)}")
    print(text)
    assert cycles.max() - cycles.min() > 0.1, text  # the grid is curved enough to test something
    assert diff.max() <= 5e-4, text


def test_random_per_island_matches_cycles(blender, tmp_path):
    ours = render(blender, bh.ENGINE_ID, tmp_path)["islands"].mean(axis=-1)
    cycles = render(blender, "CYCLES", tmp_path)["islands"].mean(axis=-1)
    windows = np.lib.stride_tricks.sliding_window_view(cycles, (3, 3))
    inside = np.zeros_like(cycles, dtype=bool)
    inside[1:-1, 1:-1] = (windows.max(axis=(2, 3)) == windows.min(axis=(2, 3))) & (cycles[1:-1, 1:-1] > 0)
    diff = np.abs(ours - cycles)[inside]
    values = np.unique(cycles[inside])
    text = f"random per island: {inside.sum()} interior px, {values.size} island values, largest difference {diff.max()}"
    print(text)
    assert values.size >= 12, text
    assert diff.max() <= 1e-6, text
