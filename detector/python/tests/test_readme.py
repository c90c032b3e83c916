"""The README's Python examples run as written (the camera loop's per-frame
part on a fixture image: there is no camera here)."""

from __future__ import annotations

import re

import cv2
import numpy as np
from conftest import FIXTURES, REPO


def python_blocks() -> list[str]:
    text = (REPO / "README.md").read_text()
    section = text.split("\n## Python\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```python\n(.*?)```", section, flags=re.S)


def test_api_example_runs() -> None:
    (example,) = [b for b in python_blocks() if "generate_svg" in b]
    exec(compile(example, "README.md", "exec"), {"__name__": "readme"})


def test_camera_loop_annotates_a_frame() -> None:
    (loop,) = [b for b in python_blocks() if "VideoCapture" in b]
    namespace = {"__name__": "readme"}  # not "__main__": no camera, no window
    exec(compile(loop, "README.md", "exec"), namespace)
    frame = cv2.imread(str(FIXTURES / "ct14" / "42.png"), cv2.IMREAD_COLOR)
    before = frame.copy()
    out = namespace["annotate"](frame)
    assert out is frame
    changed = np.any(out != before, axis=2)
    # Green outline drawn along the data square's edges (255.5 .. 768.5).
    assert changed[256, 400:600].any() and changed[400:600, 768].any()
    green = (out[..., 1] == 255) & (out[..., 0] == 0) & (out[..., 2] == 0)
    assert green.sum() > 4 * 400
