"""`coherent render --passes`: Cycles' render passes as layers of the EXR.

Read back with oiiotool (an implementation independent of the writer): the
named passes are there under Cycles' names, the light passes add up to
Combined per pixel, and a bad name or a PNG output is refused with exit 2.
"""
from test_cli import oiio_info, oiio_pixels, one_line, run

LIGHT = ["DiffDir", "DiffInd", "GlossDir", "GlossInd", "TransDir", "TransInd", "Emit", "Env"]


def test_passes_are_layers_that_add_up_to_combined(cli, cornell, tmp_path):
    out = tmp_path / "passes.exr"
    r = run(cli, "render", cornell, "-o", out, "--res", 24, 24, "--spp", 4, "--passes",
            "diffdir,diffind,glossdir,glossind,transdir,transind,emit,env,mist,indexob")
    assert r.returncode == 0, r.stderr
    _, _, channels = oiio_info(out)
    for layer, ids in [(p, "RGB") for p in LIGHT] + [("DiffCol", "RGB"), ("Mist", "Z"), ("IndexOB", "X")]:
        for c in ids:
            assert f"{layer}.{c}" in channels, channels
    assert "AO.R" not in channels  # not asked for
    index = {c: i for i, c in enumerate(channels)}
    worst = 0.0
    for v in oiio_pixels(out).values():
        for c in "RGB":
            total = v[index[f"Emit.{c}"]] + v[index[f"Env.{c}"]]
            for lobe in ("Diff", "Gloss", "Trans"):
                total += (v[index[f"{lobe}Dir.{c}"]] + v[index[f"{lobe}Ind.{c}"]]) * v[index[f"{lobe}Col.{c}"]]
            worst = max(worst, abs(total - v[index[c]]) / max(1.0, abs(v[index[c]])))
    assert worst < 1e-4


def test_unknown_pass_and_png_are_usage_errors(cli, cornell, tmp_path):
    r = run(cli, "render", cornell, "-o", tmp_path / "a.exr", "--passes", "diffdir,shiny")
    assert r.returncode == 2 and one_line(r.stderr) and "'shiny'" in r.stderr, r.stderr
    r = run(cli, "render", cornell, "-o", tmp_path / "a.png", "--passes", "mist")
    assert r.returncode == 2 and one_line(r.stderr) and ".exr" in r.stderr, r.stderr


def test_denoising_writes_its_features_and_the_noisy_image(cli, cornell, tmp_path):
    # --denoise keeps the image before denoising and the features it used, as
    # Blender's passes do; --denoising-data alone writes the features; a plain
    # render writes neither.
    features = [("Denoising Normal", "XYZ"), ("Denoising Albedo", "RGB"), ("Denoising Depth", "Z")]
    out = tmp_path / "denoised.exr"
    r = run(cli, "render", cornell, "-o", out, "--res", 24, 24, "--spp", 4, "--denoise")
    assert r.returncode == 0, r.stderr
    _, _, channels = oiio_info(out)
    for layer, ids in features + [("Noisy Image", "RGBA")]:
        for c in ids:
            assert f"{layer}.{c}" in channels, channels
    index = {c: i for i, c in enumerate(channels)}
    pixels = list(oiio_pixels(out).values())
    depths = [v[index["Denoising Depth.Z"]] for v in pixels]
    assert min(depths) >= 0.0 and max(depths) > 1.0, (min(depths), max(depths))  # the box is metres deep
    assert any(abs(v[index["Noisy Image.R"]] - v[index["R"]]) > 1e-6 for v in pixels)  # denoising changed R
    r = run(cli, "render", cornell, "-o", tmp_path / "data.exr", "--res", 24, 24, "--spp", 4, "--denoising-data")
    assert r.returncode == 0, r.stderr
    _, _, channels = oiio_info(tmp_path / "data.exr")
    assert "Denoising Depth.Z" in channels and "Noisy Image.R" not in channels, channels
    r = run(cli, "render", cornell, "-o", tmp_path / "plain.exr", "--res", 24, 24, "--spp", 4)
    assert r.returncode == 0, r.stderr
    _, _, channels = oiio_info(tmp_path / "plain.exr")
    assert not any(c.startswith(("Denoising", "Noisy")) for c in channels), channels
