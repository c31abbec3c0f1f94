"""`coherent render` options of the tracing axes (integrator, traversal, packet
assembly, BVH width, wavefront reordering, ambient occlusion), their
statistics in --json, and the --heatmaps images.

Two kinds of test: front-end plumbing (options parsed, bad values rejected
naming the option, JSON keys present and sane, files written) and properties
the renderer must honour for the option to mean anything (names start with
test_renderer_honours_...). Images are read with oiiotool, independent of
the writer.
"""
import json
import math
import re
import subprocess

import pytest

# Helpers are shared with the main CLI tests; the fixtures live in conftest.py.
from test_cli import one_line, oiio_info, oiio_pixels, run

TRACING_OPTIONS = ["--integrator", "--traversal", "--assembly", "--bvh-width", "--reorder", "--wave-size",
                   "--ao-samples", "--ao-distance", "--heatmaps", "--adaptive-min-samples"]


def render_json(cli, cornell, tmp_path, *args, name="out.exr", res=16, spp=2):
    out = tmp_path / name
    r = run(cli, "render", cornell, "-o", out, "--res", res, res, "--spp", spp, "--seed", 3, "--json", *args)
    assert r.returncode == 0, r.stderr
    return out, json.loads(r.stdout), r


def ratio_ok(value, lo=0.0, hi=math.inf):
    """A ratio in the report: null (nothing measured) or a finite number in [lo, hi]."""
    return value is None or (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi)


def exr_values(path, channel):
    w, h, channels = oiio_info(path)
    index = channels.index(channel)
    px = oiio_pixels(path)
    return w, h, [px[(x, y)][index] for y in range(h) for x in range(w)]


# --- parsing -------------------------------------------------------------------------------------

def test_every_setting_is_an_option_and_a_report_key(cli, cornell, tmp_path):
    """One settings table: each option --help lists beyond the CLI's own is a
    key of the report's settings block with the same name, and vice versa."""
    help_text = run(cli, "render", "--help").stdout
    options = set(re.findall(r"^  (--[a-z0-9-]+)", help_text, re.M))
    cli_only = {"--output", "--res", "--convergence", "--json", "--help", "--passes"}
    assert cli_only <= options
    _, stats, _ = render_json(cli, cornell, tmp_path, res=8, spp=1)
    keys = {("--all-features" if k == "force_all_features" else "--" + k.replace("_", "-")) for k in stats["settings"]}
    assert keys == options - cli_only


def test_render_help_lists_tracing_options(cli):
    r = run(cli, "render", "--help")
    assert r.returncode == 0
    for option in TRACING_OPTIONS:
        assert option in r.stdout, option
    for name in ["pt", "drt", "wrt", "rcs", "ao", "wavefront", "hash192", "csd32", "viridis"]:
        assert name in r.stdout, name


BAD_VALUES = [
    ("--integrator", "bogus"), ("--integrator", "PT"), ("--integrator", ""),
    ("--traversal", "simd"), ("--traversal", "Packet"),
    ("--assembly", "rays"),
    ("--bvh-width", "3"), ("--bvh-width", "16"), ("--bvh-width", "1"), ("--bvh-width", "eight"), ("--bvh-width", "4.0"),
    ("--reorder", "hash64"), ("--reorder", "None"),
    ("--wave-size", "0"), ("--wave-size", "-4"), ("--wave-size", "1e6"), ("--wave-size", "99999999999"),
    ("--ao-samples", "0"), ("--ao-samples", "x"), ("--ao-samples", "100000"),
    ("--ao-distance", "-1"), ("--ao-distance", "nan"), ("--ao-distance", "inf"), ("--ao-distance", "far"),
    ("--adaptive-min-samples", "1"), ("--adaptive-min-samples", "many"),
]


@pytest.mark.parametrize("option,value", BAD_VALUES, ids=[f"{o} {v!r}" for o, v in BAD_VALUES])
def test_bad_tracing_values_exit_2_naming_the_option(cli, cornell, tmp_path, option, value):
    out = tmp_path / "x.png"
    r = run(cli, "render", cornell, "-o", out, "--res", 8, 8, "--spp", 1, option, value)
    assert r.returncode == 2, r.stderr
    assert one_line(r.stderr), r.stderr
    assert option in r.stderr
    assert r.stdout == ""
    assert list(tmp_path.iterdir()) == []  # nothing written, heatmaps neither


@pytest.mark.parametrize("args", [["--integrator"], ["--heatmaps=yes"], ["--bvh-width"]])
def test_missing_or_unexpected_values_exit_2(cli, cornell, tmp_path, args):
    r = run(cli, "render", cornell, "-o", tmp_path / "x.png", "--res", 8, 8, *args)
    assert r.returncode == 2, r.stderr
    assert one_line(r.stderr), r.stderr


def test_auto_traversal_is_packets_with_cpt(cli, cornell, tmp_path):
    _, stats, _ = render_json(cli, cornell, tmp_path, "--sampler", "cpt")
    assert stats["settings"]["traversal"] == "packet"
    _, stats, _ = render_json(cli, cornell, tmp_path, "--sampler", "spt", "--traversal", "auto")
    assert stats["settings"]["traversal"] == "single"


def test_defaults_in_json(cli, cornell, tmp_path):
    _, stats, _ = render_json(cli, cornell, tmp_path)
    assert stats["settings"]["integrator"] == "pt"
    assert stats["settings"]["traversal"] == "single"
    assert stats["settings"]["assembly"] == "types"
    assert stats["settings"]["bvh_width"] == 8
    assert stats["settings"]["reorder"] == "none"
    assert stats["settings"]["wave_size"] == 65536
    assert stats["settings"]["ao_samples"] == 16
    assert stats["settings"]["ao_distance"] == 0.0
    assert stats["heatmaps"] is None


# Every accepted spelling, and what the report calls it ("wide" is single-ray
# traversal over the wide BVH; "type" is accepted for "types").
ACCEPTED = [
    *[(["--integrator", i], "integrator", i) for i in ["pt", "drt", "wrt", "rcs", "ao"]],
    *[(["--traversal", t], "traversal", t) for t in ["single", "packet", "stream", "wavefront"]],
    (["--traversal", "wide"], "traversal", "single"),
    (["--assembly", "runs"], "assembly", "runs"), (["--assembly", "type"], "assembly", "types"),
    *[(["--bvh-width", w], "bvh_width", int(w)) for w in ["2", "4", "8"]],
    *[(["--traversal", "wavefront", "--reorder", r], "reorder", r)
      for r in ["none", "static1d", "static3d", "hash32", "hash192", "csd32"]],
    (["--wave-size", "1000"], "wave_size", 1000),
    (["--wave-size=4096"], "wave_size", 4096),
    (["--ao-samples", "5"], "ao_samples", 5),
    (["--ao-distance", "0.25"], "ao_distance", 0.25),
]


@pytest.mark.parametrize("args,key,expected", ACCEPTED, ids=[" ".join(a) for a, _, _ in ACCEPTED])
def test_accepted_values_reach_the_report(cli, cornell, tmp_path, args, key, expected):
    out, stats, r = render_json(cli, cornell, tmp_path, *args, res=8, spp=1)
    assert stats["settings"][key] == expected
    assert out.exists()
    assert r.stderr == ""


def test_adaptive_min_samples_implies_adaptive(cli, cornell, tmp_path):
    _, stats, _ = render_json(cli, cornell, tmp_path, "--adaptive-min-samples", "4", spp=6)
    assert stats["adaptive"] is not None
    assert stats["settings"]["adaptive_min_samples"] == 4


# --- statistics ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def mode_reports(cli, cornell, tmp_path_factory):
    """--json reports of the Cornell box at 24x24, 2 spp, seed 3, per traversal mode."""
    d = tmp_path_factory.mktemp("modes")
    reports = {}
    for traversal in ["single", "packet", "stream", "wavefront"]:
        out = d / f"{traversal}.exr"
        r = run(cli, "render", cornell, "-o", out, "--res", 24, 24, "--spp", 2, "--seed", 3, "--threads", 2,
                "--traversal", traversal, "--json")
        assert r.returncode == 0, r.stderr
        reports[traversal] = (out, json.loads(r.stdout))
    return reports


@pytest.mark.parametrize("traversal", ["single", "packet", "stream", "wavefront"])
def test_tracing_statistics_are_present_and_sane(mode_reports, traversal):
    _, stats = mode_reports[traversal]
    # Existing keys unchanged.
    for key in ["seconds", "spp", "rays", "mrays_per_s", "features", "settings"]:
        assert key in stats, key
    for key in ["rays_per_second", "trace_seconds", "sort_seconds", "tests_per_ray", "simd_utilisation",
                "bounces"]:
        assert key in stats, key
    assert stats["rays_per_second"] == pytest.approx(stats["mrays_per_s"] * 1e6, rel=1e-9)
    assert stats["trace_seconds"] >= 0.0 and math.isfinite(stats["trace_seconds"])
    assert stats["sort_seconds"] >= 0.0 and math.isfinite(stats["sort_seconds"])
    for key in ["node_visits", "box", "triangle"]:
        assert ratio_ok(stats["tests_per_ray"][key]), stats["tests_per_ray"]
    for key in ["box", "triangle"]:
        assert ratio_ok(stats["simd_utilisation"][key], 0.0, 1.0), stats["simd_utilisation"]
    bounces = stats["bounces"]
    assert isinstance(bounces, list) and len(bounces) <= 8
    for i, b in enumerate(bounces):
        assert b["bounce"] == i
        assert b["and_deeper"] == (i == 7)
        for key in ["rays", "node_visits", "box_tests", "triangle_tests"]:
            assert isinstance(b[key], int) and b[key] >= 0, (i, key, b)
        for key in ["node_visits_per_ray", "box_tests_per_ray", "triangle_tests_per_ray"]:
            assert ratio_ok(b[key]), (i, key, b)
        for key in ["simd_box_utilisation", "simd_triangle_utilisation"]:
            assert ratio_ok(b[key], 0.0, 1.0), (i, key, b)
    if bounces:
        assert bounces[-1]["rays"] > 0  # trailing empty bounces are left out


@pytest.mark.parametrize("traversal", ["single", "packet", "stream", "wavefront"])
def test_renderer_honours_per_bounce_statistics(mode_reports, traversal):
    """Every traced ray is counted in exactly one bounce; bounce 0 holds the camera rays."""
    _, stats = mode_reports[traversal]
    bounces = stats["bounces"]
    assert bounces, "no per-bounce statistics"
    assert sum(b["rays"] for b in bounces) == stats["rays"]["total"]
    assert bounces[0]["rays"] >= stats["rays"]["camera"] == 24 * 24 * 2
    # A closed box: every ray enters the root and tests at least one box.
    # (Packets count a node visit per packet, not per ray: stats.h.)
    for b in bounces:
        assert b["box_tests"] >= b["rays"] and b["node_visits"] > 0, b
        if traversal == "single":
            assert b["node_visits"] >= b["rays"], b


def test_renderer_honours_simd_utilisation_only_for_packets(mode_reports):
    single = mode_reports["single"][1]["simd_utilisation"]
    assert single == {"box": None, "triangle": None}  # single rays fill no SIMD lanes of packets
    packet = mode_reports["packet"][1]
    assert 0.0 < packet["simd_utilisation"]["box"] <= 1.0
    assert 0.0 < packet["simd_utilisation"]["triangle"] <= 1.0
    # Camera rays of adjacent pixels are the most coherent packets of all.
    first = packet["bounces"][0]
    assert first["simd_box_utilisation"] > 0.5, first


@pytest.mark.parametrize("traversal", ["packet", "stream", "wavefront"])
def test_renderer_honours_traversal_modes_agree(mode_reports, traversal):
    """Traversal modes find the same hits for the same rays: the same image for the same seed."""
    ref_path, ref = mode_reports["single"]
    path, stats = mode_reports[traversal]
    assert stats["rays"]["camera"] == ref["rays"]["camera"]
    a, b = oiio_pixels(ref_path), oiio_pixels(path)
    _, _, channels = oiio_info(ref_path)
    rgb = [channels.index(c) for c in "RGB"]
    worst = max(abs(a[p][c] - b[p][c]) for p in a for c in rgb)
    assert worst <= 1e-4 * max(1.0, max(a[p][c] for p in a for c in rgb)), worst


def test_renderer_honours_bvh_width(cli, cornell, tmp_path):
    """Wider nodes: fewer node visits per ray (same rays, same hits)."""
    visits = {}
    for width in (2, 8):
        _, stats, _ = render_json(cli, cornell, tmp_path, "--bvh-width", width, "--integrator", "rcs",
                                  name=f"w{width}.exr", res=24, spp=1)
        visits[width] = stats["tests_per_ray"]["node_visits"]
    assert visits[8] < visits[2], visits


def test_renderer_honours_integrators(cli, cornell, tmp_path):
    """How far each integrator follows paths in the generated Cornell box
    (diffuse walls, a glossy metal block, a smooth glass sphere, an emissive
    quad and a point light)."""
    stats = {}
    for integrator in ["pt", "drt", "wrt", "rcs", "ao"]:
        _, report, _ = render_json(cli, cornell, tmp_path, "--integrator", integrator, "--ao-samples", 4,
                                   name=f"{integrator}.exr", res=16, spp=2)
        assert report["settings"]["integrator"] == integrator
        assert report["nonfinite_samples"] == 0
        stats[integrator] = report
    camera = 16 * 16 * 2
    depth = {i: len(s["bounces"]) for i, s in stats.items()}
    total = {i: s["rays"]["total"] for i, s in stats.items()}
    # Path tracing: diffuse interreflection, paths of many bounces in a closed box.
    assert stats["pt"]["rays"]["diffuse"] > 0 and depth["pt"] > 3, depth
    # Ray casting: direct light at the first hit only. Bounce 1 may hold the
    # BSDF-sampled rays of MIS (at most one per camera ray); nothing goes deeper.
    assert depth["rcs"] <= 2, depth
    if depth["rcs"] == 2:
        assert stats["rcs"]["bounces"][1]["rays"] <= camera, stats["rcs"]["bounces"]
    # Whitted: the same at diffuse and glossy hits, but it follows the glass
    # sphere's perfectly specular chains, so a few paths go deeper; only the
    # pixels that see the sphere continue past bounce 1.
    wrt = stats["wrt"]["bounces"]
    assert depth["wrt"] > 2, depth
    assert sum(b["rays"] for b in wrt[2:]) < wrt[1]["rays"] <= camera + stats["wrt"]["rays"]["refraction"], wrt
    # Distribution ray tracing follows only the glossy lobes: between the two.
    assert total["rcs"] <= total["drt"] < total["pt"], total
    # Ambient occlusion: 4 occlusion rays per camera ray that hits, nothing
    # else. The box fills all but a thin border of the frame (make_gltf.py's
    # camera sees just past the walls' front edges), so most camera rays hit.
    occlusion = total["ao"] - stats["ao"]["rays"]["camera"]
    assert occlusion % 4 == 0 and 0.8 * 4 * camera < occlusion <= 4 * camera, occlusion


def test_renderer_honours_ambient_occlusion(cli, cornell, tmp_path):
    """AO is a grey image with values in [0, 1]: white where open, darker in the corners."""
    out, stats, _ = render_json(cli, cornell, tmp_path, "--integrator", "ao", "--ao-samples", 8, res=32, spp=4)
    _, _, channels = oiio_info(out)
    px = oiio_pixels(out)
    r, g, b = (channels.index(c) for c in "RGB")
    values = [v[r] for v in px.values()]
    assert all(v[r] == v[g] == v[b] for v in px.values())  # grey
    assert all(0.0 <= x <= 1.0 for x in values)
    mean = sum(values) / len(values)
    assert 0.3 < mean < 1.0, mean
    assert min(values) < 0.8 * max(values)  # corners and contacts are occluded

    # A very short occlusion distance sees (almost) nothing: (almost) white.
    out, _, _ = render_json(cli, cornell, tmp_path, "--integrator", "ao", "--ao-samples", 8, "--ao-distance", "1e-4",
                            name="short.exr", res=32, spp=4)
    px = oiio_pixels(out)
    short = [v[r] for v in px.values()]
    assert sum(short) / len(short) > max(0.98, mean), (sum(short) / len(short), mean)


def test_renderer_honours_wavefront_reordering(cli, cornell, tmp_path):
    _, stats, _ = render_json(cli, cornell, tmp_path, "--traversal", "wavefront", "--reorder", "hash32", "--wave-size",
                              "256", res=24, spp=2)
    assert stats["sort_seconds"] > 0.0
    assert stats["trace_seconds"] > 0.0


# --- heatmaps ------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def heatmap_render(cli, cornell, tmp_path_factory):
    d = tmp_path_factory.mktemp("heat")
    out = d / "cornell.exr"
    r = run(cli, "render", cornell, "-o", out, "--res", 32, 24, "--spp", 2, "--traversal", "packet",
            "--heatmaps", "--json")
    assert r.returncode == 0, r.stderr
    return d, out, json.loads(r.stdout), r


def test_heatmaps_warn_where_visits_are_not_counted(cli, cornell, tmp_path, heatmap_render):
    # Streams count BVH visits per node queue, not per pixel: the visits
    # heatmap is zero and the CLI says so; packets count them, silently.
    assert "does not count BVH visits" not in heatmap_render[3].stderr
    r = run(cli, "render", cornell, "-o", tmp_path / "s.exr", "--res", 16, 12, "--spp", 1, "--traversal", "stream",
            "--heatmaps")
    assert r.returncode == 0, r.stderr
    assert "--traversal stream does not count BVH visits per path" in r.stderr
    _, _, values = exr_values(tmp_path / "s.bvh_visits.exr", "Y")
    assert max(values) == 0.0


def test_heatmap_files_are_written(heatmap_render):
    d, out, stats, r = heatmap_render
    names = sorted(p.name for p in d.iterdir())
    assert names == ["cornell.bvh_visits.exr", "cornell.bvh_visits.png", "cornell.exr", "cornell.simd.exr",
                     "cornell.simd.png"]
    heat = stats["heatmaps"]
    assert set(heat) == {"bvh_visits", "simd"}
    assert heat["bvh_visits"]["exr"] == str(d / "cornell.bvh_visits.exr")
    assert heat["simd"]["png"] == str(d / "cornell.simd.png")
    for stem in ["bvh_visits", "simd"]:
        w, h, channels = oiio_info(d / f"cornell.{stem}.exr")
        assert (w, h, channels) == (32, 24, ["Y"])
        w, h, channels = oiio_info(d / f"cornell.{stem}.png")
        assert (w, h, channels) == (32, 24, ["R", "G", "B"])


def test_heatmap_values_are_finite_and_match_the_report(heatmap_render):
    d, _, stats, _ = heatmap_render
    for stem, key in [("bvh_visits", "bvh_visits"), ("simd", "simd")]:
        _, _, values = exr_values(d / f"cornell.{stem}.exr", "Y")
        assert all(math.isfinite(v) and v >= 0.0 for v in values)
        report = stats["heatmaps"][key]
        assert report["min"] == pytest.approx(min(values), rel=1e-6)
        assert report["max"] == pytest.approx(max(values), rel=1e-6)
        assert report["mean"] == pytest.approx(sum(values) / len(values), rel=1e-4, abs=1e-6)
    assert stats["heatmaps"]["simd"]["scale"] == [0.0, 1.0]
    assert stats["heatmaps"]["bvh_visits"]["scale"] == [0.0, max(1.0, stats["heatmaps"]["bvh_visits"]["max"])]


def test_heatmap_png_follows_the_colour_scale(heatmap_render):
    """The PNG is the EXR's values on the printed scale through viridis (matplotlib's as the oracle)."""
    from matplotlib import colormaps
    d, _, stats, _ = heatmap_render
    for stem in ["bvh_visits", "simd"]:
        _, _, values = exr_values(d / f"cornell.{stem}.exr", "Y")
        px = oiio_pixels(d / f"cornell.{stem}.png")
        colours = [px[(x, y)] for y in range(24) for x in range(32)]
        lo, hi = stats["heatmaps"][stem]["scale"]
        expected = colormaps["viridis"]([min(1.0, max(0.0, (v - lo) / (hi - lo))) for v in values])
        worst = max(abs(c[k] - e[k]) for c, e in zip(colours, expected) for k in range(3))
        # A 17-sample table, linearly interpolated, then 8 bits: within 6/255.
        assert worst <= 6.0 / 255.0, (stem, worst)


def test_renderer_honours_heatmaps(heatmap_render):
    """Every pixel sees the closed box: every camera sample visits BVH nodes, and its packets use lanes."""
    d, _, _, r = heatmap_render
    assert "no heatmap samples" not in r.stderr
    _, _, visits = exr_values(d / "cornell.bvh_visits.exr", "Y")
    _, _, simd = exr_values(d / "cornell.simd.exr", "Y")
    assert min(visits) >= 1.0
    assert all(0.0 < u <= 1.0 for u in simd)
    assert sum(simd) / len(simd) < 1.0  # packets lose some coherence somewhere (edges, bounces)


def test_heatmaps_plain_mode_prints_value_ranges(cli, cornell, tmp_path):
    out = tmp_path / "plain.png"
    r = run(cli, "render", cornell, "-o", out, "--res", 16, 16, "--spp", 1, "--heatmaps")
    assert r.returncode == 0, r.stderr
    lines = r.stdout.strip().split("\n")
    assert len(lines) == 3, r.stdout
    assert str(out) in lines[0]
    assert "plain.bvh_visits.exr" in lines[1] and "plain.bvh_visits.png" in lines[1]
    assert "plain.simd.png" in lines[2] and "from 0 (dark) to 1 (bright)" in lines[2]
    assert (tmp_path / "plain.bvh_visits.png").exists() and (tmp_path / "plain.simd.exr").exists()


def test_heatmaps_unwritable_stem_fails(cli, cornell, tmp_path):
    # The heatmap paths are derived from -o; make one of them a directory.
    (tmp_path / "x.simd.exr").mkdir()
    r = run(cli, "render", cornell, "-o", tmp_path / "x.png", "--res", 8, 8, "--spp", 1, "--heatmaps")
    assert r.returncode == 1
    assert one_line(r.stderr) and "x.simd.exr" in r.stderr, r.stderr
