"""Run inside Blender by every farm task (`--python farm_setup.py`, after
`-E COHERENT`), before it renders.

- Fails the task (with --python-exit-code 1) unless the COHERENT add-on is
  enabled and is the scene's engine: Blender falls back to another engine for
  an unknown -E and would still write frames.
- --raw-exr: the output becomes one multilayer EXR (float32, lossless ZIP) of
  the render layers as rendered: no compositor, no sequencer, so tiles and a
  whole-frame render hold the same pixels.
- --tile I --grid COLSxROWS: render only tile I (tiles.py), cropped, with
  --raw-exr implied. Refuses stopping rules that depend on the whole image
  (target error, time limit) and adaptive sampling (a pixel's neighbours
  decide when it stops): with them a tile would not equal its part of the
  whole frame.

    blender -b FILE -E COHERENT --python farm_setup.py -o OUT -f 1 -- --tile 0 --grid 2x2
"""

import argparse
import os
import sys

import addon_utils
import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from tiles import border_fractions, parse_grid, tile_rect  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="farm_setup.py", description=__doc__.splitlines()[0])
    parser.add_argument("--raw-exr", action="store_true", help="multilayer float EXR of the raw render layers")
    parser.add_argument("--tile", type=int, help="the tile this task renders (0 = top left, row by row)")
    parser.add_argument("--grid", type=parse_grid, help="COLSxROWS tile grid, with --tile")
    args = parser.parse_args(argv)
    if (args.tile is None) != (args.grid is None):
        parser.error("--tile and --grid go together")
    return args


def require_coherent(scene):
    _, enabled = addon_utils.check("coherent")
    if not enabled:
        raise RuntimeError("coherent farm: the coherent add-on is not enabled in this Blender "
                           f"(BLENDER_USER_SCRIPTS={os.environ.get('BLENDER_USER_SCRIPTS')!r})")
    if scene.render.engine != "COHERENT":
        raise RuntimeError(f"coherent farm: the render engine is {scene.render.engine}, not COHERENT")
    import coherent
    print(f"coherent farm: add-on {os.path.dirname(coherent.__file__)}")


def set_raw_exr(render):
    render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    render.image_settings.color_depth = "32"
    render.image_settings.exr_codec = "ZIP"
    render.use_file_extension = True
    render.use_compositing = False
    render.use_sequencer = False


def set_tile(scene, index, grid):
    props = scene.coherent
    whole_image_rules = [name for name, on in (("target error", props.target_error > 0.0),
                                               ("time limit", props.time_limit > 0.0),
                                               ("adaptive sampling", props.use_adaptive_sampling)) if on]
    if whole_image_rules:
        raise RuntimeError(f"coherent farm: a still split into tiles cannot use {', '.join(whole_image_rules)}: "
                           "each tile would stop on its own pixels; turn it off or render the still whole")
    render = scene.render
    width = render.resolution_x * render.resolution_percentage // 100
    height = render.resolution_y * render.resolution_percentage // 100
    rect = tile_rect(index, *grid, width, height)
    render.use_border = True
    render.use_crop_to_border = True
    render.border_min_x, render.border_min_y, render.border_max_x, render.border_max_y = \
        border_fractions(rect, width, height)
    print(f"coherent farm: tile {index} of {grid[0]}x{grid[1]}: pixels x {rect[0]}-{rect[2]}, "
          f"y {rect[1]}-{rect[3]} (from the top) of {width}x{height}")


def main():
    args = parse_args()
    scene = bpy.context.scene
    require_coherent(scene)
    if args.raw_exr or args.tile is not None:
        set_raw_exr(scene.render)
    if args.tile is not None:
        set_tile(scene, args.tile, args.grid)


main()
