"""Shared line protocol for peer-detector adapters.

An adapter reads image paths from stdin, one per line, and for each one writes
exactly one JSON line to stdout (then flushes):

    {"image": PATH, "ms": F, "detections": [
        {"family": "tag36h11", "id": 42,
         "corners": [[x, y], [x, y], [x, y], [x, y]],
         "estimated": [false, false, false, false],
         "corrected": N_or_null}]}

or, when the image cannot be read or the detector fails on it,

    {"image": PATH, "error": "message"}

Corners are in pixel-centre coordinates (the centre of the top-left pixel is
(0, 0); pixel i spans [i - 0.5, i + 0.5]) and in marker-frame order TL, BL,
BR, TR of the outer black square as seen with the marker upright. ``ms`` is
the wall time in milliseconds of the detect call only (after one untimed
warm-up call on a blank image at start-up). Corners are rounded to 1e-4 px.
Empty lines are ignored; EOF ends the process with exit status 0.
Diagnostics go to stderr, never stdout.

This module pins every numeric library to one thread. It must be imported
before numpy or cv2 so that the environment variables below take effect.
"""

from __future__ import annotations

import os

for _var in (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
    # OpenCV's parallel_for_ default; also reaches OpenCV copies bundled
    # inside other wheels (stag-python ships its own libopencv_*.so).
    "OPENCV_FOR_THREADS_NUM",
):
    os.environ[_var] = "1"
os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")  # keep imread warnings off stderr

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from typing import Any  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)

Detection = dict[str, Any]
# An adapter supplies a pair: ``detect`` runs the library on a 2-D uint8
# grayscale image and returns its raw result (only this call is timed);
# ``convert`` turns that raw result into protocol detections.
DetectFn = Callable[[np.ndarray], Any]
ConvertFn = Callable[[Any], list[Detection]]


def detection(
    family: str, marker_id: int, corners: Sequence[Sequence[float]], corrected: int | None = None
) -> Detection:
    """Build one detection record; ``corners`` must already be TL, BL, BR, TR."""
    return {
        "family": family,
        "id": int(marker_id),
        "corners": [[round(float(x), 4), round(float(y), 4)] for x, y in corners],
        "estimated": [False, False, False, False],
        "corrected": None if corrected is None else int(corrected),
    }


def package_version(dist: str) -> str:
    """Installed version of a distribution, or "unknown"."""
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "unknown"


def log(message: str) -> None:
    """Write a diagnostic line to stderr."""
    print(message, file=sys.stderr, flush=True)


def process_line(path: str, detect: DetectFn, convert: ConvertFn) -> dict[str, Any]:
    """Load one image, run the detector on it and return the output record."""
    try:
        image = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
    except Exception as exc:  # cv2 may raise on odd inputs instead of returning None
        return {"image": path, "error": f"cannot read image: {exc}"}
    if image is None:
        reason = "no such file" if not os.path.exists(path) else "unreadable or unsupported image"
        return {"image": path, "error": f"cannot read image: {reason}"}
    try:
        start = time.perf_counter()
        raw = detect(image)
        ms = (time.perf_counter() - start) * 1000.0
        found = convert(raw)
    except Exception as exc:
        return {"image": path, "error": f"detector failed: {type(exc).__name__}: {exc}"}
    return {"image": path, "ms": round(ms, 4), "detections": found}


def run(
    name: str,
    dist: str,
    make_detector: Callable[[], tuple[DetectFn, ConvertFn]],
    argv: Sequence[str] | None = None,
) -> int:
    """Entry point shared by all adapters; returns the process exit code.

    ``make_detector`` is called once, after ``--version`` handling, and returns
    the ``(detect, convert)`` pair described at ``DetectFn``.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    if "--version" in args:
        print(json.dumps({"detector": name, "package": dist, "version": package_version(dist)}), flush=True)
        return 0
    if args:
        log(f"{name}: unknown arguments {args}; usage: {name} [--version] < paths")
        return 2
    detect, convert = make_detector()
    # One untimed, unreported call so lazy library initialisation does not
    # land on the first real image's "ms".
    convert(detect(np.full((240, 320), 200, dtype=np.uint8)))
    out = sys.stdout
    for raw in sys.stdin:
        path = raw.rstrip("\r\n")
        if not path.strip():
            continue
        out.write(json.dumps(process_line(path, detect, convert)) + "\n")
        out.flush()
    # Every answer is flushed; leave without running native destructors
    # (pupil-apriltags has been seen to crash in its teardown at exit).
    sys.stderr.flush()
    os._exit(0)
