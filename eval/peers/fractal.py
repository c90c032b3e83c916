#!/usr/bin/env python3
"""Fractal markers (nanofractal, FRACTAL_5L_6) speaking the peer line protocol; see protocol.py.

Fractal markers (F. J. Romero-Ramirez, R. Munoz-Salinas, R. Medina-Carnicer,
"Fractal Markers: a new approach for long-range marker pose estimation under
occlusion", IEEE Access 7, 2019) nest square markers inside each other; each
level is detectable alone, so the marker survives occlusion of its outer
square as long as an inner level is seen.

Configuration: FRACTAL_5L_6 (five levels). nanofractal's FractalDetector has
no default configuration (it is a required argument); FRACTAL_5L_6 is the one
the package's README quick start, its benchmark and ``nanofractal.bench``
default to. It is one marker: family ``fractal_5l_6``, id 0 (the
configuration's external marker id, ``_fractal_external_id`` = 0), the same
in the synth truth (synth/data/peers/fractal_5l_6.json).

Parameters: ``FractalDetector(CONFIG)`` with default ``DetectorParams`` and
``nanofractal.set_num_threads(1)`` (the package otherwise uses every core
inside one detect call). The timed call is ``detect(gray,
with_inner_points=True)``, because the inner points are how the outer
corners are found when the outer level is hidden (below).

How the corners are obtained. The marker square is the outer level's black
square (level 0), the square the synth truth gives.
- Every detected level 0 is reported with its four corners as the library
  gives them (sub-pixel refined), ``estimated`` all false. (A frame may show
  several copies of the one marker, as the wild set's 1-3 markers per frame
  do; each outer square is one detection.)
- Otherwise the outer corners are extrapolated: a homography is fitted from
  the matched marker-plane points (``points_3d``, normalised [-1, 1], y up:
  every detected level's corners and the inner bit-cell corners the library
  matched) to their image points (``points_2d``) with OpenCV's
  ``findHomography`` (RANSAC, ``RANSAC_REPROJ_PX`` threshold, so a stray
  match cannot bend it), and the outer square's corners (+-1, +-1) are mapped
  through it; ``estimated`` all true. Fewer than ``MIN_POINTS`` matches, or
  a degenerate fit, gives no detection. With several copies in the frame
  and none of their outer squares seen, the RANSAC fit keeps the copy with
  the most matched points: one detection, the others are missed. Inner
  levels of a copy whose outer square is hidden are dropped when another
  copy's outer square is seen (a limit of this adapter: the library's
  points carry no marker instance).
So corner error and pose error compare like with like: always the outer
square, observed or extrapolated, as for CopperTag's estimated corners.

Corner order: the library lists each level's corners TL, TR, BR, BL of the
upright marker (clockwise on screen, the order of its normalised corners
(-1, 1), (1, 1), (1, -1), (-1, -1)); we emit TL, BL, BR, TR.

Pixel convention: pixel-centre coordinates already (measured by selftest.py).

``corrected``: not exposed -> null. Threads: nanofractal bundles its own
OpenCV 4.10; protocol.py's OPENCV_FOR_THREADS_NUM=1 and set_num_threads(1)
keep it to one thread.
"""

from __future__ import annotations  # noqa: I001 (protocol must be imported before numpy/cv2)

from typing import Any

import protocol  # first: pins thread counts before numpy/cv2 load
import cv2
import nanofractal
import numpy as np

NAME = "fractal"
DIST = "nanofractal"
CONFIG = "FRACTAL_5L_6"
FAMILY = "fractal_5l_6"
MARKER_ID = 0
# Level id of the outer square (the marker square).
OUTER_LEVEL = 0
# Index into the library's corner list for each of TL, BL, BR, TR.
TO_TL_BL_BR_TR = [0, 3, 2, 1]
# The outer square's corners in the library's normalised marker plane
# (x right, y up), TL, BL, BR, TR.
OUTER_PLANE = np.array([[-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0], [1.0, 1.0]])
# Fewest matched points for the homography (four define one; more give the
# RANSAC fit something to check against).
MIN_POINTS = 6
# RANSAC inlier threshold of the homography fit, pixels: matched points are
# sub-pixel refined corners, so a point off by more is a mismatch.
RANSAC_REPROJ_PX = 2.0


def outer_from_points(points_2d: np.ndarray, points_3d: np.ndarray) -> np.ndarray | None:
    """The outer square's corners (TL, BL, BR, TR) through a homography from the matched points."""
    if points_2d is None or len(points_2d) < MIN_POINTS:
        return None
    src = np.asarray(points_3d, dtype=np.float64)[:, :2]
    dst = np.asarray(points_2d, dtype=np.float64)
    h, _mask = cv2.findHomography(src, dst, cv2.RANSAC, RANSAC_REPROJ_PX)
    if h is None or not np.all(np.isfinite(h)):
        return None
    out = cv2.perspectiveTransform(OUTER_PLANE.reshape(-1, 1, 2), h).reshape(4, 2)
    return out if np.all(np.isfinite(out)) else None


def make_detector() -> tuple[protocol.DetectFn, protocol.ConvertFn]:
    """Create the detector once; return the (detect, convert) pair."""
    nanofractal.set_num_threads(1)
    detector = nanofractal.FractalDetector(CONFIG)

    def detect(gray: np.ndarray) -> Any:
        return detector.detect(gray, with_inner_points=True)

    def convert(raw: Any) -> list[protocol.Detection]:
        if len(raw) == 0:
            return []
        observed = [
            protocol.detection(FAMILY, MARKER_ID, np.asarray(corners)[TO_TL_BL_BR_TR])
            for level, corners in raw
            if level == OUTER_LEVEL
        ]
        if observed:
            return observed
        outer = outer_from_points(raw.points_2d, raw.points_3d)
        if outer is None:
            return []
        record = protocol.detection(FAMILY, MARKER_ID, outer)
        record["estimated"] = [True, True, True, True]
        return [record]

    return detect, convert


if __name__ == "__main__":
    raise SystemExit(protocol.run(NAME, DIST, make_detector))
