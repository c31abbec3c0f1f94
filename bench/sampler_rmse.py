#!/usr/bin/python3
"""Fig. 2 of Sadeghi et al. 2009 ("Coherent Path Tracing") on our Cornell box.

Renders the scene with SPT, CPT and ICPT at 36, 256 and 1024 samples per pixel
(several seeds each) through the `coherent` CLI, and measures against a
high-sample SPT reference:

* RMSE of the linear Combined pass (all three colour channels), and the RMSE on
  the 0-255 scale of the clamped sRGB image (the scale of the paper's numbers);
* the correlation coefficient of per-pixel errors between horizontally
  adjacent pixels of the same 4-pixel-wide packet column pair (x, x+1 with
  x mod 4 != 3), and between diagonal neighbours: CPT's structured noise shows
  up as a high correlation, ICPT's interleaving removes it for pixels that
  share a row (a Latin-hypercube subset has one pixel per row).

Writes docs/results/sampler_rmse.{csv,png,md} and
docs/results/sampler_noise_crops.png (crops at the lowest spp, upscaled).

Run from the repository root:
    /usr/bin/python3 bench/sampler_rmse.py --cli build-samp/coherent
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import time

import numpy as np
import OpenImageIO as oiio

# (label, --sampler, --sequences). "image" variants share sequences over the
# whole image (the paper's equation 3), the default "packet" per packet (its Fig. 3).
VARIANTS = [
    ("CPT", "cpt", "packet"),
    ("ICPT", "icpt", "packet"),
    ("SPT", "spt", "packet"),
    ("CPT image", "cpt", "image"),
    ("ICPT image", "icpt", "image"),
]


def render(cli, scene, out, sampler, spp, seed, res, threads, packet, sequences="packet"):
    cmd = [cli, "render", scene, "--res", str(res), str(res), "--spp", str(spp), "--seed", str(seed),
           "--sampler", sampler, "--packet", packet, "--sequences", sequences, "--threads", str(threads), "--json",
           "-o", out]
    p = subprocess.run(cmd, check=True, capture_output=True, text=True)
    return json.loads(p.stdout.strip().splitlines()[-1]), cmd


def read_rgb(path):
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or px.size == 0:
        sys.exit(f"cannot read {path}: {oiio.geterror()}")
    return np.asarray(px, dtype=np.float64)[:, :, :3]


def srgb8(lin):
    c = np.clip(lin, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return s * 255.0


def correlation(err, dx, dy, packet_w, packet_h, within_packet=True):
    """Correlation coefficient of err(x, y) and err(x+dx, y+dy) (luminance).

    within_packet: only pairs inside one packet. Errors are winsorised at the 99th
    percentile of |err| first: the glossy Cornell box has rare fireflies
    (errors ~30x the typical one) that would otherwise decide the coefficient
    alone (tests/native/test_sampler_stats.cpp does the same)."""
    h, w = err.shape[:2]
    lum = err.mean(axis=2)
    q = np.percentile(np.abs(lum), 99)
    lum = np.clip(lum, -q, q)
    xs, ys = np.arange(w - dx), np.arange(h - dy)
    keep_x = (xs % packet_w) + dx < packet_w if within_packet else np.ones_like(xs, dtype=bool)
    keep_y = (ys % packet_h) + dy < packet_h if within_packet else np.ones_like(ys, dtype=bool)
    a = lum[: h - dy, : w - dx][keep_y][:, keep_x].ravel()
    b = lum[dy:, dx:][keep_y][:, keep_x].ravel()
    return float(np.corrcoef(a, b)[0, 1])


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cli", default="build-samp/coherent")
    ap.add_argument("--scene", default="../shared/scenes/cornell_box.glb")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--spps", type=int, nargs="+", default=[36, 256, 1024])
    ap.add_argument("--seeds", type=int, default=2, help="renders per (sampler, spp), seeds 1..N")
    ap.add_argument("--ref-spp", type=int, default=16384)
    ap.add_argument("--packet", default="4x4")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--work", default="/tmp/coherent_sampler_rmse", help="EXRs go here (the reference is reused)")
    ap.add_argument("--out", default="docs/results")
    args = ap.parse_args()

    os.makedirs(args.work, exist_ok=True)
    os.makedirs(args.out, exist_ok=True)
    packet_w, packet_h = (int(v) for v in args.packet.split("x"))

    # Renders first (they do not need the reference), metrics after.
    reports = {}
    example_cmd = None
    for label, sampler, sequences in VARIANTS:
        for spp in args.spps:
            for seed in range(1, args.seeds + 1):
                path = os.path.join(args.work, f"{sampler}_{sequences}_{spp}_{seed}.exr")
                report, cmd = render(args.cli, args.scene, path, sampler, spp, seed, args.res, args.threads,
                                     args.packet, sequences)
                example_cmd = example_cmd or cmd
                reports[(label, spp, seed)] = (path, report)
                print(f"rendered {label} {spp} spp seed {seed} in {report['seconds']:.1f} s", flush=True)

    ref_path = os.path.join(args.work, f"ref_spt_{args.res}_{args.ref_spp}.exr")
    ref_seconds = None
    ref_cmd = [args.cli, "render", args.scene, "--res", str(args.res), str(args.res), "--spp", str(args.ref_spp),
               "--seed", "1000", "--sampler", "spt", "--threads", str(args.threads), "--json", "-o", ref_path]
    # Another run (or a render started by hand with ref_cmd) may be producing
    # the reference: it marks that with REF.inprogress.
    while os.path.exists(ref_path + ".inprogress"):
        time.sleep(5)
    if not os.path.exists(ref_path):
        print(f"reference: SPT {args.ref_spp} spp ...", flush=True)
        report, ref_cmd = render(args.cli, args.scene, ref_path, "spt", args.ref_spp, 1000, args.res, args.threads,
                                 args.packet)
        with open(ref_path + ".json", "w") as f:
            json.dump(report, f)
    if os.path.exists(ref_path + ".json"):
        with open(ref_path + ".json") as f:
            ref_seconds = json.load(f)["seconds"]
    ref = read_rgb(ref_path)
    ref8 = srgb8(ref)

    rows = []
    images = {}
    for (sampler, spp, seed), (path, report) in reports.items():  # sampler: the variant's label
        img = read_rgb(path)
        err = img - ref
        rows.append({
            "sampler": sampler, "spp": spp, "seed": seed,
            "rmse": float(np.sqrt(np.mean(err ** 2))),
            "rmse_srgb8": float(np.sqrt(np.mean((srgb8(img) - ref8) ** 2))),
            "corr_right": correlation(err, 1, 0, packet_w, packet_h),
            "corr_diag": correlation(err, 1, 1, packet_w, packet_h),
            "corr_right_all": correlation(err, 1, 0, packet_w, packet_h, within_packet=False),
            "seconds": report["seconds"],
            "mrays_per_s": report["mrays_per_s"],
        })
        images[(sampler, spp, seed)] = img
        r = rows[-1]
        print(f"{sampler:10s} {spp:5d} spp seed {seed}: rmse {r['rmse']:.5f}  srgb8 {r['rmse_srgb8']:.3f}  "
              f"corr(+1,0) {r['corr_right']:+.3f}  corr(+1,+1) {r['corr_diag']:+.3f}  {r['seconds']:.1f} s",
              flush=True)

    csv_path = os.path.join(args.out, "sampler_rmse.csv")
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)

    def mean_of(sampler, spp, key):
        return float(np.mean([r[key] for r in rows if r["sampler"] == sampler and r["spp"] == spp]))

    # Plot: RMSE against spp, log-log, with the 1/sqrt(N) slope for reference.
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for (label, _, sequences), marker in zip(VARIANTS, "os^Dv"):
        style = "--" if sequences == "image" else "-"
        axes[0].loglog(args.spps, [mean_of(label, n, "rmse") for n in args.spps], style, marker=marker, label=label)
        axes[1].semilogx(args.spps, [mean_of(label, n, "corr_right_all") for n in args.spps], style, marker=marker,
                         label=label)
    n0 = args.spps[0]
    r0 = mean_of("SPT", n0, "rmse")
    axes[0].loglog(args.spps, [r0 * np.sqrt(n0 / n) for n in args.spps], "k:", label="1/sqrt(N)")
    axes[0].set_xlabel("samples per pixel")
    axes[0].set_ylabel("RMSE (linear) vs SPT reference")
    axes[0].set_title(f"Cornell box {args.res}x{args.res}, ref {args.ref_spp} spp")
    axes[0].legend()
    axes[1].set_xlabel("samples per pixel")
    axes[1].set_ylabel("corr. of errors, horizontal neighbours")
    axes[1].set_title("structured noise (all horizontal pairs)")
    axes[1].axhline(0.0, color="k", lw=0.5)
    axes[1].legend()
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "sampler_rmse.png"), dpi=120)

    # Crops at the lowest spp: the whole image and a 4x zoom of the centre, per sampler.
    spp_lo = args.spps[0]
    tiles = []
    for label, _, _ in VARIANTS:
        img = srgb8(images[(label, spp_lo, 1)]) / 255.0
        c = args.res // 2  # centre crop of half the side, shown 4x: as wide as the 2x full image
        crop = img[args.res // 2 - c // 2: args.res // 2 + c // 2, args.res // 2 - c // 2: args.res // 2 + c // 2]
        zoom = np.repeat(np.repeat(crop, 4, axis=0), 4, axis=1)
        full = np.repeat(np.repeat(img, 2, axis=0), 2, axis=1)
        col = np.concatenate([full, np.ones((4, full.shape[1], 3)), zoom[: full.shape[0], : full.shape[1]]], axis=0)
        tiles.append(col)
        tiles.append(np.ones((col.shape[0], 4, 3)))
    strip = np.concatenate(tiles[:-1], axis=1)
    fig = plt.figure(figsize=(strip.shape[1] / 100, strip.shape[0] / 100 + 0.4), dpi=100)
    ax = fig.add_axes([0, 0, 1, strip.shape[0] / (strip.shape[0] + 40)])
    ax.imshow(np.clip(strip, 0, 1), interpolation="nearest")
    ax.axis("off")
    w_col = strip.shape[1] / len(VARIANTS)
    for i, (label, _, _) in enumerate(VARIANTS):
        fig.text((i + 0.5) * w_col / strip.shape[1], 0.985, f"{label} {spp_lo} spp",
                 ha="center", va="top", fontsize=9)
    fig.savefig(os.path.join(args.out, "sampler_noise_crops.png"))

    # Markdown summary.
    md = [
        "# Sampler RMSE: SPT vs CPT vs ICPT (Sadeghi et al. 2009, Fig. 2)",
        "",
        f"Date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}. Scene `{args.scene}`, {args.res}x{args.res}, "
        f"packets {args.packet}, {args.threads} threads on a shared 2-core VM (times are indicative only).",
        f"Reference: SPT, {args.ref_spp} spp, seed 1000"
        + (f" ({ref_seconds:.0f} s)." if ref_seconds else "."),
        f"Each row averages {args.seeds} renders (seeds 1..{args.seeds}); per-render values are in `sampler_rmse.csv`.",
        "CPT and ICPT share sequences per packet (`--sequences packet`, the default: one sequence per 4x4 packet "
        "for CPT, four per 8x8 region for ICPT, as in the paper's Fig. 3) or over the whole image "
        "(`--sequences image`, \"image\" rows: the paper's equation 3).",
        "",
        "Command:",
        "",
        "```",
        "/usr/bin/python3 bench/sampler_rmse.py " + " ".join(a for a in sys.argv[1:]),
        "# each render, e.g.:",
        " ".join(example_cmd),
        "# reference:",
        " ".join(ref_cmd),
        "```",
        "",
        "RMSE: linear Combined pass, all channels, against the reference (includes the reference's own noise, "
        f"~1/sqrt({args.ref_spp // args.spps[-1]}) of the {args.spps[-1]}-spp error). RMSE sRGB8: clamped sRGB "
        "on the 0-255 scale, the scale of the paper's numbers. corr(+1,0) / corr(+1,+1): correlation coefficient "
        "of per-pixel errors (luminance of render - reference, winsorised at the 99th percentile of |error| so "
        "that rare fireflies do not decide it alone) between a pixel and its right / lower-right neighbour in the "
        "same packet; \"all pairs\" also counts neighbours across packet boundaries.",
        "",
        "| sampler | spp | RMSE | RMSE sRGB8 | corr(+1,0) | corr(+1,+1) | corr(+1,0) all pairs | seconds |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for sampler, _, _ in VARIANTS:
        for spp in args.spps:
            md.append(f"| {sampler} | {spp} | {mean_of(sampler, spp, 'rmse'):.5f} | "
                      f"{mean_of(sampler, spp, 'rmse_srgb8'):.3f} | {mean_of(sampler, spp, 'corr_right'):+.3f} | "
                      f"{mean_of(sampler, spp, 'corr_diag'):+.3f} | {mean_of(sampler, spp, 'corr_right_all'):+.3f} | "
                      f"{mean_of(sampler, spp, 'seconds'):.1f} |")
    md += ["", "Paper (their Cornell box, 16K-spp reference, 0-255 scale): CPT 17.92 / 5.64 / 2.42, "
           "ICPT 13.61 / 5.40 / 2.04, SPT 15.49 / 6.66 / 1.89 at 36 / 256 / 1K spp.", "",
           "![RMSE and error correlation](sampler_rmse.png)", "",
           f"Noise at {spp_lo} spp, seed 1 (top: whole image at 2x; bottom: centre half at 4x, nearest "
           "neighbour; clamped sRGB):", "",
           f"![Noise at {spp_lo} spp](sampler_noise_crops.png)", ""]
    with open(os.path.join(args.out, "sampler_rmse.md"), "w") as f:
        f.write("\n".join(md))
    print(f"wrote {csv_path}, sampler_rmse.png, sampler_rmse.md, sampler_noise_crops.png")


if __name__ == "__main__":
    main()
