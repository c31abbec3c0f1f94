"""Behaviour of the `coherent` command-line renderer.

Run by ctest as `python3 -m pytest -q tests/cli` with COHERENT_CLI set to the
built executable; the `cli` and `cornell` (the generated Cornell box)
fixtures live in conftest.py. Images are checked with `oiiotool`
(openimageio-tools), an implementation independent of the one that wrote
them.
"""
import base64
import json
import os
import re
import signal
import struct
import subprocess
import time
from pathlib import Path

import pytest


def run(cli, *args, timeout=300):
    return subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=timeout)


def one_line(text):
    lines = text.strip("\n").split("\n")
    return len(lines) == 1 and lines[0].strip() != ""


def oiio_info(path):
    """(width, height, channel names) as oiiotool reads the file."""
    out = subprocess.run(["oiiotool", "--info", "-v", str(path)], capture_output=True, text=True, check=True).stdout
    m = re.search(r":\s+(\d+)\s+x\s+(\d+),\s+(\d+) channel", out)
    assert m, out
    channels = re.search(r"channel list:\s*(.*)", out).group(1).split(", ")
    return int(m.group(1)), int(m.group(2)), [c.strip() for c in channels]


def oiio_pixels(path):
    """{(x, y): [channel values]} as floats (PNG values normalised to [0,1])."""
    out = subprocess.run(["oiiotool", "--dumpdata", str(path)], capture_output=True, text=True, check=True).stdout
    pixels = {}
    # Integer files print raw values then "(normalised floats)"; float files print floats.
    for m in re.finditer(r"Pixel \((\d+), (\d+)\):([^(\n]*)(?:\(([^)]*)\))?", out):
        values = m.group(4) if m.group(4) is not None else m.group(3)
        pixels[(int(m.group(1)), int(m.group(2)))] = [float(v) for v in values.split()]
    return pixels


def write_gltf(path, positions, indices, extra_nodes=(), materials=None):
    """A one-mesh .gltf with an embedded buffer (float32 positions, uint16 indices)."""
    pos = struct.pack(f"<{len(positions)}f", *positions)
    idx = struct.pack(f"<{len(indices)}H", *indices)
    pad = b"\0" * ((4 - len(pos) % 4) % 4)
    buf = pos + pad + idx
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(buf),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
                        {"buffer": 0, "byteOffset": len(pos) + len(pad), "byteLength": len(idx)}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(positions) // 3, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5123, "count": len(indices), "type": "SCALAR"}],
        "meshes": [{"name": "Quad", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": [{"mesh": 0}, *extra_nodes],
        "scenes": [{"nodes": list(range(1 + len(extra_nodes)))}],
        "scene": 0,
    }
    if materials:
        doc["materials"] = materials
        doc["meshes"][0]["primitives"][0]["material"] = 0
    path.write_text(json.dumps(doc))
    return path


# --- help and version -------------------------------------------------------

def test_help(cli):
    r = run(cli, "--help")
    assert r.returncode == 0
    assert "render" in r.stdout


def test_render_help_lists_every_option(cli):
    r = run(cli, "render", "--help")
    assert r.returncode == 0
    for option in ["-o", "--res", "--spp", "--seed", "--threads", "--max-bounces", "--json"]:
        assert option in r.stdout, option


def test_version(cli):
    r = run(cli, "--version")
    assert r.returncode == 0
    assert re.search(r"coherent \d+\.\d+\.\d+", r.stdout)


def test_no_arguments_is_bad_usage(cli):
    assert run(cli).returncode == 2


# --- bad usage: exit 2, one line, nothing written ----------------------------

BAD_ARGS = [
    ["frobnicate"],
    ["render", "{scene}", "-o", "{out}", "--bogus"],
    ["render", "{scene}", "-o", "{out}", "--spp"],
    ["render", "{scene}", "-o", "{out}", "--spp", "abc"],
    ["render", "{scene}", "-o", "{out}", "--spp", "4x"],
    ["render", "{scene}", "-o", "{out}", "--spp", "0"],
    ["render", "{scene}", "-o", "{out}", "--spp", "-3"],
    ["render", "{scene}", "-o", "{out}", "--spp", "99999999999999999999"],
    ["render", "{scene}", "-o", "{out}", "--res", "-5", "5"],
    ["render", "{scene}", "-o", "{out}", "--res", "0", "64"],
    ["render", "{scene}", "-o", "{out}", "--res", "64"],
    ["render", "{scene}", "-o", "{out}", "--res", "32768", "16384"],
    ["render", "{scene}", "-o", "{out}", "--res", "100000", "1"],
    ["render", "{scene}", "-o", "{out}", "--res", "64", "x"],
    ["render", "{scene}", "-o", "{out}", "--threads", "-1"],
    ["render", "{scene}", "-o", "{out}", "--seed", "-1"],
    ["render", "{scene}", "-o", "{out}", "--max-bounces", "many"],
    ["render", "{scene}", "-o", "{out}", "--json=yes"],
    ["render", "{scene}", "-o"],
    ["render", "{scene}"],
    ["render", "-o", "{out}"],
    ["render", "{scene}", "{scene}", "-o", "{out}"],
    ["render", "{scene}", "-o", "{stem}.jpg"],
    ["render", "{scene}", "-o", "{stem}"],
]


@pytest.mark.parametrize("args", BAD_ARGS, ids=[" ".join(a[1:]) or a[0] for a in BAD_ARGS])
def test_bad_arguments_exit_2_with_one_line(cli, cornell, tmp_path, args):
    out = tmp_path / "out.png"
    subst = {"scene": str(cornell), "out": str(out), "stem": str(tmp_path / "out")}
    r = run(cli, *[a.format(**subst) for a in args])
    assert r.returncode == 2, r.stderr
    assert one_line(r.stderr), r.stderr
    assert r.stdout == ""
    assert list(tmp_path.iterdir()) == []


# --- bad input: exit 1, one line naming the file, nothing written -------------

def bad_inputs(cornell, tmp_path):
    glb = cornell.read_bytes()
    files = {
        "missing.glb": None,
        "empty.glb": b"",
        "noise.glb": os.urandom(3000),
        "truncated.glb": glb[: len(glb) // 2],
        "header.glb": glb[:24],
        "text.gltf": b"{ not json",
        "dangling.gltf": json.dumps({"asset": {"version": "2.0"}, "nodes": [{"mesh": 4}],
                                     "scenes": [{"nodes": [0]}]}).encode(),
    }
    paths = []
    for name, data in files.items():
        p = tmp_path / name
        if data is not None:
            p.write_bytes(data)
        paths.append(p)
    return paths


def test_bad_input_files_exit_1_with_one_line(cli, cornell, tmp_path):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    for scene in bad_inputs(cornell, tmp_path):
        out = out_dir / "x.png"
        r = run(cli, "render", scene, "-o", out, "--res", "8", "8", "--spp", "1", "--json")
        assert r.returncode == 1, (scene.name, r.stderr)
        assert one_line(r.stderr), r.stderr
        assert str(scene) in r.stderr
        assert r.stdout == ""
        assert not out.exists()


def test_unwritable_output_exits_1(cli, cornell, tmp_path):
    out = tmp_path / "no" / "such" / "dir" / "x.png"
    r = run(cli, "render", cornell, "-o", out, "--res", "8", "8", "--spp", "1")
    assert r.returncode == 1
    assert one_line(r.stderr), r.stderr
    assert str(out) in r.stderr


# --- rendering ---------------------------------------------------------------

@pytest.fixture(scope="module")
def cornell_renders(cli, cornell, tmp_path_factory):
    """The Cornell box at 64x64, 4 spp, to PNG and EXR, with --json."""
    d = tmp_path_factory.mktemp("cornell")
    results = {}
    for ext in ("png", "exr"):
        out = d / f"cornell.{ext}"
        r = run(cli, "render", cornell, "-o", out, "--res", 64, 64, "--spp", 4, "--seed", 7, "--json")
        results[ext] = (out, r)
    return results


@pytest.mark.parametrize("ext", ["png", "exr"])
def test_render_json_statistics(cornell_renders, ext):
    out, r = cornell_renders[ext]
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""  # no progress bar off a terminal, nothing dropped
    stats = json.loads(r.stdout)  # exactly one JSON document on stdout
    assert isinstance(stats, dict)
    for key in ["seconds", "spp", "settings", "rays", "mrays_per_s", "dropped",
                "nonfinite_samples", "features", "output"]:
        assert key in stats, key
    assert stats["spp"] == 4
    assert (stats["settings"]["width"], stats["settings"]["height"]) == (64, 64)
    assert stats["output"] == str(out)
    rays = stats["rays"]
    assert rays["camera"] == 64 * 64 * 4
    assert rays["total"] == sum(v for k, v in rays.items() if k != "total")
    # The generated box holds every material kind and both light kinds; the
    # glass sphere and the metal block must each spawn their own rays.
    for feature in ["emissive_meshes", "point_lights", "diffuse", "glossy", "glass"]:
        assert feature in stats["features"], stats["features"]
    assert rays["refraction"] > 0 and rays["reflection"] > 0 and rays["glossy"] > 0
    assert rays["total"] > rays["camera"]  # light transport beyond primary rays
    assert stats["seconds"] > 0 and stats["mrays_per_s"] > 0
    assert stats["nonfinite_samples"] == 0
    dropped = stats["dropped"]
    assert dropped == {"nonfinite_vertices": 0, "out_of_range_indices": 0, "degenerate_triangles": 0,
                       "bad_material_ids": 0, "skipped_meshes": []}


def test_png_output_is_readable_and_lit(cornell_renders):
    out, r = cornell_renders["png"]
    assert r.returncode == 0, r.stderr
    w, h, channels = oiio_info(out)
    assert (w, h) == (64, 64)
    assert channels == ["R", "G", "B", "A"]
    px = oiio_pixels(out)
    assert len(px) == 64 * 64
    mean = sum(sum(v[:3]) for v in px.values()) / (3 * len(px))
    assert mean > 0.1, mean  # sRGB-encoded: a lit box, not black
    assert all(v[3] == 1.0 for v in px.values())  # opaque film (no Film > Transparent): alpha 1 everywhere
    # Left wall is red and right wall green (image row 0 is the top).
    # Albedos (0.65, 0.05, 0.05) and (0.12, 0.45, 0.15): linear ratios ~13 and
    # ~3.75, about 3.3 and 1.5 after sRGB encoding and the white light's bounces.
    left = [px[(x, y)] for x in range(1, 6) for y in range(24, 40)]
    right = [px[(x, y)] for x in range(59, 64) for y in range(24, 40)]
    assert sum(p[0] for p in left) > 2 * sum(p[1] for p in left)
    assert sum(p[1] for p in right) > 1.2 * sum(p[0] for p in right)


def test_exr_output_has_all_passes(cornell_renders):
    out, r = cornell_renders["exr"]
    assert r.returncode == 0, r.stderr
    w, h, channels = oiio_info(out)
    assert (w, h) == (64, 64)
    for c in ["R", "G", "B", "A", "Z", "N.X", "N.Y", "N.Z"]:
        assert c in channels, channels
    px = oiio_pixels(out)
    index = {c: i for i, c in enumerate(channels)}
    # Pixel (40, 16) sees the back wall (z = -1, above the glass sphere) from
    # the camera at z = 3.9 looking down -Z: depth 4.9 along the view axis
    # for every back-wall pixel, and the normal faces the camera.
    centre = px[(40, 16)]
    assert centre[index["Z"]] == pytest.approx(4.9, abs=1e-3)
    assert abs(centre[index["N.Z"]]) > 0.9
    mean = sum(sum(v[index[c]] for c in "RGB") for v in px.values()) / (3 * len(px))
    assert mean > 0.02, mean
    for v in px.values():
        assert all(abs(x) < 1e11 for x in v)  # finite everywhere


def test_plain_mode_prints_summary(cli, cornell, tmp_path):
    out = tmp_path / "plain.png"
    r = run(cli, "render", cornell, "-o", out, "--res", 16, 16, "--spp", 1)
    assert r.returncode == 0, r.stderr
    assert one_line(r.stdout) and str(out) in r.stdout
    assert out.exists()


def test_dropped_input_is_one_warning_and_in_json(cli, tmp_path):
    # A quad in front of the default camera, plus one triangle with index 9 of 4.
    scene = write_gltf(tmp_path / "bad_index.gltf", [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0],
                       [0, 1, 2, 0, 2, 3, 0, 9, 3])
    out = tmp_path / "bad_index.png"
    r = run(cli, "render", scene, "-o", out, "--res", 16, 16, "--spp", 1, "--json")
    assert r.returncode == 0, r.stderr
    assert one_line(r.stderr) and "warning" in r.stderr, r.stderr
    stats = json.loads(r.stdout)
    assert stats["dropped"]["out_of_range_indices"] == 1
    # No light in the file: the uniform white world lights the quad.
    px = oiio_pixels(out)
    assert sum(v[0] for v in px.values()) / len(px) > 0.2


def test_seed_and_threads_reach_the_renderer(cli, cornell, tmp_path):
    """Same seed: the same image whatever the thread count; another seed: a different one."""
    images = {}
    for name, seed, threads in [("a", 5, 1), ("b", 5, 2), ("c", 6, 2)]:
        out = tmp_path / f"{name}.exr"
        r = run(cli, "render", cornell, "-o", out, "--res", 24, 24, "--spp", 2, "--seed", seed,
                "--threads", threads, "--json")
        assert r.returncode == 0, r.stderr
        assert json.loads(r.stdout)["settings"]["seed"] == seed
        images[name] = oiio_pixels(out)
    assert images["a"] == images["b"]
    assert images["a"] != images["c"]


def test_max_bounces_reaches_the_renderer(cli, cornell, tmp_path):
    totals = {}
    for bounces in (0, 8):
        r = run(cli, "render", cornell, "-o", tmp_path / f"b{bounces}.png", "--res", 16, 16, "--spp", 2,
                "--max-bounces", bounces, "--json")
        assert r.returncode == 0, r.stderr
        stats = json.loads(r.stdout)
        assert stats["settings"]["max_bounces"] == bounces
        totals[bounces] = stats["rays"]["total"]
    # Longer paths inside the box: more rays (same seed, same camera rays).
    assert totals[0] < totals[8]


def test_sigint_cancels_without_writing(cli, cornell, tmp_path):
    out = tmp_path / "interrupted.exr"
    proc = subprocess.Popen([cli, "render", str(cornell), "-o", str(out), "--res", "256", "256",
                             "--spp", "100000", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Wait until the process catches SIGINT (bit 1 of SigCgt in /proc), so a
    # slow start on a busy machine cannot turn this into a plain kill; then
    # let the render itself run a while.
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and proc.poll() is None:
        status = Path(f"/proc/{proc.pid}/status").read_text()
        caught = int(re.search(r"SigCgt:\s*([0-9a-f]+)", status).group(1), 16)
        if caught & (1 << (signal.SIGINT - 1)):
            break
        time.sleep(0.05)
    time.sleep(1.0)
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGINT)
    try:
        # A hang guard, not a promptness threshold: the property is that
        # SIGINT ends the render with exit 130 and no image.
        stdout, stderr = proc.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("render hung after SIGINT")
    assert proc.returncode == 130, stderr
    assert stdout == ""
    assert one_line(stderr), stderr
    assert not out.exists()


# --- stopping rules and the error estimate -----------------------------------

def test_target_error_stops_early_and_json_reports_spp_taken(cli, cornell, tmp_path):
    out = tmp_path / "target.exr"
    r = run(cli, "render", cornell, "-o", out, "--res", 24, 24, "--spp", 100000, "--target-error", "0.15",
            "--json")
    assert r.returncode == 0, r.stderr
    stats = json.loads(r.stdout)
    assert stats["settings"]["spp"] == 100000
    assert stats["settings"]["target_error"] == pytest.approx(0.15)
    # Stopped at an even pass count, well before the maximum, at or below the target.
    assert 2 <= stats["spp"] < 100000
    assert stats["spp"] % 2 == 0
    assert 0.0 < stats["error_estimate"] <= 0.15
    # spp counts samples actually taken: one camera ray per pixel per pass.
    assert stats["rays"]["camera"] == 24 * 24 * stats["spp"]
    assert out.exists()

    # Without a stopping rule every requested sample is taken; the estimate is
    # reported when asked for (Auto leaves it out for less noise).
    r = run(cli, "render", cornell, "-o", tmp_path / "full.exr", "--res", 8, 8, "--spp", 6, "--json",
            "--error-estimate", "exact")
    assert r.returncode == 0, r.stderr
    stats = json.loads(r.stdout)
    assert stats["spp"] == 6 and stats["settings"]["spp"] == 6
    assert stats["error_estimate"] > 0.0
    r = run(cli, "render", cornell, "-o", tmp_path / "auto.exr", "--res", 8, 8, "--spp", 6, "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["error_estimate"] is None
    # One pass has no odd half: no estimate yet.
    r = run(cli, "render", cornell, "-o", tmp_path / "one.exr", "--res", 8, 8, "--spp", 1, "--json")
    assert json.loads(r.stdout)["error_estimate"] is None


def test_time_limit_stops_early(cli, cornell, tmp_path):
    r = run(cli, "render", cornell, "-o", tmp_path / "t.png", "--res", 16, 16, "--spp", 1000000,
            "--time-limit", "0.5", "--json")
    assert r.returncode == 0, r.stderr
    stats = json.loads(r.stdout)
    assert 1 <= stats["spp"] < 1000000
    assert stats["settings"]["time_limit"] == pytest.approx(0.5)


@pytest.mark.parametrize("option,value", [("--target-error", "-0.1"), ("--target-error", "abc"),
                                          ("--time-limit", "-1"), ("--time-limit", "inf"),
                                          ("--time-limit", "nan"), ("--target-error", "")])
def test_stopping_rule_options_reject_bad_values(cli, cornell, tmp_path, option, value):
    out = tmp_path / "x.png"
    r = run(cli, "render", cornell, "-o", out, "--res", 8, 8, "--spp", 1, option, value)
    assert r.returncode == 2, r.stderr
    assert one_line(r.stderr) and option in r.stderr
    assert not out.exists()


# --- convergence record and plot ----------------------------------------------------------------


def read_convergence(path):
    lines = Path(path).read_text().strip("\n").split("\n")
    assert lines[0] == "seconds,spp,error_estimate"
    rows = [line.split(",") for line in lines[1:]]
    assert all(len(r) == 3 for r in rows), lines
    return [(float(t), int(n), float(e)) for t, n, e in rows]


@pytest.fixture(scope="module")
def convergence_csv(cli, cornell, tmp_path_factory):
    d = tmp_path_factory.mktemp("convergence")
    csv = d / "cornell.csv"
    r = run(cli, "render", cornell, "-o", d / "cornell.png", "--res", 48, 48, "--spp", 32, "--threads", 2,
            "--json", "--convergence", csv, "--report-interval", 0)
    assert r.returncode == 0, r.stderr
    return csv, json.loads(r.stdout)


def test_convergence_csv_has_one_row_per_pass_with_an_estimate(convergence_csv):
    csv, report = convergence_csv
    rows = read_convergence(csv)
    seconds = [t for t, _, _ in rows]
    spp = [n for _, n, _ in rows]
    errors = [e for _, _, e in rows]
    # An estimate exists from the second pass on: passes 2..32, one row each.
    assert spp == list(range(2, 33))
    assert report["spp"] == spp[-1] == 32
    assert all(b >= a for a, b in zip(seconds, seconds[1:])), seconds
    assert all(e > 0.0 for e in errors), errors
    # Noise falls with samples: 16x the samples should cut the error ~4x; ask for less than half.
    assert errors[-1] < 0.5 * errors[0], errors


def test_batches_of_passes_end_at_even_counts_and_grow_by_at_most_half(cli, cornell, tmp_path):
    # A report interval far longer than the render: only the growth rule
    # limits the batches, so the rows are the same on any machine.
    csv, out = tmp_path / "batched.csv", tmp_path / "batched.exr"
    r = run(cli, "render", cornell, "-o", out, "--res", 48, 48, "--spp", 32, "--threads", 2,
            "--convergence", csv, "--report-interval", 60)
    assert r.returncode == 0, r.stderr
    spp = [n for _, n, _ in read_convergence(csv)]
    assert spp[0] == 2 and spp[-1] == 32, spp
    assert len(spp) < 31, spp  # fewer reports than passes
    assert all(n % 2 == 0 for n in spp), spp
    assert all(a < b <= a + max(2, a // 2) for a, b in zip(spp, spp[1:])), spp
    # The batches change when reports come, never the image. (--convergence
    # implies --error-estimate exact, which draws other samples than Auto.)
    single = tmp_path / "single.exr"
    r = run(cli, "render", cornell, "-o", single, "--res", 48, 48, "--spp", 32, "--threads", 1,
            "--report-interval", 0, "--error-estimate", "exact")
    assert r.returncode == 0, r.stderr
    assert oiio_pixels(out) == oiio_pixels(single)


def test_convergence_with_target_error_ends_at_or_below_target(cli, cornell, tmp_path):
    csv = tmp_path / "c.csv"
    r = run(cli, "render", cornell, "-o", tmp_path / "c.png", "--res", 48, 48, "--spp", 4096, "--threads", 2,
            "--target-error", "0.5", "--convergence", csv)
    assert r.returncode == 0, r.stderr
    rows = read_convergence(csv)
    assert rows[-1][1] < 4096 and rows[-1][2] <= 0.5
    # The rule is checked after even pass counts: it stopped at the first one that met the target.
    assert all(e > 0.5 for _, n, e in rows[:-1] if n % 2 == 0), rows


def test_convergence_unwritable_path_fails_before_rendering(cli, cornell, tmp_path):
    out = tmp_path / "never.png"
    r = run(cli, "render", cornell, "-o", out, "--res", 16, 16, "--spp", 2,
            "--convergence", tmp_path / "missing_dir" / "c.csv")
    assert r.returncode == 1
    assert one_line(r.stderr) and "convergence" in r.stderr
    assert not out.exists()


def test_plot_writes_png(cli, convergence_csv, tmp_path):
    csv, _ = convergence_csv
    png = tmp_path / "plot.png"
    r = run(cli, "plot", csv, "-o", png)
    assert r.returncode == 0, r.stderr
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(data) > 1024
    w, h = struct.unpack(">II", data[16:24])  # IHDR
    assert w > 100 and h > 100


def test_plot_default_output_is_csv_path_with_png(cli, convergence_csv, tmp_path):
    csv, _ = convergence_csv
    copy = tmp_path / "record.csv"
    copy.write_text(Path(csv).read_text())
    r = run(cli, "plot", copy)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "record.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("content", ["", "not,a,header\n1,2,3\n", "seconds,spp,error_estimate\n",
                                     "seconds,spp,error_estimate\n0.1,2,abc\n",
                                     "seconds,spp,error_estimate\n0.1,2,-0.5\n",
                                     "seconds,spp,error_estimate\n0.1,2\n"])
def test_plot_bad_csv_is_one_line_error(cli, tmp_path, content):
    csv = tmp_path / "bad.csv"
    csv.write_text(content)
    r = run(cli, "plot", csv, "-o", tmp_path / "bad.png")
    assert r.returncode != 0
    assert one_line(r.stderr), r.stderr
    assert "error" in r.stderr
    assert not (tmp_path / "bad.png").exists()


def test_plot_missing_csv_is_one_line_error(cli, tmp_path):
    r = run(cli, "plot", tmp_path / "nope.csv")
    assert r.returncode != 0
    assert one_line(r.stderr), r.stderr
