"""The converters' checksum file is the one the loaders verify (``verify_shipped``): a format
drift would make every shipped model fail at start."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from common.errors import MomlocError
from models.detector.base import verify_shipped

TOOL = Path(__file__).resolve().parents[2] / "tools" / "convert_nanodet.py"


def test_a_written_checksum_passes_and_a_changed_file_fails(tmp_path: Path) -> None:
    spec = importlib.util.spec_from_file_location("convert_nanodet", TOOL)
    assert spec is not None and spec.loader is not None
    converter = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(converter)
    model = tmp_path / "person.onnx"
    model.write_bytes(b"weights")
    converter.write_checksum(model)
    verify_shipped(model)
    model.write_bytes(b"weights, damaged")
    with pytest.raises(MomlocError, match="checksum mismatch"):
        verify_shipped(model)
