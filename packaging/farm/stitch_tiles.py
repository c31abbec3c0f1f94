#!/usr/bin/env python3
"""Stitches the border tiles of a still rendered across farm tasks
(tile.sbatch) into one multilayer EXR, pixel for pixel the single-process
render: every pass and channel of the tiles, each tile pasted where
tiles.py's grid puts it. Needs OpenImageIO's Python module (Debian:
python3-openimageio).

    stitch_tiles.py --grid 2x2 --frame 1 TILE_DIR OUTPUT.exr

Reads TILE_DIR/tile_<iii>_<frame>.exr for every tile i. The image size is
the sum of the tiles' sizes along the top row and the left column; every
tile must have exactly the size the grid gives it there, and the channels of
tile 0, or the stitch fails naming the tile.
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tiles import parse_grid, tile_rect  # noqa: E402

try:
    import OpenImageIO as oiio
except ImportError:  # pyenv and venv Pythons do not see Debian's module
    sys.path.append("/usr/lib/python3/dist-packages")
    import OpenImageIO as oiio


class StitchError(Exception):
    pass


def tile_path(tile_dir, index, frame):
    return os.path.join(tile_dir, f"tile_{index:03d}_{frame:04d}.exr")


def read_tile(path):
    if not os.path.isfile(path):
        raise StitchError(f"tile {path} is missing (did its array task fail?)")
    buf = oiio.ImageBuf(path)
    if buf.has_error or buf.nsubimages < 1:
        raise StitchError(f"cannot read tile {path}: {buf.geterror()}")
    if buf.nsubimages != 1:
        raise StitchError(f"tile {path} has {buf.nsubimages} parts; only single-part multilayer EXRs are stitched")
    buf.read(force=True)
    return buf


def image_size(tiles, cols, rows):
    width = sum(tiles[c].spec().width for c in range(cols))
    height = sum(tiles[r * cols].spec().height for r in range(rows))
    return width, height


def check_tile(buf, index, path, rect, channels):
    spec = buf.spec()
    want = (rect[2] - rect[0], rect[3] - rect[1])
    if (spec.width, spec.height) != want:
        raise StitchError(f"tile {index} ({path}) is {spec.width}x{spec.height} pixels; "
                          f"the grid needs {want[0]}x{want[1]} there")
    if tuple(spec.channelnames) != channels:
        raise StitchError(f"tile {index} ({path}) has channels {list(spec.channelnames)}, "
                          f"tile 0 has {list(channels)}")


def stitch(tile_dir, cols, rows, frame, output):
    paths = [tile_path(tile_dir, i, frame) for i in range(cols * rows)]
    tiles = [read_tile(p) for p in paths]
    width, height = image_size(tiles, cols, rows)
    first = tiles[0].spec()
    channels = tuple(first.channelnames)

    spec = oiio.ImageSpec(first)  # keeps the channel names, pixel format and metadata
    spec.width, spec.height = width, height
    spec.full_width, spec.full_height = width, height
    spec.x = spec.y = spec.full_x = spec.full_y = 0
    spec.tile_width = spec.tile_height = 0  # scanlines
    out = oiio.ImageBuf(spec)
    for index, (buf, path) in enumerate(zip(tiles, paths)):
        rect = tile_rect(index, cols, rows, width, height)
        check_tile(buf, index, path, rect, channels)
        if not oiio.ImageBufAlgo.paste(out, rect[0], rect[1], 0, 0, buf):
            raise StitchError(f"pasting tile {index} failed: {out.geterror()}")

    os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    # Written under a temporary name and renamed: a failed stitch never
    # leaves a truncated EXR that looks finished.
    tmp = output + ".tmp.exr"
    if not out.write(tmp, "openexr"):
        raise StitchError(f"cannot write {output}: {out.geterror()}")
    os.replace(tmp, output)
    return width, height, len(channels)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=parse_grid, required=True, help="COLSxROWS, as the tiles were rendered")
    parser.add_argument("--frame", type=int, required=True, help="the frame the tiles show")
    parser.add_argument("tile_dir")
    parser.add_argument("output", help="the stitched multilayer EXR")
    args = parser.parse_args(argv)
    try:
        width, height, channels = stitch(args.tile_dir, *args.grid, args.frame, args.output)
    except (StitchError, ValueError) as exc:
        print(f"stitch_tiles: error: {exc}", file=sys.stderr)
        return 1
    print(f"stitch_tiles: {args.grid[0] * args.grid[1]} tiles -> {args.output} ({width}x{height}, {channels} channels)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
