"""The inference runtimes NanoDet's graph runs under: onnxruntime, OpenVINO, ncnn.

Why several: on a small machine the detector's CPU time decides how many frame sets are detected
(the rest carry boxes), and the runtimes differ in CPU time on the same graph; which one is
fastest was measured, not assumed (``bench/results/detector_runtimes.md``,
``bench/detector/runtimes.py``). Every runtime computes the same function: uint8 BGR NHWC batch
in, NanoDet's ``person`` [N, A, 5] out (``models.detector.nanodet``), and the test suite checks
each against TensorFlow's reference outputs.

- **onnxruntime** always works (a base dependency): the fallback.
- **openvino** (``pip install momloc[openvino]``) reads the same ONNX file; it compiles one
  static-shape model per input shape (batch, height, width) on first use, because its dynamic-
  shape path cost more CPU in the measurement.
- **ncnn** runs ``nanodet_person.ncnn.param/.bin``, converted offline from the ONNX file by
  ``tools/convert_nanodet_ncnn.py``: NanoDet's native runtime. ncnn has no batch: one extractor
  per frame, each normalised by ncnn itself. It uses OpenMP, whose threads spin after each
  layer by default; on the shared 2-core machine that spinning took many times the CPU of the
  inference itself at two threads, so ``OMP_WAIT_POLICY=PASSIVE`` is set before ncnn is first
  imported unless the user set it. Only the shipped model exists for ncnn (a user's ONNX file
  would need the converter).

``runtime: auto`` takes the first of :data:`PREFERRED` that imports, and logs one line when it
falls back, so a missing optional runtime is visible but never fatal.
"""

from __future__ import annotations

import importlib.util
import logging
import os
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np

from common.errors import MomlocError
from common.onnx_session import default_threads, open_session

Runtime = Literal["auto", "onnxruntime", "openvino", "ncnn"]
# Least CPU first at one thread (the daemon's detector beside the pipeline), by
# bench/results/detector_runtimes.md; onnxruntime last: it always imports. At two threads the
# order between runs on the shared machine was not stable, so one order serves all.
PREFERRED: tuple[str, ...] = ("ncnn", "openvino", "onnxruntime")
# How each gets installed: ncnn and onnxruntime are base dependencies, OpenVINO is an extra.
INSTALL = {
    "onnxruntime": "pip install momloc",
    "ncnn": "pip install momloc",
    "openvino": "pip install 'momloc[openvino]'",
}
INPUT_NAME = "images"
OUTPUT_NAME = "person"
MEAN_BGR = (103.53, 116.28, 123.675)
STD_BGR = (57.375, 57.12, 58.395)
log = logging.getLogger(__name__)


class NanoDetGraph(Protocol):
    """NanoDet's graph under one runtime."""

    runtime: str

    def run(self, batch: np.ndarray) -> np.ndarray:
        """uint8 BGR [N, H, W, 3] (H, W multiples of 32) → float32 ``person`` [N, A, 5]."""
        ...


def installed(runtime: str) -> bool:
    """Whether ``runtime``'s Python package imports here (each is named as its package)."""
    return importlib.util.find_spec(runtime) is not None


def choose_runtime(runtime: Runtime, user_model: bool) -> str:
    """The runtime ``auto`` stands for here (the first installed of :data:`PREFERRED`; ncnn only
    for the shipped model), or ``runtime`` itself when it is installed; else MomlocError."""
    if runtime == "auto":
        candidates = [c for c in PREFERRED if not (c == "ncnn" and user_model)]
        for candidate in candidates:
            if installed(candidate):
                if candidate != candidates[0]:
                    log.info(
                        "detector runtime: %s is not installed, using %s (%s for the faster one)",
                        candidates[0],
                        candidate,
                        INSTALL[candidates[0]],
                    )
                return candidate
        raise MomlocError("detector runtime: none installed (onnxruntime is a dependency)")
    if runtime not in INSTALL:
        raise MomlocError(f"detector runtime {runtime!r} is unknown (choose one of: auto, "
                          f"{', '.join(INSTALL)})")  # fmt: skip
    if not installed(runtime):
        raise MomlocError(
            f"detector runtime {runtime!r} is not installed ({INSTALL[runtime]}, or runtime: auto)"
        )
    if runtime == "ncnn" and user_model:
        raise MomlocError(
            "detector runtime 'ncnn' runs the shipped NanoDet only (a model_path needs "
            "runtime onnxruntime or openvino)"
        )
    return runtime


class OnnxRuntimeGraph:
    """The ONNX file under onnxruntime (the project's session settings, common.onnx_session)."""

    runtime = "onnxruntime"

    def __init__(self, path: Path, threads: int | None) -> None:
        self.path = path
        self.session = open_session(path, threads, what="detector model")
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        ok = (
            len(inputs) == 1
            and inputs[0].name == INPUT_NAME
            and inputs[0].type == "tensor(uint8)"
            and len(inputs[0].shape) == 4
            and any(o.name == OUTPUT_NAME for o in outputs)
        )
        if not ok:
            got = ", ".join(f"{i.name} {i.type} {i.shape}" for i in inputs)
            raise MomlocError(
                f"detector model {path}: not a NanoDet person model (expected uint8 "
                f"input {INPUT_NAME!r} [N, H, W, 3] and output {OUTPUT_NAME!r}; got {got})"
            )

    def run(self, batch: np.ndarray) -> np.ndarray:
        (raw,) = self.session.run([OUTPUT_NAME], {INPUT_NAME: batch})
        return np.asarray(raw)


class OpenVinoGraph:
    """The ONNX file under OpenVINO's CPU plugin, FP32, one compiled model per input shape."""

    runtime = "openvino"

    def __init__(self, path: Path, threads: int | None) -> None:
        import openvino

        if not path.is_file():
            raise MomlocError(f"detector model {path}: file not found")
        self.path = path
        self._core = openvino.Core()
        try:
            self._model = self._core.read_model(str(path))
        except Exception as error:  # OpenVINO raises its own RuntimeError subclasses
            first = (str(error).strip().splitlines() or [type(error).__name__])[0]
            raise MomlocError(
                f"detector model {path}: not a loadable ONNX model (OpenVINO: {first})"
            ) from None
        names = [port.get_any_name() for port in self._model.inputs]
        outputs = {name for port in self._model.outputs for name in port.get_names()}
        if names != [INPUT_NAME] or OUTPUT_NAME not in outputs:
            raise MomlocError(
                f"detector model {path}: not a NanoDet person model (inputs {names}, expected "
                f"[{INPUT_NAME!r}] and output {OUTPUT_NAME!r})"
            )
        self._config = {
            "INFERENCE_NUM_THREADS": default_threads(threads),
            "NUM_STREAMS": 1,
            "PERFORMANCE_HINT": "LATENCY",
            "ENABLE_CPU_PINNING": False,  # the cameras' threads share these cores
        }
        self._requests: dict[tuple[int, ...], Any] = {}

    def run(self, batch: np.ndarray) -> np.ndarray:
        shape = tuple(int(v) for v in batch.shape)
        request = self._requests.get(shape)
        if request is None:
            model = self._model.clone()
            model.reshape({INPUT_NAME: list(shape)})
            compiled = self._core.compile_model(model, "CPU", self._config)
            request = self._requests[shape] = compiled.create_infer_request()
        result = request.infer({INPUT_NAME: batch})
        return np.asarray(result[OUTPUT_NAME]).copy()


class NcnnGraph:
    """The converted ncnn files (``tools/convert_nanodet_ncnn.py``), one extractor per frame."""

    runtime = "ncnn"

    def __init__(self, param: Path, weights: Path, threads: int | None) -> None:
        os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before libgomp loads: see above
        import ncnn

        for path in (param, weights):
            if not path.is_file():
                raise MomlocError(f"detector model {path}: file not found")
        self.path = weights
        self._ncnn = ncnn
        self._net = ncnn.Net()
        self._net.opt.num_threads = default_threads(threads)
        self._net.opt.openmp_blocktime = 0
        if self._net.load_param(str(param)) != 0 or self._net.load_model(str(weights)) != 0:
            raise MomlocError(f"detector model {param}: not loadable by ncnn")
        self._scale = [1.0 / s for s in STD_BGR]

    def run(self, batch: np.ndarray) -> np.ndarray:
        ncnn = self._ncnn
        outputs = []
        for image in batch:
            height, width = image.shape[:2]
            mat = ncnn.Mat.from_pixels(image, ncnn.Mat.PixelType.PIXEL_BGR, width, height)
            mat.substract_mean_normalize(MEAN_BGR, self._scale)
            with self._net.create_extractor() as extractor:
                extractor.input("in0", mat)
                status, out = extractor.extract("out0")
                if status != 0:
                    raise MomlocError(f"detector model {self.path}: ncnn failed ({status})")
                outputs.append(np.array(out))
        return np.stack(outputs)


def open_graph(
    runtime: Runtime, onnx_path: Path, ncnn_files: tuple[Path, Path] | None, threads: int | None
) -> NanoDetGraph:
    """NanoDet's graph under ``runtime``; ``ncnn_files`` (param, bin) is None for a user's model."""
    chosen = choose_runtime(runtime, user_model=ncnn_files is None)
    if chosen == "ncnn" and ncnn_files is not None:
        return NcnnGraph(*ncnn_files, threads)
    if chosen == "openvino":
        return OpenVinoGraph(onnx_path, threads)
    return OnnxRuntimeGraph(onnx_path, threads)
