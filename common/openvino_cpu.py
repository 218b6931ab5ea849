"""The one place OpenVINO is used: one ``Core`` per process, models compiled per input shape.

Why one ``Core``: OpenVINO's Python API is not safe with several ``Core`` objects alive in one
process; creating a second one and loading models through it crashes the process at random
later (a segmentation fault without a Python traceback: our test suite died so once in CI, and
Ultralytics traced the same crash to one ``Core`` per model load). The detector and the
keypoint network both compile through :func:`shared_core`.

Why one compiled model per input shape: OpenVINO's dynamic-shape path cost more CPU per frame
than a static model in the measurement (``bench/results/detector_runtimes.md``), and a camera
set's shapes are few and fixed, so each new shape is compiled once on first use. The compiled
model is kept next to its request so neither outlives the other.

The CPU settings mirror :mod:`common.onnx_session`: ``threads`` inference threads, one stream,
latency first, no pinning (the cameras' threads share these cores), and FP32 arithmetic where a
graph is not quantized. Why the last: on a CPU with native bfloat16 (Intel AMX or AVX512-BF16)
OpenVINO computes FP32 graphs in bfloat16 unless told otherwise; on such a machine (an Intel
Xeon with AMX, 2026-12-06) the "fp32" detector's scores drifted from the TensorFlow graph by up
to 0.0056 and the keypoint network's joints by more than their recorded tolerance, while
onnxruntime and the earlier AMD machines matched (``tests/models/test_detector_runtimes.py``,
``tests/models/test_keypoints_blazepose.py``). The engine a user picks must compute what its
name says on every machine; its speed is measured in ``bench/results/detector_runtimes.md``.
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import numpy as np

from common.errors import MomlocError
from common.onnx_session import default_threads


@functools.cache
def shared_core() -> Any:
    """The process's OpenVINO ``Core`` (imported on first use: OpenVINO is optional)."""
    import openvino

    return openvino.Core()


def read_model(path: Path, what: str) -> Any:
    """The ONNX or IR file at ``path``, or one :class:`MomlocError` naming ``what``."""
    if not path.is_file():
        raise MomlocError(f"{what} {path}: file not found")
    try:
        return shared_core().read_model(str(path))
    except Exception as error:  # OpenVINO raises its own RuntimeError subclasses
        first = (str(error).strip().splitlines() or [type(error).__name__])[0]
        kind = "ONNX" if path.suffix == ".onnx" else "OpenVINO"
        raise MomlocError(
            f"{what} {path}: not a loadable {kind} model (OpenVINO: {first})"
        ) from None


class CompiledPerShape:
    """``model`` compiled for the CPU once per input shape of its one input ``input_name``."""

    def __init__(self, model: Any, input_name: str, threads: int | None) -> None:
        self._model = model
        self._input_name = input_name
        self._config = {
            "INFERENCE_NUM_THREADS": default_threads(threads),
            "NUM_STREAMS": 1,
            "PERFORMANCE_HINT": "LATENCY",
            "ENABLE_CPU_PINNING": False,
            "INFERENCE_PRECISION_HINT": "f32",
        }
        self._compiled: dict[tuple[int, ...], tuple[Any, Any]] = {}

    def infer(self, batch: np.ndarray, outputs: tuple[str, ...]) -> list[np.ndarray]:
        """``outputs`` for ``batch``, copied out of OpenVINO's buffers (reused by the next call)."""
        shape = tuple(int(v) for v in batch.shape)
        entry = self._compiled.get(shape)
        if entry is None:
            model = self._model.clone()
            model.reshape({self._input_name: list(shape)})
            compiled = shared_core().compile_model(model, "CPU", self._config)
            entry = self._compiled[shape] = (compiled, compiled.create_infer_request())
        result = entry[1].infer({self._input_name: batch})
        return [np.asarray(result[name]).copy() for name in outputs]
