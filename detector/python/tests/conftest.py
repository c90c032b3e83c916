"""Shared fixtures of the Python package's tests: the fixture images (read
exactly as the Rust CLI reads them) and the `coppertag` binary's answers."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]
FIXTURES = REPO / "detector" / "tests" / "fixtures"


def fixture_paths() -> list[Path]:
    """Every golden tag image (ct14/*.png, ct8/*.png)."""
    return sorted(FIXTURES.glob("ct*/*.png"))


def read_grey(path: Path) -> np.ndarray:
    """The grey image the Rust CLI sees. The fixtures are grey stored as RGB
    (R = G = B), so any luma weights give the same bytes; this reads one
    channel and checks that assumption rather than converting."""
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None, f"cannot read {path}"
    if img.ndim == 3:
        assert (img[..., 0] == img[..., 1]).all() and (img[..., 1] == img[..., 2]).all(), path
        img = np.ascontiguousarray(img[..., 0])
    return img


def coppertag_bin() -> Path:
    """The CLI built with the `ci` profile (`make test` builds it first)."""
    path = Path(os.environ.get("COPPERTAG_BIN", REPO / "target" / "ci" / "coppertag"))
    if not path.is_absolute():
        path = REPO / path
    if not path.exists():
        pytest.fail(f"{path} is missing: build it with `make gate-build` (or set COPPERTAG_BIN)")
    return path


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(coppertag_bin()), *args], capture_output=True, text=True, check=True)


@pytest.fixture(scope="session")
def rust_detections() -> dict[str, list[dict]]:
    """`coppertag detect --json` on every fixture, by image path (with the
    pose for fx = fy = 1000, cx = cy = 511.5, tag side 0.05 m)."""
    paths = [str(p) for p in fixture_paths()]
    out = run_cli("detect", *paths, "--json", "--fx", "1000", "--fy", "1000", "--cx", "511.5",
                  "--cy", "511.5", "--tag-size", "0.05")
    lines = [json.loads(line) for line in out.stdout.splitlines() if line.strip()]
    assert len(lines) == len(paths)
    return {line["image"]: line["detections"] for line in lines}
