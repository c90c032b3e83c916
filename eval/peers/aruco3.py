#!/usr/bin/env python3
"""ArUco3 (OpenCV contrib cv2.aruco, DICT_ARUCO_MIP_36h12) speaking the peer line protocol; see protocol.py.

Parameters: cv2.aruco.DetectorParameters() defaults with
useAruco3Detection = True and nothing else changed. Note what those defaults
imply: minMarkerLengthRatioOriginalImg = 0 means no downscaled pyramid level
is used, and OpenCV's Aruco3 path refines corners only while walking back up
that pyramid, so the reported corners are the integer contour vertices (no
sub-pixel refinement). The selftest measures errors up to about 1 px from that.

Corner order: OpenCV reports TL, TR, BR, BL of the marker as drawn by
cv2.aruco.generateImageMarker (clockwise on screen). We emit TL, BL, BR, TR.

Pixel convention: OpenCV already uses pixel-centre coordinates (centre of
pixel (0, 0) is (0, 0)); the measured mean offset is ~0, so no correction.
"""

from __future__ import annotations  # noqa: I001 (protocol must be imported before numpy/cv2)

from typing import Any

import protocol  # first: pins thread counts before numpy/cv2 load
import cv2
import numpy as np

NAME = "aruco3"
DIST = "opencv-contrib-python-headless"
FAMILY = "aruco_mip_36h12"
# Index into the library's corner list for each of TL, BL, BR, TR.
TO_TL_BL_BR_TR = [0, 3, 2, 1]


def make_detector() -> tuple[protocol.DetectFn, protocol.ConvertFn]:
    """Create the detector once; return the (detect, convert) pair."""
    params = cv2.aruco.DetectorParameters()
    params.useAruco3Detection = True
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_ARUCO_MIP_36h12)
    detector = cv2.aruco.ArucoDetector(dictionary, params)

    def detect(gray: np.ndarray) -> Any:
        return detector.detectMarkers(gray)

    def convert(raw: Any) -> list[protocol.Detection]:
        corners, ids, _rejected = raw
        if ids is None:
            return []
        return [
            protocol.detection(FAMILY, marker_id, np.asarray(quad).reshape(4, 2)[TO_TL_BL_BR_TR])
            for marker_id, quad in zip(np.asarray(ids).ravel(), corners, strict=True)
        ]

    return detect, convert


if __name__ == "__main__":
    raise SystemExit(protocol.run(NAME, DIST, make_detector))
