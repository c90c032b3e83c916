"""detect() releases the GIL: Python code in another thread runs while it
works. Observed, not timed: a counter thread stamps each of its loop
iterations; with the GIL held for the whole detect call no iteration could
fall inside the call's middle half, so at least one must."""

from __future__ import annotations

import threading
import time

import numpy as np
from conftest import fixture_paths, read_grey

import coppertag


def big_frame() -> np.ndarray:
    """Nine fixture tags on one 3072 x 3072 frame: tens of milliseconds."""
    tiles = [read_grey(p) for p in fixture_paths()[:9]]
    rows = [np.hstack(tiles[i : i + 3]) for i in range(0, 9, 3)]
    return np.ascontiguousarray(np.vstack(rows))


def test_python_thread_runs_during_detect() -> None:
    frame = big_frame()
    detector = coppertag.Detector()
    assert len(detector.detect(frame)) == 9  # warm-up, and the frame is real work
    stamps: list[float] = []
    stop = threading.Event()

    def count() -> None:
        while not stop.is_set():
            stamps.append(time.perf_counter())

    worker = threading.Thread(target=count)
    worker.start()
    try:
        time.sleep(0.05)  # the worker is running
        inside = 0
        for _ in range(5):  # five calls, so one unlucky schedule cannot decide it
            t0 = time.perf_counter()
            detector.detect(frame)
            t1 = time.perf_counter()
            lo, hi = t0 + 0.25 * (t1 - t0), t0 + 0.75 * (t1 - t0)
            inside += sum(lo <= s <= hi for s in stamps[-200_000:])
    finally:
        stop.set()
        worker.join()
    assert inside > 0, "no Python bytecode ran in another thread while detect() worked"


def test_same_detector_from_two_threads_is_refused_not_crashed() -> None:
    frame = big_frame()
    detector = coppertag.Detector()
    errors: list[BaseException] = []
    results: list[int] = []

    def work() -> None:
        for _ in range(3):
            try:
                results.append(len(detector.detect(frame)))
            except RuntimeError as e:  # "Already borrowed": one call at a time
                errors.append(e)

    threads = [threading.Thread(target=work) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert all(n == 9 for n in results) and results
    assert all("borrow" in str(e).lower() for e in errors)
