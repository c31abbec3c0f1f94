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
