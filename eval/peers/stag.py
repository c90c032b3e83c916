#!/usr/bin/env python3
"""STag (stag-python, library HD21) speaking the peer line protocol; see protocol.py.

Parameters: stag.detectMarkers(image, 21) with the default error correction
(-1 = the maximum for HD21, (21 - 1) / 2 = 10 bits). The library does not
report how many bits it corrected, so ``corrected`` is null.

Corner order: stag-python reports the corners of the black square clockwise on
screen starting at the marker's top-left: TL, TR, BR, BL of the upright
marker (upright = the code-circle layout of synth/data/peers/stag_hd21.json).
We emit TL, BL, BR, TR.

Pixel convention: pixel-centre coordinates already; the measured mean offset
is ~0, so no correction. Corners are effectively quantised to the pixel grid
(errors up to ~0.5 px per axis when edges fall on pixel boundaries).

Threads: stag-python bundles its own OpenCV build, which cv2.setNumThreads does
not reach; protocol.py sets OPENCV_FOR_THREADS_NUM=1 for it.

This file is named stag.py, like the package it wraps, so the package is
imported with this script's directory removed from sys.path.
"""

from __future__ import annotations  # noqa: I001 (protocol must be imported before numpy/cv2)

import sys
from pathlib import Path
from typing import Any

import protocol  # first: pins thread counts before numpy/cv2 load
import numpy as np

NAME = "stag"
DIST = "stag-python"
FAMILY = "stag_hd21"
LIBRARY_HD = 21
# Index into the library's corner list for each of TL, BL, BR, TR.
TO_TL_BL_BR_TR = [0, 3, 2, 1]


def import_stag_package() -> Any:
    """Import the stag-python package rather than this script (same name)."""
    here = Path(__file__).resolve().parent
    saved = list(sys.path)
    try:
        sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != here]
        import stag as package
    finally:
        sys.path[:] = saved
    if not hasattr(package, "detectMarkers"):
        raise ImportError(f"imported {package.__file__}, not stag-python")
    return package


def make_detector() -> tuple[protocol.DetectFn, protocol.ConvertFn]:
    """Import the library once; return the (detect, convert) pair."""
    package = import_stag_package()

    def detect(gray: np.ndarray) -> Any:
        return package.detectMarkers(gray, LIBRARY_HD)

    def convert(raw: Any) -> list[protocol.Detection]:
        corners, ids, _rejected = raw
        if ids is None or len(ids) == 0:
            return []
        return [
            protocol.detection(FAMILY, marker_id, np.asarray(quad).reshape(4, 2)[TO_TL_BL_BR_TR])
            for marker_id, quad in zip(np.asarray(ids).ravel(), corners, strict=True)
        ]

    return detect, convert


if __name__ == "__main__":
    raise SystemExit(protocol.run(NAME, DIST, make_detector))
