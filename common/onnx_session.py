"""The one place an onnxruntime session is created (person detectors and the MoM encoder).

Why one helper: the detector and the encoder share two cores with the camera workers, so both
need the same settings, and a copy drifts (the encoder's copy had lost the graph optimisation
and sequential-execution settings). The settings:

- ``intra_op_num_threads`` = ``threads`` (default: the CPUs this process may use, at most 4);
- ``inter_op_num_threads`` = 1 and sequential execution: these graphs are chains;
- thread spinning off, so idle inference threads do not steal the CPU the camera workers need;
- ``ORT_ENABLE_ALL`` graph optimisations (constant folding and operator fusion at load);
- warnings only at ERROR level (onnxruntime logs benign initializer warnings per model).

A missing or unloadable file raises :class:`~common.errors.MomlocError` naming it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from common.errors import MomlocError, shorten

if TYPE_CHECKING:  # imported when a session is made: `momloc --help` need not load it
    import onnxruntime as ort

MAX_DEFAULT_THREADS = 4


def default_threads(threads: int | None = None) -> int:
    """``threads``, or by default the CPUs this process may use, at most 4 (every inference
    runtime of the project: onnxruntime here, OpenVINO and ncnn in models.detector.runtimes)."""
    if threads:
        return int(threads)
    return max(1, min(MAX_DEFAULT_THREADS, len(os.sched_getaffinity(0))))


def session_options(threads: int | None = None) -> ort.SessionOptions:
    """The project's CPU session settings (see the module docstring)."""
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = default_threads(threads)
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.add_session_config_entry("session.intra_op.allow_spinning", "0")
    options.log_severity_level = 3
    return options


def open_session(
    path: str | Path, threads: int | None = None, what: str = "ONNX model"
) -> ort.InferenceSession:
    """A CPU session for the ONNX file ``path``, or one :class:`MomlocError` naming ``what``."""
    import onnxruntime as ort

    path = Path(path)
    shown = shorten(path)
    if not path.is_file():
        raise MomlocError(f"{what} {shown}: file not found")
    try:
        return ort.InferenceSession(
            str(path), session_options(threads), providers=["CPUExecutionProvider"]
        )
    except Exception as error:  # onnxruntime raises its own Fail/InvalidProtobuf/... types
        text = str(error).strip()
        first_line = text.splitlines()[0] if text else type(error).__name__
        raise MomlocError(
            shorten(f"{what} {shown}: not a loadable ONNX model ({first_line})", 300)
        ) from None
