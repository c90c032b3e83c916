#!/usr/bin/env python3
"""CopperTag through its Python package (``import coppertag``, built from
detector/python/) speaking the peer line protocol; see protocol.py.

Not a peer: the same detector as ``coppertag detect --json``, reached through
the Python binding, so a user can check on any images that the Python path
gives the same numbers as the Rust one (detector/python/tests/
test_peer_adapter.py does it on the fixture images). Default settings, both
families (ct14, ct8), like ``coppertag detect``.

Corner order and pixel convention are the detector's own: TL, BL, BR, TR of
the data square, pixel-centre coordinates; ``estimated`` and ``corrected``
are reported as the detector gives them. The image is read by protocol.py
(OpenCV, grayscale), so colour images go through OpenCV's luma weights,
which differ from the Rust CLI's for non-grey pixels.
"""

from __future__ import annotations  # noqa: I001 (protocol must be imported before numpy/cv2)

from typing import Any

import protocol  # first: pins thread counts before numpy/cv2 load
import numpy as np

import coppertag

NAME = "coppertag-py"
DIST = "coppertag"


def make_detector() -> tuple[protocol.DetectFn, protocol.ConvertFn]:
    """Create the detector once; return the (detect, convert) pair."""
    detector = coppertag.Detector()

    def detect(gray: np.ndarray) -> Any:
        return detector.detect(gray)

    def convert(raw: Any) -> list[protocol.Detection]:
        out = []
        for d in raw:
            record = protocol.detection(d.family, d.id, d.corners, d.corrected)
            record["estimated"] = [bool(e) for e in d.estimated]
            out.append(record)
        return out

    return detect, convert


if __name__ == "__main__":
    raise SystemExit(protocol.run(NAME, DIST, make_detector))
