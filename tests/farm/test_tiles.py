"""The tile grid and the stitch of packaging/farm without a scheduler:
tiles cover every pixel once, the render border Blender is given selects
exactly a tile's pixels after its float32 rounding and truncation, and
stitch_tiles.py puts synthetic tiles back into the image they were cut from
(or names the tile that does not fit).
"""

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.append("/usr/lib/python3/dist-packages")  # Debian's OpenImageIO
import OpenImageIO as oiio  # noqa: E402

FARM = Path(__file__).resolve().parents[2] / "packaging" / "farm"
sys.path.insert(0, str(FARM))
import stitch_tiles  # noqa: E402
from tiles import border_fractions, parse_grid, tile_rect  # noqa: E402

SIZES = [(50, 30), (1920, 1080), (7, 5), (4096, 2160), (333, 777)]
GRIDS = [(1, 1), (2, 2), (3, 2), (7, 5), (16, 9)]


def blender_border_pixels(fractions, width, height):
    """What Blender makes of a border: float32 fractions times the size,
    truncated (render_init_from_main), y from the bottom; as tile_rect's rect."""
    x0, yb0, x1, yb1 = (int(np.float32(f) * np.float32(s))
                        for f, s in zip(fractions, (width, height, width, height)))
    return (x0, height - yb1, x1, height - yb0)


@pytest.mark.parametrize("width,height,cols,rows", [(w, h, c, r) for w, h in SIZES for c, r in GRIDS
                                                     if c <= w and r <= h])
def test_tiles_cover_every_pixel_once_and_blender_borders_select_them(width, height, cols, rows):
    cover = np.zeros((height, width), np.int32)
    for i in range(cols * rows):
        rect = tile_rect(i, cols, rows, width, height)
        cover[rect[1]:rect[3], rect[0]:rect[2]] += 1
        assert blender_border_pixels(border_fractions(rect, width, height), width, height) == rect
    assert (cover == 1).all()


def test_grid_parsing_and_bounds():
    assert parse_grid("3x2") == (3, 2) and parse_grid("4X4") == (4, 4)
    for bad in ("3", "0x2", "ax2", "3x2x1"):
        with pytest.raises(ValueError):
            parse_grid(bad)
    with pytest.raises(ValueError, match="outside"):
        tile_rect(6, 3, 2, 50, 30)
    with pytest.raises(ValueError, match="does not fit"):
        tile_rect(0, 8, 1, 7, 5)


CHANNELS = ["ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B", "ViewLayer.Combined.A",
            "ViewLayer.Depth.Z"]


def write_exr(path, pixels):
    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], oiio.FLOAT)
    spec.channelnames = tuple(CHANNELS[:pixels.shape[2]])
    spec.attribute("compression", "zip")
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec), oiio.geterror()
    assert out.write_image(pixels)
    out.close()


def cut_tiles(image, tile_dir, cols, rows, frame):
    height, width = image.shape[:2]
    tile_dir.mkdir()
    for i in range(cols * rows):
        x0, y0, x1, y1 = tile_rect(i, cols, rows, width, height)
        write_exr(stitch_tiles.tile_path(tile_dir, i, frame), image[y0:y1, x0:x1])


def test_stitch_puts_tiles_back_where_they_were_cut(tmp_path):
    image = np.random.default_rng(1).random((31, 47, 5), dtype=np.float32)
    cut_tiles(image, tmp_path / "tiles", 3, 2, 7)
    assert stitch_tiles.main(["--grid", "3x2", "--frame", "7", str(tmp_path / "tiles"), str(tmp_path / "out.exr")]) == 0
    out = oiio.ImageBuf(str(tmp_path / "out.exr"))
    assert list(out.spec().channelnames) == CHANNELS
    np.testing.assert_array_equal(out.get_pixels(oiio.FLOAT), image)


def test_stitch_names_a_missing_or_misfit_tile(tmp_path, capsys):
    image = np.zeros((20, 30, 4), np.float32)
    cut_tiles(image, tmp_path / "tiles", 2, 2, 1)
    Path(stitch_tiles.tile_path(tmp_path / "tiles", 3, 1)).unlink()
    assert stitch_tiles.main(["--grid", "2x2", "--frame", "1", str(tmp_path / "tiles"), str(tmp_path / "a.exr")]) == 1
    assert "tile_003_0001.exr is missing" in capsys.readouterr().err
    write_exr(stitch_tiles.tile_path(tmp_path / "tiles", 3, 1), np.zeros((10, 14, 4), np.float32))
    assert stitch_tiles.main(["--grid", "2x2", "--frame", "1", str(tmp_path / "tiles"), str(tmp_path / "b.exr")]) == 1
    err = capsys.readouterr().err
    assert "tile 3" in err and "is 14x10 pixels; the grid needs 15x10" in err, err
    assert not (tmp_path / "a.exr").exists() and not (tmp_path / "b.exr").exists()
