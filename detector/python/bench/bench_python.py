#!/usr/bin/env python3
"""Binding overhead and GIL release of the `coppertag` Python package.

1. Overhead: the median time of ``Detector.detect`` called from Python on
   the criterion benchmark's frames (``detector/benches/detect.rs`` saves
   them when COPPERTAG_BENCH_FRAMES is set), against criterion's median for
   the same frames, same build profile (``make bench-python`` runs both);
   and, robust to a busy machine, against the detector's own clock
   (``Detector.stats["total"]``) in the very same calls.
2. Threads: two detectors on two frames, in two threads, against one
   thread doing both; the ratio is the speed-up the released GIL gives
   (at most 2 on two free cores), next to the same ratio for numpy's sort
   as a control of what the machine allows at the time.

Timings are wall-clock and noisy on a machine running other work; each
figure is a median (overhead) or the best of several rounds (threads).
"""

from __future__ import annotations

import argparse
import json
import statistics
import threading
import time
from pathlib import Path

import cv2
import numpy as np

import coppertag

#: Detect calls timed per frame for the overhead median.
CALLS = 300
#: Frames per thread in one round of the thread comparison.
ROUND_CALLS = 40
#: Rounds of the thread comparison; the best of each mode is kept.
ROUNDS = 5


def median_detect_s(detector: coppertag.Detector, frame: np.ndarray) -> tuple[float, float, float]:
    """Medians over CALLS calls of (Python wall time of detect, the Rust
    detector's own clock for the same call, their per-call ratio). The
    last two are measured in the same calls, so a busy machine slows both
    alike: the ratio is the binding's overhead even when the absolute times
    are not comparable with criterion's."""
    for _ in range(10):
        detector.detect(frame)
    wall, rust = [], []
    for _ in range(CALLS):
        t0 = time.perf_counter()
        detector.detect(frame)
        wall.append(time.perf_counter() - t0)
        rust.append(detector.stats["total"])
    ratio = statistics.median(w / r for w, r in zip(wall, rust))
    return statistics.median(wall), statistics.median(rust), ratio


def criterion_median_s(root: Path, name: str) -> float:
    est = json.loads((root / name / "new" / "estimates.json").read_text())
    return est["median"]["point_estimate"] * 1e-9


def threads(frames: list[np.ndarray]) -> tuple[float, float]:
    """(one thread doing both frames, two threads one frame each): best seconds."""
    detectors = [coppertag.Detector() for _ in frames]

    def run(det: coppertag.Detector, frame: np.ndarray) -> None:
        for _ in range(ROUND_CALLS):
            det.detect(frame)

    return serial_and_parallel([lambda d=d, f=f: run(d, f) for d, f in zip(detectors, frames)])


def serial_and_parallel(jobs: list) -> tuple[float, float]:
    """Best of ROUNDS wall times (s) of running `jobs` one after another on
    this thread, and of running each on its own thread at once."""
    serial, parallel = [], []
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        for job in jobs:
            job()
        serial.append(time.perf_counter() - t0)
        workers = [threading.Thread(target=job) for job in jobs]
        t0 = time.perf_counter()
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        parallel.append(time.perf_counter() - t0)
    return min(serial), min(parallel)


def control() -> tuple[float, float]:
    """The same comparison for numpy's sort, which releases the GIL too: it
    tells what speed-up the machine allows at the moment (about 1x when
    other work holds a core), so a low figure above can be read."""
    arrays = [np.random.default_rng(i).random(2_000_000) for i in range(2)]

    def run(x: np.ndarray) -> None:
        for _ in range(3):
            np.sort(x)

    return serial_and_parallel([lambda x=x: run(x) for x in arrays])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=Path, required=True, help="frames saved by the criterion bench")
    parser.add_argument("--criterion", type=Path, required=True, help="criterion's output dir")
    args = parser.parse_args()
    paths = sorted(args.frames.glob("detect_1080p_one_tag_*m.png"))
    if not paths:
        parser.error(f"no frames in {args.frames}: run the criterion bench with COPPERTAG_BENCH_FRAMES")
    frames = []
    for path in paths:
        frame = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if frame is None or frame.ndim != 2:
            parser.error(f"{path}: not a grey image")
        frames.append(frame)
        detector = coppertag.Detector()
        assert len(detector.detect(frame)) == 1, f"{path}: the frame must hold one tag"
        py, inner, ratio = median_detect_s(detector, frame)
        rust = criterion_median_s(args.criterion, path.stem)
        print(f"{path.stem}: python median {py * 1e3:.3f} ms, criterion median {rust * 1e3:.3f} ms, "
              f"python/criterion {py / rust:.3f} ({(py / rust - 1) * 100:+.1f}%); same calls: "
              f"detector clock {inner * 1e3:.3f} ms, python/detector {ratio:.4f} "
              f"({(ratio - 1) * 100:+.2f}%)")
    serial, parallel = threads(frames)
    print(f"two frames x {ROUND_CALLS}: one thread {serial:.3f} s, two threads {parallel:.3f} s, "
          f"speed-up {serial / parallel:.2f}x (best of {ROUNDS})")
    serial, parallel = control()
    print(f"control, numpy.sort on two arrays: one thread {serial:.3f} s, two threads "
          f"{parallel:.3f} s, speed-up {serial / parallel:.2f}x (what the machine allows now)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
