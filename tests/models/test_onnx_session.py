"""One onnxruntime set-up for every session: detectors and the MoM encoder get the same one."""

from __future__ import annotations

from pathlib import Path

import onnxruntime as ort
import pytest

from common.errors import MomlocError
from common.onnx_session import open_session, session_options
from models.detector import create_detector
from models.detector.nanodet import NanoDetDetector
from models.detector.runtimes import OnnxRuntimeGraph
from models.mom.runtime import MomRuntime
from service.settings import DEMO_MODEL_DIR


def _assert_project_settings(options: ort.SessionOptions, threads: int) -> None:
    assert options.graph_optimization_level == ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    assert options.execution_mode == ort.ExecutionMode.ORT_SEQUENTIAL
    assert options.inter_op_num_threads == 1
    assert options.intra_op_num_threads == threads
    assert options.get_session_config_entry("session.intra_op.allow_spinning") == "0"


def test_session_options_are_the_documented_ones() -> None:
    _assert_project_settings(session_options(3), 3)
    assert 1 <= session_options().intra_op_num_threads <= 4


def test_encoder_and_detector_sessions_share_the_settings() -> None:
    runtime = MomRuntime.load(DEMO_MODEL_DIR, threads=1)
    _assert_project_settings(runtime._session.get_session_options(), 1)
    detector = create_detector("nanodet", threads=2, runtime="onnxruntime")
    assert isinstance(detector, NanoDetDetector) and isinstance(detector.graph, OnnxRuntimeGraph)
    _assert_project_settings(detector.graph.session.get_session_options(), 2)


def test_unloadable_files_are_one_line_errors(tmp_path: Path) -> None:
    with pytest.raises(MomlocError, match=r"^ONNX encoder .*missing\.onnx: file not found$"):
        open_session(tmp_path / "missing.onnx", what="ONNX encoder")
    broken = tmp_path / "broken.onnx"
    broken.write_bytes(b"not a protobuf")
    with pytest.raises(MomlocError, match=r"broken\.onnx: not a loadable ONNX model \(") as info:
        open_session(broken)
    assert "\n" not in str(info.value)
