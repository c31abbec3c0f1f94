#!/usr/bin/env python3
"""Bit-exact fingerprints of rendered images over every integrator, sampler,
traversal, assembly, BVH width and reorder mode, for refactors that must not
change a single pixel.

    /usr/bin/python3 tools/image_fingerprints.py --cli build/coherent --out before.json
    ... change the code, rebuild ...
    /usr/bin/python3 tools/image_fingerprints.py --cli build/coherent --compare before.json

Renders the repository's own glTF Cornell box (tests/fixtures/make_gltf.py:
diffuse, glossy metal, glass, emissive quad and a point light) with the CLI
and hashes the float pixels of every EXR channel (Combined, Depth, Normal)
as OpenImageIO reads them. --compare exits 1 and lists every configuration
whose pixels differ.
"""
import argparse
import hashlib
import itertools
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import OpenImageIO as oiio

REPO = Path(__file__).resolve().parents[1]


def configurations():
    """(name, CLI arguments): the product of the modes that must agree bit for bit."""
    base = ["--res", "40", "32", "--spp", "4", "--seed", "11", "--max-bounces", "6"]
    for integrator, sampler, traversal in itertools.product(
            ["pt", "drt", "wrt", "rcs", "ao"], ["spt", "cpt", "icpt"], ["single", "packet", "stream", "wavefront"]):
        yield (f"{integrator}-{sampler}-{traversal}",
               base + ["--integrator", integrator, "--sampler", sampler, "--traversal", traversal])
    for reorder in ["none", "static1d", "static3d", "hash32", "hash192", "csd32"]:
        yield (f"pt-spt-wavefront-{reorder}",
               base + ["--traversal", "wavefront", "--reorder", reorder, "--wave-size", "500"])
    for width in ["2", "4", "8"]:
        yield f"pt-spt-single-w{width}", base + ["--traversal", "single", "--bvh-width", width]
        yield f"pt-spt-stream-w{width}", base + ["--traversal", "stream", "--bvh-width", width]
    for assembly, packet in itertools.product(["types", "runs"], ["2x2", "4x4", "8x8"]):
        yield (f"pt-cpt-packet-{assembly}-{packet}",
               base + ["--sampler", "cpt", "--traversal", "packet", "--assembly", assembly, "--packet", packet])
    yield "pt-spt-adaptive", base + ["--spp", "12", "--adaptive", "--adaptive-min-samples", "4",
                                     "--adaptive-threshold", "0.2"]
    yield "pt-auto-auto-heatmaps", base + ["--sampler", "auto", "--heatmaps"]
    yield "pt-spt-all-features", base + ["--all-features"]


def pixel_hash(path):
    image = oiio.ImageInput.open(str(path))
    if image is None:
        raise RuntimeError(f"cannot read {path}: {oiio.geterror()}")
    pixels = image.read_image("float")
    image.close()
    return hashlib.sha256(pixels.tobytes()).hexdigest()


def fingerprints(cli, scene):
    result = {}
    with tempfile.TemporaryDirectory() as tmp:
        configs = list(configurations())
        for i, (name, args) in enumerate(configs):
            out = Path(tmp) / f"{name}.exr"
            r = subprocess.run([cli, "render", str(scene), "-o", str(out), *args], capture_output=True, text=True)
            if r.returncode != 0:
                raise RuntimeError(f"{name}: coherent exited {r.returncode}: {r.stderr.strip()}")
            result[name] = pixel_hash(out)
            print(f"\r[{i + 1}/{len(configs)}] {name:40s}", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", default=str(REPO / "build" / "coherent"))
    ap.add_argument("--scene", help="glTF scene (default: the generated Cornell box)")
    group = ap.add_mutually_exclusive_group(required=True)
    group.add_argument("--out", help="write the fingerprints to this JSON file")
    group.add_argument("--compare", help="compare against fingerprints written by --out")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        scene = args.scene
        if scene is None:
            subprocess.run([sys.executable, str(REPO / "tests" / "fixtures" / "make_gltf.py"), tmp], check=True,
                           capture_output=True)
            scene = Path(tmp) / "cornell_box.glb"
        now = fingerprints(args.cli, scene)

    if args.out:
        Path(args.out).write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"{len(now)} fingerprints written to {args.out}")
        return 0
    before = json.loads(Path(args.compare).read_text())
    changed = sorted(k for k in before if now.get(k) != before[k])
    missing = sorted(set(before) - set(now))
    for k in changed:
        print(f"changed: {k}")
    print(f"{len(before) - len(changed)} of {len(before)} configurations bit-identical"
          + (f"; {len(missing)} not rendered" if missing else ""))
    return 1 if changed else 0


if __name__ == "__main__":
    sys.exit(main())
