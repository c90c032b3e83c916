"""One-time export of the peer-marker codebooks into synth/data/peers/.

Usage (from the repository root, inside the peers venv):

    .venv/bin/python eval/peers/export_codebooks.py STAG_SOURCE_DIR [OUT_DIR]

STAG_SOURCE_DIR holds the STag authors' ``HD21.txt`` (one 48-character 0/1
code per line). OUT_DIR defaults to ``synth/data/peers`` next to this
repository's ``eval/``. The output is committed; nothing at run time reads
STAG_SOURCE_DIR again.

Square markers (tag36h11, ARUCO_MIP_36h12) are taken from opencv-contrib's
predefined dictionaries by drawing every id with ``generateImageMarker`` at 8
px per cell and sampling the cell centres, so the committed grids say exactly
what an upright marker looks like (row 0 = top row, 1 = black).

OpenCV 4.x draws its DICT_APRILTAG_36h11 markers rotated by 180 degrees
relative to the official AprilTag images (apriltag-imgs, apriltag_to_image);
pupil-apriltags reports corner 0 at the official bottom-left, which on an
OpenCV-drawn tag is the top-right. The export therefore rotates each AprilTag
grid by 180 degrees so the committed codebook is in the official orientation.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from importlib import metadata
from pathlib import Path

import cv2
import numpy as np

PX_PER_CELL = 8
DATA_BITS = 6
BORDER_BITS = 1

# STag geometry (units of the black square's edge E), from the STag authors'
# marker generator as summarised in shared/peers/stag/README.md.
STAG_MARGIN = 0.125
STAG_INNER_DISC_RADIUS = 0.4
STAG_CODE_DISC_DIAMETER = 0.7  # D
STAG_CODE_CIRCLE_RADIUS_D = 0.0624822  # code-circle radius in units of D
STAG_QUADRANT_TABLE: list[tuple[float, float]] = [  # (r, t) in units of D / radians
    (0.088363142525988, 0.785398163397448),
    (0.206935928182607, 0.459275804122858),
    (0.206935928182607, math.pi / 2 - 0.459275804122858),
    (0.313672146827381, 0.200579720495241),
    (0.327493143484516, 0.591687617505840),
    (0.327493143484516, math.pi / 2 - 0.591687617505840),
    (0.313672146827381, math.pi / 2 - 0.200579720495241),
    (0.437421957035861, 0.145724938287167),
    (0.437226762361658, 0.433363129825345),
    (0.430628029742607, 0.785398163397448),
    (0.437226762361658, math.pi / 2 - 0.433363129825345),
    (0.437421957035861, math.pi / 2 - 0.145724938287167),
]


def opencv_version() -> str:
    """Version string of the installed opencv-contrib wheel."""
    try:
        return metadata.version("opencv-contrib-python-headless")
    except metadata.PackageNotFoundError:
        return cv2.__version__


def dictionary_grids(constant: str) -> list[np.ndarray]:
    """Draw every marker of an OpenCV predefined dictionary and sample its 6x6 data cells.

    Returns one (6, 6) int array per id, row-major as drawn, 1 = black.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, constant))
    if dictionary.markerSize != DATA_BITS:
        raise ValueError(f"{constant}: expected {DATA_BITS}x{DATA_BITS} data bits, got {dictionary.markerSize}")
    cells = DATA_BITS + 2 * BORDER_BITS
    grids = []
    for marker_id in range(dictionary.bytesList.shape[0]):
        image = cv2.aruco.generateImageMarker(dictionary, marker_id, cells * PX_PER_CELL, borderBits=BORDER_BITS)
        centres = image[PX_PER_CELL // 2 :: PX_PER_CELL, PX_PER_CELL // 2 :: PX_PER_CELL]
        if np.any((centres > 32) & (centres < 223)):
            raise ValueError(f"{constant} id {marker_id}: cell centre is not pure black/white")
        black = (centres < 128).astype(int)
        if not (black[0].all() and black[-1].all() and black[:, 0].all() and black[:, -1].all()):
            raise ValueError(f"{constant} id {marker_id}: border is not black")
        grids.append(black[BORDER_BITS:-BORDER_BITS, BORDER_BITS:-BORDER_BITS])
    return grids


def square_geometry(quiet_cells: int) -> dict:
    """Cell-unit geometry of a square marker image with a white quiet zone."""
    side = DATA_BITS + 2 * BORDER_BITS + 2 * quiet_cells
    return {
        "unit": "cell; origin at the top-left corner of the whole marker image, x right, y down",
        "image_cells": side,
        "quiet_zone_cells": quiet_cells,
        "black_square": [quiet_cells, quiet_cells, side - quiet_cells, side - quiet_cells],
        "data_area": [
            quiet_cells + BORDER_BITS,
            quiet_cells + BORDER_BITS,
            side - quiet_cells - BORDER_BITS,
            side - quiet_cells - BORDER_BITS,
        ],
        "reported_corners": "outer corners of the black square, emitted by the adapters as TL, BL, BR, TR "
        "of the upright marker (corner 0 = black_square[0..2])",
    }


def square_codebook(name: str, constant: str, grids: list[np.ndarray], licence: str, note: str) -> dict:
    """JSON document for a square (6x6 data) family."""
    return {
        "name": name,
        "source": f"opencv-contrib-python-headless {opencv_version()}, cv2.aruco.{constant}, "
        f"drawn with cv2.aruco.generateImageMarker at {PX_PER_CELL} px/cell and sampled at cell centres",
        "licence note": licence,
        "note": note,
        "bits": DATA_BITS,
        "border_bits": BORDER_BITS,
        "bit_value": "1 = black, 0 = white",
        "code_layout": "row-major over the 6x6 data cells of the upright marker: index = row * 6 + col, "
        "row 0 at the top, col 0 at the left",
        "geometry": square_geometry(quiet_cells=1),
        "count": len(grids),
        "codes": [[int(v) for v in grid.ravel()] for grid in grids],
    }


def stag_code_centres() -> list[list[float]]:
    """Centres of the 48 STag code circles, in units of E from the black square's top-left corner (y down)."""
    d = STAG_CODE_DISC_DIAMETER
    origin = 0.5 - d / 2  # top-left of the code disc's bounding box, in E
    centres = []
    for quadrant in range(4):
        for r, t in STAG_QUADRANT_TABLE:
            angle = t + quadrant * math.pi / 2
            x = origin + d * (0.5 + r * math.cos(angle))
            y = origin + d * (0.5 - r * math.sin(angle))
            centres.append([round(x, 12), round(y, 12)])
    return centres


def stag_codebook(source_dir: Path) -> dict:
    """JSON document for the STag HD21 library, with the marker geometry."""
    lines = [ln.strip() for ln in (source_dir / "HD21.txt").read_text().splitlines() if ln.strip()]
    codes = []
    for i, line in enumerate(lines):
        if len(line) != 48 or set(line) - {"0", "1"}:
            raise ValueError(f"HD21.txt line {i + 1}: expected 48 characters of 0/1")
        codes.append([int(c) for c in line])
    d = STAG_CODE_DISC_DIAMETER
    code_radius = STAG_CODE_CIRCLE_RADIUS_D * d
    return {
        "name": "stag_hd21",
        "source": "STag authors' public repository (Benligiray et al.), library HD21 (HD21.txt), "
        "as detected by stag-python library 21",
        "licence note": "MIT licence, Copyright (c) 2019 Burak Benligiray",
        "hd": 21,
        "nbits": 48,
        "bit_value": "1 = black code circle, 0 = no circle (white)",
        "count": len(codes),
        "geometry": {
            "unit": "E = side of the black square; coordinates from the black square's top-left corner, "
            "x right, y down (the whole image spans [-margin, 1 + margin])",
            "image_size": 1.0 + 2 * STAG_MARGIN,
            "margin": STAG_MARGIN,
            "square": 1.0,
            "inner_disc_centre": [0.5, 0.5],
            "inner_disc_radius": STAG_INNER_DISC_RADIUS,
            "code_disc_radius": d / 2,
            "code_circle_radius": round(code_radius, 12),
            "filler_max_centre_distance": round(4 * STAG_CODE_CIRCLE_RADIUS_D * d, 12),
            "filler_radius": round(0.7 * code_radius, 12),
            "filler_rule": "for every pair of black code circles whose centres are closer than "
            "filler_max_centre_distance, draw a black circle of filler_radius at their midpoint",
            "code_centres": stag_code_centres(),
            "reported_corners": "corners of the black square, emitted by the adapters as TL, BL, BR, TR "
            "of the upright marker ((0,0), (0,1), (1,1), (1,0) in these units)",
        },
        "codes": codes,
    }


def write_json(path: Path, doc: dict) -> None:
    """Write a document with indent 2 but every list of numbers on one line (diff-friendly)."""
    text = json.dumps(doc, indent=2)
    text = re.sub(
        r"\[\s*([-+0-9.eE]+(?:\s*,\s*[-+0-9.eE]+)*)\s*\]",
        lambda m: "[" + ", ".join(re.split(r"\s*,\s*", m.group(1))) + "]",
        text,
    )
    if json.loads(text) != doc:
        raise AssertionError("compact JSON formatting changed the document")
    path.write_text(text + "\n")


def main() -> None:
    """Parse arguments and write the three codebooks."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("stag_dir", type=Path, help="directory holding the STag HD21.txt")
    default_out = Path(__file__).resolve().parents[2] / "synth" / "data" / "peers"
    parser.add_argument("out_dir", type=Path, nargs="?", default=default_out)
    args = parser.parse_args()
    args.out_dir.mkdir(parents=True, exist_ok=True)

    april = [np.rot90(g, 2) for g in dictionary_grids("DICT_APRILTAG_36h11")]
    mip = dictionary_grids("DICT_ARUCO_MIP_36h12")
    assert len(april) == 587 and len(mip) == 250, (len(april), len(mip))

    docs = {
        "tag36h11.json": square_codebook(
            "tag36h11",
            "DICT_APRILTAG_36h11",
            april,
            "AprilTag tag36h11 codes: BSD 2-Clause, AprilRobotics (University of Michigan APRIL lab); "
            "distributed in OpenCV's aruco module (Apache-2.0)",
            "Rotated by 180 degrees from OpenCV 4.x's drawing so that it matches the official AprilTag "
            "tag36h11 images (OpenCV's AprilTag patterns are drawn upside down). Official images are 10x10 "
            "cells: 1 white + 1 black border cell around the 6x6 data.",
        ),
        "aruco_mip_36h12.json": square_codebook(
            "aruco_mip_36h12",
            "DICT_ARUCO_MIP_36h12",
            mip,
            "ArUco MIP_36h12 codes from the ArUco library (Garrido-Jurado, Munoz-Salinas et al.), "
            "distributed in OpenCV's aruco module (BSD-3-Clause in opencv_contrib <= 4.4, Apache-2.0 since)",
            "As drawn by OpenCV (the same frame the OpenCV ArUco detector decodes in). ArUco images have no "
            "white border of their own; geometry adds a 1-cell quiet zone like tag36h11.",
        ),
        "stag_hd21.json": stag_codebook(args.stag_dir),
    }
    for filename, doc in docs.items():
        write_json(args.out_dir / filename, doc)
        print(f"wrote {args.out_dir / filename}: {doc['count']} codes")


if __name__ == "__main__":
    main()
