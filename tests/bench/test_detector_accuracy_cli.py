"""Command-line parsing of the detector benchmark (model files and variants per kind)."""

from __future__ import annotations

import pytest

from bench.detector.accuracy import parse_models, parse_variant
from common.errors import MomlocError


def test_variants_become_constructor_options_with_a_readable_label() -> None:
    assert parse_variant("nanodet:input_size=416,320") == (
        "nanodet 416x320",
        "nanodet",
        {"input_size": (416, 320)},
    )
    assert parse_variant("ssdlite:letterbox=true")[2] == {"letterbox": True}
    assert parse_variant("x:score_threshold=0.25")[2] == {"score_threshold": 0.25}


@pytest.mark.parametrize("bad", ["nanodet", "nanodet:input_size", ":a=1"])
def test_bad_variant_is_one_clear_error(bad: str) -> None:
    with pytest.raises(MomlocError, match="KIND:OPTION=VALUE"):
        parse_variant(bad)


def test_model_paths_per_kind() -> None:
    assert parse_models(["yolov8=/m/y.onnx"]) == {"yolov8": "/m/y.onnx"}
    with pytest.raises(MomlocError, match="KIND=PATH"):
        parse_models(["yolov8"])
