"""The tile grid of a still split across farm tasks, shared by farm_setup.py
(inside Blender: which border a task renders) and stitch_tiles.py (where each
tile goes back).

Tile i of a COLS x ROWS grid is column i % COLS, row i // COLS, rows counted
from the TOP of the image; its pixels are the half-open rectangle
[x0, x1) x [y0, y1) with x0 = col * width // COLS and likewise for the others,
so the tiles cover every pixel exactly once for any size.
"""


def parse_grid(text):
    """'3x2' -> (3, 2): columns, rows."""
    try:
        cols, rows = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise ValueError(f"a tile grid is COLSxROWS, e.g. 2x2, not {text!r}") from None
    if cols < 1 or rows < 1:
        raise ValueError(f"a tile grid needs at least 1x1 tiles, not {text!r}")
    return cols, rows


def tile_rect(index, cols, rows, width, height):
    """(x0, y0, x1, y1) pixels of tile `index`, y = 0 at the top row."""
    if not 0 <= index < cols * rows:
        raise ValueError(f"tile {index} is outside the {cols}x{rows} grid")
    if cols > width or rows > height:
        raise ValueError(f"a {cols}x{rows} grid does not fit a {width}x{height} image")
    col, row = index % cols, index // cols
    return (col * width // cols, row * height // rows, (col + 1) * width // cols, (row + 1) * height // rows)


def _border_fraction(pixel, size):
    # Blender turns the border back into pixels with a truncating
    # int(fraction * size); the middle of the pixel survives float32 rounding.
    if pixel <= 0:
        return 0.0
    if pixel >= size:
        return 1.0
    return (pixel + 0.5) / size


def border_fractions(rect, width, height):
    """Blender's render border (min_x, min_y, max_x, max_y), y measured from
    the BOTTOM, that selects exactly the pixels of `rect` (tile_rect's)."""
    x0, y0, x1, y1 = rect
    return (_border_fraction(x0, width), _border_fraction(height - y1, height),
            _border_fraction(x1, width), _border_fraction(height - y0, height))
