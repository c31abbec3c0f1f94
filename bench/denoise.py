#!/usr/bin/env python3
"""The native denoiser against more samples: relative RMSE of noisy 16/64/256
spp and denoised 16/64 spp renders against a two-seed reference, on the
repository's scenes (the generated glTF Cornell box through the CLI, the
blend_scenes/*.blend through Blender) and on ../shared/scenes/*.glb when
present; crops as a PNG; and the denoiser's time as a fraction of a 64-spp
render at 512 x 512.

    /usr/bin/python3 bench/denoise.py [--res 64] [--ref-spp 2048] [--out docs/results]
        [--cache /tmp/denoise_bench_cache] [--only LABEL] [--skip-blender] [--skip-timing]
        [--sampler spt|cpt|icpt] [--uniform]

The reference is two renders of --ref-spp samples with other seeds; a quarter
of their squared difference estimates the reference's variance and is
subtracted from every mean squared error (so a noisy reference does not
flatter or penalise anyone). The references and the noisy 256-spp renders
do not depend on the denoiser and are kept in --cache for later runs.
Because heavy-tailed (firefly) noise makes the RMSE unstable, the median
absolute error (over pixels where the reference is not black) is reported
next to it, and the RMSE over an edge mask of the reference separately.
Writes denoise.csv, denoise_crops.png and prints the markdown tables.

--sampler sets the sampler of the noisy and denoised renders (default: each
front end's own, SPT in the CLI and Auto = CPT for Blender's final renders);
the references do not depend on it (every sampler is unbiased), so they are
shared, while the noisy 256-spp render is cached per sampler.

Denoised renders distribute their samples (Distribute Samples, on by
default); --uniform turns that off, to compare. The noisy 16, 64 and 256
spp columns are always plain (undenoised, uniform) renders with the sampler
the front end picks for them (Blender's Auto: CPT) unless --sampler says.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared" / "scenes"
CLI = REPO / "build" / "coherent"
NAMES = ["noisy16", "noisy64", "noisy256", "denoised16", "denoised64"]


def read_channels(path, keys):
    """The named channels of an EXR (height x width x len(keys), float64);
    `keys` may be a function of the file's channel names."""
    inp = oiio.ImageInput.open(str(path))
    spec = inp.spec()
    px = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, "float")).reshape(spec.height, spec.width, -1)
    inp.close()
    names = list(spec.channelnames)
    keys = keys(names) if callable(keys) else keys
    return px[:, :, [names.index(k) for k in keys]].astype(np.float64)


def read_rgb(path, pass_name="Combined"):
    # The CLI writes R, G, B; Blender's multilayer EXR ViewLayer.<pass>.R, ...
    return read_channels(path, lambda names: list("RGB") if "R" in names
                         else [f"ViewLayer.{pass_name}.{c}" for c in "RGB"])


def cli_render(scene, out, res, spp, seed, denoise=False, extra=()):
    args = [str(CLI), "render", str(scene), "-o", str(out), "--res", str(res), str(res), "--spp", str(spp),
            "--seed", str(seed), "--json", *extra] + (["--denoise"] if denoise else [])
    return json.loads(subprocess.run(args, capture_output=True, text=True, check=True).stdout)


def cached_names(res, ref_spp, sampler):
    """Cache file per cached render: the references are shared by all samplers."""
    n256 = f"n256_{res}_256" + (f"_{sampler}" if sampler else "")
    return {"refa": (f"refa_{res}_{ref_spp}", ref_spp, 101), "refb": (f"refb_{res}_{ref_spp}", ref_spp, 202),
            "n256": (n256, 256, 7)}


def glb_cached(scene, cache, res, ref_spp, sampler=""):
    """The references (refa, refb) and the noisy 256-spp render (n256) of a
    glTF scene: they do not depend on the denoiser, so they are kept in
    `cache` and reused by later runs (rendered into it when missing)."""
    img = {}
    extra = ("--sampler", sampler) if sampler else ()
    for key, (name, spp, seed) in cached_names(res, ref_spp, sampler).items():
        path = cache / f"{name}.exr"
        if not path.exists():
            cli_render(scene, path, res, spp, seed, extra=extra if key == "n256" else ())
        img[key] = read_rgb(path)
    return img


def glb_images(scene, tmp, res, ref_spp, cache, sampler="", uniform=False):
    img = glb_cached(scene, cache, res, ref_spp, sampler)
    img["noisy256"] = img.pop("n256")
    extra = ("--sampler", sampler) if sampler else ()
    for spp in (16, 64):
        cli_render(scene, tmp / f"n{spp}.exr", res, spp, 7, extra=extra)
        img[f"noisy{spp}"] = read_rgb(tmp / f"n{spp}.exr")
    for spp in (16, 64):
        cli_render(scene, tmp / f"d{spp}.exr", res, spp, 7, denoise=True,
                   extra=extra + (("--distribute-samples=false",) if uniform else ()))
        img[f"denoised{spp}"] = read_rgb(tmp / f"d{spp}.exr")
    return img


def blend_images(scene, tmp, res, ref_spp, cache, sampler="", uniform=False):
    """Renders through Blender (tests/blender/denoise_renders.py) at the
    resolution percentage that gives about `res` pixels across; the
    references and noisy 256 spp are cached as in glb_images."""
    percent = max(1, round(100 * res / 512))
    names = cached_names(res, ref_spp, sampler)
    cached = {k: cache / f"{name}.exr" for k, (name, _, _) in names.items()}
    # The references keep the scene's sampler (any is unbiased); the others take `sampler`.
    specs = [f"{k}:{spp}:{seed}:0" + (f":1:{sampler}" if sampler and k == "n256" else "")
             for k, (_, spp, seed) in names.items() if not cached[k].exists()]
    specs += [f"d{spp}:{spp}:7:1:1:{sampler}:{0 if uniform else 1}" for spp in (16, 64)]
    specs += [f"n{spp}:{spp}:7:0:1:{sampler}" for spp in (16, 64)]
    users = tmp / "user_scripts"
    (users / "addons").mkdir(parents=True, exist_ok=True)
    link = users / "addons" / "coherent"
    if not link.exists():
        link.symlink_to(REPO / "addon" / "coherent")
    env = dict(os.environ, BLENDER_USER_SCRIPTS=str(users))
    subprocess.run(["blender", "-b", "--factory-startup", "--addons", "coherent", str(scene), "--python",
                    str(REPO / "tests" / "blender" / "denoise_renders.py"), "--", str(tmp), str(percent), *specs],
                   check=True, capture_output=True, env=env)
    for k, path in cached.items():
        if not path.exists():
            (tmp / f"{k}.exr").replace(path)
    img = {k: read_rgb(cached[k]) for k in ("refa", "refb")}
    img["noisy256"] = read_rgb(cached["n256"])
    for spp in (16, 64):
        img[f"noisy{spp}"] = read_rgb(tmp / f"n{spp}.exr")
        img[f"denoised{spp}"] = read_rgb(tmp / f"d{spp}.exr")
    return img


def edge_mask(ref):
    """Pixels on a sharp edge of the reference (a texture, a shadow, an
    object's outline): the luminance differs from a 4-neighbour's by more
    than half of the larger of the two (and more than 2 % of the image
    mean, so that noise in black regions is not an edge)."""
    lum = ref.mean(axis=2)
    floor = 0.02 * lum.mean()
    mask = np.zeros(lum.shape, bool)
    for axis in (0, 1):
        a, b = (lum[1:], lum[:-1]) if axis == 0 else (lum[:, 1:], lum[:, :-1])
        edge = np.abs(a - b) > np.maximum(0.5 * np.maximum(a, b), floor)
        if axis == 0:
            mask[1:] |= edge
            mask[:-1] |= edge
        else:
            mask[:, 1:] |= edge
            mask[:, :-1] |= edge
    return mask


def errors(img):
    ref = (img["refa"] + img["refb"]) / 2
    ref_var = (img["refa"] - img["refb"]) ** 2 / 4
    mean = ref.mean()
    lit = ref.mean(axis=2) > 0  # the median over black background would be 0
    edges = edge_mask(ref)
    row = {"reference_self_rmse": float(np.sqrt(ref_var.mean()) / mean), "edge_fraction": float(edges.mean())}
    for n in NAMES:
        se = (img[n] - ref) ** 2 - ref_var
        row[f"{n}_rmse"] = float(np.sqrt(max(float(se.mean()), 0.0)) / mean)
        row[f"{n}_edge_rmse"] = float(np.sqrt(max(float(se[edges].mean()), 0.0)) / mean) if edges.any() else 0.0
        row[f"{n}_median"] = float(np.median(np.abs(img[n] - ref)[lit]) / mean)
    return row, ref


def timing(scene, tmp, res=512, spp=64):
    """Denoiser seconds over the rest of one render's seconds, same process."""
    stats = cli_render(scene, tmp / "timing.exr", res, spp, 7, denoise=True)
    denoise = stats["denoised"]["seconds"]
    return denoise, stats["seconds"] - denoise


def crops(all_images, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cols = ["noisy16", "denoised16", "noisy64", "denoised64", "noisy256", "ref"]
    fig, axes = plt.subplots(len(all_images), len(cols), figsize=(2.2 * len(cols), 2.3 * len(all_images)),
                             squeeze=False)
    for r, (scene, (img, ref)) in enumerate(all_images.items()):
        h, w = ref.shape[:2]
        y0, x0 = h // 4, w // 4
        scale = 1.0 / max(np.quantile(ref.mean(axis=2), 0.95), 1e-6)
        for c, name in enumerate(cols):
            im = ref if name == "ref" else img[name]
            crop = np.clip(im[y0:y0 + h // 2, x0:x0 + w // 2] * scale, 0, 1) ** (1 / 2.2)
            axes[r][c].imshow(crop, interpolation="nearest")
            axes[r][c].set_xticks([]), axes[r][c].set_yticks([])
            if r == 0:
                axes[r][c].set_title(name, fontsize=9)
        axes[r][0].set_ylabel(scene, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--out", default=str(REPO / "docs" / "results"))
    ap.add_argument("--skip-blender", action="store_true")
    ap.add_argument("--skip-timing", action="store_true")
    ap.add_argument("--only", default="", help="only scenes whose label contains this")
    ap.add_argument("--cache", default="/tmp/denoise_bench_cache", help="references and noisy 256 spp, reused")
    ap.add_argument("--sampler", default="", help="sampler of the noisy and denoised renders (default: the front end's)")
    ap.add_argument("--uniform", action="store_true", help="denoised renders without Distribute Samples")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)  # before the renders: a missing folder must not lose them
    work = Path(tempfile.mkdtemp(prefix="denoise_bench_"))
    subprocess.run([sys.executable, str(REPO / "tests" / "fixtures" / "make_gltf.py"), str(work)], check=True)
    scenes = [("fixture cornell_box.glb (CLI)", work / "cornell_box.glb", glb_images)]
    if not args.skip_blender:
        scenes += [(f"{p.name} (Blender)", p, blend_images) for p in sorted((REPO / "blend_scenes").glob("*.blend"))]
    if SHARED.is_dir():
        scenes += [(f"shared {p.name} (CLI)", p, glb_images) for p in sorted(SHARED.glob("*.glb"))]
    else:
        print(f"note: {SHARED} absent; public scenes skipped")
    rows, images = [], {}
    for label, path, render in scenes:
        if args.only not in label:
            continue
        key = label.split(" (")[0].replace(" ", "_").replace(".", "_")
        tmp, cache = work / key, Path(args.cache) / key
        tmp.mkdir(parents=True, exist_ok=True)
        cache.mkdir(parents=True, exist_ok=True)
        img = render(path, tmp, args.res, args.ref_spp, cache, args.sampler, args.uniform)
        row, ref = errors(img)
        rows.append({"scene": label, **row})
        images[label.split(" (")[0]] = (img, ref)
        print(label, {k: round(v, 4) for k, v in row.items()}, flush=True)
    with open(out / "denoise.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        writer.writeheader()
        writer.writerows(rows)
    crops(images, out / "denoise_crops.png")
    print("\n| scene | ref self | noisy 16 | noisy 64 | noisy 256 | denoised 16 | denoised 64 | target |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        cells = " | ".join(f"{r[f'{n}_rmse']:.4f} ({r[f'{n}_median']:.4f})" for n in NAMES)
        met = "met" if r["denoised16_rmse"] < r["noisy256_rmse"] else "not met"
        print(f"| {r['scene']} | {r['reference_self_rmse']:.4f} | {cells} | {met} |")
    print("\nEdge pixels only (relative RMSE over the edge mask, normalised by the whole image's mean):")
    print("\n| scene | edge pixels | noisy 16 | noisy 64 | noisy 256 | denoised 16 | denoised 64 |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        cells = " | ".join(f"{r[f'{n}_edge_rmse']:.4f}" for n in NAMES)
        print(f"| {r['scene']} | {100 * r['edge_fraction']:.1f} % | {cells} |")
    if args.skip_timing:
        return
    for label, path in [("fixture cornell_box.glb", work / "cornell_box.glb")] + (
            [("shared crytek_sponza.glb", SHARED / "crytek_sponza.glb")] if (SHARED / "crytek_sponza.glb").exists()
            else []):
        d, render = timing(path, work)
        print(f"\ntiming {label} 512x512 64 spp: render {render:.2f} s, denoise {d:.2f} s = {100 * d / render:.1f} %")


if __name__ == "__main__":
    main()
