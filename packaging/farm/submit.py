#!/usr/bin/env python3
"""Submits COHERENT renders to a Slurm cluster.

    submit.py frames SHOT.blend --start 1 --end 240 --chunk 10 --output /shared/out/shot_####
    submit.py still  SHOT.blend --frame 1 --grid 4x2 --output /shared/out/still.exr

frames: a job array, one task per CHUNK frames, each task running
    blender -b SHOT.blend -E COHERENT -s FIRST -e LAST -a
still: a job array, one task per border tile of one frame (tile.sbatch), and
a job that depends on it (afterok) and stitches the tiles into one multilayer
EXR equal to the single-process render (stitch.sbatch).

Every task first installs the add-on zip into a per-node user scripts folder
(coherent_node.sh). The blend file, the zip, this folder and the output must
be on storage that every node sees under the same path. Prints the job ids,
one per line (frames: 1, still: tiles then stitch).
"""

import argparse
import math
import os
import shlex
import subprocess
import sys
from pathlib import Path

FARM_DIR = Path(__file__).resolve().parent
REPO_ROOT = FARM_DIR.parents[1]
sys.path.insert(0, str(FARM_DIR))
from tiles import parse_grid  # noqa: E402


class SubmitError(Exception):
    pass


def addon_zip(path):
    """The given zip, or a freshly built one (packaging/build_zip.py)."""
    if path is not None:
        if not path.is_file():
            raise SubmitError(f"the add-on zip {path} does not exist")
        return path.resolve()
    built = subprocess.run([sys.executable, str(REPO_ROOT / "packaging" / "build_zip.py")],
                           capture_output=True, text=True)
    if built.returncode != 0:
        raise SubmitError(f"building the add-on zip failed: {built.stderr.strip()}")
    return Path(built.stdout.strip().splitlines()[-1])


def sbatch_command(args, zip_path, job_script, script_args, array=None, dependency=None, log_name="%x_%j"):
    log_dir = args.log_dir.resolve()
    env = f"ALL,COHERENT_FARM_DIR={FARM_DIR},COHERENT_ADDON_ZIP={zip_path}"
    if args.blender:
        env += f",COHERENT_BLENDER={args.blender}"
    cmd = [args.sbatch, "--parsable", f"--export={env}", f"--output={log_dir}/{log_name}.log"]
    if args.partition:
        cmd.append(f"--partition={args.partition}")
    if args.cpus:
        cmd.append(f"--cpus-per-task={args.cpus}")
    if array is not None:
        cmd.append(f"--array={array}")
    if dependency is not None:
        # A failed tile fails the stitch at once instead of leaving it pending forever.
        cmd += [f"--dependency=afterok:{dependency}", "--kill-on-invalid-dep=yes"]
    cmd += args.sbatch_arg
    return cmd + [str(FARM_DIR / job_script)] + [str(a) for a in script_args]


def run_sbatch(cmd, dry_run):
    if dry_run:
        print(shlex.join(cmd))
        return "<job id>"
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SubmitError(f"sbatch failed ({done.returncode}): {done.stderr.strip()}")
    return done.stdout.strip().split(";")[0]  # --parsable: "jobid[;cluster]"


def submit_frames(args, zip_path):
    if args.end < args.start:
        raise SubmitError(f"--end {args.end} is before --start {args.start}")
    if args.chunk < 1:
        raise SubmitError("--chunk must be at least 1")
    chunks = math.ceil((args.end - args.start + 1) / args.chunk)
    array = f"0-{chunks - 1}" + (f"%{args.max_parallel}" if args.max_parallel else "")
    script_args = [args.blend, args.start, args.end, args.chunk] + ([args.output] if args.output else [])
    cmd = sbatch_command(args, zip_path, "frames.sbatch", script_args, array=array, log_name="%x_%A_%a")
    return [run_sbatch(cmd, args.dry_run)]


def submit_still(args, zip_path):
    cols, rows = args.grid
    output = Path(args.output).resolve()
    tile_dir = Path(args.tile_dir).resolve() if args.tile_dir else output.with_name(output.stem + "_tiles")
    array = f"0-{cols * rows - 1}" + (f"%{args.max_parallel}" if args.max_parallel else "")
    tiles = sbatch_command(args, zip_path, "tile.sbatch", [args.blend, args.frame, cols, rows, tile_dir],
                           array=array, log_name="%x_%A_%a")
    tiles_id = run_sbatch(tiles, args.dry_run)
    stitch = sbatch_command(args, zip_path, "stitch.sbatch", [cols, rows, tile_dir, args.frame, output],
                            dependency=tiles_id)
    return [tiles_id, run_sbatch(stitch, args.dry_run)]


def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], epilog=__doc__.split("\n", 2)[2],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("blend", type=lambda p: str(Path(p).resolve()), help="the .blend file (shared storage)")
    common.add_argument("--addon-zip", type=Path, help="add-on zip (default: build one with packaging/build_zip.py)")
    common.add_argument("--log-dir", type=Path, default=Path("coherent-farm-logs"),
                        help="Slurm logs, one per task (default: ./%(default)s)")
    common.add_argument("--partition", help="Slurm partition (default: the cluster's default)")
    common.add_argument("--cpus", type=int, help="CPUs per task (Blender renders with that many threads)")
    common.add_argument("--max-parallel", type=int, help="at most this many array tasks at once")
    common.add_argument("--blender", help="Blender executable on the nodes (default: blender)")
    common.add_argument("--sbatch", default="sbatch", help="sbatch executable (default: %(default)s)")
    common.add_argument("--sbatch-arg", action="append", default=[], help="extra sbatch argument (repeatable)")
    common.add_argument("--dry-run", action="store_true",
                        help="print the sbatch commands instead of the job ids, submit nothing")
    sub = parser.add_subparsers(dest="mode", required=True)
    frames = sub.add_parser("frames", parents=[common], help="a frame range, CHUNK frames per array task")
    frames.add_argument("--start", type=int, required=True)
    frames.add_argument("--end", type=int, required=True)
    frames.add_argument("--chunk", type=int, default=1, help="frames per array task (default: %(default)s)")
    frames.add_argument("--output", help="Blender -o pattern, e.g. /shared/out/shot_#### (default: the file's)")
    still = sub.add_parser("still", parents=[common], help="one frame split into border tiles, then stitched")
    still.add_argument("--frame", type=int, default=1)
    still.add_argument("--grid", type=parse_grid, required=True, help="COLSxROWS tiles, e.g. 4x2")
    still.add_argument("--output", required=True, help="the stitched multilayer EXR")
    still.add_argument("--tile-dir", help="where the tiles go (default: next to --output, <name>_tiles)")
    return parser.parse_args(argv)


def main(argv=None):
    args = parse_args(argv)
    try:
        zip_path = addon_zip(args.addon_zip)
        if not args.dry_run:
            args.log_dir.mkdir(parents=True, exist_ok=True)
        ids = submit_frames(args, zip_path) if args.mode == "frames" else submit_still(args, zip_path)
    except SubmitError as exc:
        print(f"submit.py: error: {exc}", file=sys.stderr)
        return 1
    if not args.dry_run:
        print("\n".join(ids))
    return 0


if __name__ == "__main__":
    sys.exit(main())
