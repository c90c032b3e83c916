"""The Python detector against the Rust CLI, and the input layouts it takes."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import fixture_paths, read_grey

import coppertag

CORNER_TOL_PX = 1e-9
POSE_TOL = 1e-9


@pytest.fixture(scope="module")
def detector() -> coppertag.Detector:
    return coppertag.Detector()


def key(dets):
    return [(d.family, d.id) for d in dets]


def same(a, b) -> None:
    """Two detection lists are identical (ids, corners to the bit)."""
    assert key(a) == key(b)
    for x, y in zip(a, b):
        assert np.array_equal(x.corners, y.corners)
        assert x.estimated == y.estimated and x.corrected == y.corrected


@pytest.mark.parametrize("path", fixture_paths(), ids=lambda p: f"{p.parent.name}-{p.stem}")
def test_same_detections_as_the_cli(path, detector, rust_detections) -> None:
    found = detector.detect(read_grey(path))
    expected = rust_detections[str(path)]
    assert [(d.family, d.id) for d in found] == [(e["family"], e["id"]) for e in expected]
    assert len(found) == 1 and found[0].id == int(path.stem)
    for d, e in zip(found, expected):
        assert np.abs(d.corners - np.array(e["corners"])).max() <= CORNER_TOL_PX
        assert list(d.estimated) == e["estimated"]
        assert d.corrected == e["corrected"]
        assert d.corner_sigma == pytest.approx(tuple(e["corner_sigma"]), abs=CORNER_TOL_PX)
        best, alternative = d.pose(1000.0, 1000.0, 511.5, 511.5, 0.05)
        for ours, theirs in ((best, e["pose"]["best"]), (alternative, e["pose"]["alternative"])):
            assert np.abs(ours.rotation - np.array(theirs["rotation"])).max() <= POSE_TOL
            assert np.abs(ours.translation - np.array(theirs["translation"])).max() <= POSE_TOL


def test_detection_fields(detector) -> None:
    img = read_grey(fixture_paths()[0])
    (d,) = detector.detect(img)
    assert d.corners.shape == (4, 2) and d.corners.dtype == np.float64
    # The fixtures' data square corners sit at 255.5 and 768.5 (README).
    np.testing.assert_allclose(d.corners, [[255.5, 255.5], [255.5, 768.5], [768.5, 768.5], [768.5, 255.5]], atol=0.05)
    assert d.center == pytest.approx((512.0, 512.0), abs=0.05)
    # A sharp, whole 513 px tag: every corner measured, to a tenth of a pixel
    # or so (the floor of the uncertainty is 0.1 px).
    assert d.corner_sigma is not None and all(0.1 <= s < 0.5 for s in d.corner_sigma)
    h = d.homography
    assert h.shape == (3, 3)
    # The homography maps tag units (corner TL = (-0.5, -0.5)) onto the corners.
    for (u, v), corner in zip([(-0.5, -0.5), (-0.5, 0.5), (0.5, 0.5), (0.5, -0.5)], d.corners):
        p = h @ [u, v, 1.0]
        np.testing.assert_allclose(p[:2] / p[2], corner, atol=1e-6)
    assert d.contrast > 100
    assert "Detection(family=" in repr(d)


def test_pose_both_solutions_best_first(detector) -> None:
    (d,) = detector.detect(read_grey(fixture_paths()[0]))
    best, alternative = d.pose(1000.0, 1000.0, 511.5, 511.5, 0.05)
    assert best.reprojection_error <= alternative.reprojection_error
    # Square, centred, seen face-on: identity rotation, z = f * side / side_px.
    side_px = 768.5 - 255.5
    np.testing.assert_allclose(best.rotation, np.eye(3), atol=1e-3)
    np.testing.assert_allclose(best.rotation_vector, np.zeros(3), atol=1e-3)
    assert best.translation[2] == pytest.approx(1000.0 * 0.05 / side_px, rel=1e-3)
    with pytest.raises(ValueError, match="tag_side"):
        d.pose(1000.0, 1000.0, 511.5, 511.5, -1.0)
    with pytest.raises(ValueError, match="intrinsics"):
        d.pose(0.0, 1000.0, 511.5, 511.5, 0.05)
    with pytest.raises(ValueError, match="intrinsics"):
        d.pose(1000.0, 1000.0, float("nan"), 511.5, 0.05)


def test_rotation_vector_of_an_upside_down_tag(detector) -> None:
    img = read_grey(fixture_paths()[0])
    (d,) = detector.detect(img[::-1, ::-1])  # the tag turned by 180 degrees
    best, _ = d.pose(1000.0, 1000.0, 511.5, 511.5, 0.05)
    r = best.rotation_vector
    assert np.linalg.norm(r) == pytest.approx(np.pi, abs=1e-3)
    assert abs(r[2]) == pytest.approx(np.pi, abs=1e-3)


def test_roi_slice_is_read_in_place(detector) -> None:
    img = read_grey(fixture_paths()[0])
    canvas = np.full((1400, 1500), 255, np.uint8)
    canvas[100:1124, 200:1224] = img
    roi = canvas[100:1124, 200:1224]
    assert not roi.flags.c_contiguous and coppertag.reads_in_place(roi)
    same(detector.detect(roi), detector.detect(img))


def test_non_contiguous_every_other_pixel(detector) -> None:
    img = read_grey(fixture_paths()[0])
    half = img[::2, ::2]
    assert not coppertag.reads_in_place(half)
    found = detector.detect(half)
    assert key(found) == key(detector.detect(img))
    same(found, detector.detect(np.ascontiguousarray(half)))
    rows = img[::2, :]
    assert coppertag.reads_in_place(rows)
    same(detector.detect(rows), detector.detect(np.ascontiguousarray(rows)))


def test_fortran_order_and_negative_strides(detector) -> None:
    img = read_grey(fixture_paths()[3])
    fortran = np.asfortranarray(img)
    assert not coppertag.reads_in_place(fortran)
    same(detector.detect(fortran), detector.detect(img))
    flipped = img[::-1, ::-1]
    assert not coppertag.reads_in_place(flipped)
    same(detector.detect(flipped), detector.detect(np.ascontiguousarray(flipped)))


def test_read_only_array(detector) -> None:
    img = read_grey(fixture_paths()[0])
    img.flags.writeable = False
    assert key(detector.detect(img)) == [("ct14", 0)]


def test_wrong_dtype(detector) -> None:
    with pytest.raises(TypeError, match="dtype uint8.*float32"):
        detector.detect(np.zeros((100, 100), np.float32))


def test_wrong_ndim(detector) -> None:
    with pytest.raises(ValueError, match="must be 2-D.*1 dimension"):
        detector.detect(np.zeros(100, np.uint8))


def test_colour_image_says_to_convert(detector) -> None:
    with pytest.raises(ValueError, match="3 channels.*cv2.cvtColor"):
        detector.detect(np.zeros((100, 100, 3), np.uint8))


def test_empty_array(detector) -> None:
    with pytest.raises(ValueError, match="empty"):
        detector.detect(np.zeros((0, 100), np.uint8))


def test_one_by_one_array(detector) -> None:
    with pytest.raises(ValueError, match="1 x 1 pixels; at least 20 x 20"):
        detector.detect(np.zeros((1, 1), np.uint8))


def test_not_an_array(detector) -> None:
    with pytest.raises(TypeError, match="numpy array.*list"):
        detector.detect([[0] * 50] * 50)


def test_blank_frame_has_no_tags(detector) -> None:
    assert detector.detect(np.full((240, 320), 200, np.uint8)) == []
    assert detector.detect(np.zeros((20, 20), np.uint8)) == []


def test_stats_per_stage(detector) -> None:
    detector.detect(read_grey(fixture_paths()[0]))
    stats = detector.stats
    assert list(stats) == ["downsample", "threshold", "contours", "lines", "corners", "ellipses",
                           "quads", "decode", "small", "rim", "dedup", "verify", "total"]
    assert stats["total"] > 0
    assert sum(v for k, v in stats.items() if k != "total") <= stats["total"] * 1.0001
