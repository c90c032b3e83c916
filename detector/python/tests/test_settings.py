"""Detector keywords: the Rust config's fields, defaults and validation."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import coppertag

STUB = Path(__file__).resolve().parents[1] / "coppertag.pyi"


def stub_defaults() -> dict[str, object]:
    """Keyword defaults written in the type stub's Detector.__init__."""
    tree = ast.parse(STUB.read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Detector")
    init = next(n for n in cls.body if isinstance(n, ast.FunctionDef) and n.name == "__init__")
    args = init.args
    out = {a.arg: ast.literal_eval(d) for a, d in zip(args.kwonlyargs, args.kw_defaults)}
    out[args.args[-1].arg] = ast.literal_eval(args.defaults[-1])
    return out


def test_every_config_field_is_a_keyword_with_its_default() -> None:
    defaults = stub_defaults()
    assert defaults.pop("families") == ("ct14", "ct8")
    assert defaults == coppertag.DEFAULT_SETTINGS
    det = coppertag.Detector()
    assert det.settings == coppertag.DEFAULT_SETTINGS
    assert [name for name, _ in det.families] == ["ct14", "ct8"]


def test_keywords_reach_the_detector() -> None:
    det = coppertag.Detector(families=["ct8"], downsample=1, dp_epsilon=2, recover_occluded=False)
    assert det.settings["downsample"] == 1
    assert det.settings["dp_epsilon"] == 2.0
    assert det.settings["recover_occluded"] is False
    assert det.families == [("ct8", 3)]
    assert coppertag.Detector(families=[("ct8", 1)]).families == [("ct8", 1)]


@pytest.mark.parametrize(
    ("setting", "value"),
    [
        ("downsample", 3),
        ("threshold_radius", 0),
        ("threshold_offset", 300),
        ("threshold_offset", -1),
        ("dp_epsilon", 0.0),
        ("dp_epsilon", float("nan")),
        ("corner_min_angle_deg", 95.0),
        ("max_candidates", 0),
        ("threads", 257),
        ("recover_occluded", 1),
        ("pin_threads", 1),
        ("min_line_length", 2 ** 70),
    ],
)
def test_bad_value_names_the_setting(setting, value) -> None:
    with pytest.raises(ValueError, match=f"invalid parameter {setting}"):
        coppertag.Detector(**{setting: value})


def test_bad_families() -> None:
    with pytest.raises(ValueError, match="unknown tag family 'ct99'"):
        coppertag.Detector(families=["ct99"])
    with pytest.raises(ValueError, match="families: at least one"):
        coppertag.Detector(families=[])
    with pytest.raises(ValueError, match="listed twice"):
        coppertag.Detector(families=["ct8", "ct8"])
    with pytest.raises(TypeError, match="not a string"):
        coppertag.Detector(families="ct14")


def test_unknown_keyword_and_wrong_type() -> None:
    with pytest.raises(TypeError, match="unknown setting 'downsampling'"):
        coppertag.Detector(downsampling=2)
    with pytest.raises(TypeError, match="setting downsample: expected a number"):
        coppertag.Detector(downsample="2")
