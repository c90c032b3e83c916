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
  gives them (sub-pixel refined), ``estimated`` all false.
- When level 0 is hidden, the outer corners are extrapolated: a homography is fitted from
  the matched marker-plane points (``points_3d``, normalised [-1, 1], y up:
  every detected level's corners and the inner bit-cell corners the library
  matched) to their image points (``points_2d``) with OpenCV's
  ``findHomography`` (RANSAC, ``RANSAC_REPROJ_PX`` threshold, so a stray
  match cannot bend it), and the outer square's corners (+-1, +-1) are mapped
  through it; ``estimated`` all true.
- A frame may show several copies of the one marker (the wild set has 1-3
  markers per frame), and the library's points say not which copy they
  belong to. So the detected levels are grouped into copies first: each
  inner level implies an outer square (its four corners through the level's
  place in the marker, from the library's level table); levels whose
  implied squares share a centre (within SAME_COPY_FRACTION of the side)
  are one copy, and a copy with an observed level 0 is that detection. For
  each other copy the homography above is fitted to the matched points
  inside its implied outer square (grown by REGION_GROWTH); with fewer than
  MIN_POINTS of them (the library matches points for one copy only, so
  other copies often have none beyond their levels' corners), the outer
  square implied by the copy's largest level is reported (estimated).
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
from nanofractal import _nanofractal as nf_native

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
# Two detected levels belong to the same copy of the marker when the outer
# squares they imply have centres closer than this fraction of the side
# (copies cannot overlap, so any fraction well below 1 separates them).
SAME_COPY_FRACTION = 0.25
# A copy's matched points are those inside the outer square implied by its
# largest detected level, grown by this fraction about its centre (the
# points on the outer square's own edges then count too).
REGION_GROWTH = 0.05


def level_halves() -> dict[int, float]:
    """Half side of each level's square in the library's normalised marker plane (outer level = 1).

    From the library's own level table (a private function of the pinned
    nanofractal 0.6.1; eval/peers/export_fractal.py reads the same table).
    """
    return {int(i): float(np.abs(np.asarray(c)).max()) for i, c, _bits in nf_native._fractal_markers(CONFIG)}


def implied_outer(corners: np.ndarray, half: float) -> np.ndarray:
    """The outer square (TL, BL, BR, TR) implied by one level's four corners (library order TL, TR, BR, BL)."""
    plane = np.array([[-half, half], [half, half], [half, -half], [-half, -half]], dtype=np.float32)
    h = cv2.getPerspectiveTransform(plane, np.asarray(corners, dtype=np.float32))
    return cv2.perspectiveTransform(OUTER_PLANE.reshape(-1, 1, 2), h).reshape(4, 2)


def centre_and_side(quad: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and mean side of a quadrilateral."""
    side = float(np.mean(np.linalg.norm(quad - np.roll(quad, 1, axis=0), axis=1)))
    return quad.mean(axis=0), side


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

    halves = level_halves()

    def convert(raw: Any) -> list[protocol.Detection]:
        if len(raw) == 0:
            return []
        found = []
        # (outer quad TL, BL, BR, TR; observed?) per copy of the marker.
        copies: list[tuple[np.ndarray, bool]] = []
        for level, corners in sorted(raw, key=lambda lc: lc[0]):
            corners = np.asarray(corners, dtype=np.float64)
            if level == OUTER_LEVEL:
                copies.append((corners[TO_TL_BL_BR_TR], True))
                continue
            region = implied_outer(corners, halves[level])
            centre, side = centre_and_side(region)
            if all(np.linalg.norm(centre - centre_and_side(q)[0]) > SAME_COPY_FRACTION * side for q, _ in copies):
                copies.append((region, False))
        points_2d = np.asarray(raw.points_2d, dtype=np.float64).reshape(-1, 2)
        points_3d = np.asarray(raw.points_3d, dtype=np.float64).reshape(-1, 3)
        for quad, observed in copies:
            if observed:
                found.append(protocol.detection(FAMILY, MARKER_ID, quad))
                continue
            centre, _side = centre_and_side(quad)
            grown = (centre + (quad - centre) * (1.0 + REGION_GROWTH)).astype(np.float32)
            inside = np.array(
                [cv2.pointPolygonTest(grown, (float(x), float(y)), False) >= 0 for x, y in points_2d], dtype=bool
            )
            outer = outer_from_points(points_2d[inside], points_3d[inside])
            if outer is None:
                # Too few matched points of this copy: its largest level's
                # own four corners say where the outer square is.
                outer = quad
            record = protocol.detection(FAMILY, MARKER_ID, outer)
            record["estimated"] = [True, True, True, True]
            found.append(record)
        return found

    return detect, convert


if __name__ == "__main__":
    raise SystemExit(protocol.run(NAME, DIST, make_detector))
