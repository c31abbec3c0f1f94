#!/usr/bin/python3
"""Plots a `coherent render --convergence` record: estimated relative RMSE
against render time, log-log, with a dashed 1/sqrt(t) reference line through
the last point (Monte Carlo error falls as 1/sqrt(samples), and samples grow
linearly with time, so a healthy render runs parallel to it).

usage: coherent_plot.py CONVERGENCE.csv [-o OUT.png]
Run by `coherent plot`. Exit status: 0 written, 1 bad input or missing
matplotlib, 2 bad usage. Errors are one line on stderr.
"""
import argparse
import csv
import math
import os
import sys

HEADER = ["seconds", "spp", "error_estimate"]


class BadInput(Exception):
    pass


def fail(message, status=1):
    print(f"coherent plot: error: {message}", file=sys.stderr)
    sys.exit(status)


def read_record(path):
    """Returns (seconds, spp, errors); raises BadInput for anything unplottable."""
    try:
        with open(path, newline="") as f:
            rows = list(csv.reader(f))
    except OSError as e:
        raise BadInput(f"cannot read '{path}': {e.strerror}")
    except (UnicodeDecodeError, csv.Error) as e:
        raise BadInput(f"'{path}' is not a CSV file ({e})")
    if not rows or [c.strip() for c in rows[0]] != HEADER:
        raise BadInput(f"'{path}' does not start with the header {','.join(HEADER)}")
    seconds, spp, errors = [], [], []
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        if len(row) != 3:
            raise BadInput(f"'{path}' line {line}: expected 3 columns, got {len(row)}")
        try:
            t, n, e = float(row[0]), int(row[1]), float(row[2])
        except ValueError:
            raise BadInput(f"'{path}' line {line}: not numbers: {','.join(row)}")
        # Log axes need positive finite values.
        if not (math.isfinite(t) and t > 0 and math.isfinite(e) and e > 0 and n > 0):
            raise BadInput(f"'{path}' line {line}: seconds, spp and error must be positive and finite")
        seconds.append(t)
        spp.append(n)
        errors.append(e)
    if not seconds:
        raise BadInput(f"'{path}' has no rows (an estimate needs at least 2 sample passes)")
    return seconds, spp, errors


def plot(path, seconds, spp, errors, output):
    try:
        import matplotlib
        matplotlib.use("Agg")  # no display needed
        import matplotlib.pyplot as plt
    except ImportError:
        fail("matplotlib is not installed for " + sys.executable + " (e.g. apt install python3-matplotlib)")

    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    ax.plot(seconds, errors, "o-", markersize=3, linewidth=1.2, label="estimated error")
    # 1/sqrt(t) through the last point: e(t) = e_last * sqrt(t_last / t).
    t0, t1 = min(seconds), max(seconds)
    if t1 > t0:
        ts = [t0 * (t1 / t0) ** (k / 50) for k in range(51)]
    else:
        ts = [t0 / 2, t0 * 2]
    ax.plot(ts, [errors[-1] * math.sqrt(t1 / t) for t in ts], "--", color="gray", linewidth=1,
            label=r"$1/\sqrt{t}$ through last point")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("render time (s)")
    ax.set_ylabel("estimated relative RMSE")
    ax.set_title(f"{os.path.basename(path)}: {spp[-1]} spp, {100 * errors[-1]:.2f} % at {t1:.2f} s")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    try:
        fig.savefig(output)
    except (OSError, ValueError) as e:
        fail(f"cannot write '{output}': {e}")
    plt.close(fig)


def main(argv):
    parser = argparse.ArgumentParser(prog="coherent plot", description="Plot a coherent --convergence record.")
    parser.add_argument("csv", help="convergence record written by coherent render --convergence")
    parser.add_argument("-o", "--output", help="output image (default: the CSV path with .png)")
    args = parser.parse_args(argv)
    output = args.output or os.path.splitext(args.csv)[0] + ".png"
    try:
        seconds, spp, errors = read_record(args.csv)
    except BadInput as e:
        fail(str(e))
    plot(args.csv, seconds, spp, errors, output)
    print(f"coherent plot: wrote {output}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
