"""One-time export of the fractal marker's bitmap into synth/data/peers/.

Usage (from the repository root, inside the peers venv):

    .venv/bin/python eval/peers/export_fractal.py [OUT_DIR]

OUT_DIR defaults to ``synth/data/peers``. The output (``fractal_5l_6.json``)
is committed; nothing at run time imports nanofractal to draw a marker.

The bitmap is ``nanofractal.generate_fractal(CONFIG, size_px=CELLS)`` with
CELLS the side of the configuration's finest common cell grid (312 for
FRACTAL_5L_6): every level's cells are whole cells of that grid, and the
function samples each output pixel at its centre, so one pixel per cell is
the exact marker. The export checks that by drawing it again at 4 px per
cell and comparing the cell centres. The bitmap spans the outer black
border exactly (the marker square); the white quiet zone around it is the
renderer's, 0.125 of the square on each side as for the other peers.

The nested levels' squares (id, data bits, corners) come from the package's
own level table (``nanofractal._nanofractal._fractal_markers``, normalised
coordinates in [-1, 1] with y up), converted to marker units ([-0.5, 0.5],
y down) and listed TL, BL, BR, TR.
"""

from __future__ import annotations

import argparse
import json
from fractions import Fraction
from importlib import metadata
from math import lcm
from pathlib import Path

import nanofractal as nf
import numpy as np
from nanofractal import _nanofractal as nf_native

CONFIG = "FRACTAL_5L_6"
NAME = "fractal_5l_6"
# Drawn again at this many pixels per cell to check the one-cell bitmap.
CHECK_PX_PER_CELL = 4
# Largest denominator accepted when turning the library's float32 level
# corners into exact fractions of the marker (they are ratios of small
# cell counts; float32 carries ~7 digits).
MAX_DENOMINATOR = 10_000


def finest_grid(levels: list[tuple[int, np.ndarray, np.ndarray]]) -> int:
    """Cells per side of the common grid on which every level's cells lie."""
    cells = 1
    for _id, corners, bits in levels:
        half = Fraction(float(np.abs(np.asarray(corners)).max())).limit_denominator(MAX_DENOMINATOR)
        n = np.asarray(bits).shape[0] + 2  # data bits plus the black border
        # One cell of this level, as a fraction of the whole marker side (2).
        cell = half * 2 / n / 2
        cells = lcm(cells, cell.denominator)
        # The level's edge must also lie on the grid.
        edge = (1 - half) / 2
        cells = lcm(cells, edge.denominator)
    return cells


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    default_out = Path(__file__).resolve().parents[2] / "synth" / "data" / "peers"
    parser.add_argument("out_dir", nargs="?", type=Path, default=default_out)
    args = parser.parse_args()

    levels = nf_native._fractal_markers(CONFIG)
    cells = finest_grid(levels)
    bitmap = nf.generate_fractal(CONFIG, size_px=cells)
    fine = nf.generate_fractal(CONFIG, size_px=cells * CHECK_PX_PER_CELL)
    centre = CHECK_PX_PER_CELL // 2
    if not np.array_equal(fine[centre::CHECK_PX_PER_CELL, centre::CHECK_PX_PER_CELL], bitmap):
        raise SystemExit(f"{CONFIG}: the {cells}-cell bitmap is not the marker's cell grid")
    if bitmap[0].any() or bitmap[-1].any() or bitmap[:, 0].any() or bitmap[:, -1].any():
        raise SystemExit(f"{CONFIG}: the bitmap does not start with the black border")

    out_levels = []
    for level_id, corners, bits in sorted(levels, key=lambda m: int(m[0])):
        half = float(Fraction(float(np.abs(np.asarray(corners)).max())).limit_denominator(MAX_DENOMINATOR))
        h = half / 2  # normalised [-1, 1] -> marker units [-0.5, 0.5]
        out_levels.append(
            {
                "id": int(level_id),
                "bits": int(np.asarray(bits).shape[0]),
                # TL, BL, BR, TR in marker units, x right, y down.
                "corners": [[-h, -h], [-h, h], [h, h], [h, -h]],
            }
        )

    doc = {
        "name": NAME,
        "config": CONFIG,
        "source": {
            "package": "nanofractal",
            "version": metadata.version("nanofractal"),
            "function": f"nanofractal.generate_fractal({CONFIG!r}, size_px={cells})",
            "levels": f"nanofractal._nanofractal._fractal_markers({CONFIG!r})",
        },
        "cells": cells,
        "quiet_zone": 0.125,
        "external_id": int(nf_native._fractal_external_id(CONFIG)),
        "levels": out_levels,
        # Row-major, row 0 at the top of the upright marker; '1' = black.
        "rows": ["".join("0" if v else "1" for v in row) for row in bitmap],
    }
    args.out_dir.mkdir(parents=True, exist_ok=True)
    path = args.out_dir / f"{NAME}.json"
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=1) + "\n")
    tmp.replace(path)
    print(f"wrote {path}: {cells} x {cells} cells, {len(out_levels)} levels")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
