"""Tag generation: the same pixels and SVG as `coppertag generate`."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from conftest import run_cli

import coppertag


@pytest.mark.parametrize(("family", "tag_id"), [("ct14", 42), ("ct8", 65535)])
def test_png_matches_the_cli(tmp_path, family, tag_id) -> None:
    out = tmp_path / "tag.png"
    run_cli("generate", "--family", family, "--id", str(tag_id), "--px", "300", "-o", str(out))
    theirs = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    ours = coppertag.generate(family, tag_id, px=300)
    assert ours.shape == (300, 300) and ours.dtype == np.uint8
    assert np.array_equal(ours, theirs)


def test_svg_matches_the_cli(tmp_path) -> None:
    out = tmp_path / "tag.svg"
    run_cli("generate", "--family", "ct8", "--id", "7", "--size", "50mm", "-o", str(out))
    assert coppertag.generate_svg("ct8", 7, size_mm=50.0) == out.read_text()


def test_generated_tag_is_detected() -> None:
    img = np.pad(coppertag.generate("ct8", 4097, px=240), 40, constant_values=255)
    found = coppertag.Detector().detect(img)
    assert [(d.family, d.id) for d in found] == [("ct8", 4097)]


def test_bad_input() -> None:
    with pytest.raises(ValueError, match="unknown tag family"):
        coppertag.generate("ct9", 1)
    with pytest.raises(ValueError, match="out of range"):
        coppertag.generate("ct14", 256)
    with pytest.raises(ValueError, match="px: 15 .must be 16..=16384"):
        coppertag.generate("ct14", 1, px=15)
    with pytest.raises(ValueError, match="px"):
        coppertag.generate("ct14", 1, px=100_000)
    with pytest.raises(ValueError):
        coppertag.generate_svg("ct14", 1, size_mm=-3.0)
    with pytest.raises(OverflowError):
        coppertag.generate("ct14", -1)
