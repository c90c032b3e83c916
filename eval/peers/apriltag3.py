#!/usr/bin/env python3
"""AprilTag 3 (pupil-apriltags, family tag36h11) speaking the peer line protocol; see protocol.py.

Parameters: the library defaults (quad_decimate=2.0, quad_sigma=0.0,
refine_edges=1, decode_sharpening=0.25) with nthreads=1 set explicitly.

Corner order: pupil-apriltags reports the corners counter-clockwise on screen
starting at the tag's bottom-left, i.e. BL, BR, TR, TL of the upright tag
(upright = the official AprilTag image orientation, which is the orientation of
synth/data/peers/tag36h11.json). We emit TL, BL, BR, TR.

Pixel convention: AprilTag places the centre of pixel (i, j) at (i + 0.5, j + 0.5).
The selftest measured a mean corner offset of about +0.43 px in x and y before
correction, so we subtract 0.5 to get pixel-centre coordinates.
"""

from __future__ import annotations  # noqa: I001 (protocol must be imported before numpy/cv2)

from typing import Any

import protocol  # first: pins thread counts before numpy/cv2 load
import numpy as np

NAME = "apriltag3"
DIST = "pupil-apriltags"
FAMILY = "tag36h11"
# Index into the library's corner list for each of TL, BL, BR, TR.
TO_TL_BL_BR_TR = [3, 0, 1, 2]
# Library coordinate minus pixel-centre coordinate.
PIXEL_OFFSET = 0.5


def make_detector() -> tuple[protocol.DetectFn, protocol.ConvertFn]:
    """Create the detector once; return the (detect, convert) pair."""
    from pupil_apriltags import Detector

    detector = Detector(families=FAMILY, nthreads=1)

    def detect(gray: np.ndarray) -> list[Any]:
        return detector.detect(gray)

    def convert(raw: list[Any]) -> list[protocol.Detection]:
        return [
            protocol.detection(
                FAMILY, d.tag_id, np.asarray(d.corners)[TO_TL_BL_BR_TR] - PIXEL_OFFSET, corrected=d.hamming
            )
            for d in raw
        ]

    return detect, convert


if __name__ == "__main__":
    raise SystemExit(protocol.run(NAME, DIST, make_detector))
